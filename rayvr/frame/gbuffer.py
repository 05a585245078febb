"""The layered G-buffer: one texture array per channel, layer = eye (mono is 1 layer).

rayvr/gl/gpu_layout.py CHANNELS is the one declaration of what the G-buffer holds. It is made in two steps: a
visibility raster writes `depth` and `triangle` only (glsl/gbuffer/visibility.*), then a
compute resolve fills every other channel from the triangle and the pixel's ray
(glsl/gbuffer/resolve.comp, images bound at `image` below). Later passes read all channels
through glsl/common/gbuffer.glsl at texture unit `unit`.
"""
from __future__ import annotations

import ctypes

import moderngl

from ..gl.gpu_layout import CHANNELS, NO_HIT  # noqa: F401  (the channel table is declared there)

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


COLOR_CHANNELS = tuple(c for c in CHANNELS if c.dtype != "depth")


def layered_depth_target(gl, fbo, size, layers: int) -> int:
    """A GL_DEPTH_COMPONENT32F texture array (moderngl has none) attached layered to `fbo`; its name."""
    raw = gl.raw
    w, h = size
    name = ctypes.c_uint()
    raw.glGenTextures(1, ctypes.byref(name))
    raw.glBindTexture(GL_TEXTURE_2D_ARRAY, name.value)
    raw.glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_DEPTH_COMPONENT32F, w, h, layers)
    raw.glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST)
    raw.glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST)
    raw.glBindTexture(GL_TEXTURE_2D_ARRAY, 0)
    fbo.use()
    raw.glBindFramebuffer(GL_FRAMEBUFFER, fbo.glo)
    raw.glFramebufferTexture(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, name.value, 0)
    status = raw.glCheckFramebufferStatus(GL_FRAMEBUFFER)
    if status != GL_FRAMEBUFFER_COMPLETE:
        raise RuntimeError(f"layered framebuffer incomplete (status 0x{status:x})")
    return name.value


def delete_texture(gl, name: int) -> None:
    gl.raw.glDeleteTextures(1, ctypes.byref(ctypes.c_uint(name)))


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
        self.depth_name = layered_depth_target(gl, self.fbo, self.size, layers)

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

    def bind_for_writing(self, read_position: bool = False) -> None:
        """Bind the channels the resolve writes to their image units (and depth for reading);
        it also reads the triangle IDs, and the positions when primary rays left distances there."""
        for ch in COLOR_CHANNELS:
            reads = ch.name == "triangle" or (read_position and ch.name == "position")
            self.textures[ch.name].bind_to_image(ch.image, read=reads, write=True)
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
        self.gl.release_framebuffer(self.fbo)
        for t in self.textures.values():
            t.release()
        delete_texture(self.gl, self.depth_name)
