"""`photon_kdtree`: the paper's baseline photon map, a balanced kd-tree built on the CPU
(accel/photon_map.build_kdtree) from the traced photons read back, uploaded for the GPU search
(glsl/photon/kdtree.glsl). Record 0 of the buffer is a header (word 0: the photon count), the
tree's array follows, each record's extra word its split axis. Only frames with a material on the
kd-tree estimators build it; the others upload the header alone. A frame whose photons are those
of the frame before (a still view: same seed, same map) uploads the tree it built then: the tree
is a function of the photons, and building it takes seconds on the CPU at 512² paths."""
from __future__ import annotations

import numpy as np

from ....accel.photon_map import PHOTON_WORDS, build_kdtree, unpack_photons
from ...graph import Buffer, FramePlan, read, write
from .setup import PhotonPass, photon_setup


def kdtree_records(raw: bytes) -> np.ndarray:
    """(1 + valid photons, 8) uint32: the header and the kd-tree's array of the stored photons."""
    rec = np.frombuffer(raw, np.uint32).reshape(-1, PHOTON_WORDS)
    ph = unpack_photons(rec)
    keep = rec[ph["extra"] != 0]
    order, axis = build_kdtree(keep[:, 0:3].view(np.float32))
    out = np.zeros((len(keep) + 1, PHOTON_WORDS), np.uint32)
    out[0, 0] = len(keep)
    out[1:] = keep[order]
    out[1:, 7] = axis
    return out


class PhotonKdTreePass(PhotonPass):
    name = "photon_kdtree"
    role = "the kd-tree estimators"

    def io(self, plan: FramePlan) -> list:
        return [read("photons"),
                write("photon_kdtree", Buffer(lambda s: 32 * (1 + (photon_setup(s).slots if photon_setup(s).kdtree else 0)),
                                              "32 B per photon slot when a material uses a kd-tree estimator"))]

    def setup(self, gl, plan) -> None:
        self.last = (None, None)  # the photons last built from (bytes) and their tree's records

    def execute(self, fc) -> None:
        out = fc.resource("photon_kdtree")
        if not photon_setup(fc.sizing).kdtree:
            out.write(np.zeros(PHOTON_WORDS, np.uint32).tobytes())
            return
        raw = fc.resource("photons").read()
        if raw != self.last[0]:
            self.last = (raw, kdtree_records(raw).tobytes())
        out.write(self.last[1])

    def release(self) -> None:
        self.last = (None, None)
