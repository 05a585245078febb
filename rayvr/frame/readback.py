"""Reading frames back to numpy: each channel once for both eyes, through pixel buffer objects.

`start()` queues the copies GPU-side (glGetTexImage into a PBO returns at once) and `finish()`
maps them; `Renderer.render_sequence` records frame N+1 before finishing frame N, so transfers
overlap rendering. Only what is asked for travels: colour (packed to RGB by GL) and depth (the
G-buffer's exact linear view depth, 4 bytes a pixel) by default, other channels on request; a
capture that writes no depth leaves it out (`depth=False`), which more than halves the bytes.

`finish()` first waits on a fence behind the copies, through ctypes, which lets go of the GIL
while the GPU works: mapping a buffer the GPU still writes blocks inside moderngl with the GIL
held, and the capture's writer threads (app/writers.py) would stop with it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .graph import EyeImage
from .gbuffer import COLOR_CHANNELS, GL_DEPTH_COMPONENT, GL_FLOAT, GL_TEXTURE_2D_ARRAY
from .passes import radiance
from .stereo import WARP_DEPTH

GL_PIXEL_PACK_BUFFER = 0x88EB
GL_PACK_ALIGNMENT = 0x0D05
GL_RGB, GL_UNSIGNED_BYTE = 0x1907, 0x1401
AUX_CHANNELS = ("depth", "zbuffer", "position", "normal", "albedo", "material", "effect", "triangle", "hdr")
INTEGER_AUX = ("material", "effect", "triangle")  # uint32 IDs; every other aux channel is float
# aux name -> G-buffer channel it comes from
_SOURCE = {"zbuffer": "zbuffer", "position": "position", "normal": "normal", "albedo": "albedo",
           "material": "material", "effect": "material", "triangle": "triangle", "hdr": "hdr"}
_DTYPES = {"f1": np.uint8, "f2": np.float16, "f4": np.float32, "u4": np.uint32}


@dataclass
class Pending:
    """A frame whose readbacks are in flight."""

    fc: object
    buffers: dict  # channel -> (moderngl.Buffer, dtype, components, layers)
    aux: tuple
    copied: object = None  # a gl.context.Fence behind the copies into the buffers


class Reader:
    """Owns the pixel buffers (two sets, for one frame in flight while the next is recorded)."""

    def __init__(self, gl):
        self.gl = gl
        self._pool: dict = {}
        self.finish_s = 0.0  # time spent mapping and cutting frames, for the capture's progress bar

    def _buffer(self, key, nbytes):
        buf = self._pool.get(key)
        if buf is None or buf.size != nbytes:
            if buf is not None:
                buf.release()
            buf = self._pool[key] = self.gl.ctx.buffer(reserve=nbytes)
        return buf

    def channels_for(self, fc, aux, depth: bool = True) -> list[str]:
        """Colour; the linear depth when asked for or when an aux channel needs it (its hit mask)."""
        need = ["ldr"] + (["linear_depth"] if depth or aux else []) + [_SOURCE[a] for a in aux if a in _SOURCE]
        return list(dict.fromkeys(need))

    def start(self, fc, aux, parity: int, depth: bool = True) -> Pending:
        gb, raw = fc.gbuffer, self.gl.raw
        w, h = gb.size
        warped = fc.plan.stereo == "warp"  # the eyes come from the warp pass, the G-buffer is the central view
        buffers = {}
        for name in self.channels_for(fc, aux, depth):
            layers = len(fc.out_eyes) if warped and name in ("ldr", "linear_depth") else gb.layers
            if name in ("zbuffer", "ldr"):
                # Read by GL itself: the depth array moderngl does not know, and colour packed to
                # RGB by the driver (no alpha to strip on the CPU afterwards).
                depth = name == "zbuffer"
                dtype, comps = (np.float32, 1) if depth else (np.uint8, 3)
                buf = self._buffer((parity, name), w * h * layers * comps * np.dtype(dtype).itemsize)
                texture = gb.depth_name if depth else fc.resource(fc.plan.output).glo
                raw.glBindBuffer(GL_PIXEL_PACK_BUFFER, buf.glo)
                raw.glPixelStorei(GL_PACK_ALIGNMENT, 1)
                raw.glBindTexture(GL_TEXTURE_2D_ARRAY, texture)
                raw.glGetTexImage(GL_TEXTURE_2D_ARRAY, 0, GL_DEPTH_COMPONENT if depth else GL_RGB,
                                  GL_FLOAT if depth else GL_UNSIGNED_BYTE, None)
                raw.glBindTexture(GL_TEXTURE_2D_ARRAY, 0)
                raw.glBindBuffer(GL_PIXEL_PACK_BUFFER, 0)
                buffers[name] = (buf, dtype, comps, layers)
                continue
            if name == "hdr":  # the linear colour before exposure and tonemapping
                name_, fmt = radiance(fc.plan)  # accumulated / denoised where the frame has them
                tex, dtype, comps = fc.resource(name_), np.float32 if fmt == "rgba32f" else np.float16, 4
            elif warped and name == "linear_depth":
                tex, dtype, comps = fc.resource(WARP_DEPTH), np.float32, 1
            else:
                ch = next(c for c in COLOR_CHANNELS if c.name == name)
                tex, dtype, comps = gb.textures[name], _DTYPES[ch.dtype], ch.components
            nbytes = w * h * layers * comps * np.dtype(dtype).itemsize
            buf = self._buffer((parity, name), nbytes)
            tex.read_into(buf, alignment=1)
            buffers[name] = (buf, dtype, comps, layers)
        return Pending(fc, buffers, tuple(aux), self.gl.fence())

    def finish(self, pending: Pending):
        """Map the buffers and cut them into per-eye numpy images (rows top-down)."""
        start = time.perf_counter()
        try:
            if pending.copied is not None:
                pending.copied.wait()  # without the GIL: see the module's note
                pending.copied = None
            return self._finish(pending)
        finally:
            self.finish_s += time.perf_counter() - start

    def _finish(self, pending: Pending):
        fc = pending.fc
        w, h = fc.gbuffer.size
        data = {}
        for name, (buf, dtype, comps, layers) in pending.buffers.items():
            raw = np.empty(buf.size, np.uint8)  # one copy out of the mapped buffer, writable
            buf.read_into(raw)
            # Rows top-down as a view (GL rows go bottom-up): no copy per channel.
            a = raw.view(dtype).reshape(layers, h, w, comps)[:, ::-1]
            data[name] = a.astype(np.float32) if dtype == np.float16 else a
        out = {}
        for layer, eye in enumerate(fc.out_eyes):
            color = data["ldr"][layer]
            depth = data["linear_depth"][layer, ..., 0] if "linear_depth" in data else None
            hit = depth > 0 if depth is not None else None
            extra = {name: self._aux(name, data, layer, hit, depth, fc.scene.origin) for name in pending.aux}
            out[eye.name] = EyeImage(eye.name, color, depth, extra)
        return out

    @staticmethod
    def _aux(name, data, layer, hit, depth, origin):
        if name == "depth":
            return depth
        if name == "zbuffer":
            return np.ascontiguousarray(data["zbuffer"][layer, ..., 0])
        if name == "triangle":
            return np.ascontiguousarray(data["triangle"][layer, ..., 0])
        if name == "position":  # world space, float64, NaN-free: background is 0
            world = data["position"][layer, ..., :3].astype(np.float64) + origin
            return np.where(hit[..., None], world, 0.0)
        if name in ("material", "effect"):
            return np.ascontiguousarray(data["material"][layer, ..., 0 if name == "material" else 1])
        return np.ascontiguousarray(data[name][layer, ..., :3])

    def release(self) -> None:
        for buf in self._pool.values():
            buf.release()
        self._pool.clear()
