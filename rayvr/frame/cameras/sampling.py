"""Sub-samples of a camera sample (MSAA / SSAA for rays, thin-lens positions): a fixed
low-discrepancy set of N points, the same for every pixel and both eyes (so a stereo pair sees
the same pattern at the same surface point and IPD 0 gives identical eyes).

Sub-sample i of N has
- an offset inside the sample's footprint, in footprint units, GL axes (x right, y up):
  a Hammersley point ((i + 0.5) / N, phi_2(i) + 0.5 / N) moved to [-0.5, 0.5)^2;
- a lens position in the unit disk: the Halton pair (phi_3(i), phi_5(i)) shifted by 1/2 (mod 1)
  and mapped to the disk by Shirley and Chiu's concentric map, decorrelated from the offsets.
Sub-sample 0 of 1 is the footprint centre and the lens centre: 1x is one pinhole-like ray per
sample. glsl/cameras/sampling.glsl computes the same points; tests compare the two.
"""
from __future__ import annotations

import math

import numpy as np

from ...options import plan_part
from ...render_options.sampling import SAMPLE_COUNTS, MSAA


def radical_inverse(i: int, base: int) -> float:
    """phi_base(i): the digits of i in `base` mirrored around the point."""
    out, f = 0.0, 1.0 / base
    while i > 0:
        out += f * (i % base)
        i //= base
        f /= base
    return out


def concentric_disk(u: float, v: float) -> tuple[float, float]:
    """[0, 1)^2 -> unit disk, area preserving, (0.5, 0.5) -> centre (Shirley and Chiu 1997)."""
    a, b = 2.0 * u - 1.0, 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r, phi = a, (math.pi / 4) * (b / a)
    else:
        r, phi = b, math.pi / 2 - (math.pi / 4) * (a / b)
    return r * math.cos(phi), r * math.sin(phi)


def check_count(n: int) -> int:
    if n not in SAMPLE_COUNTS:
        raise ValueError(f"sub-rays per sample must be one of {', '.join(map(str, SAMPLE_COUNTS))}, got {n}")
    return n


def subsamples(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (n, 2), lens (n, 2)) of the n-point set, float64 (module notes)."""
    check_count(n)
    offsets = np.array([((i + 0.5) / n - 0.5, radical_inverse(i, 2) + 0.5 / n - 0.5) for i in range(n)])
    lens = np.array([concentric_disk((radical_inverse(i, 3) + 0.5) % 1.0, (radical_inverse(i, 5) + 0.5) % 1.0)
                     for i in range(n)])
    return offsets, lens


@plan_part("sampling")
def sampling_plan(ask, plan) -> None:
    """Sub-rays per sample, and whether each is shaded (supersampling) or each distinct triangle."""
    plan["subsamples"] = ask.settings.msaa
    plan["shading"] = "ssaa" if ask.settings.ssaa and ask.settings.msaa > 1 else "msaa"
