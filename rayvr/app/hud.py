"""Text overlay for the preview window: a font atlas baked by Pillow, drawn as textured quads.

Pillow's bundled default font (FreeType, any size; the old bitmap font where Pillow has no
FreeType) is rasterized once into a one-channel texture holding printable ASCII. Each frame the
HUD collects quads (glyphs and solid panels) in window pixels, origin top-left, and draws them
in one call with alpha blending. No UI library: nothing to install beyond Pillow.
"""
from __future__ import annotations

import math

import moderngl
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..gl import shaders

FIRST, LAST = 32, 126  # printable ASCII; anything else is drawn as '?'
COLUMNS = 16
FLOATS_PER_VERTEX = 8  # x, y, u, v, r, g, b, a


def _load_font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, ValueError, OSError, ImportError):  # Pillow without FreeType
        return ImageFont.load_default()


class FontAtlas:
    """Glyph images in a grid; per glyph: texture rectangle and advance width in pixels."""

    def __init__(self, size: int = 14):
        font = _load_font(size)
        try:
            ascent, descent = font.getmetrics()
        except AttributeError:  # bitmap font
            ascent, descent = font.getbbox("Hg")[3], 2
        self.line_height = ascent + descent + 2
        self.advance = {}
        for code in range(FIRST, LAST + 1):
            self.advance[chr(code)] = max(1, int(math.ceil(font.getlength(chr(code)))))
        self.pad = 2  # room for glyphs that overhang their advance (italics, 'j')
        self.cell_w = max(self.advance.values()) + 2 * self.pad
        self.cell_h = self.line_height
        rows = (LAST - FIRST + 1 + COLUMNS - 1) // COLUMNS + 1  # last row: the solid block
        image = Image.new("L", (COLUMNS * self.cell_w, rows * self.cell_h), 0)
        draw = ImageDraw.Draw(image)
        self.cells = {}
        for i, code in enumerate(range(FIRST, LAST + 1)):
            x, y = (i % COLUMNS) * self.cell_w, (i // COLUMNS) * self.cell_h
            draw.text((x + self.pad, y + 1), chr(code), font=font, fill=255)
            self.cells[chr(code)] = (x, y)
        # A solid block for panels, sampled at its centre so filtering never reaches glyphs.
        self.solid = (2, (rows - 1) * self.cell_h + 2)
        draw.rectangle([0, (rows - 1) * self.cell_h, 5, (rows - 1) * self.cell_h + 5], fill=255)
        self.image = np.asarray(image, dtype=np.uint8)

    def width(self, text: str) -> int:
        return sum(self.advance.get(c, self.advance["?"]) for c in text)


class Hud:
    """Collects text and rectangles during a frame; `draw` puts them on the current framebuffer."""

    def __init__(self, ctx: moderngl.Context, font_size: int = 14):
        self.ctx = ctx
        self.font = FontAtlas(font_size)
        h, w = self.font.image.shape
        self.texture = ctx.texture((w, h), 1, self.font.image.tobytes())  # row 0 = image top
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.program = shaders.program(ctx, "preview/text.vert", "preview/text.frag")
        self.buffer = ctx.buffer(reserve=4096, dynamic=True)
        self.vao = self._vertex_array()
        self._quads: list[np.ndarray] = []

    def _vertex_array(self):
        return self.ctx.vertex_array(self.program, [(self.buffer, "2f 2f 4f", "in_pos", "in_uv", "in_color")])

    @property
    def line_height(self) -> int:
        return self.font.line_height

    def width(self, text: str) -> int:
        return self.font.width(text)

    def _quad(self, x, y, w, h, u0, v0, u1, v1, color) -> None:
        r, g, b, a = color
        x0, y0, x1, y1 = x, y, x + w, y + h
        self._quads.append(np.array([
            [x0, y0, u0, v0, r, g, b, a], [x1, y0, u1, v0, r, g, b, a], [x1, y1, u1, v1, r, g, b, a],
            [x0, y0, u0, v0, r, g, b, a], [x1, y1, u1, v1, r, g, b, a], [x0, y1, u0, v1, r, g, b, a],
        ], np.float32))

    def rect(self, x, y, w, h, color=(0.0, 0.0, 0.0, 0.6)) -> None:
        tw, th = self.texture.size
        u, v = (self.font.solid[0] + 0.5) / tw, (self.font.solid[1] + 0.5) / th
        self._quad(x, y, w, h, u, v, u, v, color)

    def text(self, x, y, text: str, color=(1.0, 1.0, 1.0, 1.0)) -> int:
        """Draw `text` with its top-left corner at (x, y) pixels; returns its width."""
        f = self.font
        tw, th = self.texture.size
        pen = int(round(x))
        top = int(round(y))
        for ch in text:
            if ch not in f.cells:
                ch = "?"
            cx, cy = f.cells[ch]
            if ch != " ":
                self._quad(pen - f.pad, top, f.cell_w, f.cell_h,
                           cx / tw, cy / th, (cx + f.cell_w) / tw, (cy + f.cell_h) / th, color)
            pen += f.advance[ch]
        return pen - int(round(x))

    def panel(self, x, y, lines, pad: int = 6, background=(0.0, 0.0, 0.0, 0.6), min_width: int = 0):
        """A block of lines [(text, rgba) or text] on a dark panel; returns (width, height)."""
        lines = [(ln, (1.0, 1.0, 1.0, 1.0)) if isinstance(ln, str) else ln for ln in lines]
        w = max([self.width(t) for t, _ in lines] + [min_width]) + 2 * pad
        h = len(lines) * self.line_height + 2 * pad
        self.rect(x, y, w, h, background)
        for i, (t, color) in enumerate(lines):
            self.text(x + pad, y + pad + i * self.line_height, t, color)
        return w, h

    def draw(self, viewport_size) -> None:
        """Draw what was collected since the last draw onto the bound framebuffer."""
        if not self._quads:
            return
        data = np.concatenate(self._quads).tobytes()
        self._quads = []
        if len(data) > self.buffer.size:
            self.buffer.orphan(max(len(data), 2 * self.buffer.size))  # same GL name: the VAO stays valid
        self.buffer.write(data)
        self.program["viewport"].value = tuple(float(v) for v in viewport_size)
        self.texture.use(0)
        self.program["atlas"].value = 0
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.vao.render(moderngl.TRIANGLES, vertices=len(data) // (4 * FLOATS_PER_VERTEX))
        ctx.disable(moderngl.BLEND)  # leave the state as the renderer's passes expect it

    def release(self) -> None:
        for obj in (self.vao, self.buffer, self.texture, self.program):
            obj.release()
