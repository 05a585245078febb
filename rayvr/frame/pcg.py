"""The host twin of glsl/common/random.glsl's `pcg_hash` (PCG-RXS-M-XS on 32 bits), for the numpy
reference paths and the seeds the host hands to the shaders: one definition, so the two cannot drift."""

import numpy as np


def pcg_hash(v):
    """pcg_hash on uint32: a Python int in, an int out; a numpy array in, a uint64 array (values < 2^32) out."""
    if isinstance(v, (int, np.integer)):
        state = (int(v) * 747796405 + 2891336453) & 0xFFFFFFFF
        word = (((state >> ((state >> 28) + 4)) ^ state) * 277803737) & 0xFFFFFFFF
        return (word >> 22) ^ word
    v = np.asarray(v, np.uint64) & 0xFFFFFFFF
    state = (v * 747796405 + 2891336453) & 0xFFFFFFFF
    word = (((state >> ((state >> 28) + 4)) ^ state) * 277803737) & 0xFFFFFFFF
    return (word >> 22) ^ word
