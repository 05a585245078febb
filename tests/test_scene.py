import json
import struct
import warnings

import numpy as np
import pytest
import trimesh

from rayvr.scene.loader import SceneError, from_arrays, load

TRI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)


@pytest.mark.parametrize("verts, faces, words", [
    (np.array([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]]), [[0, 1, 2]], ["NaN or inf", "vertex 1"]),
    (np.array([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]]), [[0, 1, 2]], ["NaN or inf"]),
    (TRI, np.zeros((0, 3), int), ["no faces"]),
    (TRI, [[0, 1, 3]], ["out of range", "max 3", "3 vertices"]),
    (TRI, [[0, -1, 2]], ["out of range"]),
    (TRI, [[0.0, 1.0, 2.0]], ["integers"]),
    (TRI[:, :2], [[0, 1, 2]], ["(N, 3)"]),
    (TRI, [[0, 0, 0]], ["every triangle is degenerate"]),
])
def test_bad_meshes_rejected_with_name(verts, faces, words):
    with pytest.raises(SceneError) as e:
        from_arrays(verts, np.asarray(faces), name="broken.obj")
    assert "broken.obj" in str(e.value)
    for w in words:
        assert w in str(e.value)


def test_degenerate_triangles_dropped_and_counted():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [0, 0, 1]], float)
    f = np.array([[0, 1, 2], [0, 0, 1], [0, 1, 3], [1, 3, 4], [2, 1, 0], [0, 1, 5], [1, 2, 5]])
    s = from_arrays(v, f)
    assert s.triangle_count == 4 and s.dropped_degenerate == 3
    assert "3 degenerate triangles dropped" in s.summary()


def test_missing_normals_are_computed_for_a_sphere():
    m = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    s = from_arrays(m.vertices + [5, 0, 0], m.faces)
    radial = s.world_vertices() - [5, 0, 0]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", s.normals, radial).min() > 0.995


def test_positions_are_relative_to_origin_far_from_zero():
    off = np.array([1e5, -2e5, 3e5])
    s = from_arrays(TRI * 1e-3 + off, np.array([[0, 1, 2]]))
    assert np.allclose(s.origin, off + [5e-4, 5e-4, 0])
    # float32 local coordinates keep sub-micrometre detail that float32 world ones would lose.
    assert np.abs(s.world_vertices() - (TRI * 1e-3 + off)).max() < 1e-9
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # centring keeps even 1e300 out of float32's way
        s = from_arrays(TRI[:, [2, 0, 1]] + [1e300, 0, 0], np.array([[0, 1, 2]]))
    assert np.allclose(s.vertices, TRI[:, [2, 0, 1]] - [0, 0.5, 0.5]) and s.triangle_count == 1
    assert all(abs(l.position[0] - 1e300) < 1e290 for l in s.lights)   # light positions near the scene too


def test_obj_mtl_emission_illum_and_area_light(tmp_path):
    (tmp_path / "m.mtl").write_text(
        "newmtl lamp\nKd 0.8 0.8 0.8\nKe 5 4 3\nillum 2\n\n"
        "newmtl chrome\nKd 0.01 0.01 0.01\nKs 0.9 0.9 0.9\nNs 1000\nillum 3\n")
    (tmp_path / "s.obj").write_text(
        "mtllib m.mtl\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl lamp\nf 1 2 3\nf 1 3 4\nusemtl chrome\nf 5 6 7\n")
    s = load(tmp_path / "s.obj")
    mats = {m.name: m for m in s.materials}
    assert mats["lamp"].emission == pytest.approx((5, 4, 3))
    assert mats["chrome"].metallic == 1.0 and mats["chrome"].roughness < 0.25
    assert mats["chrome"].base_color[:3] == pytest.approx((0.9, 0.9, 0.9))
    (light,) = s.lights
    assert light.kind == "rect" and light.intensity == 5
    assert np.allclose(light.position, [0, 2, 0])
    normal = np.cross(light.u, light.v)
    assert normal[1] < 0  # faces 1 2 3 / 1 3 4 wind downwards (-Y)
    assert 4 * np.linalg.norm(normal) == pytest.approx(4.0)  # 2 x 2 rectangle


