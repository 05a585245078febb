"""The GPU interface, no rendering in it: the numbers the shaders share with Python (glsl_constants,
gpu_layout), the shader loader, the GL context, GPU timers, and the float32 ranges of what reaches
the GPU.
"""
