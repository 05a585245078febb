"""Local-memory arrays of the hot programs (rayvr/gl/program_memory.py).

The GPU checks read NVIDIA's NV assembly and skip elsewhere (llvmpipe's binaries hold none): a
traversal may keep its stack in local memory and nothing else, since an array the compiler could not
keep in registers made cwbvh 3.5-4.4x slower and photon tracing 2.2x slower on the H200."""
from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

from rayvr.accel.gpu import DEFAULT_TRAVERSAL, GpuBvh, RayTracer, layout_defines
from rayvr.accel.scene import build_scene_bvh
from rayvr.frame.cameras.rig import StereoRig
from rayvr.gl import shaders
from rayvr.gl.program_memory import PROGRAM_BINARY_LENGTH, local_arrays, nv_assembly
from rayvr.renderer import Renderer
from rayvr.scene import loader
from rayvr.scene.materials import load_config

ASSETS = Path(__file__).resolve().parents[1] / "rayvr" / "assets"


class FakeRaw:
    """glGetProgramiv / glGetProgramBinary answering with a given blob."""

    def __init__(self, blob: bytes):
        self.blob = blob

    def glGetProgramiv(self, program, pname, out):
        assert pname == PROGRAM_BINARY_LENGTH
        out._obj.value = len(self.blob)

    def glGetProgramBinary(self, program, size, written, fmt, data):
        ctypes.memmove(data, self.blob, len(self.blob))
        written._obj.value = len(self.blob)


class FakeProgram:
    glo = 7


def test_the_arrays_are_read_from_the_nv_assembly_inside_the_binary():
    text = b"!!NVcp5.0\nGROUP_SIZE 64;\nTEMP R0, R1;\nTEMP lmem0[64];\nTEMP lmem1[5];\nMOV.S lmem0[R0.x].x, R1;\nEND\n"
    blob = b"\x01\x02header" + text + b"\0trailing machine code lmem9[3]"
    assert nv_assembly(FakeRaw(blob), FakeProgram()) == text.decode()
    assert local_arrays(FakeRaw(blob), FakeProgram()) == {"lmem0": 64, "lmem1": 5}
    no_arrays = blob.replace(b"TEMP lmem0[64];\nTEMP lmem1[5];\n", b"")
    assert local_arrays(FakeRaw(no_arrays), FakeProgram()) == {}


def test_a_binary_without_nv_assembly_says_nothing():
    assert local_arrays(FakeRaw(b"\x7fELF some other driver's binary"), FakeProgram()) is None
    assert local_arrays(FakeRaw(b""), FakeProgram()) is None


def arrays_or_skip(gl, program) -> dict:
    found = local_arrays(gl.raw, program)
    if found is None:
        pytest.skip("the driver's program binary holds no NV assembly (not NVIDIA): local arrays unknown")
    return found


@pytest.fixture(scope="module")
def room_bvh():
    return build_scene_bvh(loader.load(None), "sah", progress=False)


@pytest.mark.parametrize("layout", ["bvh2", "bvh4", "bvh8", "cwbvh"])
@pytest.mark.parametrize("mode", ["closest", "any"])
def test_a_traversal_keeps_only_its_stack_in_local_memory(gl, room_bvh, layout, mode):
    gpu = GpuBvh(gl, room_bvh, layout=layout)
    try:
        found = arrays_or_skip(gl, RayTracer(gl, gpu).program(mode))
        stack = int(gpu.own_defines()["BVH_STACK_SIZE"])
    finally:
        gpu.release()
    # one array of at most the stack's ints (at 7e618a5 cwbvh's node joined it: lmem0[69])
    assert len(found) <= 1 and all(size <= stack for size in found.values()), \
        f"{layout} {mode}: local arrays {found}, only the traversal stack ({stack}) belongs there"


def test_photon_tracing_keeps_only_its_stack_in_local_memory(gl, monkeypatch):
    made = {}
    compute = shaders.compute

    def recording(ctx, name, defines=None, root=shaders.GLSL_DIR):
        made[name] = program = compute(ctx, name, defines, root)
        return program

    monkeypatch.setattr(shaders, "compute", recording)
    with Renderer(None, load_config(ASSETS / "photon_room.toml"), gl=gl) as r:
        r.record(StereoRig(size=(32, 24)), "both", "color")
        gl.ctx.finish()
        found = arrays_or_skip(gl, made["photon/trace.comp"])
    stack = int(layout_defines(layout=DEFAULT_TRAVERSAL[2])["BVH_STACK_SIZE"])  # photons trace as reflect rays
    assert len(found) <= 1 and all(size <= stack for size in found.values()), \
        f"photon/trace.comp: local arrays {found} (TriangleVerts filled in a loop went there once)"
