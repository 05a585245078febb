"""`photon_cells`: the hash grid's cell per photon and photons per cell (glsl/photon/cells.comp):
the (cell, slot) keys the sort orders (empty slots get the key one past the last cell) and the
counts that `photon_scan` turns into start indices. The grid (accel/photon_map.grid_shape): cells
of the largest search radius of the `photon` materials over the scene's bounds, padded."""
from __future__ import annotations

import moderngl
import numpy as np

from ....gl import shaders
from ...graph import Buffer, FramePlan, read, write
from ....gl.glsl_constants import declare
from ....gl.gpu_layout import SSBO
from ...passes.prefix_scan import dispatch_shape, scan_words
from .setup import PhotonPass, photon_setup

CELLS_GROUP = declare("PHOTON_CELLS_GROUP", 256)  # photons a cells.comp group keys


def set_grid_uniforms(program, grid) -> None:
    """grid_origin / grid_inv_cell / grid_dims of glsl/photon/photon.glsl (float32 as numpy has them)."""
    values = {"grid_origin": tuple(float(x) for x in np.float32(grid.origin)),
              "grid_inv_cell": float(np.float32(1.0) / np.float32(grid.cell)), "grid_dims": tuple(grid.dims)}
    for k, v in values.items():
        if shaders.declares(program, k):
            program[k].value = v


class CellKeys:
    """Keys and counts for `count` photon slots of a buffer, on the grid `grid`."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs = [shaders.compute(ctx, "photon/cells.comp", {"CELLS_STAGE": s}) for s in (0, 1)]

    def run(self, photons, keys, counts, count: int, grid) -> None:
        photons.bind_to_storage_buffer(SSBO["photons"])
        keys.bind_to_storage_buffer(SSBO["photon_keys"])
        counts.bind_to_storage_buffer(SSBO["photon_scan"])
        for prog, n in zip(self.programs, (grid.cells + 2, count)):
            set_grid_uniforms(prog, grid)
            prog["item_count"].value = n
            prog.run(*dispatch_shape(n, CELLS_GROUP))
            self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)

    def release(self) -> None:
        for p in self.programs:
            p.release()


class PhotonCellsPass(PhotonPass):
    name = "photon_cells"
    role = "the hash grid's cells"

    def io(self, plan: FramePlan) -> list:
        return [read("photons"),
                write("photon_keys", Buffer(lambda s: 8 * photon_setup(s).slots, "8 B (cell, slot) per photon slot")),
                write("photon_start", Buffer(lambda s: 4 * scan_words(photon_setup(s).grid.cells + 2),
                                             "4 B per grid cell (+ the scan's block totals)"))]

    def setup(self, gl, plan: FramePlan) -> None:
        self.cells = CellKeys(gl.ctx)

    def execute(self, fc) -> None:
        ps = photon_setup(fc.sizing)
        self.cells.run(fc.resource("photons"), fc.resource("photon_keys"), fc.resource("photon_start"),
                       ps.slots, ps.grid)

    def release(self) -> None:
        self.cells.release()
