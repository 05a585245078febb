"""Helpers shared by compute passes."""
from __future__ import annotations

import moderngl
import numpy as np

TILE = 8  # local_size_x/y of every per-pixel compute shader


def dispatch_per_pixel(fc, program: moderngl.ComputeShader) -> None:
    """One invocation per pixel per layer, then make the writes visible to what follows."""
    w, h = fc.gbuffer.size
    program.run((w + TILE - 1) // TILE, (h + TILE - 1) // TILE, fc.gbuffer.layers)
    fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)


def set_eye_uniforms(program, fc) -> None:
    """The per-eye camera block of glsl/common/camera.glsl (uniforms the shader does not use
    are skipped: GLSL compilers drop them)."""
    position = np.zeros((2, 3), np.float32)
    rotation = np.zeros((2, 3, 3), np.float32)
    tangents = np.zeros((2, 4), np.float32)
    for i, eye in enumerate(fc.eyes):
        position[i] = eye.position - fc.scene.origin
        rotation[i] = eye.rotation.T  # GLSL mat3 is column-major
        tangents[i] = eye.tangents
    eye = fc.eyes[0]
    values = {"eye_position": position, "eye_rotation": rotation, "eye_tangents": tangents,
              "eye_depth": np.array([eye.near, eye.far or 0.0], np.float32)}
    for name, value in values.items():
        if name in program:
            program[name].write(value.tobytes())
