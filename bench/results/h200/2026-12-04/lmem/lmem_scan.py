"""Which compute programs of a frame keep arrays in local memory on NVIDIA (NV assembly `TEMP lmemN[k]`).
usage: python3 .gpu/lmem_scan.py OUT"""
import ctypes, json, re, sys
from pathlib import Path
from rayvr.gl import shaders
from rayvr.gl.context import create_context
from rayvr.renderer import Renderer, RenderSettings
from rayvr.scene.materials import parse_config, load_config
from rayvr.bench.scenes import bench_scenes
from rayvr.bench.rays import hybrid_config, INCOHERENT_FRAMES

out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
made = []
orig = shaders.compute
def compute(ctx, name, defines=None, root=shaders.GLSL_DIR):
    p = orig(ctx, name, defines, root)
    made.append((name, dict(defines or {}), p))
    return p
shaders.compute = compute
egl = ctypes.CDLL("libEGL.so.1"); egl.eglGetProcAddress.restype = ctypes.c_void_p
def glfn(name, *args):
    return ctypes.CFUNCTYPE(None, *args)(egl.eglGetProcAddress(name.encode()))
getiv = glfn("glGetProgramiv", ctypes.c_uint, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))
getbin = glfn("glGetProgramBinary", ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_uint), ctypes.c_void_p)
def nvasm(prog):
    n = ctypes.c_int(0); getiv(prog.glo, 0x8741, ctypes.byref(n))
    buf = ctypes.create_string_buffer(max(n.value, 1)); ln = ctypes.c_int(0); fmt = ctypes.c_uint(0)
    getbin(prog.glo, n.value, ctypes.byref(ln), ctypes.byref(fmt), buf)
    data = buf.raw[:ln.value]; i = data.find(b"!!NV")
    return data[i:data.find(b"\0", i)].decode("latin1") if i >= 0 else ""

seen, rows = set(), []
def scan(case):
  for name, defines, p in list(made):
    text = nvasm(p)
    key = (name, len(text))
    if key in seen: continue
    seen.add(key)
    arrays = re.findall(r"TEMP (lmem\d+\[\d+\])", text)
    uses = len(re.findall(r"lmem\d+\[", text)) - len(arrays)
    rows.append(dict(case=case, shader=name, lines=text.count("\n"), arrays=arrays, lmem_ops=uses,
                     defines={k: v for k, v in defines.items() if "BINDING" not in k}))
    (out / (name.replace("/", "_") + f"_{len(rows)}.nvasm")).write_text(text)

gl = create_context()
room = lambda f: load_config(Path("rayvr/assets") / f)
cases = []
for name, scene, rig in bench_scenes(["default", "sponza"], (320, 288), {}):
    cfgs = {"hybrid": hybrid_config(name),
            **{k: parse_config({"default": "raster", "materials": {"*": v}}, k) for k, v in INCOHERENT_FRAMES.items()}}
    if name == "default":
        cfgs.update(default_room=room("default_room.toml"), path_room=room("path_room.toml"), photon_room=room("photon_room.toml"))
    for cname, cfg in cfgs.items():
        for sname, st in {"plain": {}, "denoise": {"denoise": True}, "rays4x": {"primary": "rays", "msaa": 4},
                          "cw": {"traversal": ("cwbvh",) * 3}}.items():
            if sname != "plain" and cname not in ("default_room", "path", "hybrid"): continue
            try:
                made.clear()
                r = Renderer(scene, cfg, gl=gl, settings=RenderSettings(**st))
                r.record(rig, "both", "color"); gl.ctx.finish()
                scan(f"{name}/{cname}/{sname}"); r.release()
            except Exception as e:
                print(f"{name} {cname} {sname}: {str(e)[:300]}", flush=True)
rows.sort(key=lambda r: -r["lmem_ops"])
for r in rows:
    print(f"{r['case']:28s} {r['shader']:32s} {r['lines']:6d} lines  lmem {r['arrays']} ops {r['lmem_ops']}")
(out / "lmem.json").write_text(json.dumps(rows, indent=1, default=str))
