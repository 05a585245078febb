"""The scene on the GPU: vertex/index buffers, per-triangle material IDs, material and light
SSBOs (layouts mirror glsl/common/scene.glsl) and the base-colour texture array."""
from __future__ import annotations

import numpy as np

from ..frame.effects import EFFECTS, PARAM_WORDS
from ..gl.gpu_layout import LIGHT_KINDS, SSBO
from .light_selection import pick_table
from .loader import Light, Scene
from .materials import Assignment
from .surfaces import surface_groups

MATERIAL_DTYPE = np.dtype([("base_color", "<f4", 4), ("emission", "<f4", 4), ("metallic", "<f4"),
                           ("roughness", "<f4"), ("texture_layer", "<i4"), ("effect", "<u4"),
                           ("params", "<u4", PARAM_WORDS)])
# `params` carries the material's effect parameters, packed by the effect (frame/effect_registry.py).
LIGHT_DTYPE = np.dtype([("position_kind", "<f4", 4), ("radiance", "<f4", 4), ("direction", "<f4", 4),
                        ("u", "<f4", 4), ("v", "<f4", 4)])
LIGHT_KIND_ID = {k: i for i, k in enumerate(LIGHT_KINDS)}
TEXTURE_SIZE_LIMIT = 1024  # base-colour textures are resampled to one size for the array


class BufferTooLarge(ValueError):
    """The scene needs a buffer larger than the device allows."""


def check_buffer_size(name: str, nbytes: int, limit: int) -> None:
    if limit and nbytes > limit:
        raise BufferTooLarge(f"scene too large: buffer {name!r} needs {nbytes / 2**20:.1f} MiB, "
                             f"the device allows {limit / 2**20:.1f} MiB per shader storage buffer")


def material_records(scene: Scene, assignments: list[Assignment], texture_layers: list[int]) -> np.ndarray:
    rec = np.zeros(max(len(scene.materials), 1), MATERIAL_DTYPE)
    for i, m in enumerate(scene.materials):
        rec[i]["base_color"] = m.base_color
        rec[i]["emission"][:3] = m.emission
        rec[i]["emission"][3] = float(m.double_sided)  # scene.glsl emits_both_sides
        rec[i]["metallic"] = m.metallic
        rec[i]["roughness"] = m.roughness
        rec[i]["texture_layer"] = texture_layers[i]
        effect = EFFECTS[assignments[i].effect]
        rec[i]["effect"] = effect.id
        rec[i]["params"] = effect.pack_params(assignments[i].params)
    return rec


def light_records(scene: Scene) -> np.ndarray:
    rec = np.zeros(max(len(scene.lights), 1), LIGHT_DTYPE)
    if not scene.lights:  # keep the SSBO non-empty; radiance 0 adds nothing
        rec[0]["position_kind"][3] = LIGHT_KIND_ID["point"]
    for i, light in enumerate(scene.lights):
        rec[i] = _light_record(light, scene.origin)
    if scene.lights:  # light_selection.py: each light's probability and the running sum, for --light-picks
        lo, hi = scene.bounds
        pmf, cdf = pick_table(scene.lights, 0.5 * float(np.linalg.norm(hi - lo)))
        rec["radiance"][:, 3], rec["direction"][:, 3] = pmf, cdf
    return rec


def _light_record(light: Light, origin: np.ndarray):
    if light.kind not in LIGHT_KIND_ID:
        raise ValueError(f"unknown light kind {light.kind!r}; allowed: {', '.join(LIGHT_KIND_ID)}")
    r = np.zeros((), LIGHT_DTYPE)
    r["position_kind"][:3] = np.asarray(light.position, np.float64) - origin
    r["position_kind"][3] = LIGHT_KIND_ID[light.kind]
    r["radiance"][:3] = np.asarray(light.color, np.float64) * light.intensity
    r["direction"][:3] = light.direction
    r["u"][:3] = light.u
    r["u"][3] = float(light.two_sided)  # scene.glsl light_two_sided
    r["v"][:3] = light.v
    return r


