"""`classify`: the G-buffer's effect channel -> one list of packed pixels per traced effect plus the
indirect-dispatch sizes, in one dispatch (glsl/rt/classify.comp; layout glsl/rt/pixel_list.glsl).
Each traced effect's passes then run over their own list only, both eyes at once."""
from __future__ import annotations

import moderngl
import numpy as np

from ...gl import shaders
from ..effect_registry import traced_effects
from ..graph import Buffer, FramePlan, Pass, read, write
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
from .primary_rays import bind_round_skip, round_skip_defines, round_skip_reads
from .compute import dispatch_frame
from .reuse import bind_reuse, reuse_defines, reuse_reads

ARGS_BYTES = 16  # per list: uvec4 (groups x, groups y, groups z, pixel count)


def list_slots() -> int:
    """Lists the shaders hold: one per traced effect of the registry (RT_SLOTS)."""
    return max(len(traced_effects()), 1)


def args_bytes() -> int:
    # After the lists' arguments: classify's running count per list and its finished-group ticket.
    return ARGS_BYTES * list_slots() + 4 * (list_slots() + 1)


MAX_LIST_EXTENT = 1 << 14  # rt_pack_pixel (glsl/rt/pixel_list.glsl) keeps x and y in 14 bits
PIXEL_LISTS = Buffer(lambda s: 4 * s.pixels * list_slots(), "4 B per eye pixel per traced effect",
                     max_extent=MAX_LIST_EXTENT)
LIST_ARGS = Buffer(lambda s: args_bytes(), "16 B per traced effect + counters", zeroed=True)


def pixel_counts(args: moderngl.Buffer) -> dict:
    """Pixels per traced effect in the last classified frame (reads back; for tests and stats)."""
    a = np.frombuffer(args.read(ARGS_BYTES * list_slots()), np.uint32).reshape(-1, 4)
    return {e.name: int(a[i, 3]) for i, e in enumerate(traced_effects())}


def bind_lists(fc) -> None:
    fc.resource("rt_lists").bind_to_storage_buffer(SSBO["rt_lists"])
    fc.resource("rt_list_args").bind_to_storage_buffer(SSBO["rt_list_args"])


# glsl/rt/classify.comp aggregation, best first: (CLASSIFY_BALLOT, the extension it needs)
BALLOT_MODES = {"khr": (1, "GL_KHR_shader_subgroup"), "arb": (2, "GL_ARB_shader_ballot"), "shared": (0, None)}


class ClassifyPass(Pass):
    """`ballot` picks the in-wave aggregation: "khr", "arb" or "shared" (no subgroup operations);
    None takes the first the context has whose shader builds."""

    name = "classify"

    def __init__(self, ballot: str | None = None, group: tuple[int, int] = (32, 16)):
        assert group[0] % 8 == 0 and group[1] % 8 == 0 and group[0] * group[1] <= 1024, group
        self.ballot, self.group, self.mode = ballot, group, None

    def io(self, plan: FramePlan) -> list:
        return [read("gbuffer"), write("rt_lists", PIXEL_LISTS), write("rt_list_args", LIST_ARGS)] + reuse_reads(plan) + \
            round_skip_reads(plan)

    def setup(self, gl, plan: FramePlan) -> None:
        modes = [self.ballot] if self.ballot else list(BALLOT_MODES)
        gx, gy = self.group
        d = {"CLASSIFY_GROUP_X": gx, "CLASSIFY_GROUP_Y": gy, "CLASSIFY_INVOCATIONS": gx * gy, **reuse_defines(plan),
             **round_skip_defines(plan)}
        for mode in modes:
            value, ext = BALLOT_MODES[mode]
            if ext and not gl.has_extension(ext) and self.ballot is None:
                continue
            try:
                self.program = shaders.compute(gl.ctx, "rt/classify.comp", {**d, "CLASSIFY_BALLOT": value})
            except shaders.ShaderError:
                if mode == modes[-1]:
                    raise
                continue
            self.mode = mode
            return

    def execute(self, fc) -> None:
        bind_lists(fc)
        bind_reuse(fc)
        bind_round_skip(fc)
        fc.gbuffer.bind_for_reading()
        w, h = fc.gbuffer.size
        self.program["rt_capacity"].value = w * h * fc.gbuffer.layers
        gx, gy = self.group
        dispatch_frame(fc, self.program, ((w + gx - 1) // gx, (h + gy - 1) // gy, fc.gbuffer.layers))
        fc.gl.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        self.program.release()
