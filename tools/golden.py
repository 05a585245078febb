"""Golden frames: render a fixed set of `rayvr capture` runs and record the SHA-256 of every file
they write (a PNG's decoded pixels), so that a refactor can show it renders bit-identically (issue 21).

    python tools/golden.py record golden.json      # on the commit before the change
    python tools/golden.py compare golden.json     # after it: exit 1 and the differing runs

The runs cover the effect ladder (each rung on every material, and the mixed configs rayvr ships),
every camera model, the three stereo modes and the settings that change a frame (primary
visibility, MSAA/SSAA, depth of field, second layer, BVH layout and build, tonemapping,
accumulation and denoising, aux channels, sequences and multi-view capture). They go through the
CLI on purpose: the flags, their parsing and the settings they become are part of what must not
change. Hashes are only comparable on one driver (llvmpipe of one Mesa version): the file records it.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

SIZE = "48x36"
EFFECTS = ("raster", "shadows", "ssr", "reflections", "glossy", "path", "photon")
ASSETS = Path(__file__).resolve().parents[1] / "rayvr" / "assets"


def runs() -> dict[str, list[str]]:
    """Name -> the arguments of one `rayvr capture` (the config file placeholders are filled in later)."""
    out = {f"effect={e}": ["--materials", f"@{e}"] for e in EFFECTS}
    out["config=default_room"] = []
    out["config=photon_room"] = ["--materials", str(ASSETS / "photon_room.toml")]
    for model in ("pinhole", "distorted", "wide", "foveated", "dof"):
        out[f"camera={model}"] = ["--camera-model", model]
    out["camera=distorted+params"] = ["--camera-model", "distorted", "--camera-param",
                                      "coefficients=0.3,0.05,0/0.31,0.05,0/0.32,0.06,0", "--camera-param", "center=0.02,0"]
    out["camera=wide+params"] = ["--camera-model", "wide", "--camera-param", "mapping=equidistant",
                                 "--camera-param", "fov_x=150"]
    out["camera=foveated+params"] = ["--camera-model", "foveated", "--camera-param", "gaze=0.3,0.6",
                                     "--camera-param", "fovea_radius=8"]
    out["camera=dof+params"] = ["--camera-model", "dof", "--camera-param", "aperture=0.05",
                                "--camera-param", "focus=1.5"]
    for mode in ("dual", "warp", "reuse"):
        out[f"stereo={mode}"] = ["--stereo", mode]
    out["stereo=warp,layers=1"] = ["--stereo", "warp", "--warp-layers", "1"]
    out["primary=rays"] = ["--primary", "rays"]
    out["msaa=4"] = ["--msaa", "4"]
    out["msaa=4,ssaa"] = ["--msaa", "4", "--ssaa"]
    out["msaa=8,tile-culling"] = ["--msaa", "8", "--tile-culling"]
    out["msaa=8,no-tile-culling"] = ["--msaa", "8", "--no-tile-culling"]
    out["aperture"] = ["--aperture", "0.2", "--focus-distance", "2.5", "--dof-samples", "4"]
    out["second-layer=peel"] = ["--materials", "@ssr", "--second-layer", "peel"]
    out["quadtree-adapt"] = ["--materials", "@ssr", "--quadtree-adapt", "0.5"]
    out["traversal=bvh2"] = ["--traversal", "bvh2"]
    out["traversal=mixed"] = ["--traversal", "primary=bvh8,shadow=bvh4,reflect=bvh2", "--primary", "rays"]
    out["bvh-build=sbvh"] = ["--bvh-build", "sbvh"]
    out["tonemap"] = ["--tonemapper", "reinhard", "--exposure", "2.5"]
    out["seed"] = ["--seed", "7"]
    out["layer-mode=passes"] = ["--layer-mode", "passes"]
    out["spp=3,denoise"] = ["--spp", "3", "--denoise", "--denoise-iterations", "2"]
    out["eye=left,view=normal"] = ["--eye", "left", "--view", "normal"]
    out["aux"] = ["--aux", "depth,zbuffer,position,normal,albedo,material,effect,triangle,hdr"]
    out["frames=2"] = ["--frames", "2"]
    out["views=sphere:2"] = ["--views", "sphere:2"]
    out["pose"] = ["--pose", "0.3,1.4,2.2,0,1,0", "--fov", "75", "--ipd", "0.07", "--near", "0.05"]
    return out


def effect_config(folder: Path, effect: str) -> Path:
    path = folder / f"all_{effect}.toml"
    path.write_text(f'default = "{effect}"\n')
    return path


def capture(name: str, args: list[str], work: Path) -> dict:
    out = work / name.replace("/", "_")
    args = [str(effect_config(work, a[1:])) if a.startswith("@") else a for a in args]
    cmd = [sys.executable, "-m", "rayvr", "capture", "-q", "--size", SIZE, "--out", str(out), *args]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode:
        return {"error": (run.stderr.strip().splitlines() or ["exit %d" % run.returncode])[-1]}
    return {p.relative_to(out).as_posix(): content_hash(p) for p in sorted(out.rglob("*"))
            if p.is_file() and p.name != "frame_timings.json" and not p.name.endswith("_record.json")}


def content_hash(path: Path) -> str:
    """A PNG's decoded pixels (so that the encoder may change), any other file's bytes. Frame
    records hold their files' checksums, so they are left out: their PNGs are compared instead."""
    if path.suffix != ".png":
        return hashlib.sha256(path.read_bytes()).hexdigest()
    from PIL import Image

    with Image.open(path) as im:
        pixels = np.asarray(im)
    return hashlib.sha256(repr((im.mode, pixels.shape)).encode() + pixels.tobytes()).hexdigest()


def record(jobs: int) -> dict:
    from rayvr.gl.context import create_context

    gl = create_context()
    renderer = gl.ctx.info.get("GL_RENDERER")
    gl.release()
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(jobs) as pool:
        work = Path(tmp)
        named = runs()
        hashes = dict(zip(named, pool.map(lambda kv: capture(*kv, work), named.items())))
    return {"renderer": renderer, "size": SIZE, "runs": hashes}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("action", choices=("record", "compare"))
    p.add_argument("file", type=Path)
    p.add_argument("-j", "--jobs", type=int, default=2, help="captures run at once")
    a = p.parse_args(argv)
    now = record(a.jobs)
    failed = [n for n, r in now["runs"].items() if "error" in r]
    for n in failed:
        print(f"{n}: {now['runs'][n]['error']}", file=sys.stderr)
    if a.action == "record":
        a.file.write_text(json.dumps(now, indent=1) + "\n")
        print(f"{len(now['runs'])} runs recorded in {a.file} ({now['renderer']})")
        return 1 if failed else 0
    before = json.loads(a.file.read_text())
    if before["renderer"] != now["renderer"] or before["size"] != now["size"]:
        print(f"{a.file} was recorded on {before['renderer']} at {before['size']}: not comparable", file=sys.stderr)
        return 2
    differ = [n for n in before["runs"] if now["runs"].get(n) != before["runs"][n]]
    for n in differ:
        was, got = before["runs"][n], now["runs"].get(n, {})
        files = sorted(k for k in set(was) | set(got) if was.get(k) != got.get(k))
        print(f"differs: {n}: {', '.join(files)}")
    print(f"{len(before['runs']) - len(differ)} of {len(before['runs'])} runs bit-identical")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
