"""Text overlay for the preview window: a font atlas baked by Pillow, drawn as textured quads.

Pillow's bundled default font (FreeType, any size; the old bitmap font where Pillow has no
FreeType) is rasterized once into a one-channel texture holding printable ASCII. Each frame the
HUD collects quads (glyphs and solid panels) in window pixels, origin top-left, and draws them
in one call with alpha blending. No UI library: nothing to install beyond Pillow.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..gl import shaders

FIRST, LAST = 32, 126  # printable ASCII; anything else is drawn as '?'
COLUMNS = 16
FLOATS_PER_VERTEX = 8  # x, y, u, v, r, g, b, a
# The HUD's font has its full size (14 px, times the screen's content scale) in windows of this
# size and larger; a smaller window gets a smaller font, down to MIN_FONT_SIZE, so that the HUD
# covers about the same share of it (at 14 px it covered half of a 640x360 window).
FULL_SIZE_WINDOW = (1280, 720)
MIN_FONT_SIZE = 7
MARGIN = 8  # pixels between an overlay and the window's edge
PAD = 6  # pixels inside an overlay's panel
HELP_COLUMN_GAP = 16
MIN_TEXT_WIDTH = 200  # pixels a HUD line may always take, however narrow the window


def text_width_for(window) -> int:
    """Pixels a HUD line may take before it wraps: the left half of the window, so that side by
    side the right eye stays clear."""
    return max(MIN_TEXT_WIDTH, window[0] // 2 - MARGIN - 2 * PAD)


def font_size_for(window, base: int) -> int:
    """The HUD's font size in a window of `window` (width, height) pixels: `base` in a window of
    FULL_SIZE_WINDOW or larger, in proportion below it, never under MIN_FONT_SIZE."""
    share = min(1.0, window[0] / FULL_SIZE_WINDOW[0], window[1] / FULL_SIZE_WINDOW[1])
    return max(MIN_FONT_SIZE, min(base, round(base * share)))


@dataclass(frozen=True)
class HelpLayout:
    """Where the help overlay goes: its font size, its key table cut into `columns` of `rows`
    rows each, and its panel (x, y, w, h) in window pixels, top-left origin."""

    font_size: int
    columns: int
    rows: int
    key_width: int  # pixels of the key column within each column
    column_width: int
    box: tuple
    fits: bool  # False: the window is too small even at MIN_FONT_SIZE (the overlay is clipped)


def help_layout(window, keys, largest: int, measure) -> HelpLayout:
    """The largest font size from `largest` down to MIN_FONT_SIZE, and the fewest columns, at which
    the title and the (key, what it does) rows fit the window inside MARGIN; `measure(size)` gives
    (line height, width of a text) for a font size. Centred in the window. Where nothing fits, the
    smallest font in the columns that overflow the window least."""
    room = (window[0] - 2 * MARGIN, window[1] - 2 * MARGIN)
    rows_total = len(keys) + 1  # the title row
    overflow = []
    for size in range(max(largest, MIN_FONT_SIZE), MIN_FONT_SIZE - 1, -1):
        line_height, width = measure(size)
        key_w = max(width(k) for k, _ in keys) + HELP_COLUMN_GAP
        column_w = key_w + max(width(d) for _, d in keys)
        for columns in range(1, 4):
            rows = -(-rows_total // columns)
            w = columns * column_w + (columns - 1) * HELP_COLUMN_GAP + 2 * PAD
            h = rows * line_height + 2 * PAD
            box = (max(MARGIN, (window[0] - w) // 2), max(MARGIN, (window[1] - h) // 2), w, h)
            if w <= room[0] and h <= room[1]:
                return HelpLayout(size, columns, rows, key_w, column_w, box, True)
            if size == MIN_FONT_SIZE:
                overflow.append((max(w - room[0], h - room[1]), HelpLayout(size, columns, rows, key_w, column_w,
                                                                           box, False)))
    return min(overflow, key=lambda o: o[0])[1]


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
        self.base_size = font_size  # the size in a FULL_SIZE_WINDOW; set_window_size scales it
        self._atlases: dict = {}  # font size -> (FontAtlas, its texture), made when first used
        self.font_size = 0
        self.use_font_size(font_size)
        self.program = shaders.program(ctx, "preview/text.vert", "preview/text.frag")
        self.buffer = ctx.buffer(reserve=4096, dynamic=True)
        self.vao = self._vertex_array()
        self._quads: list[np.ndarray] = []

    def atlas(self, size: int) -> FontAtlas:
        if size not in self._atlases:
            font = FontAtlas(size)
            h, w = font.image.shape
            texture = self.ctx.texture((w, h), 1, font.image.tobytes())  # row 0 = image top
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._atlases[size] = (font, texture)
        return self._atlases[size][0]

    def use_font_size(self, size: int) -> None:
        """Draw from now on at this font size (what is collected already must be drawn first)."""
        if size != self.font_size:
            self.atlas(size)
            self.font, self.texture = self._atlases[size]
            self.font_size = size

    def set_window_size(self, window) -> None:
        """Scale the font to the window (font_size_for)."""
        self.use_font_size(font_size_for(window, self.base_size))

    def measure(self, size: int):
        """(line height, text width function) of a font size: for help_layout."""
        font = self.atlas(size)
        return font.line_height, font.width

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
        for obj in (self.vao, self.buffer, self.program, *(t for _, t in self._atlases.values())):
            obj.release()
        self._atlases.clear()
