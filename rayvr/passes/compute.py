"""Helpers shared by compute passes."""
from __future__ import annotations

import moderngl

TILE = 8  # local_size_x/y of every per-pixel compute shader


def dispatch_per_pixel(fc, program: moderngl.ComputeShader) -> None:
    """One invocation per pixel per layer, then make the writes visible to what follows."""
    w, h = fc.gbuffer.size
    program.run((w + TILE - 1) // TILE, (h + TILE - 1) // TILE, fc.gbuffer.layers)
    fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)
