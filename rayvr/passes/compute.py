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


def camera_defines(plan) -> dict:
    """CAMERA_MODEL for programs that include glsl/common/camera.glsl (the plan's camera model)."""
    from ..cameras import get_camera_model

    return get_camera_model(plan.camera).defines()


def set_eye_uniforms(program, fc) -> None:
    """The per-eye camera block of glsl/common/camera.glsl, with the values the eyes' camera
    model gives (rayvr/cameras/base.py uniforms). Uniforms the shader does not use are skipped:
    GLSL compilers drop them."""
    values = fc.eyes[0].camera.uniforms(fc.eyes, fc.scene.origin)
    for name, value in values.items():
        if name in program:
            program[name].write(value if isinstance(value, bytes) else np.ascontiguousarray(value).tobytes())
