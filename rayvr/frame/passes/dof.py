"""`dof`: thin-lens depth of field through screen-space rays (Widmer et al. 2015 §5.2;
glsl/post/dof.comp): each pixel's lens rays (RenderSettings dof_diameter, dof_focus,
dof_samples) from points of the lens disk through the pixel ray's point in focus, traced through
the frame's quadtree, gathering the frame's final colour where they meet the screen (the hit
pixel; behind a foreground object, the near side of the discontinuity: inpainting). Writes
`hdr_dof`, which tonemap then shows (frame/passes/__init__.py radiance). Pinhole camera, stereo `dual`.
gather_reference below is the numpy reference of the shader (tests/test_dof.py compares them)."""
from __future__ import annotations

import numpy as np

from ...gl import shaders
from ..cameras.sampling import concentric_disk
from ..graph import FramePlan, Pass, Texture, read, write
from ...gl.gpu_layout import IMAGE, SSBO
from ..pcg import pcg_hash
from . import scene_radiance
from .compute import camera_defines, dispatch_per_pixel, set_eye_uniforms
from .quadtree import set_tree_uniforms
from ...options import PlanRefusal, plan_part


THICKNESS = 0.02  # relative depth of each surface's slab: a lens ray deeper than that passed behind it
HDR_DOF = Texture("rgba32f")


@plan_part("dof", after=("stereo",))
def dof_plan(ask, plan) -> None:
    """Depth of field blurs each eye's own pinhole frame: a warped or reused eye has none, and the
    other models' rays are not that frame's (the dof camera model has a lens of its own)."""
    plan["dof"] = ask.color and ask.settings.dof_diameter > 0
    if not plan["dof"] or (plan["stereo"] == "dual" and ask.camera.rasterizable):
        return
    reason = "depth of field blurs each eye's own pinhole frame, and "
    if plan["stereo"] != "dual":
        raise PlanRefusal(reason + f"stereo mode {plan['stereo']!r} makes an eye from the other's frame", "use",
                          ("stereo", "dual"))
    hint = (f": use its {ask.camera.lens_parameter} parameter" if ask.camera.lens_parameter
            else ": use the pinhole camera")
    raise PlanRefusal(reason + f"the {ask.camera.name} camera is not a pinhole{hint}", "or leave out",
                      ("dof_diameter", ask.settings.dof_diameter))


class DofPass(Pass):
    name = "dof"

    def why(self, plan: FramePlan) -> str | None:
        return "depth of field (thin lens, screen-space rays)" if plan.dof else None

    def io(self, plan: FramePlan) -> list:
        return [read(scene_radiance(plan)[0]), read("gbuffer"), read("quadtree"), write("hdr_dof", HDR_DOF)]

    def setup(self, gl, plan: FramePlan) -> None:
        self.source, fmt = scene_radiance(plan)
        self.program = shaders.compute(gl.ctx, "post/dof.comp", {"HDR_FORMAT": fmt, **camera_defines(plan)})

    def execute(self, fc) -> None:
        st, p = fc.settings, self.program
        set_eye_uniforms(p, fc)
        set_tree_uniforms(p, fc.gbuffer.size, fc.gbuffer.layers)
        for name, v in (("dof_diameter", float(st.dof_diameter)), ("dof_focus", float(st.dof_focus)),
                        ("dof_samples", int(st.dof_samples)), ("dof_thickness", THICKNESS),
                        ("frame_seed", int(st.seed))):
            if shaders.declares(p, name):
                p[name].value = v
        fc.gbuffer.bind_for_reading()
        fc.resource("quadtree").bind_to_storage_buffer(SSBO["quadtree_nodes"])
        fc.resource(self.source).bind_to_image(IMAGE["dof_in"], read=True, write=False)
        fc.resource("hdr_dof").bind_to_image(IMAGE["dof_out"], read=False, write=True)
        dispatch_per_pixel(fc, p)

    def release(self) -> None:
        self.program.release()


# ------------------------------------------------------------------ numpy reference (tests)

def _seed_surface(p, footprint, frame):
    """common/random.glsl rng_seed_surface (float32 as on the GPU)."""
    level = np.floor(np.log2(np.maximum(np.float32(footprint), np.float32(1e-30)))).astype(np.int64)
    cell = np.clip(np.floor(np.asarray(p, np.float32) * np.float32(2.0 ** -float(level))), -2.0e9, 2.0e9).astype(np.int64)
    h = pcg_hash(int(level) & 0xFFFFFFFF ^ int(pcg_hash(frame)))
    for c in (cell[2], cell[1], cell[0]):
        h = pcg_hash((int(c) & 0xFFFFFFFF) ^ int(h))
    return int(h)


def gather_reference(image, position, levels, cam, aperture: float, focus: float, samples: int, seed: int = 0,
                     thickness: float = THICKNESS) -> np.ndarray:
    """The numpy reference of dof.comp for one eye: `image` (H, W, >= 3) the colour before depth
    of field, `position` (H, W, 4) the G-buffer positions (w = view depth, 0: background), both in
    GL row order (bottom-up), `levels` that eye's quadtree (rayvr/accel/quadtree.py), `cam` its
    ScreenCamera. Per pixel the same lens points (the surface point's random stream), the lens
    rays traced by quadtree.trace_layers (one layer), the colour gathered where they meet the
    screen; (H, W, 3) float64."""
    from ...accel import quadtree as qt

    H, W = image.shape[:2]
    l, r, b, t = cam.tangents
    fwd = -cam.rotation[:, 2]
    out = np.zeros((H, W, 3))
    n = max(int(samples), 1)
    for y in range(H):
        for x in range(W):
            d = cam.rotation @ np.array([l + (r - l) * (x + 0.5) / W, b + (t - b) * (y + 0.5) / H, -1.0])
            d /= np.linalg.norm(d)
            f = cam.position + d * (focus / (d @ fwd))
            geo = position[y, x, 3] > 0
            point = position[y, x, :3] if geo else f
            depth = position[y, x, 3] if geo else focus
            state = _seed_surface(point, np.float32(depth) * np.float32(t - b) / np.float32(H), seed)
            total = np.zeros(3)
            for _ in range(n):
                u = []
                for _ in range(2):
                    state = int(pcg_hash(state))
                    u.append((state >> 8) / 16777216.0)
                lens = cam.position + cam.rotation @ np.array([*(np.array(concentric_disk(*u)) * 0.5 * aperture), 0.0])
                tr = qt.trace_layers([levels], cam, lens, f - lens, thickness)
                if tr.status in (qt.HIT, qt.OCCLUDED) and tr.pixel[0] >= 0:
                    px, py = tr.pixel
                else:
                    px = min(max(int(np.floor(tr.point[0])), 0), W - 1)
                    py = min(max(int(np.floor(tr.point[1])), 0), H - 1)
                total += image[py, px, :3]
            out[y, x] = total / n
    return out