def _write_gltf(path, doc, bin_data):
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    bin_data += b"\0" * (-len(bin_data) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(bin_data), 0x004E4942) + bin_data
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


def test_gltf_lights_camera_and_pbr(tmp_path):
    pos = TRI.astype(np.float32).tobytes()
    idx = np.array([0, 1, 2], np.uint32).tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [{"mesh": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1, 2, 3]},
                  {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [-0.7071068, 0, 0, 0.7071068]},
                  {"camera": 0, "translation": [0, 1, 5]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1, 0.5, 0.25], "intensity": 7},
            {"type": "directional", "intensity": 3}]}},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"name": "lamp_shade", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1],
                       "metallicFactor": 0.25, "roughnessFactor": 0.75}, "emissiveFactor": [1, 0.5, 0],
                       "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}}}],
        "buffers": [{"byteLength": 48}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
    }
    _write_gltf(tmp_path / "t.glb", doc, pos + idx)
    s = load(tmp_path / "t.glb")
    point = next(l for l in s.lights if l.kind == "point")
    sun = next(l for l in s.lights if l.kind == "directional")
    assert np.allclose(point.position, [1, 2, 3]) and point.intensity == 7 and point.color == (1, 0.5, 0.25)
    assert np.allclose(sun.direction, [0, -1, 0], atol=1e-6)  # -Z rotated -90 deg about X
    m = s.materials[0]
    assert m.name == "lamp_shade" and m.metallic == pytest.approx(0.25) and m.roughness == pytest.approx(0.75)
    assert m.base_color[:3] == pytest.approx((0.2, 0.4, 0.6)) and m.emission == pytest.approx((4, 2, 0))
    assert np.allclose(s.camera["position"], [0, 1, 5]) and s.camera["fov_y"] == pytest.approx(np.degrees(0.8))


def test_ply_and_default_scene():
    s = load()
    assert s.triangle_count > 1000 and s.camera is not None
    names = s.material_names()
    assert {"mirror", "floor", "light", "gold"} <= set(names)
    assert any(l.kind == "rect" for l in s.lights)


def test_ply_loads(tmp_path):
    m = trimesh.creation.box()
    m.export(tmp_path / "b.ply")
    s = load(tmp_path / "b.ply")
    assert s.triangle_count == 12 and len(s.lights) == 2  # default lights when the file has none


def test_unsupported_and_missing_files(tmp_path):
    with pytest.raises(SceneError, match="no such file"):
        load(tmp_path / "nope.glb")
    (tmp_path / "x.fbx").write_text("")
    with pytest.raises(SceneError, match="unsupported format"):
        load(tmp_path / "x.fbx")
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SceneError, match="NaN"):
        load(tmp_path / "bad.obj")


def test_shared_scenes_load(shared_scene):
    s = load(shared_scene("cornell_box/CornellBox-Original.trimesh.obj"))
    assert s.triangle_count == 36 - s.dropped_degenerate
    assert [l.kind for l in s.lights] == ["rect"]
    s = load(shared_scene("damaged_helmet/DamagedHelmet.gltf"))
    assert s.materials[0].texture is not None and s.triangle_count == 15452


def test_obj_without_materials_splits_by_group(tmp_path, shared_scene):
    """No mtllib/usemtl: one material per `g` group, named after it (configs select parts)."""
    p = tmp_path / "groups.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\n"
                 "g floor\nf 1 2 3\ng mirror\nf 4 5 6\n")
    s = load(p)
    assert sorted(s.material_names()) == ["floor", "mirror"]   # trimesh's order, not the file's
    assert sorted(s.triangle_material.tolist()) == [0, 1]
    floor = s.material_names().index("floor")
    tri = s.world_vertices()[s.indices[s.triangle_material == floor][0]]
    assert np.allclose(tri[:, 2], 0)   # the floor group's triangle
    # Grey and rough as trimesh made them (Kd 0.8, Blinn-Phong Ns 10 -> GGX roughness (2/12)^0.25):
    # diffuse, so the reference renders them with `shadows`, not `glossy` (0.5 would be glossy).
    for m in s.materials:
        assert m.base_color[:3] == (0.8, 0.8, 0.8) and m.metallic == 0.0
        assert m.roughness == pytest.approx(0.6389, abs=1e-4)
    sponza = load(shared_scene("sponza_dabrovic/sponza.obj"))
    assert {"floors", "walls", "ceiling"} <= set(sponza.material_names())
    assert len(sponza.materials) == 34 and sponza.triangle_count >= 66000


