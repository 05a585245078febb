"""Scenes: glTF/GLB and PLY through trimesh, OBJ+MTL through rayvr's own reader, flattened into
GPU-ready arrays.

Positions are stored in float32 *relative to* `Scene.origin` (float64, the centre of the
bounds), so a scene placed 1e5 units from the world origin keeps sub-millimetre precision;
cameras build their view matrices in float64 against that origin.

Arrays (one draw call covers the whole scene, so a triangle's index is its ID everywhere):
  vertices  (V,3) float32   scene-local positions
  normals   (V,3) float32   unit shading normals (computed when the file has none)
  uvs       (V,2) float32   texture coordinates (0 when the file has none)
  indices   (T,3) uint32
  triangle_material (T,) uint32   index into `materials`
"""
from __future__ import annotations

import json
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

ASSETS_DIR = Path(__file__).resolve().parents[1] / "assets"
DEFAULT_SCENE = ASSETS_DIR / "default_room.glb"
SUPPORTED_SUFFIXES = (".glb", ".gltf", ".obj", ".ply")
# The material of a `g` group in an OBJ without materials: Blinn-Phong Ns 10 as GGX roughness
# (alpha = sqrt(2 / (Ns + 2)), roughness = sqrt(alpha)), trimesh's default before rayvr read OBJ itself.
GROUP_MATERIAL_ROUGHNESS = (2.0 / 12.0) ** 0.25
# Largest scene-local coordinate (distance from the centre of the bounds along an axis): edges up
# to 2*sqrt(3)*1e8 keep their fourth powers (what the GPU computes) near 1.4e34, well inside
# float32 (3.4e38), with room for the camera's distance. Measured: 5e8 renders lit, 5e9 does not.
MAX_LOCAL_COORDINATE = 1e8


class SceneError(ValueError):
    """A scene file cannot be used; the message names the file and the problem."""


@dataclass
class Material:
    name: str
    base_color: tuple = (0.8, 0.8, 0.8, 1.0)  # linear RGBA
    metallic: float = 0.0
    roughness: float = 0.5
    emission: tuple = (0.0, 0.0, 0.0)  # linear RGB radiance
    texture: np.ndarray | None = field(default=None, repr=False)  # HxWx4 uint8 sRGB base colour
    # Emission leaves both faces (glTF `doubleSided`); otherwise only the front face, the side its
    # triangles' winding points to (OBJ, glTF's default). Shading is two-sided either way.
    double_sided: bool = False

    @property
    def is_emissive(self) -> bool:
        return max(self.emission) > 0.0


@dataclass
class Light:
    """kind: 'point' (position), 'directional' (direction the light travels), 'rect'
    (position = centre, u/v = half-edge vectors, emits on the side of cross(u, v), or on both
    sides when `two_sided`: an emissive rectangle of a double-sided material).
    `color` is linear RGB and `intensity` scales it (point: W/sr-like, directional: irradiance,
    rect: radiance)."""

    kind: str
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    position: tuple = (0.0, 0.0, 0.0)  # world space (float64)
    direction: tuple = (0.0, -1.0, 0.0)
    u: tuple = (0.0, 0.0, 0.0)
    v: tuple = (0.0, 0.0, 0.0)
    source: str = "default"
    two_sided: bool = False


@dataclass
class Scene:
    name: str
    path: Path | None
    origin: np.ndarray  # float64 (3,)
    vertices: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    indices: np.ndarray
    triangle_material: np.ndarray
    materials: list[Material]
    lights: list[Light]
    dropped_degenerate: int = 0
    dropped_unreadable: int = 0  # faces a loader could not read (bad indices), in triangles
    camera: dict | None = None  # the file's default view: {"position", "rotation", "fov_y"} (world, degrees)

    @property
    def triangle_count(self) -> int:
        return int(len(self.indices))

    @property
    def bounds(self) -> np.ndarray:
        """(2,3) float64 world-space bounds."""
        if len(self.vertices) == 0:
            return np.zeros((2, 3)) + self.origin
        lo = self.vertices.min(axis=0).astype(np.float64) + self.origin
        hi = self.vertices.max(axis=0).astype(np.float64) + self.origin
        return np.stack([lo, hi])

    @property
    def center(self) -> np.ndarray:
        return self.bounds.mean(axis=0)

    @property
    def extent(self) -> float:
        b = self.bounds
        return float(np.linalg.norm(b[1] - b[0]))

    def material_names(self) -> list[str]:
        return [m.name for m in self.materials]

    def world_vertices(self) -> np.ndarray:
        """float64 world-space positions (for cross-checks)."""
        return self.vertices.astype(np.float64) + self.origin

    def summary(self) -> str:
        return (f"{self.name}: {self.triangle_count} triangles, {len(self.materials)} materials, "
                f"{len(self.lights)} lights"
                + (f", {self.dropped_degenerate} degenerate triangles dropped" if self.dropped_degenerate else "")
                + (f", {self.dropped_unreadable} unreadable triangles dropped" if self.dropped_unreadable else ""))


