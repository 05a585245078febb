"""An independent numpy reference of rayvr's direct lighting, for checking the GPU numerically.

What it models (float64, vectorised over the pixels of one eye):
  * primary visibility: the eye's pixel-centre rays (`EyeView.ray_directions`, from the eye
    position in scene-local coordinates) traced through the numpy BVH (`trace_reference`);
  * the surface: shading normal interpolated from `scene.normals` with the hit's barycentrics
    (the geometric normal when the interpolation vanishes), turned to the geometric normal's side
    and then to face the eye (two-sided, by the geometric normal, as the G-buffer does); base colour, metallic, roughness and emission
    are the material's constants; emission is seen on the front face only (where the triangle's
    winding points) unless the material is double-sided;
  * the BRDF: metallic-roughness microfacet model, GGX normal distribution with alpha =
    roughness^2 (at least 1e-3), Smith height-correlated masking-shadowing, Schlick Fresnel with
    F0 = mix(0.04, base colour, metallic), plus Lambert diffuse weighted by (1 - F)(1 - metallic);
  * lights: point (intensity / d^2), directional, rectangular (radiance, emitting on the side of
    cross(u, v), or both sides when `two_sided`, area 4 |u x v|);
  * effect "raster": no shadows, rect lights by the fixed 4x4 grid of points the GPU uses;
    effect "shadows": hard shadows by any-hit shadow rays through the numpy BVH (starting at
    `offset_ray` off the geometric normal on the light's side, stopping just short of the
    light), rect lights by jittered-stratified random points from this module's own generator,
    an unbiased Monte Carlo estimate of the area-light integral;
  * pixel colour = emission + direct light + ambient * base colour; background colour for misses.

What it does not model: textures (base colour textures, texture LOD; the scenes it is meant for
have none), the G-buffer's half-precision storage, the GPU's own random sequence, reflections,
glossy rays, tone mapping and sRGB encoding.
"""
from __future__ import annotations

import numpy as np

from ..accel.bvh import build_bvh, offset_ray, trace_reference
from ..gl.gpu_layout import RECT_LIGHT_GRID

SHADOW_RAY_CHUNK = 1 << 16   # shadow rays per numpy traversal call (bounds memory)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _normalize(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


# ------------------------------------------------------------------------------ BRDF

def brdf_cos(n, v, l, base, metallic, roughness):
    """f(v, l) * cos(theta_l) for unit vectors (P,3), base (P,3), metallic/roughness (P,).

    Standard definitions (Walter et al. 2007; Heitz 2014):
      D(h) = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2)                    GGX / Trowbridge-Reitz
      Lambda(x) = (sqrt(1 + a^2 tan^2 theta_x) - 1) / 2              Smith, GGX
      G2 = 1 / (1 + Lambda(v) + Lambda(l))                           height-correlated
      F = F0 + (1 - F0) (1 - v.h)^5                                  Schlick
      f = F D G2 / (4 n.l n.v) + (1 - F)(1 - metallic) base / pi
    n.v is clamped to 1e-4 (a shading normal may face slightly away from the eye) and the result
    is 0 where the light is below the shading normal.
    """
    n_l = _dot(n, l)
    n_v = np.maximum(_dot(n, v), 1e-4)
    lit = n_l > 0
    n_l = np.where(lit, n_l, 1.0)                            # placeholder where unlit, masked below
    h = _normalize(v + l)
    n_h = np.clip(_dot(n, h), 0.0, 1.0)
    v_h = np.clip(_dot(v, h), 0.0, 1.0)
    a2 = np.maximum(roughness ** 2, 1e-3) ** 2
    D = a2 / (np.pi * (n_h ** 2 * (a2 - 1.0) + 1.0) ** 2)

    def smith_lambda(c):
        tan2 = (1.0 - c * c) / (c * c)
        return 0.5 * (np.sqrt(1.0 + a2 * tan2) - 1.0)

    G2 = 1.0 / (1.0 + smith_lambda(n_v) + smith_lambda(n_l))
    f0 = 0.04 * (1.0 - metallic[:, None]) + base * metallic[:, None]
    F = f0 + (1.0 - f0) * ((1.0 - v_h) ** 5)[:, None]
    specular = F * (D * G2 / (4.0 * n_l * n_v))[:, None]
    diffuse = (1.0 - F) * (1.0 - metallic[:, None]) * base / np.pi
    return np.where(lit[:, None], (specular + diffuse) * n_l[:, None], 0.0)


