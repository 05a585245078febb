"""Helpers shared by compute passes."""
from __future__ import annotations

import moderngl
import numpy as np

from ...gl.glsl_constants import declare
from ...gl.shaders import declares

TILE = declare("PIXEL_TILE", 8)  # local_size_x/y of every per-pixel compute shader
RT_LOCAL_SIZE = declare("RT_LOCAL_SIZE", 64)  # invocations per work group of the effect passes' lists


def dispatch_per_pixel(fc, program: moderngl.ComputeShader, listed: bool = False) -> None:
    """One invocation per pixel per layer (none in an MSAA round past its count; with `listed` only
    the round's listed tiles': round_gate.py), then make the writes visible to what follows."""
    dispatch_frame(fc, program, pixel_grid(fc.sizing), listed)
    fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)


def pixel_grid(sizing) -> tuple:
    """The workgroups of a per-pixel pass: TILE x TILE pixels each, per layer."""
    w, h = sizing.size
    return (w + TILE - 1) // TILE, (h + TILE - 1) // TILE, sizing.layers


def dispatch_frame(fc, program: moderngl.ComputeShader, grid: tuple, listed: bool = False) -> None:
    """A frame-wide pass of a round: `program` over `grid`; `listed` (a program built with ROUND_TILES):
    over the round's listed tiles only, where the select made them (Round.tiles, round_gate.py); else
    through the round's gate where the round may lie past its channel set's count (Round.gate), else
    directly."""
    tiles = fc.round.tiles if listed else None
    if declares(program, "round_listed"):
        program["round_listed"].value = int(tiles is not None)
    if tiles is not None:
        program.run_indirect(tiles)
    elif fc.round.gate is not None:
        fc.round.gate.dispatch(program, grid)
    else:
        program.run(*grid)


def camera_defines(plan) -> dict:
    """The defines of programs that include glsl/common/camera.glsl: the plan's camera model's
    (CameraModel.defines: its id, its GLSL file, its capabilities) and its sub-rays per sample."""
    from ..cameras import CAMERA_MODELS

    # with shared channel shading the three colour channel sets are sub-rays too (CHANNEL_SAMPLES)
    return {**CAMERA_MODELS[plan.camera].defines(), "CAMERA_SUBSAMPLES": plan.subsamples,
            "CHANNEL_SAMPLES": plan.channels if plan.share_channels else 1}


def set_eye_uniforms(program, fc) -> None:
    """The per-eye camera block of glsl/common/camera.glsl, with the values the eyes' camera
    model gives (rayvr/frame/cameras/base.py uniforms), the colour channel set of this frame round
    (fc.round) and the model's textures. Uniforms the shader does not use are skipped: GLSL
    compilers drop them. The block is computed once per frame (fc.uniform_cache): a sampled frame
    sets it for every pass of every round, and the CPU records rounds while the GPU works."""
    model = fc.eyes[0].camera
    cache = getattr(fc, "uniform_cache", None)
    block = None if cache is None else cache.get("camera")
    if block is None:
        block = {name: value if isinstance(value, bytes) else np.ascontiguousarray(value).tobytes()
                 for name, value in model.uniforms(fc.eyes, fc.scene.origin).items()}
        if cache is not None:
            cache["camera"] = block
    channel = np.array([getattr(getattr(fc, "round", None), "channel", 0)], np.int32).tobytes()
    write_uniforms(program, fc, {**block, "camera_channel": channel})
    model.bind(fc.gl)


_UNSET = object()


def write_uniforms(program, fc, values: dict) -> None:
    """Set each uniform of `values` (name -> bytes in GLSL layout, or a value moderngl takes) that
    `program` declares, unless this frame set it to that value before (fc.uniform_cache). A program
    keeps its uniforms between dispatches, and a sampled frame's passes set the same ones in every
    round: each write costs the CPU a call into the driver while the GPU may wait for commands.
    Only for uniforms nothing else writes within the frame (the cache would not see that write)."""
    cache = getattr(fc, "uniform_cache", None)
    written = {} if cache is None else cache.setdefault(("written", id(program)), {})
    for name, value in values.items():
        if written.get(name, _UNSET) == value:
            continue
        written[name] = value
        if declares(program, name):
            if isinstance(value, bytes):
                program[name].write(value)
            else:
                program[name].value = value
