"""Widmer et al. 2015's screen-space quadtree (HPG 2015, §3-4): host side and numpy references.

Screen space S of one eye layer: (x, y, z), x and y in pixels (GL: origin bottom-left, pixel
centres at +0.5), z = near / view_depth (reversed Z, infinite far: 1 at the near plane, 0 at
infinity). For a pinhole, 1/view_depth of a view-space plane is affine in the frustum tangents
(tx, ty) and so in (x, y): planar surfaces are planes in S and rays are straight lines in S, with z
linear along them.

Nodes (64 bits as two uint32 words, GLSL `uvec2`); level k has ceil(W/2^k) x ceil(H/2^k) nodes,
node (qx, qy) covers pixels [qx 2^k, min((qx+1) 2^k, W)) x [qy 2^k, min((qy+1) 2^k, H)):

  plane  word0 = float bits of -z0 (sign bit set), z0 > 0 = z at the centre of the node's
         (image-clipped) rectangle; word1 = packHalf2x16(sx, sy), the slopes *relative to z0*:
         z(x, y) = z0 (1 + sx (x - xc) + sy (y - yc)). Relative slopes keep the half floats in
         range at every depth scale (near/far 1e-4..1e7): a half's 2^-11 relative error gives a
         relative z error <= 2^-11 (|sx| hx + |sy| hy) over a node of half-extents hx, hy.
  AABB   word0 = float bits of zmin >= 0 (sign bit clear), word1 = float bits of zmax.
         Background (no geometry) is the AABB [0, 0]: no ray (z > 0) passes behind it.

The lowest bit of word0 is the depth-discontinuity flag O (§3.2): a 4-neighbour is background or
its plane differs from this one by more than DISCONTINUITY (relative) at their shared edge; a
parent's flag is the OR of its children's. Decoding clears the bit (<= 1 ulp of z0).

Build (§3.3): leaves are the pixels' planes from the G-buffer (position.w = view depth gives z0
exactly, the geometric normal of the pixel's triangle the slopes; no finite differences): the
triangle's own plane. Not the shading normal: with smoothed vertex normals neighbouring pixels of
one flat face got planes ~4 % apart at their shared edge (a ray slipped between them: warp's dark
line across the room box's top, docs/stereo.md) and silhouette pixels slopes of ~50 per pixel. A parent becomes a plane when all
its (up to 2x2) children are planes, the cosine between each child's normal and the proxy's is
>= gamma_norm, and every child-rectangle corner lies within gamma_dist *relative* depth of the
proxy: |z_child - z_proxy| <= gamma_dist z_proxy (so the bound means the same at every distance).
Normals are view-space normals of the planes. The proxy normal is the normalised mean of the
children's, its offset the least-squares fit of the children's corner z (the paper's v = (0,0,1)
in S); both tests run on the *encoded* proxy, so what is stored is what was checked. Otherwise the
parent is an AABB of its children's z ranges, widened by AABB_MARGIN (float rounding must not
cull a leaf's hit). gamma_dist = 0 never merges (lossless: plane leaves under a max-z tree).
A proxy is within gamma_dist of its children at every point of the node (the difference of two
planes is affine: its largest relative value is at a corner), so after m merges the stored surface
lies within (1 - gamma_dist)^-m - 1 relative depth of the leaf planes.

Height-field semantics (single layer): a ray hits where it first passes behind the surface
(z_ray < z_surface) in a pixel with geometry; not on the leaf of its origin's pixel when it
starts on that leaf (_starts_on: a mirror ray off that surface). Statuses as in rayvr/bench/tracers/dda.py: HIT, OFFSCREEN
(left the image), NEAR (reached the near plane or lies wholly in front of it), NONE (reached
infinity on screen without a hit).

GLSL: glsl/ssrt/quadtree_build.comp (build), glsl/ssrt/quadtree.glsl (decode + traversal),
glsl/ssrt/quadtree_batch.comp (batch harness). The frame-graph pass and the GPU batch tracer
(QuadtreeTracer): rayvr/frame/passes/quadtree.py.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import moderngl
import numpy as np

from ..gl.glsl_constants import declare
from ..gl.gpu_layout import SSRT_RAY_GROUP
from ..gl.shaders import declares

# A screen-space ray's status, shared by the three tracers (quadtree, bench/tracers/hiz.py, bench/tracers/dda.py)
HIT = declare("SSRT_HIT", 1, uint=True)
OFFSCREEN = declare("SSRT_OFFSCREEN", 2, uint=True)  # left the viewport
NEAR = declare("SSRT_NEAR", 3, uint=True)  # reached the near plane
NONE = declare("SSRT_NONE", 4, uint=True)  # ran out of steps or nodes, or past the far end
OCCLUDED = declare("SSRT_OCCLUDED", 5, uint=True)  # depth layers: passed deeper than the last layer's slab
STATUS_NAMES = {HIT: "hit", OFFSCREEN: "offscreen", NEAR: "near", NONE: "none", OCCLUDED: "occluded"}
INF = declare("SSRT_INF", 3.0e38)  # a screen ray's "no bound" parameter (finite: INF * 0 is 0, not NaN)
PLANE_BIT = declare("QT_PLANE_BIT", 0x80000000, uint=True)
FLAG_BIT = declare("QT_FLAG_BIT", 1, uint=True)
MAX_LEVELS = declare("QT_MAX_LEVELS", 16)  # images up to 32768 pixels a side (the Hi-Z's too)
DISCONTINUITY = declare("QT_DISCONTINUITY", 0.01)  # relative z jump at a shared edge that flags a depth discontinuity
GRAZING = declare("QT_GRAZING", 1e-4)  # |n . v| / |v| floor for a leaf: slopes stay finite for edge-on normals
AABB_MARGIN = declare("QT_AABB_MARGIN", 2.0 ** -20)  # relative widening of AABB bounds over the children's exact ranges
# relative z within which a ray's origin lies on its own pixel's leaf (float rounding), _starts_on
ON_LEAF = declare("QT_ON_LEAF", 2.0 ** -18)
HALF_MAX = declare("QT_HALF_MAX", 65504.0)


def level_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """(w, h) of every level, leaves first, up to the single root: ceil(W/2^k) x ceil(H/2^k)."""
    sizes = [(int(width), int(height))]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append(((w + 1) // 2, (h + 1) // 2))
    if len(sizes) > MAX_LEVELS:
        raise ValueError(f"{width}x{height}: the quadtree takes at most {MAX_LEVELS} levels "
                         f"({1 << (MAX_LEVELS - 1)} pixels a side)")
    return sizes


def level_offsets(sizes) -> tuple[list[int], int]:
    """Node index of each level's first node within a layer, and nodes per layer."""
    offs, n = [], 0
    for w, h in sizes:
        offs.append(n)
        n += w * h
    return offs, n


