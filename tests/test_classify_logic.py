"""The `khr` aggregation of the classify pass (glsl/rt/classify.comp, CLASSIFY_BALLOT 1) on a driver
without GL_KHR_shader_subgroup (llvmpipe, so CI).

What this covers: classify.comp's own CLASSIFY_BALLOT 1 code, compiled as it is, with the five KHR
built-ins it calls (subgroupBallot, subgroupBallotExclusiveBitCount, subgroupBallotBitCount,
subgroupElect, subgroupBroadcastFirst) supplied by an emulation written here with shared memory
and barriers, for subgroups of 8 to 128 consecutive invocations: the per-slot ballot loop, each
lane's place from the exclusive bit count, the wave's run reserved by one shared atomic from its
elected lane and broadcast, the group's run from one global atomic, the ticket that writes the
dispatch sizes. The lists must hold exactly the pixels the effect channel says, each once.

What only a GPU with the extension covers: that the real built-ins behave as emulated (the
hardware's subgroup size and which invocations share a subgroup, which may not be consecutive or
full), and that the `#extension` lines compile there; test_raytrace.py's
test_classify_lists_every_traced_pixel_once_in_each_aggregation_mode runs the real `khr` mode
wherever the driver has it.
"""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.gl import shaders
from rayvr.frame.cameras.rig import StereoRig
from rayvr.frame.effects import EFFECTS, traced_effects
from rayvr.scene.materials import parse_config
from rayvr.frame.passes.classify import ClassifyPass
from rayvr.renderer import Renderer
from rayvr.scene.loader import load

EXTENSIONS = ("#extension GL_KHR_shader_subgroup_basic : require",
              "#extension GL_KHR_shader_subgroup_ballot : require")

# Subgroups of EMU_SUBGROUP_SIZE consecutive invocations (gl_LocalInvocationIndex order), every
# lane active at each call (classify calls them in uniform control flow). Barriers stand in for
# the lockstep of a real subgroup; each call ends with one so the next may reuse the scratch.
EMULATION = """
// ---- test emulation of the GL_KHR_shader_subgroup built-ins classify.comp uses (renamed, so
// that no driver sees a redefinition of a built-in)
#define subgroupBallot emu_subgroupBallot
#define subgroupBallotBitCount emu_subgroupBallotBitCount
#define subgroupBallotExclusiveBitCount emu_subgroupBallotExclusiveBitCount
#define subgroupElect emu_subgroupElect
#define subgroupBroadcastFirst emu_subgroupBroadcastFirst
#define EMU_WAVES (CLASSIFY_INVOCATIONS / EMU_SUBGROUP_SIZE)
shared uint emu_ballot[EMU_WAVES * 4];
shared uint emu_first[EMU_WAVES];
uint emu_lane() { return gl_LocalInvocationIndex % uint(EMU_SUBGROUP_SIZE); }
uint emu_wave() { return gl_LocalInvocationIndex / uint(EMU_SUBGROUP_SIZE); }

uvec4 subgroupBallot(bool value) {
    uint w = emu_wave(), lane = emu_lane();
    if (lane < 4u) emu_ballot[w * 4u + lane] = 0u;
    barrier();
    if (value) atomicOr(emu_ballot[w * 4u + (lane >> 5)], 1u << (lane & 31u));
    barrier();
    uvec4 b = uvec4(emu_ballot[w * 4u], emu_ballot[w * 4u + 1u], emu_ballot[w * 4u + 2u], emu_ballot[w * 4u + 3u]);
    barrier();
    return b;
}

uint subgroupBallotBitCount(uvec4 b) {
    return uint(bitCount(b.x) + bitCount(b.y) + bitCount(b.z) + bitCount(b.w));
}

uint subgroupBallotExclusiveBitCount(uvec4 b) {
    uint lane = emu_lane(), n = 0u;
    for (uint k = 0u; k < 4u; k++) {
        uint lo = 32u * k;
        uint below = lane >= lo + 32u ? 0xFFFFFFFFu : (lane <= lo ? 0u : (1u << (lane - lo)) - 1u);
        n += uint(bitCount(b[k] & below));
    }
    return n;
}

bool subgroupElect() { return emu_lane() == 0u; }  // every lane is active: the lowest is lane 0

uint subgroupBroadcastFirst(uint value) {
    if (emu_lane() == 0u) emu_first[emu_wave()] = value;
    barrier();
    uint v = emu_first[emu_wave()];
    barrier();
    return v;
}
// ---- end of the emulation

"""


def emulated_source() -> str:
    """classify.comp with the KHR #extension lines dropped and the emulation put before the
    code that calls the built-ins (refuses to go on if the file no longer looks as expected)."""
    text = (shaders.GLSL_DIR / "rt" / "classify.comp").read_text()
    for line in EXTENSIONS:
        assert text.count(line) == 1, f"classify.comp changed: {line!r} not found once"
        text = text.replace(line, "")
    anchor = "#if CLASSIFY_BALLOT != 0\n"
    assert text.count(anchor) == 2, "classify.comp changed: the emulation needs its two CLASSIFY_BALLOT != 0 blocks"
    at = text.index(anchor)
    assert "#if CLASSIFY_BALLOT == 1" in text[at:], "classify.comp changed: no CLASSIFY_BALLOT == 1 branch"
    return text[:at] + EMULATION + text[at:]


