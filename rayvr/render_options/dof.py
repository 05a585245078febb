"""Options of depth of field (rayvr/frame/passes/dof.py)."""
from __future__ import annotations

from ..gl.limits import MAX_CAMERA_COORDINATE, MAX_FOCUS_DISTANCE, MIN_DISTANCE
from ..options import Option, declare

# The lens is named by its DIAMETER here; the `dof` camera model's `aperture` is its lens RADIUS
# (frame/cameras/thin_lens.py). `--aperture` / RenderSettings.dof_aperture, the old names of this
# diameter, are still accepted (deprecated). Ranges: GPU uniforms with the dof camera's float32
# ranges (rayvr/gl/limits.py).
DOF_DIAMETER = declare(Option("dof_diameter", float, 0.0, "depth of field through screen-space rays: lens DIAMETER "
                              "in scene units, 0 = off (pinhole, stereo dual; the dof camera model's aperture is a "
                              "lens radius)", scope="plan", plan_field="dof", bounds=(0, MAX_CAMERA_COORDINATE),
                              commands=("capture", "preview"), deprecated_flags=("--aperture",),
                              old_names=("dof_aperture",)))

DOF_FOCUS = declare(Option("dof_focus", float, 2.0, "depth of field: view depth in focus, scene units",
                           bounds=(MIN_DISTANCE, MAX_FOCUS_DISTANCE), flag="--focus-distance",
                           commands=("capture", "preview")))

DOF_SAMPLES = declare(Option("dof_samples", int, 16, "depth of field: lens rays per pixel", bounds=(1, 1024),
                             commands=("capture", "preview")))
