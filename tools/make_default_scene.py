"""Builds rayvr/assets/default_room.glb, the built-in default scene.

A closed 8 x 3.2 x 8 m room lit by a ceiling area light, with something for every rung of the
effect ladder: a mirror sphere and a mirror panel (reflections), a gold torus and a glossy
floor (glossy), diffuse boxes and coloured walls (shadows, colour bleeding for path/photon),
a glass-like sphere for later refraction work. A glTF camera node gives the default view.
Run: python tools/make_default_scene.py
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import trimesh
from trimesh.visual.material import PBRMaterial

OUT = Path(__file__).resolve().parents[1] / "rayvr" / "assets" / "default_room.glb"


def mat(name, color, metallic=0.0, roughness=0.6, emission=(0, 0, 0)):
    return PBRMaterial(name=name, baseColorFactor=[*color, 1.0], metallicFactor=metallic,
                       roughnessFactor=roughness, emissiveFactor=list(emission))


def box(extents, center, material, flip=False):
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(center)
    if flip:
        m.invert()
    m.visual = trimesh.visual.TextureVisuals(material=material)
    return m


def quad(center, u, v, material):
    """Rectangle spanning center ± u ± v, front face along cross(u, v)."""
    c, u, v = (np.asarray(x, float) for x in (center, u, v))
    verts = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
    m = trimesh.Trimesh(verts, [[0, 1, 2], [0, 2, 3]], process=False)
    m.visual = trimesh.visual.TextureVisuals(material=material)
    return m


def build() -> trimesh.Scene:
    s = trimesh.Scene()
    W, H, D = 8.0, 3.2, 8.0
    walls = mat("walls", (0.75, 0.73, 0.70), roughness=0.9)
    s.add_geometry(quad((0, 0, 0), (W / 2, 0, 0), (0, 0, -D / 2), mat("floor", (0.45, 0.32, 0.22), roughness=0.25)),
                   geom_name="floor")
    s.add_geometry(quad((0, H, 0), (W / 2, 0, 0), (0, 0, D / 2), mat("ceiling", (0.8, 0.8, 0.8), roughness=0.95)),
                   geom_name="ceiling")
    s.add_geometry(quad((0, H / 2, -D / 2), (W / 2, 0, 0), (0, H / 2, 0), walls), geom_name="wall_back")
    s.add_geometry(quad((0, H / 2, D / 2), (-W / 2, 0, 0), (0, H / 2, 0), walls), geom_name="wall_front")
    s.add_geometry(quad((-W / 2, H / 2, 0), (0, 0, D / 2), (0, H / 2, 0), mat("wall_red", (0.65, 0.08, 0.06), roughness=0.9)),
                   geom_name="wall_left")
    s.add_geometry(quad((W / 2, H / 2, 0), (0, 0, -D / 2), (0, H / 2, 0), mat("wall_green", (0.10, 0.45, 0.12), roughness=0.9)),
                   geom_name="wall_right")
    # Area light just below the ceiling, emitting downwards.
    s.add_geometry(quad((0, H - 0.01, -0.5), (0.8, 0, 0), (0, 0, 0.8), mat("light", (1, 1, 1), emission=(12.0, 11.5, 10.5))),
                   geom_name="light")
    mirror = mat("mirror", (0.95, 0.95, 0.95), metallic=1.0, roughness=0.02)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.6)
    sphere.apply_translation((-1.4, 0.6, -1.2))
    sphere.visual = trimesh.visual.TextureVisuals(material=mirror)
    s.add_geometry(sphere, geom_name="mirror_sphere")
    s.add_geometry(quad((1.2, 1.5, -D / 2 + 0.02), (1.0, 0, 0), (0, 0.9, 0), mat("mirror_panel", (0.9, 0.9, 0.92), metallic=1.0, roughness=0.0)),
                   geom_name="mirror_panel")
    torus = trimesh.creation.torus(major_radius=0.45, minor_radius=0.16, major_sections=48, minor_sections=24)
    torus.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2.5, [1, 0, 0]))
    torus.apply_translation((1.5, 0.62, -0.4))
    torus.visual = trimesh.visual.TextureVisuals(material=mat("gold", (1.0, 0.78, 0.34), metallic=1.0, roughness=0.3))
    s.add_geometry(torus, geom_name="gold_torus")
    s.add_geometry(box((0.9, 1.4, 0.9), (0.2, 0.7, -2.4), mat("box_white", (0.8, 0.8, 0.78), roughness=0.8)), geom_name="tall_box")
    s.add_geometry(box((0.7, 0.7, 0.7), (-0.1, 0.35, 0.3), mat("box_blue", (0.15, 0.25, 0.7), roughness=0.5)), geom_name="short_box")
    glass = trimesh.creation.icosphere(subdivisions=4, radius=0.35)
    glass.apply_translation((-0.2, 1.05, 0.3))
    glass.visual = trimesh.visual.TextureVisuals(material=mat("glass", (0.9, 0.95, 1.0), roughness=0.05))
    s.add_geometry(glass, geom_name="glass_sphere")
    return s


def add_camera(glb: bytes, position, target, yfov_deg=75.0) -> bytes:
    """Append a glTF perspective camera node looking from `position` at `target`."""
    length = struct.unpack_from("<I", glb, 12)[0]
    doc = json.loads(glb[20:20 + length])
    rest = glb[20 + length:]
    back = np.asarray(position, float) - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross([0, 1, 0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, position
    doc.setdefault("cameras", []).append({"type": "perspective", "name": "default_view",
                                           "perspective": {"yfov": np.radians(yfov_deg), "znear": 0.05}})
    doc["nodes"].append({"name": "default_view", "camera": len(doc["cameras"]) - 1,
                         "matrix": m.T.reshape(-1).tolist()})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    # glTF clamps emissiveFactor to [0, 1]: brighter emitters use KHR_materials_emissive_strength.
    for m in doc.get("materials", []):
        e = m.get("emissiveFactor")
        if e and max(e) > 1.0:
            strength = max(e)
            m["emissiveFactor"] = [x / strength for x in e]
            m.setdefault("extensions", {})["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
            doc.setdefault("extensionsUsed", []).append("KHR_materials_emissive_strength")
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


if __name__ == "__main__":
    data = build().export(file_type="glb")
    data = add_camera(data, position=(0.3, 1.6, 3.4), target=(0.0, 0.9, -1.5))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_bytes(data)
    print(f"wrote {OUT} ({len(data) / 1024:.0f} KiB)")