def pack_screen_rays(origins, directions, eyes=0) -> np.ndarray:
    """(N, 8) float32 rays for the screen-space batch shaders: origin, eye layer (as a float),
    direction, 0 (dda_batch.comp, hiz_batch.comp and quadtree_batch.comp read this layout)."""
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    if d.shape != o.shape:
        raise ValueError(f"origins {o.shape} and directions {d.shape} differ")
    rays = np.zeros((len(o), 8), np.float32)
    rays[:, 0:3], rays[:, 4:7] = o, d
    rays[:, 3] = np.broadcast_to(np.asarray(eyes, np.float32), (len(o),))
    return rays


def dispatch_per_ray(program, n: int) -> None:
    """One invocation per ray (groups of SSRT_RAY_GROUP, spread over y past GL's 65535 groups in x)."""
    groups = -(-n // SSRT_RAY_GROUP)
    gx = min(groups, 65535)
    program.run(gx, -(-groups // gx), 1)


def trace_screen_rays(ctx, program, origins, directions, eye, bind) -> np.ndarray:
    """Run a screen-space tracer once: the rays packed and uploaded, `bind(rays, results, n)`,
    one invocation per ray, the results read back as (N, 8) uint32 words (the quadtree's and
    Hi-Z's result layout: status, count, pixel x y, point xyz, layer)."""
    rays = pack_screen_rays(origins, directions, eye)
    n = len(rays)
    rbuf = ctx.buffer(rays.tobytes() if n else b"\0" * 32)
    obuf = ctx.buffer(reserve=max(n, 1) * 32)
    try:
        bind(rbuf, obuf, n)
        if n:
            dispatch_per_ray(program, n)
        ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)
        return np.frombuffer(obuf.read(), np.uint32).reshape(-1, 8)[:n]
    finally:
        rbuf.release()
        obuf.release()


def time_build_and_trace(ctx, program, origins, directions, eye, build, bind, repeats: int,
                         min_seconds: float) -> dict:
    """GPU ms of a screen-space tracer's `build()` and of tracing the rays with `program` (the rays
    packed and uploaded once; `bind(rays, results, n)` binds them before each dispatch), after the
    times settle (timing.time_gpu: median of 5 batches of `repeats`); the quadtree and Hi-Z
    tracers' `time`. Returns {"build", "trace", "rays", "rays_per_s"}."""
    from ..gl.timing import time_gpu

    rays = pack_screen_rays(origins, directions, eye)
    n = len(rays)
    rbuf = ctx.buffer(rays.tobytes())
    obuf = ctx.buffer(reserve=max(n, 1) * 32)

    def trace() -> None:
        bind(rbuf, obuf, n)
        dispatch_per_ray(program, n)

    try:
        out = {"build": time_gpu(ctx, build, repeats, min_seconds), "trace": time_gpu(ctx, trace, repeats, min_seconds),
               "rays": n}
    finally:
        rbuf.release()
        obuf.release()
    out["rays_per_s"] = n / (out["trace"]["ms"] * 1e-3)
    return out


def set_level_uniforms(program, size, prefix: str, per_layer_name: str) -> None:
    """The level table of a screen-space pyramid (the quadtree's, Hi-Z's) for an eye image of
    `size`: `<prefix>_level[k]` = (width, height, first index of level k in a layer, 0),
    `<prefix>_top` = the root's level, `per_layer_name` = entries per layer."""
    sizes = level_sizes(*size)
    offs, per_layer = level_offsets(sizes)
    table = np.zeros((MAX_LEVELS, 4), np.int32)
    table[:len(sizes), :2] = sizes
    table[:len(sizes), 2] = offs
    for name, value in ((f"{prefix}_level", table.tobytes()), (f"{prefix}_top", np.int32(len(sizes) - 1).tobytes()),
                        (per_layer_name, np.uint32(per_layer).tobytes())):
        if declares(program, name):
            program[name].write(value)


def quadtree_bytes(width: int, height: int, layers: int) -> int:
    return 8 * level_offsets(level_sizes(width, height))[1] * layers


@dataclass(frozen=True)
class ScreenCamera:
    """What the tree and the tracer need of an eye: pinhole frustum tangents (l, r, b, t), near,
    image size, scene-local position and camera-to-world rotation (float64)."""

    tangents: tuple
    near: float
    size: tuple
    position: np.ndarray
    rotation: np.ndarray

    @classmethod
    def from_eye(cls, eye, origin=(0.0, 0.0, 0.0)) -> "ScreenCamera":
        return cls(tuple(float(t) for t in eye.tangents), float(eye.near), tuple(eye.size),
                   np.asarray(eye.position, np.float64) - np.asarray(origin, np.float64),
                   np.asarray(eye.rotation, np.float64))

    @property
    def scale(self) -> tuple[float, float]:
        """Pixels per unit of frustum tangent in x and y."""
        l, r, b, t = self.tangents
        return self.size[0] / (r - l), self.size[1] / (t - b)

    def tangent_at(self, x, y):
        l, r, b, t = self.tangents
        kx, ky = self.scale
        return l + np.asarray(x) / kx, b + np.asarray(y) / ky


# ------------------------------------------------------------------ node encoding

def _f32_bits(v) -> np.ndarray:
    return np.asarray(v, np.float32).view(np.uint32)


def encode_planes(z0, sx, sy, flag) -> np.ndarray:
    """Plane nodes: (..., 2) uint32."""
    w0 = _f32_bits(-np.abs(np.asarray(z0, np.float32)))
    w0 = (w0 & ~np.uint32(FLAG_BIT)) | np.asarray(flag, np.uint32)
    s = np.stack([np.clip(sx, -HALF_MAX, HALF_MAX), np.clip(sy, -HALF_MAX, HALF_MAX)], -1).astype(np.float16)
    w1 = s.view(np.uint16).astype(np.uint32)
    return np.stack([w0, w1[..., 0] | (w1[..., 1] << np.uint32(16))], -1)


def encode_aabbs(zmin, zmax, flag) -> np.ndarray:
    zmin, zmax, flag = np.broadcast_arrays(np.maximum(zmin, 0.0), np.maximum(zmax, 0.0), flag)
    w0 = (_f32_bits(zmin) & ~np.uint32(FLAG_BIT)) | np.asarray(flag, np.uint32)
    return np.stack([w0, _f32_bits(zmax)], -1)


class Nodes(NamedTuple):
    plane: np.ndarray   # bool
    flag: np.ndarray    # bool
    z0: np.ndarray      # plane: z at the rectangle's centre (0 for AABBs)
    sx: np.ndarray      # plane: relative slopes
    sy: np.ndarray
    zmin: np.ndarray    # AABB: bounds; plane: its range over the node's rectangle
    zmax: np.ndarray


def decode(nodes: np.ndarray, half_x=None, half_y=None) -> Nodes:
    """Decode (..., 2) uint32 nodes (float64 values). With the node rectangles' half-extents,
    planes get their z range over the rectangle (zmin clamped at 0)."""
    w0, w1 = nodes[..., 0].astype(np.uint32), nodes[..., 1].astype(np.uint32)
    plane = (w0 & np.uint32(PLANE_BIT)) != 0
    flag = (w0 & np.uint32(FLAG_BIT)) != 0
    v0 = (w0 & ~np.uint32(FLAG_BIT)).view(np.float32).astype(np.float64)
    halves = np.stack([w1 & np.uint32(0xFFFF), w1 >> np.uint32(16)], -1).astype(np.uint16).view(np.float16)
    sx = np.where(plane, halves[..., 0].astype(np.float64), 0.0)
    sy = np.where(plane, halves[..., 1].astype(np.float64), 0.0)
    z0 = np.where(plane, -v0, 0.0)
    zmin = np.where(plane, 0.0, v0)
    zmax = np.where(plane, 0.0, w1.view(np.float32).astype(np.float64))
    if half_x is not None:
        spread = np.abs(sx) * half_x + np.abs(sy) * half_y
        zmax = np.where(plane, z0 * (1 + spread), zmax)
        zmin = np.where(plane, np.maximum(z0 * (1 - spread), 0.0), zmin)
    return Nodes(plane, flag, z0, sx, sy, zmin, zmax)


# ------------------------------------------------------------------ leaves and the numpy build

def geometric_normals(triangle: np.ndarray, vertices: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """The unnormalised geometric normal (v1 - v0) x (v2 - v0) of each pixel's triangle, as
    glsl/ssrt/quadtree_build.comp computes it: triangle (H, W) IDs (the G-buffer's "triangle"
    channel, NO_HIT for background: zero), the scene's vertices (V, 3) and indices (T, 3).
    Returns (H, W, 3) float64, the normal leaf_planes wants."""
    tri = np.asarray(triangle, np.uint32)
    hit = tri < len(indices)
    p = np.asarray(vertices, np.float64)[np.asarray(indices)[np.where(hit, tri, 0)]]  # (H, W, 3 vertices, 3)
    n = np.cross(p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :])
    return np.where(hit[..., None], n, 0.0)


def frame_geometric_normals(gbuffer, scene) -> np.ndarray:
    """geometric_normals of every eye layer of a rendered G-buffer (its "triangle" channel) in
    `scene` (the rendered Scene): (layers, H, W, 3), rows bottom-up, for build_reference."""
    w, h = gbuffer.size
    tri = np.frombuffer(gbuffer.textures["triangle"].read(), np.uint32).reshape(gbuffer.layers, h, w)
    return geometric_normals(tri, scene.vertices, scene.indices)


def leaf_planes(position: np.ndarray, normal: np.ndarray, cam: ScreenCamera):
    """Per-pixel planes in S from G-buffer channels of one layer, rows bottom-up (GL texture
    order): position (H, W, 4) with w = view depth (0: background), normal (H, W, >= 3) world,
    the geometric normal of the pixel's surface (geometric_normals; either side, any length).
    Returns geometry mask, z0, sx, sy (relative slopes), float64."""
    h, w = position.shape[:2]
    depth = position[..., 3].astype(np.float64)
    geo = depth > 0
    n = normal[..., :3].astype(np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    nv = n @ cam.rotation  # world -> view: R^T n, row vectors
    tx, ty = cam.tangent_at(np.arange(w)[None, :] + 0.5, np.arange(h)[:, None] + 0.5)
    tx, ty = np.broadcast_to(tx, (h, w)), np.broadcast_to(ty, (h, w))
    vlen = np.sqrt(tx * tx + ty * ty + 1)
    # z = z0 (n . (tx, ty, -1)) / (n . v_c): relative slope = n_xy / (n . v_c) per tangent unit,
    # the same for n and -n but for the grazing clamp, which wants n facing the eye (n . v_c < 0).
    facing = nv[..., 0] * tx + nv[..., 1] * ty - nv[..., 2]
    nv = np.where((facing > 0)[..., None], -nv, nv)
    den = np.minimum(-np.abs(facing), -GRAZING * vlen)
    kx, ky = cam.scale
    z0 = np.where(geo, cam.near / np.where(geo, depth, 1.0), 0.0)
    return geo, z0, np.where(geo, nv[..., 0] / den / kx, 0.0), np.where(geo, nv[..., 1] / den / ky, 0.0)


def _discontinuity(geo, z0, sx, sy):
    """Flag pixels whose 4-neighbour is background or jumps by > DISCONTINUITY at the shared edge."""
    h, w = geo.shape
    flag = np.zeros((h, w), bool)
    for axis, s in ((1, sx), (0, sy)):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        za = z0[a] * (1 + 0.5 * s[a])       # the lower pixel at its upper edge
        zb = z0[b] * (1 - 0.5 * s[b])       # the upper pixel at its lower edge
        jump = ~geo[a] | ~geo[b] | (np.abs(za - zb) > DISCONTINUITY * np.maximum(np.abs(za), np.abs(zb)))
        flag[a] |= jump & geo[a]
        flag[b] |= jump & geo[b]
    return flag


def node_rects(k: int, size):
    """x0, x1, y0, y1 pixel bounds of level k's nodes, (h_k, w_k) arrays."""
    W, H = size
    wk, hk = (W + (1 << k) - 1) >> k, (H + (1 << k) - 1) >> k
    x0 = (np.arange(wk) << k).astype(np.float64)
    y0 = (np.arange(hk) << k).astype(np.float64)
    x1 = np.minimum(x0 + (1 << k), W)
    y1 = np.minimum(y0 + (1 << k), H)
    X0, Y0 = np.meshgrid(x0, y0)
    X1, Y1 = np.meshgrid(x1, y1)
    return X0, X1, Y0, Y1


def plane_normals(z0, sx, sy, xc, yc, cam: ScreenCamera):
    """View-space unit normals (facing the eye) of S-planes z = z0 (1 + sx (x-xc) + sy (y-yc)).
    1/depth = z/near is affine in the tangents: n ~ (-ax, -ay, 1 - ax tx_c - ay ty_c)."""
    kx, ky = cam.scale
    ax, ay = sx * kx, sy * ky
    txc, tyc = cam.tangent_at(xc, yc)
    n = np.stack([-ax, -ay, 1 - ax * txc - ay * tyc], -1)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)


def adaptive_thresholds(gamma_norm, gamma_dist, gamma_adapt, view_depth):
    """The distance-adaptive thresholds of §6: gamma_dist and the angle acos(gamma_norm) grow by
    the factor 1 + gamma_adapt x view_depth (the node's mean, scene units; the angle capped at
    90 degrees): far nodes, whose depth errors move hits by fewer pixels, merge more. 0: off."""
    f = 1.0 + gamma_adapt * view_depth
    if gamma_adapt <= 0:
        return np.broadcast_to(gamma_norm, np.shape(f)), np.broadcast_to(gamma_dist, np.shape(f))
    return np.cos(np.minimum(np.arccos(np.clip(gamma_norm, -1, 1)) * f, np.pi / 2)), gamma_dist * f


def build_reference(position, normal, cam: ScreenCamera, gamma_norm: float = 1.0, gamma_dist: float = 0.0,
                    gamma_adapt: float = 0.0):
    """The numpy build of one layer: list of (h_k, w_k, 2) uint32 node arrays, leaves first."""
    W, H = cam.size
    sizes = level_sizes(W, H)
    geo, z0, sx, sy = leaf_planes(position, normal, cam)
    flag = _discontinuity(geo, z0, sx, sy)
    leaf = np.where(geo[..., None], encode_planes(z0, sx, sy, flag), encode_aabbs(0.0, 0.0, flag))
    levels = [leaf]
    for k in range(1, len(sizes)):
        levels.append(_build_level(levels[-1], k, cam, gamma_norm, gamma_dist, gamma_adapt))
    return levels


def _build_level(child_nodes, k, cam, gamma_norm, gamma_dist, gamma_adapt=0.0):
    W, H = cam.size
    wk, hk = (W + (1 << k) - 1) >> k, (H + (1 << k) - 1) >> k
    hc, wc = child_nodes.shape[:2]
    CX0, CX1, CY0, CY1 = node_rects(k - 1, cam.size)
    cd = decode(child_nodes, (CX1 - CX0) / 2, (CY1 - CY0) / 2)
    # Pad the children to (2 hk, 2 wk); missing children (past the image) are marked absent.
    def pad(a, fill):
        out = np.full((2 * hk, 2 * wk) + a.shape[2:], fill, a.dtype)
        out[:hc, :wc] = a
        return out.reshape(hk, 2, wk, 2, *a.shape[2:]).transpose(0, 2, 1, 3, *range(4, a.ndim + 2))
    exists = pad(np.ones((hc, wc), bool), False)            # (hk, wk, 2, 2)
    P = {name: pad(getattr(cd, name), 0.0 if name not in ("plane", "flag") else False) for name in cd._fields}
    R = {name: pad(v, 0.0) for name, v in zip(("x0", "x1", "y0", "y1"), (CX0, CX1, CY0, CY1))}
    flag = (P["flag"] & exists).any(axis=(2, 3))
    zmax = np.where(exists, P["zmax"], 0.0).max(axis=(2, 3)) * (1 + AABB_MARGIN)
    zmin = np.where(exists, P["zmin"], np.inf).min(axis=(2, 3)) * (1 - AABB_MARGIN)
    aabb = encode_aabbs(np.asarray(zmin, np.float32), _round_up(zmax), flag)
    if gamma_dist <= 0:
        return aabb
    # Proxy planes where every existing child is a plane.
    all_planes = np.where(exists, P["plane"], True).all(axis=(2, 3))
    cxc, cyc = (R["x0"] + R["x1"]) / 2, (R["y0"] + R["y1"]) / 2
    with np.errstate(all="ignore"):
        cn = plane_normals(P["z0"], P["sx"], P["sy"], cxc, cyc, cam)            # (hk, wk, 2, 2, 3)
        mean = np.where(exists[..., None], cn, 0.0).sum(axis=(2, 3))
        npx = mean / np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-30)
        # The children's rectangle corners and their z on the children's planes.
        xs = np.stack([R["x0"], R["x1"], R["x0"], R["x1"]], -1)
        ys = np.stack([R["y0"], R["y0"], R["y1"], R["y1"]], -1)
        zc = P["z0"][..., None] * (1 + P["sx"][..., None] * (xs - cxc[..., None]) + P["sy"][..., None] * (ys - cyc[..., None]))
        tx, ty = cam.tangent_at(xs, ys)
        nb = npx[:, :, None, None, None, :]
        f = -nb[..., 0] * tx - nb[..., 1] * ty + nb[..., 2]                     # z_proxy = kappa f
        e = exists[..., None] & np.ones(4, bool)
        kappa = np.where(e, f * zc, 0).sum(axis=(2, 3, 4)) / np.where(e, f * f, 0).sum(axis=(2, 3, 4))
        X0, X1, Y0, Y1 = node_rects(k, cam.size)
        xc, yc = (X0 + X1) / 2, (Y0 + Y1) / 2
        txc, tyc = cam.tangent_at(xc, yc)
        kx, ky = cam.scale
        pz0 = kappa * (-npx[..., 0] * txc - npx[..., 1] * tyc + npx[..., 2])
        psx = kappa * -npx[..., 0] / kx / pz0
        psy = kappa * -npx[..., 1] / ky / pz0
        proxy = encode_planes(pz0, psx, psy, flag)
        q = decode(proxy)
        zp = q.z0[..., None, None, None] * (1 + q.sx[..., None, None, None] * (xs - xc[..., None, None, None])
                                              + q.sy[..., None, None, None] * (ys - yc[..., None, None, None]))
        rel = np.where(e, np.abs(zp - zc) / zp, 0.0)
        mean_z = np.where(exists, P["z0"], 0.0).sum(axis=(2, 3)) / exists.sum(axis=(2, 3))
        gn, gd = adaptive_thresholds(gamma_norm, gamma_dist, gamma_adapt, cam.near / mean_z)
        dist_ok = (np.where(e, zp, 1.0) > 0).all(axis=(2, 3, 4)) & (rel.max(axis=(2, 3, 4)) < gd)
        qn = plane_normals(q.z0, q.sx, q.sy, xc, yc, cam)
        cos = np.where(exists, (cn * qn[:, :, None, None, :]).sum(-1), 1.0).min(axis=(2, 3))
        ok = all_planes & (pz0 > 0) & np.isfinite(pz0) & dist_ok & (cos >= gn)
    return np.where(ok[..., None], proxy, aabb)


def _round_up(z) -> np.ndarray:
    """float64 -> the nearest float32 not below it."""
    f = np.asarray(z, np.float32)
    return np.where(f.astype(np.float64) < z, np.nextafter(f, np.float32(np.inf)), f)


def flatten(levels) -> np.ndarray:
    """Levels of one layer -> (nodes, 2) uint32 in buffer order."""
    return np.concatenate([lv.reshape(-1, 2) for lv in levels])


def unflatten(flat: np.ndarray, size) -> list[np.ndarray]:
    sizes = level_sizes(*size)
    offs, n = level_offsets(sizes)
    return [flat[o:o + w * h].reshape(h, w, 2) for o, (w, h) in zip(offs, sizes)]


# ------------------------------------------------------------------ rays in S

class ScreenRay(NamedTuple):
    """A ray in S: p(u) = s0 + u sd, u in pixels along the screen (|sd.xy| = 1) except when the
    ray is a point on screen (then |sd.xy| = 0 and u in [0, 1]); [u_lo, u_hi] is the part on
    screen and in front of the near plane; `end` is the status of a ray that hits nothing there;
    `moved`: s0 is where the ray crosses the near plane, not its origin."""

    s0: np.ndarray
    sd: np.ndarray
    u_lo: float
    u_hi: float
    end: int
    moved: bool = False


def screen_ray(cam: ScreenCamera, origin, direction) -> ScreenRay:
    """Project a scene-local ray into S (float64): clip it at the near plane, then to the image."""
    W, H = cam.size
    n = cam.near
    l, r, b, t = cam.tangents
    kx, ky = cam.scale
    o = cam.rotation.T @ (np.asarray(origin, np.float64) - cam.position)
    d = cam.rotation.T @ np.asarray(direction, np.float64)
    da, dd = -o[2], -d[2]                              # view depth at the origin, its rate
    nothing = ScreenRay(np.zeros(3), np.zeros(3), 0.0, -1.0, NEAR)
    if dd > 0:
        s = max(0.0, (n - da) / dd)
    elif da >= n:
        s = 0.0
    else:
        return nothing                                  # wholly in front of the near plane
    a = o + s * d
    da = -a[2]
    s0 = np.array([(a[0] / da - l) * kx, (a[1] / da - b) * ky, n / da])
    # Screen direction of the projected line (any sign of dd), and dz per pixel along it.
    wx = (d[0] * da - a[0] * dd) * kx
    wy = (d[1] * da - a[1] * dd) * ky
    wlen = np.hypot(wx, wy)
    scale = (abs(d[0] * da) + abs(a[0] * dd)) * kx + (abs(d[1] * da) + abs(a[1] * dd)) * ky
    end = NONE if dd >= 0 else NEAR
    if wlen <= 1e-6 * scale or wlen == 0:             # along a pixel's line of sight
        if dd == 0:
            return nothing._replace(end=NONE)
        sd = np.array([0.0, 0.0, (0.0 if dd > 0 else 1.0) - s0[2]])
        u_max = 1.0
    else:
        sd = np.array([wx / wlen, wy / wlen, -n * dd / wlen])
        u_max = np.inf if dd == 0 else ((0.0 if dd > 0 else 1.0) - s0[2]) / sd[2]
    lo, hi = 0.0, u_max
    for c, dc, extent in ((s0[0], sd[0], W), (s0[1], sd[1], H)):
        if dc != 0:
            u0, u1 = (0 - c) / dc, (extent - c) / dc
            lo, hi = max(lo, min(u0, u1)), min(hi, max(u0, u1))
        elif not 0 <= c <= extent:
            lo, hi = 0.0, -1.0
    if lo > hi:
        return ScreenRay(s0, sd, lo, hi, OFFSCREEN, s > 0)
    return ScreenRay(s0, sd, lo, hi, end if hi >= u_max else OFFSCREEN, s > 0)


def _origin_cell(ray: ScreenRay, size):
    """The pixel holding the ray's origin (on a pixel edge: the one the ray goes into), or None
    when the origin is off screen or before the near plane (glsl qt_origin_cell)."""
    if ray.moved or ray.u_lo != 0 or ray.u_lo > ray.u_hi:
        return None
    cell = []
    for c, dc, extent in ((ray.s0[0], ray.sd[0], size[0]), (ray.s0[1], ray.sd[1], size[1])):
        i = int(np.floor(c))
        i -= 1 if (i == c and dc < 0) else 0
        cell.append(min(max(i, 0), extent - 1))
    return tuple(cell)


class Trace(NamedTuple):
    status: int
    pixel: tuple      # (x, y) GL pixel of the hit, (-1, -1) otherwise
    point: np.ndarray  # hit in S (x, y, z); the origin's S point when nothing was tested
    nodes: int        # nodes (cells for the brute force) tested


def _plane_interval(ray: ScreenRay, ua, ub, z0, sx, sy, xc, yc):
    """First u in [ua, ub] where the ray is behind the plane, or None. d(u) = z_ray - z_plane is
    linear in u: behind at ua, or crossing inside."""
    def d(u):
        p = ray.s0 + u * ray.sd
        return p[2] - z0 * (1 + sx * (p[0] - xc) + sy * (p[1] - yc))
    da, db = d(ua), d(ub)
    if da < 0:
        return ua
    if db < 0:
        return ua + (ub - ua) * da / (da - db)
    return None


def trace_heightfield_reference(leaves: np.ndarray, cam: ScreenCamera, origin, direction) -> Trace:
    """Brute force: every pixel cell the ray's screen segment crosses, in order (all its
    crossings of the pixel grid lines, sorted), each tested against that pixel's leaf plane; the
    first hit wins; the leaf of the origin's pixel is none to a ray that starts on it (_starts_on).
    `leaves`: level-0 nodes (H, W, 2) (encoded: the tree's own planes)."""
    ray = screen_ray(cam, origin, direction)
    if ray.u_lo > ray.u_hi:
        return Trace(ray.end, (-1, -1), ray.s0, 0)
    nd = decode(leaves)
    tested = 0
    own = _origin_cell(ray, cam.size)
    for ua, ub, x, y in _cells(ray, cam.size):
        tested += 1
        if not nd.plane[y, x] or ((x, y) == own and _starts_on(ray, nd.z0[y, x], nd.sx[y, x], nd.sy[y, x], x + 0.5, y + 0.5)):
            continue
        u = _plane_interval(ray, ua, ub, nd.z0[y, x], nd.sx[y, x], nd.sy[y, x], x + 0.5, y + 0.5)
        if u is not None:
            return Trace(HIT, (x, y), ray.s0 + u * ray.sd, tested)
    return Trace(ray.end, (-1, -1), _end_point(ray), tested)


def _cells(ray: ScreenRay, size):
    """The pixel cells the ray's screen segment crosses, in order: (ua, ub, x, y) between its
    successive crossings of the pixel grid lines."""
    W, H = size
    us = [ray.u_lo, ray.u_hi]
    for c, dc, extent in ((ray.s0[0], ray.sd[0], W), (ray.s0[1], ray.sd[1], H)):
        if dc != 0 and np.isfinite(ray.u_hi):
            a, b = sorted((c + ray.u_lo * dc, c + ray.u_hi * dc))
            us += list((np.arange(np.ceil(a), np.floor(b) + 1) - c) / dc)
    us = np.unique(np.clip(us, ray.u_lo, ray.u_hi))
    for ua, ub in zip(us[:-1], us[1:]):
        if ub > ua:
            m = ray.s0 + 0.5 * (ua + ub) * ray.sd
            yield ua, ub, min(max(int(np.floor(m[0])), 0), W - 1), min(max(int(np.floor(m[1])), 0), H - 1)


def _end_point(ray: ScreenRay) -> np.ndarray:
    """Where a ray that hit nothing left the screen or reached the near plane / infinity."""
    return ray.s0 + ray.u_hi * ray.sd if np.isfinite(ray.u_hi) else ray.s0


def _find_msb(v: int) -> int:
    return v.bit_length() - 1  # -1 for 0, as GLSL findMSB


class _Walk(NamedTuple):
    """What one layer's traversal found in [u_from, u_to]: the first surface hit (u, pixel) or
    u = inf; the first point deeper than the surface's slab (an occlusion volume, §4.1) or inf;
    nodes tested; whether the node cap ended it."""

    u_hit: float
    pixel: tuple
    u_occ: float
    nodes: int
    capped: bool


def _deep(ray: ScreenRay, u, z0, sx, sy, xc, yc, thickness) -> bool:
    """Is p(u) more than `thickness` (relative) behind the plane? (never for an infinite thickness)"""
    p = ray.s0 + u * ray.sd
    zs = z0 * (1 + sx * (p[0] - xc) + sy * (p[1] - yc))
    return bool((zs - p[2]) > thickness * zs)


def _starts_on(ray: ScreenRay, z0, sx, sy, xc, yc) -> bool:
    """Does the ray's origin s0 lie on the leaf plane, within what the leaf is sure to: its
    half-float slopes' 2^-11 of the z change across the pixel, and ON_LEAF of float rounding?
    (glsl qt_starts_on). A ray starting on the leaf of its origin's pixel starts on that surface
    (a mirror ray off it): that leaf is no surface for it; where rounding or the slopes put the
    origin behind the plane, or let the ray dip behind it, the mirror saw itself."""
    zs = z0 * (1 + sx * (ray.s0[0] - xc) + sy * (ray.s0[1] - yc))
    return bool(abs(ray.s0[2] - zs) <= (ON_LEAF + 2.0 ** -11 * 0.5 * (abs(sx) + abs(sy))) * zs)


def _behind(ray: ScreenRay, u, z0, sx, sy, xc, yc) -> bool:
    """Is p(u) behind the plane (z_ray < z_plane)?"""
    p = ray.s0 + u * ray.sd
    return bool(p[2] - z0 * (1 + sx * (p[0] - xc) + sy * (p[1] - yc)) < 0)


def _cell(ray: ScreenRay, ua, ub, z0, sx, sy, xc, yc, thickness, cont):
    """Events of one plane over [ua, ub]: (u of the first point in its slab [z (1 - thickness), z]
    or None, u of the first point deeper than the slab or None). The first point behind the plane
    (as the height field has it) is one or the other; continuing (`cont`), a ray deeper than the
    slab may still rise into it before ub."""
    uf = _plane_interval(ray, ua, ub, z0, sx, sy, xc, yc)
    if uf is None:
        return None, None
    if not _deep(ray, uf, z0, sx, sy, xc, yc, thickness):
        return uf, None
    if not cont:
        return None, uf

    def h(u):  # > 0: deeper than the slab
        p = ray.s0 + u * ray.sd
        zs = z0 * (1 + sx * (p[0] - xc) + sy * (p[1] - yc))
        return (1 - thickness) * zs - p[2]
    ha, hb = h(uf), h(ub)
    if hb <= 0 < ha:
        return uf + (ub - uf) * ha / (ha - hb), uf
    return None, uf


def _walk(levels, cam: ScreenCamera, ray: ScreenRay, u_from: float, u_to: float, thickness: float = np.inf,
          cont: bool = False, max_nodes: int | None = None, start_level: int = MAX_LEVELS) -> _Walk:
    """The stackless traversal of §4 over [u_from, u_to] of one layer's tree, step for step as
    glsl/ssrt/quadtree.glsl qt_walk does it: test the node (AABB: does the ray dip below zmax
    inside it; plane: its slab events, _cell); an AABB hit descends into the child holding the
    ray's entry point (after skipping the part above zmax); a miss moves to the neighbour across
    the wall the ray leaves by, then climbs findMSB((qx ^ qx') | (qy ^ qy')) levels, to the
    largest node that starts there. Stops at the first event, or (`cont`) at the first surface
    hit only, noting the first occlusion on the way; an AABB the ray crosses wholly below
    zmin (1 - thickness) is then one occlusion, not descended. A merged plane (level > 0) the ray
    enters already behind is descended like an AABB: a proxy lies up to gamma_dist off its leaves,
    so a ray starting on the surface (a mirror ray) may start behind it; taking that as a hit made
    the mirror see itself. Only crossings of a proxy are hits on it. Likewise the leaf of the
    origin's pixel is none to a ray that starts on it (_starts_on). The walk starts on `start_level`
    (capped at the root's) in the node holding p(u_from)."""
    W, H = cam.size
    top = len(levels) - 1
    u = u_from
    k = min(start_level, top)
    p0 = ray.s0 + u * ray.sd
    cell = []
    for c, dc, extent in ((p0[0], ray.sd[0], W), (p0[1], ray.sd[1], H)):
        i = int(np.floor(c))
        i -= 1 if (i == c and dc < 0) else 0             # on a pixel edge: the cell the ray goes into
        cell.append(min(max(i, 0), extent - 1))
    qx, qy = min(cell[0] >> k, levels[k].shape[1] - 1), min(cell[1] >> k, levels[k].shape[0] - 1)
    sx_dir, sy_dir = ray.sd[0], ray.sd[1]
    nodes = 0
    u_occ = np.inf
    own = _origin_cell(ray, cam.size)
    limit = max_nodes or 16 * (W + H) + 64
    while nodes < limit:
        nodes += 1
        x0, y0 = qx << k, qy << k
        x1, y1 = min(x0 + (1 << k), W), min(y0 + (1 << k), H)
        ux = ((x1 if sx_dir > 0 else x0) - ray.s0[0]) / sx_dir if sx_dir != 0 else np.inf
        uy = ((y1 if sy_dir > 0 else y0) - ray.s0[1]) / sy_dir if sy_dir != 0 else np.inf
        u_exit = min(ux, uy)
        ub = min(u_exit, u_to)
        n = decode(levels[k][qy, qx])
        go_down = False
        if ub > u:
            if n.plane and k > 0 and _behind(ray, u, float(n.z0), float(n.sx), float(n.sy), (x0 + x1) / 2, (y0 + y1) / 2):
                go_down = True   # entered behind a proxy: its error, or a surface? its leaves decide
            elif n.plane and k == 0 and (qx, qy) == own and _starts_on(ray, float(n.z0), float(n.sx), float(n.sy),
                                                                    x0 + 0.5, y0 + 0.5):
                pass             # the surface the ray starts on: no hit
            elif n.plane:
                c = ((x0 + x1) / 2, (y0 + y1) / 2)
                uh, uo = _cell(ray, u, ub, float(n.z0), float(n.sx), float(n.sy), *c, thickness, cont)
                if uo is not None:
                    u_occ = min(u_occ, uo)
                    if not cont:
                        return _Walk(np.inf, (-1, -1), u_occ, nodes, False)
                if uh is not None:
                    p = ray.s0 + uh * ray.sd
                    px = min(max(int(np.floor(p[0])), x0), x1 - 1)
                    py = min(max(int(np.floor(p[1])), y0), y1 - 1)
                    return _Walk(uh, (px, py), u_occ, nodes, False)
            else:
                zmax = float(n.zmax)
                za, zb = ray.s0[2] + u * ray.sd[2], ray.s0[2] + ub * ray.sd[2]
                if cont and max(za, zb) < (1 - thickness) * float(n.zmin):
                    u_occ = min(u_occ, u)      # behind every slab in the node: occluded all through
                elif min(za, zb) < zmax:
                    if za >= zmax:   # skip the part of the node the ray crosses above zmax
                        u = max(u, min(ub, (zmax - ray.s0[2]) / ray.sd[2]))
                    go_down = k > 0
        if go_down:
            # Child holding p(u); on a mid line, the one the ray goes into.
            p = ray.s0 + u * ray.sd
            k -= 1
            half = 1 << k
            mx, my = x0 + half, y0 + half
            cx = 1 if (p[0] > mx or (p[0] == mx and sx_dir >= 0)) else 0
            cy = 1 if (p[1] > my or (p[1] == my and sy_dir >= 0)) else 0
            qx = min(2 * qx + cx, ((W + half - 1) >> k) - 1)
            qy = min(2 * qy + cy, ((H + half - 1) >> k) - 1)
            continue
        if u_exit >= u_to:
            break
        u = u_exit
        nx = qx + ((1 if sx_dir > 0 else -1) if ux <= uy else 0)
        ny = qy + ((1 if sy_dir > 0 else -1) if uy <= ux else 0)
        wk, hk = (W + (1 << k) - 1) >> k, (H + (1 << k) - 1) >> k
        if not (0 <= nx < wk and 0 <= ny < hk):
            break
        up = max(_find_msb((qx ^ nx) | (qy ^ ny)), 0)   # findMSB(0) = -1: stay on this level
        up = min(up, top - k)
        k, qx, qy = k + up, nx >> up, ny >> up
    return _Walk(np.inf, (-1, -1), u_occ, nodes, nodes >= limit)


def trace_quadtree_reference(levels, cam: ScreenCamera, origin, direction, max_nodes: int | None = None,
                             start_level: int = MAX_LEVELS) -> Trace:
    """One layer as a height field (the first point behind the surface): the traversal _walk."""
    ray = screen_ray(cam, origin, direction)
    if ray.u_lo > ray.u_hi:
        return Trace(ray.end, (-1, -1), ray.s0, 0)
    w = _walk(levels, cam, ray, ray.u_lo, ray.u_hi, max_nodes=max_nodes, start_level=start_level)
    if w.u_hit < np.inf:
        return Trace(HIT, w.pixel, ray.s0 + w.u_hit * ray.sd, w.nodes)
    return Trace(NONE if w.capped else ray.end, (-1, -1), _end_point(ray), w.nodes)


class LayeredTrace(NamedTuple):
    """A trace through depth layers: status (HIT, OCCLUDED or how it ended), the layer hit
    (-1 otherwise), the hit pixel (OCCLUDED: the pixel the ray crossed just before, on the
    near side of the discontinuity, for inpainting; (-1, -1) if none), the point in S (OCCLUDED:
    where the ray went deeper than the last layer's slab) and the nodes tested."""

    status: int
    layer: int
    pixel: tuple
    point: np.ndarray
    nodes: int


def _before(cam: ScreenCamera, ray: ScreenRay, u: float) -> tuple:
    """The pixel the ray crossed just before u (inpainting's background side), or (-1, -1)."""
    if not u > ray.u_lo or not (ray.sd[0] or ray.sd[1]):
        return (-1, -1)
    p = ray.s0 + max(u - 1e-3, ray.u_lo) * ray.sd
    W, H = cam.size
    return (min(max(int(np.floor(p[0])), 0), W - 1), min(max(int(np.floor(p[1])), 0), H - 1))


def trace_layers(layer_levels, cam: ScreenCamera, origin, direction, thickness: float = np.inf) -> LayeredTrace:
    """The occlusion-aware trace of §4.1 through one or two depth layers' trees, as
    glsl/ssrt/quadtree.glsl qt_trace_layers does it. A surface is a slab of relative
    `thickness` behind each layer's planes. One layer: the first point behind the surface; deeper
    than the slab it is OCCLUDED (the ray passed behind an object). Two layers: the first layer
    is walked to its first slab hit, noting where the ray first went deeper than a slab; from
    there to that hit the second layer decides: its first point behind a surface is a hit (in its
    slab) or OCCLUDED (deeper: behind both layers, unknown); else the first layer's answer holds.
    Where the second layer is empty the space behind the first is known to be empty."""
    ray = screen_ray(cam, origin, direction)
    if ray.u_lo > ray.u_hi:
        return LayeredTrace(ray.end, -1, (-1, -1), ray.s0, 0)
    two = len(layer_levels) > 1
    w = _walk(layer_levels[0], cam, ray, ray.u_lo, ray.u_hi, thickness, cont=two)
    nodes, layer, u_hit, pixel, u_occ, capped = w.nodes, 0, w.u_hit, w.pixel, w.u_occ, w.capped
    if two and u_occ < u_hit and not capped:
        w2 = _walk(layer_levels[1], cam, ray, u_occ, min(u_hit, ray.u_hi), thickness)
        nodes += w2.nodes
        if w2.u_hit < np.inf or w2.u_occ < np.inf or w2.capped:
            layer, u_hit, pixel, u_occ, capped = 1, w2.u_hit, w2.pixel, w2.u_occ, w2.capped
        else:
            u_occ = np.inf
    if u_hit < np.inf:
        return LayeredTrace(HIT, layer, pixel, ray.s0 + u_hit * ray.sd, nodes)
    if u_occ < np.inf and not capped:
        return LayeredTrace(OCCLUDED, -1, _before(cam, ray, u_occ), ray.s0 + u_occ * ray.sd, nodes)
    return LayeredTrace(NONE if capped else ray.end, -1, (-1, -1), _end_point(ray), nodes)


def trace_layers_brute_force(layer_leaves, cam: ScreenCamera, origin, direction,
                             thickness: float = np.inf) -> LayeredTrace:
    """The multi-layer height field by brute force: every pixel cell the ray crosses, in order;
    in each, every layer's plane: the first point in any layer's slab is a hit; the first point
    deeper than the slab of the last layer given (where that layer has a surface) is OCCLUDED;
    whichever comes first (the hit on a tie); the leaf of the origin's pixel is none to a ray that
    starts on it (_starts_on). `layer_leaves`: level-0 nodes per layer."""
    ray = screen_ray(cam, origin, direction)
    if ray.u_lo > ray.u_hi:
        return LayeredTrace(ray.end, -1, (-1, -1), ray.s0, 0)
    nds = [decode(lv) for lv in layer_leaves]
    last = len(nds) - 1
    tested = 0
    own = _origin_cell(ray, cam.size)
    for ua, ub, x, y in _cells(ray, cam.size):
        tested += 1
        events = []
        for li, nd in enumerate(nds):
            if not nd.plane[y, x]:
                continue
            if (x, y) == own and _starts_on(ray, nd.z0[y, x], nd.sx[y, x], nd.sy[y, x], x + 0.5, y + 0.5):
                continue
            uh, uo = _cell(ray, ua, ub, nd.z0[y, x], nd.sx[y, x], nd.sy[y, x], x + 0.5, y + 0.5, thickness, True)
            if uh is not None:
                events.append((uh, 0, li))
            if uo is not None and li == last:
                events.append((uo, 1, li))
        if events:
            u, kind, li = min(events)
            if kind == 0:
                return LayeredTrace(HIT, li, (x, y), ray.s0 + u * ray.sd, tested)
            return LayeredTrace(OCCLUDED, -1, _before(cam, ray, u), ray.s0 + u * ray.sd, tested)
    return LayeredTrace(ray.end, -1, (-1, -1), _end_point(ray), tested)


__all__ = ["trace_screen_rays", "time_build_and_trace", "HIT", "OFFSCREEN", "NEAR", "NONE", "STATUS_NAMES", "level_sizes", "level_offsets", "quadtree_bytes",
           "ScreenCamera", "encode_planes", "encode_aabbs", "decode", "geometric_normals", "frame_geometric_normals", "leaf_planes", "build_reference",
           "flatten", "unflatten", "screen_ray", "trace_heightfield_reference", "trace_quadtree_reference",
           "trace_layers", "trace_layers_brute_force", "LayeredTrace", "OCCLUDED", "Trace", "ScreenRay", "plane_normals", "node_rects"]