# --------------------------------------------------------------------------- building


def from_arrays(vertices, indices, *, triangle_material=None, materials=None, normals=None, uvs=None,
                lights=None, name="arrays", path=None, ambient_lights=True, unreadable: int = 0,
                emissive_lights: bool | None = None) -> Scene:
    """Validate raw world-space arrays and make a Scene. Used by the loaders and by tests.

    `emissive_lights`: whether emissive rectangles become rect lights besides `lights` (True: the
    loaders, a file's emissive quads are its area lights whatever other lights it has), or not at
    all (False); None: only when no `lights` are given (a caller that gives lights gives them all,
    so a test can have glowing geometry that is no light).

    `unreadable`: triangles the loader had to skip; with the degenerate ones they must stay a
    minority, or the load is refused (a half-read mesh is not rendered silently)."""
    where = str(path) if path else f"<{name}>"
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(indices)
    if v.ndim != 2 or v.shape[1] != 3:
        raise SceneError(f"{where}: vertices must be (N, 3), got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise SceneError(f"{where}: faces must be (M, 3) triangles, got shape {f.shape}")
    if len(f) == 0:
        raise SceneError(f"{where}: the mesh has no faces")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise SceneError(f"{where}: {int(bad.sum())} vertices have NaN or inf coordinates "
                         f"(first: vertex {first} = {v[first].tolist()})")
    if not np.issubdtype(f.dtype, np.integer):
        raise SceneError(f"{where}: face indices must be integers, got {f.dtype}")
    if f.min() < 0 or f.max() >= len(v):
        raise SceneError(f"{where}: face indices out of range: min {int(f.min())}, max {int(f.max())}, "
                         f"but there are {len(v)} vertices")
    materials = list(materials) if materials else [Material("default")]
    tm = (np.zeros(len(f), np.uint32) if triangle_material is None
          else np.asarray(triangle_material, dtype=np.int64))
    if tm.shape != (len(f),):
        raise SceneError(f"{where}: triangle_material must have one entry per face")
    if len(tm) and (tm.min() < 0 or tm.max() >= len(materials)):
        raise SceneError(f"{where}: material index out of range (have {len(materials)} materials)")

    # Positions are stored in float32 relative to the centre of the bounds (halves: no overflow
    # even at +-1.7e308). The GPU multiplies up to four of them (the G-buffer resolve's
    # barycentrics divide by |cross(e1, e2)|^2), so scene-local coordinates must stay far below
    # float32's max ** (1/4) ~ 1.4e9: beyond, surfaces render unlit with NaN normals.
    lo, hi = v.min(axis=0), v.max(axis=0)
    origin = lo / 2.0 + hi / 2.0
    half = hi / 2.0 - lo / 2.0
    if half.max() > MAX_LOCAL_COORDINATE:
        k = int(np.argmax(half))
        median = np.partition(v[:, k], len(v) // 2)[len(v) // 2]
        i = int(np.argmax(np.abs(v[:, k] - median)))  # the outlier
        raise SceneError(f"{where}: vertex {i} = {v[i].tolist()} lies {abs(v[i, k] - origin[k]):.3g} from the "
                         f"centre of the scene's bounds along {'xyz'[k]}; coordinates beyond {MAX_LOCAL_COORDINATE:.0e} "
                         f"from it overflow the renderer's float32 arithmetic (scale the scene or drop far geometry)")
    local = v - origin
    local32 = local.astype(np.float32)

    # Degenerate (zero-area, repeated-index, collinear) triangles rasterize to nothing and
    # break ray tests: drop them and count. Judged on the float32 positions the GPU gets, so a
    # triangle too small for float32 at its distance from the centre counts too (and is said).
    def zero_area(p):
        tri = p[f]
        area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        return area2 <= (max(float(np.abs(tri).max()), 1e-30) * 1e-12) ** 2

    degenerate = zero_area(local32.astype(np.float64))
    lost = int((degenerate & ~zero_area(local)).sum())
    dropped = int(degenerate.sum())
    why = (f" ({lost} of them only in float32: too small for their distance from the scene's centre, "
           f"extent {2 * half.max():.3g})") if lost else ""
    if len(f) == dropped:
        raise SceneError(f"{where}: every triangle is degenerate (zero area){why}")
    total = len(f) + unreadable
    if 2 * (dropped + unreadable) > total:
        raise SceneError(f"{where}: {dropped + unreadable} of {total} triangles would be dropped ({dropped} degenerate"
                         f"{why}, {unreadable} unreadable); refusing a load that loses most of the mesh")
    if lost:
        log.warning("%s: dropped %d triangles that collapse in float32 scene-local coordinates (too small for "
                    "their distance from the scene's centre, extent %.3g)", where, lost, 2 * half.max())
    if dropped:
        log.info("%s: dropped %d degenerate triangles", where, dropped)
        f, tm = f[~degenerate], tm[~degenerate]

    # The file's normals, made unit; rows that are missing (NaN), zero or not finite are computed.
    n = None if normals is None else np.asarray(normals, dtype=np.float64)
    if n is None or n.shape != v.shape:
        n = vertex_normals(local, f)
    else:
        with np.errstate(invalid="ignore", over="ignore"):
            length = np.linalg.norm(n, axis=1, keepdims=True)
        ok = np.isfinite(length) & (length > 1e-12)
        n = np.where(ok, n / np.where(ok, length, 1.0), vertex_normals(local, f) if not ok.all() else 0.0)
    uv = np.zeros((len(v), 2), np.float32) if uvs is None else np.asarray(uvs, dtype=np.float32)
    if uv.shape != (len(v), 2) or not np.isfinite(uv).all():
        uv = np.zeros((len(v), 2), np.float32)
    scene = Scene(
        name=name, path=Path(path) if path else None, origin=origin,
        vertices=np.ascontiguousarray(local32), normals=np.ascontiguousarray(n, dtype=np.float32),
        uvs=np.ascontiguousarray(uv), indices=np.ascontiguousarray(f, dtype=np.uint32),
        triangle_material=np.ascontiguousarray(tm, dtype=np.uint32), materials=materials,
        lights=list(lights or []), dropped_degenerate=dropped, dropped_unreadable=int(unreadable),
    )
    if emissive_lights or (emissive_lights is None and not scene.lights):
        scene.lights += emissive_rect_lights(scene, existing=scene.lights)
    if not scene.lights and ambient_lights:
        scene.lights = default_lights(scene)
    return scene


def vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals; vertices no face touches get +Y."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0, n / np.maximum(length, 1e-300), np.array([0.0, 1.0, 0.0]))
    return n


def default_lights(scene: Scene) -> list[Light]:
    """A key directional light and a point light above the scene, sized to its bounds."""
    b = scene.bounds
    c, size = scene.center, max(scene.extent, 1e-6)
    top = np.array([c[0], b[1][1] + 0.25 * size, c[2] + 0.25 * size])
    return [
        Light("directional", (1.0, 0.97, 0.92), 2.0, position=tuple(c),  # unused; kept near the scene
              direction=tuple(_unit([-0.4, -1.0, -0.3])), source="default"),
        Light("point", (1.0, 1.0, 1.0), 0.5 * size * size, position=tuple(top), source="default"),
    ]


def emissive_rect_lights(scene: Scene, existing=()) -> list[Light]:
    """Each emissive material whose triangles form one planar rectangle becomes a rect light
    (how OBJ/Cornell-box files describe area lights), unless a rect light in `existing` already
    covers that rectangle. One-sided (emitting where the triangles' winding points) unless the
    material is double-sided, as its emission is in the shaders."""
    lights = []
    world = scene.world_vertices()
    for mi, m in enumerate(scene.materials):
        if not m.is_emissive:
            continue
        tris = scene.indices[scene.triangle_material == mi]
        if len(tris) == 0:
            continue
        pts = world[np.unique(tris)]
        rect = _fit_rectangle(pts)
        if rect is None:
            log.info("emissive material %r is not a rectangle; it glows but casts no light", m.name)
            continue
        centre, u, v, normal = rect
        # Orient to the emitting side: the triangles' winding.
        corners = world[tris]
        fn = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        facing = fn @ np.cross(u, v)
        if facing[0] < 0:
            v, facing = -v, -facing
        if not m.double_sided:  # one-sided: say when the winding makes it light the wrong way
            if (facing < 0).any():
                log.warning("emissive material %r: %d of its %d triangles are wound the other way; they glow "
                            "towards the back while its area light lights the front", m.name,
                            int((facing < 0).sum()), len(tris))
            side = (world - centre) @ np.cross(u, v)
            tol = 1e-6 * float(np.abs(side).max(initial=0.0))
            if not (side > tol).any() and (side < -tol).any():
                log.warning("emissive material %r faces away from all other geometry (by its triangles' winding): "
                            "its area light lights none of it; if that is wrong, flip its winding or make the "
                            "material double-sided (glTF doubleSided)", m.name)
        scale = max(m.emission)
        color = tuple(float(e / scale) for e in m.emission)
        light = Light("rect", color, float(scale), position=tuple(centre), u=tuple(u), v=tuple(v),
                      source=f"emissive material {m.name}", two_sided=m.double_sided)
        if any(same_rectangle(light, other) for other in existing):
            continue
        lights.append(light)
    return lights


def _rect_corners(light: Light) -> np.ndarray:
    c, u, v = (np.asarray(x, np.float64) for x in (light.position, light.u, light.v))
    return np.array([c - u - v, c - u + v, c + u - v, c + u + v])


def same_rectangle(a: Light, b: Light) -> bool:
    """Whether rect lights a and b cover the same rectangle (corners equal to 1e-4 of its size,
    in any order): an emissive quad the caller already made a light is not added twice."""
    if a.kind != "rect" or b.kind != "rect":
        return False
    ca, cb = _rect_corners(a), _rect_corners(b)
    tol = 1e-4 * max(np.ptp(ca, axis=0).max(), 1e-30)
    return all(np.linalg.norm(cb - p, axis=1).min() <= tol for p in ca)


def _fit_rectangle(pts: np.ndarray):
    """(centre, u, v, normal) of the rectangle whose corners are among `pts`, or None.

    The side directions are tried from the point pairs (a rectangle's sides are among them), not
    from an SVD: for a square the SVD's in-plane axes are any rotation, so whether a square
    light was recognised depended on the LAPACK build."""
    if len(pts) < 3:
        return None
    centre = pts.mean(axis=0)
    d = pts - centre
    _, s, vt = np.linalg.svd(d, full_matrices=False)
    if s[0] <= 0 or s[-1] > 1e-4 * s[0]:
        return None  # not planar
    normal = vt[2] if len(vt) > 2 else np.cross(vt[0], vt[1])
    for i in range(len(pts)):
        for j in range(i + 1, len(pts)):
            edge = d[j] - d[i]
            edge -= normal * (edge @ normal)
            if np.linalg.norm(edge) <= 1e-9 * s[0]:
                continue
            a1 = edge / np.linalg.norm(edge)
            a2 = np.cross(normal, a1)
            p1, p2 = d @ a1, d @ a2
            lo1, hi1, lo2, hi2 = p1.min(), p1.max(), p2.min(), p2.max()
            tol = 1e-3 * max(hi1 - lo1, hi2 - lo2)
            corners = [(lo1, lo2), (lo1, hi2), (hi1, lo2), (hi1, hi2)]
            if all(np.any((np.abs(p1 - c1) < tol) & (np.abs(p2 - c2) < tol)) for c1, c2 in corners):
                c = centre + a1 * (lo1 + hi1) / 2 + a2 * (lo2 + hi2) / 2
                return c, a1 * (hi1 - lo1) / 2, a2 * (hi2 - lo2) / 2, np.cross(a1, a2)
    return None


def _unit(x) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return x / np.linalg.norm(x)


# --------------------------------------------------------------------------- loading files


def load(path: str | Path | None = None) -> Scene:
    """Load a scene file (glTF/GLB, OBJ+MTL, PLY); None loads the built-in default scene."""
    import trimesh

    path = Path(path) if path is not None else DEFAULT_SCENE
    if not path.exists():
        raise SceneError(f"{path}: no such file")
    if path.is_dir():
        raise SceneError(f"{path}: is a folder, not a scene file (give the .glb/.gltf/.obj/.ply inside it)")
    if path.suffix.lower() not in SUPPORTED_SUFFIXES:
        raise SceneError(f"{path}: unsupported format {path.suffix!r}; use one of {', '.join(SUPPORTED_SUFFIXES)}")
    try:
        with path.open("rb") as fh:
            head = fh.read(64)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    if not head:
        raise SceneError(f"{path}: the file is empty")
    suffix = path.suffix.lower()
    if suffix == ".obj":
        return load_obj(path)
    if suffix == ".glb" and head[:4] != b"glTF":
        raise SceneError(f"{path}: not a binary glTF (GLB) file: it does not start with 'glTF'")
    if suffix in (".gltf", ".glb"):
        try:
            _gltf_json(path)
        except Exception as exc:
            raise SceneError(f"{path}: not glTF JSON: {_one_line(exc)}") from None
    try:
        tscene = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:
        raise SceneError(f"{path}: trimesh could not read it: {_one_line(exc)}") from exc

    verts, faces, norms, uvs, tri_mat = [], [], [], [], []
    materials: list[Material] = []
    mat_index: dict[int, int] = {}
    offset = 0
    for node in tscene.graph.nodes_geometry:
        transform, geom_name = tscene.graph[node]
        geom = tscene.geometry[geom_name]
        if not hasattr(geom, "faces") or geom.faces is None or len(geom.faces) == 0:
            continue
        v = np.asarray(geom.vertices, dtype=np.float64)
        if not np.isfinite(v).all():
            bad = int((~np.isfinite(v).all(axis=1)).sum())
            raise SceneError(f"{path}: mesh {geom_name!r} has {bad} vertices with NaN or inf coordinates")
        f = np.asarray(geom.faces, dtype=np.int64)
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise SceneError(f"{path}: mesh {geom_name!r} has face indices out of range "
                             f"(max {int(f.max())}, {len(v)} vertices)")
        vw = v @ transform[:3, :3].T + transform[:3, 3]
        n = _file_normals(geom)
        if n is not None:
            n = n @ np.linalg.inv(transform[:3, :3]).T
        uv = getattr(geom.visual, "uv", None)
        uv = np.asarray(uv, dtype=np.float32) if uv is not None and len(uv) == len(v) else np.zeros((len(v), 2), np.float32)
        tmat = getattr(geom.visual, "material", None)
        key = id(tmat)
        if key not in mat_index:
            mat_index[key] = len(materials)
            materials.append(_material_from_trimesh(tmat, geom_name, len(materials)))
        verts.append(vw)
        faces.append(f + offset)
        norms.append(n if n is not None else np.full_like(vw, np.nan))
        uvs.append(uv)
        tri_mat.append(np.full(len(f), mat_index[key], np.int64))
        offset += len(v)
    if not faces:
        raise SceneError(f"{path}: the file has no triangle meshes")
    _dedupe_material_names(materials)
    is_gltf = path.suffix.lower() in (".gltf", ".glb")
    lights, camera = ([], None)
    if is_gltf:
        lights, camera = _gltf_extras(path, materials)
    scene = from_arrays(np.concatenate(verts), np.concatenate(faces), triangle_material=np.concatenate(tri_mat),
                       materials=materials, normals=np.concatenate(norms),
                       uvs=np.concatenate(uvs), lights=lights, name=path.stem, path=path, emissive_lights=True)
    scene.camera = camera
    return scene


# --------------------------------------------------------------------------- OBJ + MTL
# rayvr reads OBJ itself: trimesh 5.2 ignores `v<TAB>` lines and resolves relative (negative)
# indices against the whole file instead of the vertices read so far, so McGuire's Cornell boxes
# loaded with collapsed walls and no error.


def _obj_index(text: str, count: int) -> int:
    """0-based index of an OBJ reference (1-based, or negative: counted back from the `count`
    elements read so far); ValueError when it is 0, not an integer or out of range."""
    i = int(text)
    r = i - 1 if i > 0 else count + i if i < 0 else -1
    if not 0 <= r < count:
        raise ValueError(f"index {text} out of range ({count} read so far)")
    return r


def load_obj(path: str | Path) -> Scene:
    """Read an OBJ (+ its MTL files): v/vt/vn, faces with positive and negative (relative)
    indices, polygons fanned into triangles from their first corner, `o`/`g` groups, `usemtl`,
    `mtllib`, tabs, CRLF and `\\` line continuations. Each distinct (v, vt, vn) corner becomes one
    vertex. Faces with bad references are skipped, counted and warned about (line number).

    Materials come from the MTL (`newmtl`, one per `usemtl` name, in order of first use); an OBJ
    without materials (no mtllib/usemtl, e.g. the Dabrovic Sponza) gets one material per `g`/`o`
    group instead, named after the group, so a material config can select parts of it."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    if b"\0" in data:
        raise SceneError(f"{path}: binary data (NUL bytes), not a text OBJ file")
    text = data.decode("utf-8", errors="replace")
    text = re.sub(r"\\[ \t]*\r?\n", " ", text)
    pos, tex, nrm = [], [], []
    corner_ids: dict[tuple, int] = {}
    faces, face_state = [], []
    states: dict[tuple, int] = {}  # (usemtl, group) -> id, in order of first use by a face
    mtllibs, usemtl, group, has_materials = [], None, None, False
    bad_tris, first_bad = 0, None
    readers = {"v": (pos, 3), "vn": (nrm, 3), "vt": (tex, 2)}
    by_token: dict[str, int] = {}  # corner text -> id, for positive (absolute) references only
    for ln, raw in enumerate(text.splitlines(), 1):
        tok = (raw.split("#", 1)[0] if "#" in raw else raw).split()
        if not tok:
            continue
        kind = tok[0]
        if kind == "f":
            try:
                if len(tok) < 4:
                    raise ValueError(f"a face needs 3 corners, got {len(tok) - 1}")
                ids = []
                for c in tok[1:]:
                    cid = by_token.get(c)
                    if cid is None:
                        parts = c.split("/")
                        key = (_obj_index(parts[0], len(pos)),
                               _obj_index(parts[1], len(tex)) if len(parts) > 1 and parts[1] else -1,
                               _obj_index(parts[2], len(nrm)) if len(parts) > 2 and parts[2] else -1)
                        cid = corner_ids.setdefault(key, len(corner_ids))
                        if "-" not in c:  # an absolute reference that resolved once always will
                            by_token[c] = cid
                    ids.append(cid)
            except ValueError as exc:
                bad_tris += max(len(tok) - 3, 1)
                first_bad = first_bad or f"line {ln}: {raw.strip()[:60]!r}: {exc}"
                continue
            state = states.setdefault((usemtl, group), len(states))
            for k in range(1, len(ids) - 1):
                faces.append((ids[0], ids[k], ids[k + 1]))
                face_state.append(state)
        elif kind in readers:
            out, n = readers[kind]
            vals = tok[1:n + 1]
            if kind == "vt" and len(vals) == 1:
                vals.append("0")
            try:
                if len(vals) < n:
                    raise ValueError
                out.append(list(map(float, vals)))
            except ValueError:
                raise SceneError(f"{path}: line {ln}: cannot read {kind!r} line {raw.strip()[:60]!r}") from None
        elif kind in ("g", "o"):
            group = " ".join(tok[1:]) or None
        elif kind == "usemtl":
            usemtl, has_materials = " ".join(tok[1:]) or None, True
        elif kind == "mtllib":
            mtllibs.append(raw.split("#", 1)[0].strip()[len("mtllib"):].strip())
            has_materials = True
    if not faces:
        if bad_tris:
            raise SceneError(f"{path}: none of its faces could be read (first: {first_bad})")
        raise SceneError(f"{path}: " + ("the file is empty" if not text.strip() else
                                        f"no faces ('f' lines) among {len(pos)} vertices: not an OBJ mesh"))
    if bad_tris:
        log.warning("%s: skipped %d unreadable triangles (first: %s)", path, bad_tris, first_bad)

    corners = np.array(list(corner_ids), dtype=np.int64)
    vertices = np.asarray(pos, dtype=np.float64)[corners[:, 0]]
    uvs = np.zeros((len(corners), 2))
    normals = np.full((len(corners), 3), np.nan)
    has_t, has_n = corners[:, 1] >= 0, corners[:, 2] >= 0
    if has_t.any():
        uvs[has_t] = np.asarray(tex)[corners[has_t, 1]]
    if has_n.any():
        normals[has_n] = np.asarray(nrm)[corners[has_n, 2]]

    defs: dict[str, dict] = {}
    for ref in mtllibs:
        defs.update(_read_mtllib(path, ref))
    materials, by_key, state_material = [], {}, []
    for mtl, grp in states:  # in order of first use
        key = (mtl if has_materials else grp) or "default"
        if key not in by_key:
            by_key[key] = len(materials)
            if not has_materials:  # grey Kd 0.8, Blinn-Phong Ns 10: what trimesh gave (renders kept)
                materials.append(Material(key, roughness=GROUP_MATERIAL_ROUGHNESS))
            elif key in defs:
                materials.append(_material_from_mtl(key, defs[key], where=path))
            else:
                log.warning("%s: material %r is used but no mtllib (%s) defines it: default grey, no emission",
                            path, key, ", ".join(mtllibs) or "none given")
                materials.append(Material(key))
        state_material.append(by_key[key])
    _dedupe_material_names(materials)
    return from_arrays(vertices, np.asarray(faces, dtype=np.int64),
                       triangle_material=np.asarray(state_material, dtype=np.int64)[face_state],
                       materials=materials, normals=normals, uvs=uvs, name=path.stem, path=path,
                       unreadable=bad_tris, emissive_lights=True)


def _read_mtllib(obj_path: Path, ref: str) -> dict[str, dict]:
    """{material name: {lower-case key: value tokens, "_dir": folder}} from an `mtllib` line's
    file(s) (several names on one line, or one name with spaces); a missing file warns."""
    folder = obj_path.parent
    refs = [ref] if (folder / ref.replace("\\", "/")).is_file() else ref.split()
    defs: dict[str, dict] = {}
    for name in refs:
        p = folder / name.replace("\\", "/")
        try:
            text = p.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            log.warning("%s: mtllib %s: cannot read %s (%s); its materials get default parameters",
                        obj_path, ref, p, exc.strerror or exc)
            continue
        current = None
        for raw in text.splitlines():
            tok = raw.split()
            if not tok or tok[0].startswith("#"):
                continue
            key = tok[0].lower()
            if key == "newmtl":
                current = defs[" ".join(tok[1:])] = {"_dir": p.parent}
            elif current is not None and key.startswith("map_"):
                current[key] = raw.strip()[len(key):].strip()  # a file name, maybe with options
            elif current is not None:
                current[key] = raw.split("#", 1)[0].split()[1:]
    return defs


def _one_line(exc: BaseException, limit: int = 200) -> str:
    """An exception as one short line, with its type when the text alone says little."""
    text = " ".join(str(exc).split())
    if len(text) > limit:
        text = text[:limit] + "..."
    return text if len(text) > 24 and " " in text else f"{type(exc).__name__}: {text}".rstrip(": ")


def _file_normals(geom):
    """Normals stored in the file, or None (then they are computed)."""
    cached = getattr(geom, "_cache", None)
    try:
        if cached is not None and "vertex_normals" in cached:
            return np.asarray(cached["vertex_normals"], dtype=np.float64)
    except Exception:
        pass
    return None


def _dedupe_material_names(materials: list[Material]) -> None:
    seen: dict[str, int] = {}
    for m in materials:
        if m.name in seen:
            seen[m.name] += 1
            m.name = f"{m.name}.{seen[m.name]}"
        else:
            seen[m.name] = 0


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _texture_array(image, what: str = "texture") -> np.ndarray | None:
    """HxWx4 uint8 from a PIL image or an image file; None (and a warning naming `what` and the
    file) when it cannot be decoded."""
    if image is None:
        return None
    try:
        if isinstance(image, (str, Path)):
            from PIL import Image

            with Image.open(image) as im:
                return np.asarray(im.convert("RGBA"), dtype=np.uint8)
        return np.asarray(image.convert("RGBA"), dtype=np.uint8)
    except Exception as exc:
        src = image if isinstance(image, (str, Path)) else getattr(image, "info", {}).get("file_path", "its image")
        log.warning("%s: texture %s is not an image rayvr can read (%s); rendered untextured",
                    what, src, " ".join(str(exc).split())[:200] or type(exc).__name__)
        return None


def _texture_mean(image, linear: bool, default) -> np.ndarray:
    rgba = _texture_array(image)
    if rgba is None:
        return np.asarray(default, dtype=np.float64)
    rgb = rgba[::4, ::4, :3].astype(np.float64) / 255.0
    return (_srgb_to_linear(rgb) if linear else rgb).reshape(-1, 3).mean(axis=0)


def _material_from_trimesh(tmat, fallback_name: str, index: int) -> Material:
    """glTF PBR material (or trimesh's OBJ-style SimpleMaterial, read like MTL) -> Material."""
    if tmat is None:
        return Material(fallback_name or f"material_{index}")
    name = getattr(tmat, "name", None) or fallback_name or f"material_{index}"
    if type(tmat).__name__ == "PBRMaterial":
        bc = tmat.baseColorFactor
        bc = (np.asarray(bc, dtype=np.float64) / (255.0 if np.asarray(bc).dtype == np.uint8 else 1.0)
              if bc is not None else np.ones(4))
        emissive = np.asarray(tmat.emissiveFactor if tmat.emissiveFactor is not None else (0.0, 0.0, 0.0),
                              dtype=np.float64)[:3]
        metallic = float(tmat.metallicFactor if tmat.metallicFactor is not None else 1.0)
        roughness = float(tmat.roughnessFactor if tmat.roughnessFactor is not None else 1.0)
        # Emissive and metallic-roughness textures are not sampled yet: scale the factors by the
        # textures' means so a mostly dark emissive map does not make the whole mesh glow.
        emissive = emissive * _texture_mean(getattr(tmat, "emissiveTexture", None), linear=True, default=(1, 1, 1))
        mr = _texture_mean(getattr(tmat, "metallicRoughnessTexture", None), linear=False, default=(1, 1, 1))
        return Material(
            name=name,
            base_color=tuple(float(x) for x in bc[:4]) if len(bc) >= 4 else (*map(float, bc[:3]), 1.0),
            metallic=metallic * float(mr[2]),
            roughness=roughness * float(mr[1]),
            emission=tuple(float(x) for x in emissive),
            texture=_texture_array(getattr(tmat, "baseColorTexture", None), f"material {name!r}"),
            double_sided=bool(getattr(tmat, "doubleSided", False)),  # absent in the file: glTF's false
        )
    # trimesh's SimpleMaterial keeps the MTL keys it has no field for in `kwargs`.
    kw = dict(getattr(tmat, "kwargs", {}) or {})
    kw.setdefault("kd", list(np.asarray(getattr(tmat, "diffuse", [102, 102, 102, 255])[:3], dtype=np.float64) / 255.0))
    kw.setdefault("ns", [float(getattr(tmat, "glossiness", 1.0) or 1.0)])
    m = _material_from_mtl(name, kw)
    m.texture = _texture_array(getattr(tmat, "image", None), f"material {name!r}")
    return m


def _material_from_mtl(name: str, kw: dict, where=None) -> Material:
    """An MTL material ({lower-case key: value tokens}) -> Material: Kd (already linear
    reflectance in practice), Ks/illum (metal), Ns (roughness), Ke (emission), d, map_Kd (the
    base colour texture, loaded relative to the MTL file; a missing or unreadable one warns)."""

    def vec(key, default):
        val = kw.get(key)
        if val is None:
            return np.asarray(default, dtype=np.float64)
        try:
            arr = np.asarray([float(x) for x in np.atleast_1d(val)], dtype=np.float64)
        except (TypeError, ValueError):
            return np.asarray(default, dtype=np.float64)
        return np.resize(arr, 3) if arr.size else np.asarray(default, dtype=np.float64)

    kd = vec("kd", [0.4, 0.4, 0.4])  # trimesh's default when an MTL material has no Kd
    ks = vec("ks", [0.0, 0.0, 0.0])
    ke = vec("ke", [0.0, 0.0, 0.0])
    ns = float(vec("ns", [1.0])[0])
    illum = int(vec("illum", [2])[0])
    # Blinn-Phong exponent -> GGX roughness (alpha = sqrt(2 / (Ns + 2)), roughness = sqrt(alpha)).
    roughness = float(np.clip((2.0 / (max(ns, 0.0) + 2.0)) ** 0.25, 0.02, 1.0))
    metallic = 0.0
    base = kd
    # illum 3/5 (reflection on) with a strong specular colour: a metal whose colour is Ks.
    if illum in (3, 5, 6, 7) and ks.max() > max(kd.max(), 0.2):
        metallic, base = 1.0, ks
    d = float(vec("d", [1.0])[0])
    folders = [kw.get("_dir") or Path(".")] + ([Path(where).parent] if where else [])
    texture = _mtl_texture(name, kw["map_kd"], folders, where) if kw.get("map_kd") else None
    return Material(name=name, base_color=(*map(float, base), d), metallic=metallic, roughness=roughness,
                    emission=tuple(map(float, ke)), texture=texture)


def _mtl_texture(material: str, ref: str, folders: list, where) -> np.ndarray | None:
    """Load a map_Kd image (the whole value as a file name, else its last word: options such as
    `-bm 1 file.png` come first; looked up next to the MTL, then the OBJ), or warn naming the
    material and the file and return None."""
    names = [ref] + ([ref.split()[-1]] if len(ref.split()) > 1 else [])
    found = next((p for n in names for d in folders if (p := Path(d) / n.replace("\\", "/")).is_file()), None)
    if found is None:
        log.warning("%s: material %r: texture %s: no such file (looked in %s); rendered untextured",
                    where, material, ref, ", ".join(dict.fromkeys(str(d) for d in folders)))
        return None
    return _texture_array(found, f"{where}: material {material!r}")


def _gltf_extras(path: Path, materials: list[Material]):
    """What trimesh drops from glTF: KHR_lights_punctual lights, KHR_materials_emissive_strength
    and the first camera node (the file's default view)."""
    try:
        doc = _gltf_json(path)
    except Exception as exc:
        log.warning("%s: could not read glTF JSON: %s", path, exc)
        return [], None
    by_name = {m.name: m for m in materials}
    for gi, gm in enumerate(doc.get("materials", [])):
        strength = gm.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength")
        m = by_name.get(gm.get("name"))
        if m is not None and strength:
            m.emission = tuple(float(e) * float(strength) for e in m.emission)
        _warn_gltf_textures(path, doc, gm, gm.get("name") or f"#{gi}", m)
    nodes = doc.get("nodes", [])
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}

    def world(i):
        m = _node_matrix(nodes[i])
        while i in parent:
            i = parent[i]
            m = _node_matrix(nodes[i]) @ m
        return m

    camera = None
    cams = doc.get("cameras", [])
    for i, node in enumerate(nodes):
        ref = node.get("camera")
        if ref is not None and ref < len(cams) and cams[ref].get("type") == "perspective":
            m = world(i)
            rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
            camera = {"position": m[:3, 3].copy(), "rotation": rot,
                      "fov_y": math.degrees(float(cams[ref]["perspective"].get("yfov", math.radians(60))))}
            break

    defs = (doc.get("extensions", {}).get("KHR_lights_punctual", {}) or {}).get("lights", [])
    lights = []
    for i, node in enumerate(nodes):
        ref = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if ref is None or ref >= len(defs):
            continue
        d = defs[ref]
        m = world(i)
        color = tuple(float(c) for c in d.get("color", [1, 1, 1]))
        intensity = float(d.get("intensity", 1.0))
        kind = d.get("type")
        if kind == "directional":
            direction = _unit(m[:3, :3] @ np.array([0.0, 0.0, -1.0]))
            lights.append(Light("directional", color, intensity, direction=tuple(direction), source=f"{path.name} node {i}"))
        elif kind in ("point", "spot"):  # spot cones are not modelled yet: lit as a point light
            lights.append(Light("point", color, intensity, position=tuple(m[:3, 3]), source=f"{path.name} node {i}"))
    return lights, camera


def _warn_gltf_textures(path: Path, doc: dict, gm: dict, label: str, m: Material | None) -> None:
    """trimesh drops a glTF texture it cannot load without a word: say which material lost
    which image and why (external files are checked here; embedded ones through the result)."""
    from urllib.parse import unquote

    pbr = gm.get("pbrMetallicRoughness", {})
    slots = (("base colour", pbr.get("baseColorTexture")), ("metallic-roughness", pbr.get("metallicRoughnessTexture")),
             ("emissive", gm.get("emissiveTexture")))
    for slot, ref in slots:
        if not isinstance(ref, dict):
            continue
        try:
            image = doc["images"][doc["textures"][ref["index"]]["source"]]
        except (KeyError, IndexError, TypeError):
            log.warning("%s: material %r: %s texture %s refers to no image; ignored", path, label, slot, ref.get("index"))
            continue
        uri = image.get("uri", "")
        if uri and not uri.startswith("data:"):
            problem = _image_problem(path.parent / unquote(uri))
        else:
            problem = ("the embedded image could not be decoded"
                       if slot == "base colour" and m is not None and m.texture is None else None)
        if problem:
            log.warning("%s: material %r: %s texture %s: %s; rendered without it",
                        path, label, slot, uri or "(embedded)", problem)


def _image_problem(p: Path) -> str | None:
    """Why the image file `p` cannot be used, or None (only its header is read)."""
    if not p.is_file():
        return "no such file"
    try:
        from PIL import Image

        with Image.open(p):
            return None
    except Exception as exc:
        return f"not an image rayvr can read ({' '.join(str(exc).split())[:200] or type(exc).__name__})"


def _gltf_json(path: Path) -> dict:
    data = path.read_bytes()
    if path.suffix.lower() == ".glb":
        length = int.from_bytes(data[12:16], "little")
        return json.loads(data[20:20 + length])
    return json.loads(data)


def _node_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    t = np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float64)
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    s = np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    m = np.eye(4)
    m[:3, :3] = r * s
    m[:3, 3] = t
    return m