# ------------------------------------------------------------------------------ lights

def _rect_points(effect, count, rng, n_pixels):
    """Points on a rect light in [-1,1]^2, one (P,2) array per sample."""
    if effect == "raster":
        g = RECT_LIGHT_GRID
        for i in range(g):
            for j in range(g):
                yield np.broadcast_to((np.array([i, j]) + 0.5) / g * 2.0 - 1.0, (n_pixels, 2)), g * g
        return
    m = max(1, int(round(np.sqrt(count))))                  # m x m strata, one jittered point each
    for i in range(m):
        for j in range(m):
            yield (np.array([i, j]) + rng.random((n_pixels, 2))) / m * 2.0 - 1.0, m * m


def light_samples(light, origin, p, effect, rect_samples, rng):
    """Yield (l, dist, incident) per sample of `light` seen from scene-local points p (P,3)
    (`origin`: the scene origin the light's world position is taken relative to): unit direction
    to the light (P,3), distance (P,) and the unshadowed incident radiance times the sample's
    geometric weight (P,3), so that sum(incident * cos) over the samples is the irradiance.
    Rect lights: the 4x4 grid for "raster", `rect_samples` random points otherwise."""
    radiance = np.asarray(light.color, np.float64) * light.intensity
    if light.kind == "directional":
        l = np.broadcast_to(-_normalize(np.asarray(light.direction, np.float64)), p.shape)
        yield l, np.full(len(p), 1e30), np.broadcast_to(radiance, p.shape)
    elif light.kind == "point":
        d = np.asarray(light.position, np.float64) - origin - p
        dist = np.linalg.norm(d, axis=-1)
        ok = dist > 0
        safe = np.where(ok, dist, 1.0)
        yield d / safe[:, None], dist, np.where(ok, 1.0 / safe ** 2, 0.0)[:, None] * radiance
    elif light.kind == "rect":
        c = np.asarray(light.position, np.float64) - origin
        u, w = np.asarray(light.u, np.float64), np.asarray(light.v, np.float64)
        normal = _normalize(np.cross(u, w))
        area = 4.0 * np.linalg.norm(np.cross(u, w))
        for s, count in _rect_points(effect, rect_samples, rng, len(p)):
            d = c + s[:, :1] * u + s[:, 1:] * w - p
            dist = np.linalg.norm(d, axis=-1)
            safe = np.where(dist > 0, dist, 1.0)
            l = d / safe[:, None]
            cos_light = -_dot(l, normal)
            if light.two_sided:
                cos_light = np.abs(cos_light)
            weight = np.where((dist > 0) & (cos_light > 0), cos_light / safe ** 2 * area / count, 0.0)
            yield l, dist, weight[:, None] * radiance
    else:
        raise ValueError(f"unknown light kind {light.kind!r}")


# ------------------------------------------------------------------------------ shading