class EmulatedKhrClassify(ClassifyPass):
    def __init__(self, root, subgroup: int, group):
        super().__init__("khr", group)
        self.root, self.subgroup = root, subgroup

    def setup(self, gl, plan) -> None:
        gx, gy = self.group
        self.program = shaders.compute(gl.ctx, "rt/classify.comp", {
            "CLASSIFY_GROUP_X": gx, "CLASSIFY_GROUP_Y": gy, "CLASSIFY_INVOCATIONS": gx * gy,
            "CLASSIFY_BALLOT": 1, "EMU_SUBGROUP_SIZE": self.subgroup}, root=self.root)
        self.mode = f"khr, emulated subgroups of {self.subgroup}"


@pytest.fixture(scope="module")
def emulated_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("glsl")
    (root / "rt").mkdir()
    (root / "rt" / "classify.comp").write_text(emulated_source())
    return root


@pytest.mark.parametrize("subgroup, group", [(8, (8, 8)), (32, (8, 8)), (64, (8, 8)), (32, (32, 16)),
                                             (64, (32, 16)), (128, (32, 16))])
def test_khr_classify_lists_every_traced_pixel_once(gl, emulated_root, subgroup, group):
    scene = load()
    rig = StereoRig.for_scene(scene, size=(37, 29))  # not a multiple of any group size: partial groups
    cfg = parse_config({"default": "shadows", "materials": {"mirror*": "reflections", "floor": "glossy"}}, "t")
    r = Renderer(scene, cfg, gl=gl)
    try:
        plan = r.plan(2, "color")
        passes = r.compiled(plan).passes
        i = [p.name for p in passes].index("classify")
        passes[i].release()
        passes[i] = EmulatedKhrClassify(emulated_root, subgroup, group)
        passes[i].setup(gl, plan)
        traced = [e.name for e in traced_effects()]
        for frame_no in range(2):  # the second frame starts from the counters the first left
            frame = r.render(rig, aux=("effect",))
            effect = np.stack([frame.left.aux["effect"], frame.right.aux["effect"]])[:, ::-1]  # rows bottom-up
            args = np.frombuffer(r.resource("rt_list_args").read(), np.uint32)
            lists = np.frombuffer(r.resource("rt_lists").read(), np.uint32).reshape(len(traced), -1)
            assert not args[4 * len(traced):].any(), "running counts and ticket not left at zero"
            total = 0
            for s, name in enumerate(traced):
                z, y, x = np.nonzero(effect == EFFECTS[name].id)
                want = np.sort(x.astype(np.uint32) | (y.astype(np.uint32) << 14) | (z.astype(np.uint32) << 28))
                n = int(args[4 * s + 3])
                got = np.sort(lists[s, :n])
                assert n == len(want), f"{name}: {n} listed, {len(want)} pixels have the effect"
                assert np.array_equal(got, want), f"{name}: listed pixels differ (frame {frame_no})"
                groups = -(-n // 64)
                assert tuple(args[4 * s:4 * s + 3]) == ((groups, 1, 1) if n else (0, 1, 1))
                total += n
            used = {"shadows", "reflections", "glossy"}  # the config's traced effects: each list non-empty
            assert total > 500 and all(args[4 * s + 3] > 0 for s, name in enumerate(traced) if name in used)
    finally:
        r.release()


def test_the_emulation_is_what_ran(gl, emulated_root):
    """The program built is classify.comp's CLASSIFY_BALLOT 1 branch with the emulation in it: the
    driver has no GL_KHR_shader_subgroup here (else the real mode runs in test_raytrace.py) and the
    real file does not build in mode 1 without it."""
    if gl.has_extension("GL_KHR_shader_subgroup"):
        pytest.skip("this driver has GL_KHR_shader_subgroup: the real khr mode is tested in test_raytrace.py")
    d = {"CLASSIFY_GROUP_X": 8, "CLASSIFY_GROUP_Y": 8, "CLASSIFY_INVOCATIONS": 64, "CLASSIFY_BALLOT": 1}
    with pytest.raises(shaders.ShaderError):
        shaders.compute(gl.ctx, "rt/classify.comp", d)
    src = shaders.load_source("rt/classify.comp", {**d, "EMU_SUBGROUP_SIZE": 32}, root=emulated_root)
    assert "emulation of the GL_KHR_shader_subgroup" in src.text and "#extension GL_KHR" not in src.text
    shaders.compute(gl.ctx, "rt/classify.comp", {**d, "EMU_SUBGROUP_SIZE": 32}, root=emulated_root).release()
