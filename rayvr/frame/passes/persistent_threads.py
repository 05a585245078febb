"""Persistent threads for the wavefront's trace kernels (Aila and Laine 2009, "Understanding
the efficiency of ray traversal on GPUs"): in place of one invocation per ray, a fixed number of work
groups, about what the GPU holds resident at once, and each invocation fetches its next ray from an
atomic counter of the kernel whenever it is done with one, until the batch's rays are all taken
(glsl/rt/wave_fetch.glsl). Incoherent rays take very different times; with fetching, a SIMD group
whose rays ended early takes new ones instead of the GPU waiting on a new group being launched.
Each ray's result goes to its own slot as before: the images are exactly those of one ray per
invocation. On the GPU it changes nothing within 1 % (`rayvr bench rays --persistent off,on`,
docs/design.md): these kernels have no long tail for it to remove."""
from __future__ import annotations


from .compute import RT_LOCAL_SIZE
from ...options import plan_part


# Work groups (of RT_LOCAL_SIZE, 64 invocations) a persistent trace kernel launches: a GPU of 132
# SMs holds 16 such groups each at half occupancy (32 of 64 warps), 2112 in all (not tuned: the mode
# measured no different from off).
PERSISTENT_GROUPS = 2048


def persistent_groups(capacity: int) -> int:
    """Work groups of a persistent trace kernel over at most `capacity` rays: no more than
    one ray per invocation would keep busy."""
    return max(1, min(PERSISTENT_GROUPS, -(-capacity // RT_LOCAL_SIZE)))


@plan_part("persistent")
def persistent_plan(ask, plan) -> None:
    plan["persistent"] = ask.settings.persistent == "on"