@pytest.mark.parametrize("angle", [0.0, 0.3, 45.0, 71.0])
def test_square_and_rotated_rect_lights_are_recognised(angle):
    """Squares have no preferred in-plane axes: the fit must not depend on an SVD's choice."""
    from rayvr.scene.loader import Material, emissive_rect_lights

    a = np.radians(angle)
    u = np.array([np.cos(a), 0.0, np.sin(a)]) * 0.8
    v = np.array([-np.sin(a), 0.0, np.cos(a)]) * 0.8
    c = np.array([1.0, 3.0, -2.0])
    quad = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
    floor = np.array([[-5, 0, -5], [5, 0, -5], [0, 0, 5]], float)
    s = from_arrays(np.vstack([quad, floor]), np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6]]),
                    triangle_material=[0, 0, 1], materials=[Material("lamp", emission=(3, 3, 3)), Material("floor")])
    (light,) = emissive_rect_lights(s)
    assert np.allclose(light.position, c)
    assert 4 * np.linalg.norm(np.cross(light.u, light.v)) == pytest.approx(1.6 * 1.6)  # the square's area
    assert np.cross(light.u, light.v)[1] > 0  # emits to the side faces 0 2 1 / 0 3 2 wind to (+Y)


# --------------------------------------------------------------------------- OBJ reading


def _tri_set(s):
    """Each triangle as a tuple of its 9 world coordinates (rounded), winding kept."""
    w = np.round(s.world_vertices()[s.indices], 5)
    return sorted(map(tuple, w.reshape(-1, 9).tolist()))


def test_obj_relative_indices_tabs_crlf_and_polygons(tmp_path):
    """Negative indices count back from the vertices read *so far* (two quads written the
    McGuire way, `f -4 -3 -2 -1` after each one's vertices), `v<TAB>` lines, CRLF, a pentagon
    fanned into 3 triangles, `o`/`g` lines and trailing comments."""
    (tmp_path / "m.mtl").write_text("newmtl floor\nKd 0.5 0.5 0.5\n\nnewmtl lamp\nKd 1 1 1\nKe 4 4 4 # warm\n")
    lines = ["mtllib m.mtl", "o floor",
             "v\t-1 0 -1", "v\t 1 0 -1", "v\t 1 0  1", "v\t-1 0 1 # corner",
             "g floor", "usemtl floor", "f -1 -2 -3 -4",
             "v -0.25\t1.5 -0.25", "v 0.25 1.5 -0.25", "v 0.25 1.5 0.25", "v -0.25 1.5 0.25",
             "g lamp", "usemtl lamp", "f\t-4 -3 -2 -1",
             "v 0 0.5 0", "v 1 0.5 0", "v 1.5 0.5 0.5", "v 1 0.5 1", "v 0 0.5 1",
             "usemtl floor", "f 9 10 11 12 13"]
    (tmp_path / "s.obj").write_bytes("\r\n".join(lines).encode() + b"\r\n")
    s = load(tmp_path / "s.obj")
    assert s.triangle_count == 2 + 2 + 3 and s.dropped_degenerate == 0
    assert s.material_names() == ["floor", "lamp"]          # file order
    w = s.world_vertices()
    for name, y in (("floor", 0.0), ("lamp", 1.5)):
        tris = s.indices[s.triangle_material == s.material_names().index(name)][:2]
        assert np.allclose(w[tris][..., 1], y), name        # each quad on its own vertices
    pent = w[s.indices[4:]]
    assert np.allclose(pent[..., 1], 0.5) and np.allclose(pent[:, 0], [0, 0.5, 0])  # fanned from its first vertex
    (light,) = s.lights
    assert light.kind == "rect" and light.intensity == 4 and np.allclose(light.position, [0, 1.5, 0])
    assert 4 * np.linalg.norm(np.cross(light.u, light.v)) == pytest.approx(0.25)


