"""Device probe: program binaries (SASS if an ELF is inside) and GRays/s of traversal variants.
usage: python3 .gpu/cw_probe.py OUT [variant_dir ...]   (a variant dir overrides files under rayvr/glsl)"""
import ctypes, functools, json, os, subprocess, sys, time
from pathlib import Path
import numpy as np
from rayvr.accel import gpu as G
from rayvr.accel.gpu import GpuBvh, RayTracer
from rayvr.accel.scene import build_scene_bvh
from rayvr.bench.rays import primary_rays, secondary_rays
from rayvr.bench.scenes import bench_scenes
from rayvr.gl import shaders
from rayvr.gl.context import create_context

out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
variants = [None] + [Path(v).resolve() for v in sys.argv[2:]]
scenes = os.environ.get("SCENES", "sponza").split(",")
kinds = os.environ.get("KINDS", "primary,glossy_0.3,diffuse,shadow").split(",")
layouts = os.environ.get("LAYOUTS", "bvh2,cwbvh").split(",")
size = tuple(int(x) for x in os.environ.get("SIZE", "1440x1600").split("x"))
gl = create_context()
ctx = gl.ctx if hasattr(gl, "ctx") else gl
egl = ctypes.CDLL("libEGL.so.1"); egl.eglGetProcAddress.restype = ctypes.c_void_p
def glfn(name, *args):
    return ctypes.CFUNCTYPE(None, *args)(egl.eglGetProcAddress(name.encode()))
getiv = glfn("glGetProgramiv", ctypes.c_uint, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))
getbin = glfn("glGetProgramBinary", ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_uint), ctypes.c_void_p)

def dump(prog, name):
    n = ctypes.c_int(0); getiv(prog.glo, 0x8741, ctypes.byref(n))
    buf = ctypes.create_string_buffer(max(n.value, 1)); ln = ctypes.c_int(0); fmt = ctypes.c_uint(0)
    getbin(prog.glo, n.value, ctypes.byref(ln), ctypes.byref(fmt), buf)
    data = buf.raw[:ln.value]
    (out / f"{name}.bin").write_bytes(data)
    notes = [f"{name}: {len(data)} bytes, format {fmt.value:#x}"]
    i = data.find(b"!!NV")
    if i >= 0:
        j = data.find(b"\0", i)
        (out / f"{name}.nvasm").write_bytes(data[i:j if j > 0 else None])
        notes.append(f"  NV assembly at {i}")
    k = data.find(b"\x7fELF")
    while k >= 0:
        elf = out / f"{name}_{k}.elf"; elf.write_bytes(data[k:])
        for cmd in (["cuobjdump", "-res-usage", str(elf)], ["nvdisasm", "-c", str(elf)], ["cuobjdump", "-sass", str(elf)]):
            try:
                r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
                txt = r.stdout + r.stderr
                (out / f"{name}_{k}.{cmd[0]}{cmd[1]}.txt").write_text(txt)
                notes.append(f"  {' '.join(cmd[:2])}: rc {r.returncode}, {len(txt)} chars: {txt[:300]!r}")
            except Exception as e:
                notes.append(f"  {cmd[0]}: {e}")
        k = data.find(b"\x7fELF", k + 4)
    print("\n".join(notes), flush=True)

orig_compute = shaders.compute
rows = []
for sname, scene, rig in bench_scenes(scenes, size, {}):
    bvh = build_scene_bvh(scene, "sah", progress=False)
    gpus = {l: GpuBvh(ctx, bvh, layout=l) for l in layouts}
    rt = RayTracer(ctx, gpus["bvh2"])
    o, d = primary_rays(rig, scene.origin, tiled=True)
    hits = rt.trace(o, d)
    rays = {"primary": (o, d, np.float32(3e38), "closest"), **secondary_rays(scene, bvh, o, d, hits)}
    refs = {}
    for vi, v in enumerate(variants):
        G.shaders.compute = functools.partial(orig_compute, root=v) if v else orig_compute
        vname = v.name if v else "base"
        for layout in (layouts if v is None else [l for l in layouts if l == 'cwbvh']):
            vrt = RayTracer(ctx, gpus[layout])
            if sname == scenes[0]:
                try:
                    dump(vrt.program("closest"), f"{vname}_{layout}_closest")
                except Exception as e:
                    print("dump failed", e)
            for kind in kinds:
                if kind not in rays: continue
                ro, rd, tmax, mode = rays[kind]
                try:
                    g = vrt.time_trace(ro, rd, tmax=tmax, mode=mode, repeats=10)
                    hit = vrt.trace(ro, rd, tmax=tmax, mode=mode)
                except Exception as e:
                    print(f"{sname} {vname} {layout} {kind}: FAILED {str(e)[:2000]}", flush=True); continue
                hit = hit if mode == "any" else hit.prim
                refs.setdefault(kind, hit)
                agree = float((hit == refs[kind]).mean())
                row = dict(scene=sname, variant=vname, layout=layout, kind=kind, rays=len(ro), gpu_ms=g["gpu_ms"],
                           grays=g["rays_per_s"] / 1e9, agree=agree)
                rows.append(row)
                print(f"{sname:7s} {vname:14s} {layout:6s} {kind:11s} {row['grays']:.3f} GRays/s {g['gpu_ms']:.3f} ms agree {agree:.5f}", flush=True)
    for g in gpus.values(): g.release()
(out / "probe.json").write_text(json.dumps(rows, indent=1))
