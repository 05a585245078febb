"""The round gate: an MSAA round recorded before the CPU knew the channel set's count of rounds
(frame/graph.py Round.start_polled) may lie past it. Such a round used to run every pass of the
round over the whole frame to skip every pixel: about 0.3 ms a round at 2x1440x1600 on the GPU,
most of a 16x frame's rounds in the room, where pixels see two triangles and the CPU records the
eight the slots allow (docs/design.md). Instead, primary_rays runs the gate
(glsl/rt/round_gate.comp, one invocation) at the start of each such round; it reads the count on the
GPU and writes the dispatch size of each frame-wide pass of the round: its grid where the round is
within the count, nothing where it is not. The round's per-pixel passes then dispatch indirectly
from it (compute.py `dispatch_frame`), and the traced effects, which dispatch from classify's
pixel lists, find those lists emptied.

Round tiles: within the count, most of a round's pixels are still skipped (a pixel has fewer
distinct triangles than the round's slot), and each per-pixel pass over the whole frame cost ~0.05
ms to skip them. The select lists the 8x8 tiles that hold a pixel the round shades
(glsl/common/round_skip.glsl ROUND_TILES), the gate turns the list's count into a dispatch size
(`list_tiles`; the frame's grid where most tiles are listed, as in a round of slot 0), and the
gbuffer resolve, shade and sample_accumulate run one workgroup a listed tile (compute.py
`dispatch_frame(..., listed=True)`). The frame is bit-identical (tests/test_round_gate.py,
tests/test_msaa_rounds.py)."""
from __future__ import annotations

import moderngl

from ...gl import shaders
from ...gl.glsl_constants import declare
from ...gl.gpu_layout import SSBO
from .compute import pixel_grid

# Whether a round's per-pixel passes run over its listed tiles (primary_rays sets Round.tiles). A test
# hook, not a setting (tests/test_round_gate.py compares frames with and without): read afresh by each
# round, no program or resource depends on it.
LIST_TILES = True
GATE_GRIDS = declare("GATE_GRIDS", 8)  # grids the gate sizes at once (a round's frame-wide passes have two)


class RoundGate:
    """The dispatch sizes of one round that may lie past its channel set's count, on the GPU."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.args = ctx.buffer(reserve=16 * GATE_GRIDS)
        self.grids: list = []  # the grids asked for so far (the same every round and frame)
        self.programs: dict = {}  # (GATE_TILES, GATE_LISTS) -> program
        self.round = 0
        self.lists = None  # the frame's rt_list_args buffer, or None (no traced effect)

    def program(self, tiles: bool, lists: bool = False) -> moderngl.ComputeShader:
        if (tiles, lists) not in self.programs:
            self.programs[tiles, lists] = shaders.compute(self.ctx, "rt/round_gate.comp",
                                                          {"GATE_TILES": int(tiles), "ROUND_TILES": int(tiles),
                                                           "GATE_LISTS": int(lists)})
        return self.programs[tiles, lists]

    def open(self, fc, ordinal: int) -> None:
        """Size the round `ordinal` of the channel set whose count the bound msaa_count holds."""
        self.round = ordinal
        self.lists = fc.resources.get("rt_list_args")
        self.write()

    def write(self) -> None:
        program = self.program(False, self.lists is not None)
        program["msaa_round"].value = self.round
        program["gate_grid_count"].value = len(self.grids)
        if self.grids:
            program["gate_grids"].value = self.grids + [(0, 1, 1)] * (GATE_GRIDS - len(self.grids))
        self.args.bind_to_storage_buffer(SSBO["round_gate"])
        if self.lists is not None:
            self.lists.bind_to_storage_buffer(SSBO["rt_list_args"])
        program.run(1)
        self.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def dispatch(self, program: moderngl.ComputeShader, grid: tuple) -> None:
        """`program` over `grid`, if the round lies within the count. A grid not seen before (a
        frame's first gated round, or a new frame size) is added and the gate run again for it; a
        full table starts over (commands run in order: dispatches made read the sizes of their time)."""
        grid = tuple(int(g) for g in grid)
        if grid not in self.grids:
            if len(self.grids) == GATE_GRIDS:
                self.grids = []
            self.grids.append(grid)
            self.write()
        program.run_indirect(self.args, offset=16 * self.grids.index(grid))

    def list_tiles(self, tiles: moderngl.Buffer, grid: tuple) -> None:
        """After a round's select: the dispatch size of the passes over its listed tiles (`grid`, the
        frame's per-pixel grid, where most are listed)."""
        tiles.bind_to_storage_buffer(SSBO["round_tiles"])
        program = self.program(True)
        program["round_grid"].value = tuple(int(g) for g in grid)
        program.run(1)
        self.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)

    def release(self) -> None:
        for p in [self.args, *self.programs.values()]:
            p.release()


def round_tile_bytes(sizing) -> int:
    """The round tiles' buffer: the dispatch size, the running count, the whole-frame flag, a word a tile."""
    gx, gy, layers = pixel_grid(sizing)
    return 24 + 4 * gx * gy * layers