def test_obj_texcoords_normals_and_undefined_material(tmp_path, caplog):
    (tmp_path / "m.mtl").write_text("newmtl known\nKd 0.2 0.4 0.6\n")
    (tmp_path / "s.obj").write_text(
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.75\nvt 1 0\nvt 0 1\nvn 0 0 2\n"
        "usemtl known\nf 1/1/1 2/2/1 3/3/1\nusemtl ghost\nf 1//-1 3//-1 2//-1\n")
    with caplog.at_level("WARNING"):
        s = load(tmp_path / "s.obj")
    assert s.material_names() == ["known", "ghost"]
    assert s.materials[0].base_color[:3] == pytest.approx((0.2, 0.4, 0.6))
    assert "ghost" in caplog.text and "m.mtl" in caplog.text       # used but never defined: said
    first = s.indices[0]
    assert np.allclose(s.uvs[first], [[0.25, 0.75], [1, 0], [0, 1]])
    assert np.allclose(s.normals[first], [0, 0, 1])                 # the file's normal, unit length
    assert s.triangle_count == 2 and len(s.world_vertices()) == 6   # corners differ by uv: not shared


def test_obj_unreadable_faces_are_counted_and_most_refused(tmp_path, caplog):
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    (tmp_path / "some.obj").write_text(quad + "f 1 2 3\nf 1 3 4\nf 1 3 4\nf 1 2 9\n")
    with caplog.at_level("WARNING"):
        s = load(tmp_path / "some.obj")
    assert s.triangle_count == 3 and s.dropped_unreadable == 1
    assert "some.obj" in caplog.text and "line 8" in caplog.text
    (tmp_path / "most.obj").write_text(quad + "f 1 2 3\nf 1 2 9\nf 1 0 3\nf 5 6 7 8\n")
    with pytest.raises(SceneError) as e:
        load(tmp_path / "most.obj")
    assert "most.obj" in str(e.value) and "4 of 5 triangles" in str(e.value)


def test_most_triangles_degenerate_refused():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 0, 1], [0, 1, 3], [1, 1, 1]])
    with pytest.raises(SceneError) as e:
        from_arrays(v, f, name="flat.obj")
    assert "flat.obj" in str(e.value) and "3 of 4 triangles" in str(e.value) and "degenerate" in str(e.value)


def _independent_obj_count(path):
    """Triangles an OBJ really has: every `f` line with n corners fans into n - 2."""
    tris, mats = 0, set()
    for line in path.read_bytes().decode("utf-8", "replace").splitlines():
        t = line.split()
        if t and t[0] == "f":
            tris += len(t) - 3
        elif t and t[0] == "usemtl":
            mats.add(" ".join(t[1:]))
    return tris, mats


