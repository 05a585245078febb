"""Builds docs/room.png, the README's picture: the built-in room's stereo pair as a first run
renders it (rayvr/assets/default_room.toml, the first view, one sample a pixel, denoised: a
capture's defaults), above a ladder strip of the left eye's view rendered with each effect on
every material (the light stays `raster`), cheapest first.

    python tools/make_room_figure.py [--size 448x504] [--spp 16]

Every image is the Python API's (rayvr.Renderer); the ladder's sampled rungs are the mean of --spp
samples, not denoised.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from rayvr import Renderer, RenderSettings
from rayvr.app.viewpoint import first_rig
from rayvr.commands.args import CAPTURE_DEFAULTS
from rayvr.frame.effects import EFFECTS
from rayvr.scene import loader
from rayvr.scene.defaults import ROOM_CONFIG
from rayvr.scene.materials import load_config, parse_config

OUT = Path(__file__).resolve().parents[1] / "docs" / "room.png"
LADDER = ("raster", "shadows", "ssr", "reflections", "glossy", "path", "photon")
LABEL_HEIGHT = 18


def labelled(image: np.ndarray, text: str) -> Image.Image:
    out = Image.new("RGB", (image.shape[1], image.shape[0] + LABEL_HEIGHT), (24, 24, 24))
    out.paste(Image.fromarray(image), (0, LABEL_HEIGHT))
    ImageDraw.Draw(out).text((4, 3), text, fill=(235, 235, 235))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="448x504", help="per-eye size of the stereo pair (WIDTHxHEIGHT)")
    p.add_argument("--spp", type=int, default=16, help="samples a pixel of the ladder's images")
    p.add_argument("--out", type=Path, default=OUT)
    args = p.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    missing = [e for e in LADDER if e not in EFFECTS]
    if missing:
        raise SystemExit(f"this rayvr lacks the effects {', '.join(missing)}")
    room = loader.load(None)
    with Renderer(room, load_config(ROOM_CONFIG), settings=RenderSettings(**CAPTURE_DEFAULTS)) as r:
        pair = r.render(first_rig(room, (w, h)))  # what `rayvr capture --size WxH` writes
        top = [labelled(pair.left.color, "left eye: default_room.toml, 1 sample, denoised"),
               labelled(pair.right.color, "right eye")]
        r.settings = RenderSettings()
        side = 2 * w // len(LADDER)  # the strip is as wide as the pair
        small = first_rig(room, (side, round(side * h / w)))
        strip = []
        for effect in LADDER:
            r.set_materials(parse_config({"default": effect, "materials": {"light": "raster"}}, f"<all {effect}>"))
            strip.append(labelled(r.render(small, eyes="left", spp=args.spp).left.color, effect))
    width = max(sum(i.width for i in top), sum(i.width for i in strip))
    sheet = Image.new("RGB", (width, top[0].height + strip[0].height), (24, 24, 24))
    x = 0
    for image in top:
        sheet.paste(image, (x, 0))
        x += image.width
    x = 0
    for image in strip:
        sheet.paste(image, (x, top[0].height))
        x += image.width
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, optimize=True)
    print(f"wrote {args.out} ({sheet.width}x{sheet.height})")


if __name__ == "__main__":
    main()
