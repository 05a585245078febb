"""The layered G-buffer: one texture array per channel, layer = eye (mono is 1 layer).

CHANNELS is the one declaration of what the G-buffer holds. It is made in two steps: a
visibility raster writes `depth` and `triangle` only (glsl/gbuffer/visibility.*), then a
compute resolve fills every other channel from the triangle and the pixel's ray
(glsl/gbuffer/resolve.comp, images bound at `image` below). Later passes read all channels
through glsl/common/gbuffer.glsl at texture unit `unit`.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass

import moderngl

GL_TEXTURE_2D_ARRAY = 0x8C1A
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_DEPTH_COMPONENT = 0x1902
GL_FLOAT = 0x1406
GL_FRAMEBUFFER = 0x8D40
GL_DEPTH_ATTACHMENT = 0x8D00
GL_COLOR_ATTACHMENT0 = 0x8CE0
GL_FRAMEBUFFER_COMPLETE = 0x8CD5
GL_TEXTURE_MIN_FILTER, GL_TEXTURE_MAG_FILTER, GL_NEAREST = 0x2801, 0x2800, 0x2600
GL_TEXTURE0 = 0x84C0
GL_DEPTH = 0x1801


@dataclass(frozen=True)
class Channel:
    name: str
    components: int
    dtype: str  # moderngl dtype; 'depth' = 32-bit float depth attachment
    unit: int  # texture unit compute passes read it from
    image: int  # image unit the resolve writes it at (-1: written by the raster only)
    meaning: str


CHANNELS = (
    Channel("depth", 1, "depth", 0, -1, "reversed-Z depth: near/view_distance (1 at near, 0 at infinity)"),
    Channel("position", 4, "f4", 1, 0, "xyz scene-local position (world - scene.origin), w linear view depth"),
    Channel("normal", 4, "f2", 2, 1, "xyz world-space shading normal facing the eye, w roughness"),
    Channel("albedo", 4, "f2", 3, 2, "rgb linear base colour, a metallic"),
    Channel("emission", 4, "f2", 4, 3, "rgb emitted radiance"),
    Channel("material", 2, "u4", 5, 4, "x material index, y effect ID (255 = background)"),
    Channel("triangle", 1, "u4", 6, 5, "triangle ID (0xFFFFFFFF = background)"),
    Channel("linear_depth", 1, "f4", 7, 6, "view depth of the pixel ray's hit, exact (0 = background); "
                                           "what frames return as depth, 4 bytes a pixel"),
)
COLOR_CHANNELS = tuple(c for c in CHANNELS if c.dtype != "depth")
NO_HIT = 0xFFFFFFFF
BASE_COLOR_TEXTURE_UNIT = 9  # after the G-buffer's units (glsl/common/triangle_surface.glsl)


class GBuffer:
    """The G-buffer textures for one size and layer count, plus the layered visibility framebuffer
    (triangle + depth attachments)."""

    def __init__(self, gl, size: tuple[int, int], layers: int):
        self.gl, self.size, self.layers = gl, tuple(size), layers
        self._multiview = False
        ctx = gl.ctx
        w, h = self.size
        self.textures = {}
        for ch in COLOR_CHANNELS:
            tex = ctx.texture_array((w, h, layers), ch.components, dtype=ch.dtype)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.textures[ch.name] = tex
        self.fbo = ctx.framebuffer([self.textures["triangle"]])
        # moderngl sets glDepthMask from the attachments it knows of on every use(): it does not
        # know the raw depth array attached below, so depth writes must be enabled explicitly.
        self.fbo.depth_mask = True
        # moderngl has no depth texture arrays: make one with raw GL and attach it layered.
        raw = gl.raw
        name = ctypes.c_uint()
        raw.glGenTextures(1, ctypes.byref(name))
        self.depth_name = name.value
        raw.glBindTexture(GL_TEXTURE_2D_ARRAY, self.depth_name)
        raw.glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_DEPTH_COMPONENT32F, w, h, layers)
        raw.glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST)
        raw.glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST)
        raw.glBindTexture(GL_TEXTURE_2D_ARRAY, 0)
        self.fbo.use()
        raw.glBindFramebuffer(GL_FRAMEBUFFER, self.fbo.glo)
        raw.glFramebufferTexture(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, self.depth_name, 0)
        status = raw.glCheckFramebufferStatus(GL_FRAMEBUFFER)
        if status != GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"layered G-buffer framebuffer incomplete (status 0x{status:x})")

    def attach_multiview(self) -> None:
        """Re-attach triangle and depth as GL_OVR_multiview views (view i = layer i); a
        multiview draw needs its attachments made this way rather than layered."""
        if self._multiview:
            return
        raw = self.gl.raw
        self.fbo.use()
        raw.glBindFramebuffer(GL_FRAMEBUFFER, self.fbo.glo)
        raw.glFramebufferTextureMultiviewOVR(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, self.textures["triangle"].glo,
                                             0, 0, self.layers)
        raw.glFramebufferTextureMultiviewOVR(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, self.depth_name, 0, 0, self.layers)
        status = raw.glCheckFramebufferStatus(GL_FRAMEBUFFER)
        if status != GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"multiview G-buffer framebuffer incomplete (status 0x{status:x})")
        self._multiview = True

    def clear(self) -> None:
        """Depth to 0 (reversed-Z: infinitely far) on every layer. The triangle channel needs no
        clear: the resolve treats depth 0 as background and rewrites it."""
        self.fbo.use()
        raw = self.gl.raw
        raw.glBindFramebuffer(GL_FRAMEBUFFER, self.fbo.glo)
        raw.glClearBufferfv(GL_DEPTH, 0, (ctypes.c_float * 1)(0.0))

    def bind_for_writing(self) -> None:
        """Bind the channels the resolve writes to their image units (and depth for reading)."""
        for ch in COLOR_CHANNELS:
            self.textures[ch.name].bind_to_image(ch.image, read=ch.name == "triangle", write=True)
        self._bind_depth()

    def _bind_depth(self) -> None:
        self.gl.raw.glActiveTexture(GL_TEXTURE0 + CHANNELS[0].unit)
        self.gl.raw.glBindTexture(GL_TEXTURE_2D_ARRAY, self.depth_name)

    def bind_for_reading(self) -> None:
        """Bind every channel to its texture unit (glsl/common/gbuffer.glsl)."""
        for ch in COLOR_CHANNELS:
            self.textures[ch.name].use(ch.unit)
        self._bind_depth()

    def release(self) -> None:
        self.fbo.release()
        for t in self.textures.values():
            t.release()
        name = ctypes.c_uint(self.depth_name)
        self.gl.raw.glDeleteTextures(1, ctypes.byref(name))