@pytest.mark.parametrize("rel, light", [
    ("cornell_box/CornellBox-Original.obj", True), ("cornell_box/CornellBox-Original.trimesh.obj", True),
    ("cornell_box/CornellBox-Mirror.obj", True), ("cornell_box/CornellBox-Mirror.trimesh.obj", True),
    ("cornell_box/CornellBox-Sphere.obj", True),
    ("cornell_box/CornellBox-Glossy.obj", False),   # its MTL defines no `light` material (no Ke)
    ("sponza_dabrovic/sponza.obj", False),
])
def test_shared_objs_load_whole(shared_scene, rel, light):
    p = shared_scene(rel)
    tris, mats = _independent_obj_count(p)
    s = load(p)
    assert s.triangle_count + s.dropped_degenerate == tris and s.dropped_unreadable == 0
    assert s.dropped_degenerate <= 1                  # Sponza has one zero-area triangle
    if mats:
        assert set(s.material_names()) == mats
    kinds = [l.kind for l in s.lights]
    if light:
        assert kinds == ["rect"] and s.lights[0].source == "emissive material light"
        assert s.lights[0].position[1] > 1.5          # under the ceiling
    else:
        assert "rect" not in kinds
    if "cornell" in rel:
        assert np.allclose(s.bounds[0], [-1.02, 0, -1.04], atol=2e-4)
        assert s.bounds[1] == pytest.approx([1.0, 1.99 if ("Original" in rel or "Mirror" in rel) else 1.59, 0.99])
        w = s.world_vertices()
        part = {m.name: w[np.unique(s.indices[s.triangle_material == i])] for i, m in enumerate(s.materials)}
        assert part["floor"][:, 1].max() < 0.01 and part["ceiling"][:, 1].min() > 1.55
        assert part["leftWall"][:, 0].max() < -0.98 and part["rightWall"][:, 0].min() > 0.98
        assert part["backWall"][:, 2].max() < -1.0


@pytest.mark.parametrize("box", ["Original", "Mirror"])
def test_relative_index_boxes_equal_their_absolute_copies(shared_scene, box):
    """The *.trimesh.obj copies were converted (whitespace, absolute indices) by someone else:
    reading both must give the same triangles, winding included."""
    a = load(shared_scene(f"cornell_box/CornellBox-{box}.obj"))
    b = load(shared_scene(f"cornell_box/CornellBox-{box}.trimesh.obj"))
    assert _tri_set(a) == _tri_set(b) and len(_tri_set(a)) == 36


# --------------------------------------------------------------------------- float32 range


@pytest.mark.parametrize("verts, value", [
    (TRI * 1e30, "1e+30"),                                           # the triangle from the issue
    (np.vstack([TRI, [[-1.7e308, 0, 0]]]), "-1.7e+308"),             # unused, but it moves the centre
    (TRI + [[0, 0, 0], [0, 0, 0], [3e9, 0, 0]], "3000000000.0"),     # float32 holds it; its 4th power not
])
def test_coordinates_beyond_float32_arithmetic_refused_without_numpy_warnings(verts, value):
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # a RuntimeWarning from numpy fails the test
        with pytest.raises(SceneError) as e:
            from_arrays(verts, [[0, 1, 2]])
    msg = str(e.value)
    assert msg.startswith("<arrays>: vertex ") and value in msg and "float32" in msg and "\n" not in msg


