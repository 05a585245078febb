"""A digest of numpy arrays: their dtypes, shapes and bytes, so equal arrays of another layout or
type never share one (the BVH disk cache's key, a scene's smooth surfaces' cache)."""
from __future__ import annotations

import hashlib

import numpy as np


def arrays_digest(*arrays) -> str:
    """blake2b (16 bytes, hex) over each array's dtype, shape and contiguous bytes, in order."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()
