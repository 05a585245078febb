"""What a scene is made of, for choosing where to look: its enclosing shell (walls, floors and
ceilings: the large axis-aligned planes) and its content (everything else a user looks at). The
benches' content-facing head poses (rayvr/bench/head_poses.py) and a scene's first view
(rayvr/app/viewpoint.py) gaze at the content."""
from __future__ import annotations

import math

import numpy as np

# The enclosing shell (shell_triangles): a triangle within SHELL_NORMAL_DEG of an axis lies in an
# axis-aligned plane; the plane's area is that of the triangles facing the same way whose offsets
# along the axis lie within SHELL_PLANE_M of its own; a plane of at least SHELL_SHARE of the
# scene's largest plane is shell. Printed on the bench scenes: the room's floor and ceiling are
# 64 m2, its walls 25.6 m2 (0.40), its largest other plane the mirror panel 2 cm in front of a wall
# (3.6 m2, 0.06); Sponza's largest plane is the outer box's side (577 m2), its end walls 187-193
# m2 (0.32-0.34), the colonnades' flat faces 173-177 m2 (0.30-0.31), the largest plane below them
# the aisles' flat ceilings (72 m2, 0.13). Relative to the largest plane, not to the total area:
# detailed content does not push the walls under the bar.
SHELL_NORMAL_DEG = 5.0
SHELL_PLANE_M = 0.005  # modelled walls are flat to well under this; the room's light hangs 1 cm below the ceiling
SHELL_SHARE = 0.2


def triangles(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(world vertices (T, 3, 3), unit geometric normals (T, 3), areas (T,)) of the scene's triangles."""
    tri = scene.world_vertices()[scene.indices]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(cross, axis=1)
    return tri, cross / np.maximum(length, 1e-300)[:, None], 0.5 * length


def plane_areas(scene) -> np.ndarray:
    """Per triangle, the area of its axis-aligned plane (SHELL_* above), 0 for a
    triangle in no axis-aligned plane: the same-facing triangles of its axis whose offsets along
    it lie within SHELL_PLANE_M of its own (a window round each offset, so no plane is split at a
    bin's edge)."""
    tri, normal, area = triangles(scene)
    axis = np.argmax(np.abs(normal), axis=1)
    rows = np.arange(len(tri))
    along = normal[rows, axis]
    aligned = (np.abs(along) >= math.cos(math.radians(SHELL_NORMAL_DEG))) & (area > 0)
    offset = tri.mean(axis=1)[rows, axis]
    out = np.zeros(len(tri))
    for a in range(3):
        for sign in (-1.0, 1.0):
            mine = np.flatnonzero(aligned & (axis == a) & (np.sign(along) == sign))
            if not len(mine):
                continue
            order = mine[np.argsort(offset[mine], kind="stable")]
            sorted_off = offset[order]
            total = np.concatenate([[0.0], np.cumsum(area[order])])
            lo = np.searchsorted(sorted_off, sorted_off - SHELL_PLANE_M, side="left")
            hi = np.searchsorted(sorted_off, sorted_off + SHELL_PLANE_M, side="right")
            out[order] = total[hi] - total[lo]
    return out


def shell_triangles(scene) -> np.ndarray:
    """Per triangle, whether it belongs to the scene's enclosing shell: its walls, floors and
    ceilings, the axis-aligned planes of at least SHELL_SHARE of the largest one's area
    (plane_areas). Everything else is the content a user looks at (furniture, pillars, arches)."""
    planes = plane_areas(scene)
    return planes >= SHELL_SHARE * planes.max() if planes.max() > 0 else np.zeros(len(planes), bool)


def content_triangles(scene) -> np.ndarray:
    """Per triangle, whether a view may gaze at it: neither shell nor emissive, with an area."""
    emissive = np.array([m.is_emissive for m in scene.materials], bool)
    _, _, area = triangles(scene)
    return ~shell_triangles(scene) & ~emissive[scene.triangle_material] & (area > 0)


def draw_points(tri: np.ndarray, ids: np.ndarray, cdf: np.ndarray, rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(triangle ids, points) of `n` points drawn uniformly over the area of triangles `ids` of `tri`
    ((T, 3, 3) world vertices), `cdf` their normalized cumulative areas: a triangle by area, then a
    point in it (three draws of `rng` each, in this order: seeded poses depend on it)."""
    pick = ids[np.minimum(np.searchsorted(cdf, rng.random(n)), len(ids) - 1)]
    r1, r2 = np.sqrt(rng.random(n)), rng.random(n)
    t = tri[pick]
    return pick, ((1 - r1)[:, None] * t[:, 0] + (r1 * (1 - r2))[:, None] * t[:, 1] + (r1 * r2)[:, None] * t[:, 2])