def direct_light(scene, bvh, p, n, ng, v, base, metallic, roughness, effect, rect_samples, rng):
    """Direct radiance (P,3) towards v at points p; ng: unit geometric normals (either side)."""
    total = np.zeros((len(p), 3))
    rays = []                                                # shadows: (pixels, origin, l, tmax, value)
    for light in scene.lights:
        for l, dist, incident in light_samples(light, scene.origin, p, effect, rect_samples, rng):
            value = brdf_cos(n, v, l, base, metallic, roughness) * incident
            if effect == "raster":
                total += value
                continue
            idx = np.flatnonzero((value > 0).any(axis=1))    # no light to lose: no ray
            side = np.where((_dot(ng[idx], l[idx]) >= 0)[:, None], ng[idx], -ng[idx])
            rays.append((idx, offset_ray(p[idx], side), l[idx], dist[idx] * (1.0 - 1e-4), value[idx]))
    if rays:
        idx, o, d, tmax, value = (np.concatenate(x) for x in zip(*rays))
        for s in range(0, len(idx), SHADOW_RAY_CHUNK):
            c = slice(s, s + SHADOW_RAY_CHUNK)
            blocked = trace_reference(bvh, o[c], d[c], 0.0, tmax[c], any_hit=True)
            np.add.at(total, idx[c][~blocked], value[c][~blocked])
    return total


def shade_eye(scene, eye, effect="raster", *, ambient=(0.03, 0.03, 0.03), background=(0.02, 0.02, 0.025),
              rect_samples=256, seed=0, bvh=None):
    """Reference HDR image of one eye (EyeView) for a scene all of whose materials use `effect`
    ("raster" or "shadows"). `rect_samples`: random points per rect light per pixel ("shadows";
    rounded to a square, jittered-stratified). Returns dict(hdr=(H,W,3) float64 rows top-down,
    triangle=(H,W) int64, material=(H,W) int64, both -1 for background)."""
    if effect not in ("raster", "shadows"):
        raise ValueError(f"effect must be 'raster' or 'shadows', got {effect!r}")
    rng = np.random.default_rng(seed)
    if bvh is None:
        bvh = build_bvh(scene.vertices, scene.indices)
    w, h = eye.size
    origin = np.asarray(eye.position, np.float64) - scene.origin
    dirs = eye.ray_directions().reshape(-1, 3)
    prim, t, b1, b2 = trace_reference(bvh, np.broadcast_to(origin, dirs.shape), dirs)
    hit = prim != 0xFFFFFFFF
    tri = prim[hit].astype(np.int64)
    d = dirs[hit]
    p = origin + t[hit, None] * d

    corners = scene.vertices[scene.indices[tri]].astype(np.float64)          # (P,3,3)
    ng = _normalize(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    weights = np.stack([1.0 - b1[hit] - b2[hit], b1[hit], b2[hit]], axis=1)
    ni = np.einsum("pk,pki->pi", weights, scene.normals[scene.indices[tri]].astype(np.float64))
    length2 = _dot(ni, ni)
    n = np.where((length2 > 1e-20)[:, None], ni / np.sqrt(np.maximum(length2, 1e-300))[:, None], ng)
    n = np.where((_dot(n, ng) < 0)[:, None], -n, n)        # normals wound against the triangle: to ng's side
    facing_away = _dot(ng, d) > 0
    n = np.where(facing_away[:, None], -n, n)
    ng = np.where(facing_away[:, None], -ng, ng)            # geometric normal on the eye's side

    mat = scene.triangle_material[tri].astype(np.int64)
    table = scene.materials
    base = np.array([m.base_color[:3] for m in table], np.float64)[mat]
    metallic = np.array([m.metallic for m in table], np.float64)[mat]
    roughness = np.array([m.roughness for m in table], np.float64)[mat]
    emission = np.array([m.emission for m in table], np.float64)[mat]
    one_sided = ~np.array([m.double_sided for m in table], bool)[mat]
    emission[facing_away & one_sided] = 0.0                 # the back of a one-sided emitter

    color = emission + direct_light(scene, bvh, p, n, ng, -d, base, metallic, roughness, effect,
                                    rect_samples, rng) + np.asarray(ambient, np.float64) * base
    hdr = np.empty((h * w, 3))
    hdr[:] = np.asarray(background, np.float64)
    hdr[hit] = color
    triangle = np.where(hit, prim.astype(np.int64), -1)
    material = np.full(h * w, -1, np.int64)
    material[hit] = mat
    return {"hdr": hdr.reshape(h, w, 3), "triangle": triangle.reshape(h, w), "material": material.reshape(h, w)}