def test_coordinates_far_out_in_a_file_are_refused_naming_it(tmp_path):
    (tmp_path / "far.obj").write_text("v 0 0 0\nv 1e30 0 0\nv 0 1e30 0\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SceneError) as e:
            load(tmp_path / "far.obj")
    assert str(e.value).startswith(str(tmp_path / "far.obj")) and "[1e+30, 0.0, 0.0]" in str(e.value)


def test_triangles_float32_cannot_resolve_are_dropped_said_and_most_refused(caplog):
    """A big triangle 1e7 away makes float32 scene-local coordinates 0.5 apart near the origin:
    triangles 1e-3 across collapse there. Counted as degenerate and warned about; refused when
    they are most of the mesh."""
    far = TRI * 10 + [1e7, 0, 0]
    tiny = [TRI * 1e-3 + [0, k, 0] for k in range(3)]
    v = np.vstack([far] + tiny)
    with caplog.at_level("WARNING"), warnings.catch_warnings():
        warnings.simplefilter("error")
        s = from_arrays(np.vstack([v, far + [0, 5, 0]]), np.arange(15).reshape(5, 3)[[0, 1, 4]], name="mix")
    assert s.triangle_count == 2 and s.dropped_degenerate == 1 and "float32" in caplog.text
    with pytest.raises(SceneError, match=r"<mix>: 3 of 4 triangles .*float32"):
        from_arrays(v, np.arange(12).reshape(4, 3), name="mix")


# --------------------------------------------------------------------------- textures


def _textured_obj(tmp_path, map_kd):
    from PIL import Image

    Image.new("RGB", (4, 2), (255, 0, 0)).save(tmp_path / "red.png")
    (tmp_path / "fake.png").write_text("this is not a PNG\n")
    (tmp_path / "m.mtl").write_text(f"newmtl painted\nKd 1 1 1\nmap_Kd {map_kd}\n")
    (tmp_path / "t.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "usemtl painted\nf 1/1 2/2 3/3\n")
    return tmp_path / "t.obj"


@pytest.mark.parametrize("map_kd", ["red.png", "-bm 0.5 red.png"])
def test_obj_texture_loads(tmp_path, caplog, map_kd):
    with caplog.at_level("WARNING"):
        s = load(_textured_obj(tmp_path, map_kd))
    assert s.materials[0].texture.shape == (2, 4, 4) and tuple(s.materials[0].texture[0, 0]) == (255, 0, 0, 255)
    assert not caplog.records


@pytest.mark.parametrize("map_kd, why", [("gone.png", "no such file"), ("fake.png", "not an image")])
def test_obj_missing_or_broken_texture_warns_naming_material_and_file(tmp_path, caplog, map_kd, why):
    with caplog.at_level("WARNING"):
        s = load(_textured_obj(tmp_path, map_kd))
    assert s.materials[0].texture is None
    (rec,) = [r for r in caplog.records if r.levelname == "WARNING"]
    assert rec.name == "rayvr.scene.loader" and "'painted'" in rec.getMessage() and map_kd in rec.getMessage()
    assert why in rec.getMessage()


def _textured_glb(path, uri):
    pos = TRI.astype(np.float32).tobytes()
    uv = np.array([[0, 0], [1, 0], [0, 1]], np.float32).tobytes()
    idx = np.array([0, 1, 2], np.uint32).tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"name": "skin", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}], "images": [{"uri": uri}],
        "buffers": [{"byteLength": 72}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                        {"buffer": 0, "byteOffset": 60, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5125, "count": 3, "type": "SCALAR"}],
    }
    _write_gltf(path, doc, pos + uv + idx)
    return path


@pytest.mark.parametrize("uri, why", [("red.png", None), ("gone.png", "no such file"), ("fake.png", "not an image")])
def test_gltf_missing_or_broken_texture_warns_naming_material_and_file(tmp_path, caplog, uri, why):
    _textured_obj(tmp_path, "red.png")   # writes red.png and fake.png
    with caplog.at_level("WARNING"):
        s = load(_textured_glb(tmp_path / "t.glb", uri))
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and r.name == "rayvr.scene.loader"]
    if why is None:
        assert s.materials[0].texture is not None and not warned
    else:
        assert s.materials[0].texture is None and len(warned) == 1
        assert "'skin'" in warned[0] and uri in warned[0] and why in warned[0]


# --------------------------------------------------------------------------- not a scene


def test_not_a_scene_is_one_clear_line(tmp_path):
    rng = np.random.default_rng(7)
    (tmp_path / "folder.obj").mkdir()
    (tmp_path / "plain_folder").mkdir()
    noise = rng.integers(0, 256, 4096, dtype=np.uint8).tobytes()
    for name in ("noise.glb", "noise.gltf", "noise.ply", "noise.obj"):
        (tmp_path / name).write_bytes(noise)
    for name in ("empty.obj", "empty.glb", "empty.ply"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "words.obj").write_text("hello world\nthis is not a mesh\n")
    (tmp_path / "json.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{}]}]}')
    expect = {"folder.obj": "is a folder", "plain_folder": "is a folder", "noise.glb": "not a binary glTF",
              "noise.gltf": "not glTF JSON", "noise.ply": "", "noise.obj": "binary", "empty.obj": "empty",
              "empty.glb": "empty", "empty.ply": "empty", "words.obj": "no faces", "json.gltf": ""}
    for name, words in expect.items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(SceneError) as e:
                load(tmp_path / name)
        msg = str(e.value)
        assert msg.startswith(str(tmp_path / name) + ": ") and words in msg and "\n" not in msg, msg
        assert len(msg) < 300 + len(str(tmp_path)), msg