def interleaved_vertices(scene: Scene) -> np.ndarray:
    """(V, VERTEX_FLOATS) float32 rows: position, normal, uv."""
    return np.ascontiguousarray(np.concatenate([scene.vertices, scene.normals, scene.uvs], axis=1), dtype="f4")


class GpuScene:
    """Uploads a Scene once; `set_assignments` re-uploads only the material table (live reload)."""

    def __init__(self, gl, scene: Scene, assignments: list[Assignment]):
        ctx = gl.ctx
        self.ctx, self.scene = ctx, scene
        limit = gl.max_ssbo_bytes
        interleaved = interleaved_vertices(scene)
        check_buffer_size("vertices", interleaved.nbytes, limit)
        check_buffer_size("indices", scene.indices.nbytes, limit)
        check_buffer_size("triangle_material", scene.triangle_material.nbytes, limit)
        self.vbo = ctx.buffer(interleaved)
        self.ibo = ctx.buffer(scene.indices)
        self.triangle_material = ctx.buffer(scene.triangle_material)
        self.texture_layers, self.textures = self._upload_textures(ctx, scene)
        self.materials = ctx.buffer(material_records(scene, assignments, self.texture_layers))
        self.lights = ctx.buffer(light_records(scene))
        self.assignments = assignments
        self.triangle_surface = None  # made on first use (surfaces)

    def surfaces(self):
        """The buffer of each triangle's smooth surface (scene/surfaces.py), for the MSAA merge; made
        when a frame first merges by surface (the scene's geometry as loaded)."""
        if self.triangle_surface is None:
            scene = self.scene
            groups = surface_groups(scene.vertices, scene.indices, scene.triangle_material, scene.normals)
            self.triangle_surface = self.ctx.buffer(groups if len(groups) else np.zeros(1, np.uint32))
        return self.triangle_surface

    def upload_vertices(self) -> None:
        """Re-upload the scene's (moved) vertices; same count and layout."""
        self.vbo.write(interleaved_vertices(self.scene))

    def set_assignments(self, assignments: list[Assignment]) -> None:
        self.assignments = assignments
        self.materials.write(material_records(self.scene, assignments, self.texture_layers))

    def bind(self) -> None:
        self.triangle_material.bind_to_storage_buffer(SSBO["triangle_material"])
        self.materials.bind_to_storage_buffer(SSBO["materials"])
        self.lights.bind_to_storage_buffer(SSBO["lights"])
        self.vbo.bind_to_storage_buffer(SSBO["vertices"])
        self.ibo.bind_to_storage_buffer(SSBO["indices"])

    @staticmethod
    def _upload_textures(ctx, scene: Scene):
        from PIL import Image

        images = [m.texture for m in scene.materials if m.texture is not None]
        layers, next_layer = [], 0
        if not images:
            tex = ctx.texture_array((1, 1, 1), 4, np.full(4, 255, np.uint8).tobytes())
            return [-1] * len(scene.materials), tex
        size = min(TEXTURE_SIZE_LIMIT, max(max(im.shape[0], im.shape[1]) for im in images))
        size = 1 << max(int(np.ceil(np.log2(max(size, 1)))), 0)
        data = []
        for m in scene.materials:
            if m.texture is None:
                layers.append(-1)
                continue
            im = m.texture
            if im.shape[0] != size or im.shape[1] != size:
                im = np.asarray(Image.fromarray(im).resize((size, size), Image.BILINEAR))
            # trimesh gives UVs with (0,0) at the image's bottom-left (it flips glTF's); GL's
            # texel row 0 is the bottom while the image's row 0 is its top: flip the rows.
            data.append(np.ascontiguousarray(im[::-1]))
            layers.append(next_layer)
            next_layer += 1
        tex = ctx.texture_array((size, size, len(data)), 4, np.stack(data).tobytes())
        tex.build_mipmaps()
        tex.repeat_x = tex.repeat_y = True
        tex.anisotropy = 8.0
        return layers, tex

    def release(self) -> None:
        for obj in (self.vbo, self.ibo, self.triangle_material, self.materials, self.lights, self.textures,
                    *([self.triangle_surface] if self.triangle_surface is not None else [])):
            obj.release()
