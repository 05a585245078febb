"""The numpy references the GPU's shading and denoiser are tested against (independent of the shaders)."""
