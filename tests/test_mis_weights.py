"""The MIS weights of glsl/common/mis.glsl, run on the GPU in a one-line compute shader and held
against the power heuristic (Veach 1997, beta = 2) written here in numpy: w(a, b) = a^2 / (a^2 + b^2)
for "count x pdf" values a (the technique that made the sample) and b (the other one). The balance
heuristic a / (a + b) (or any other beta) is off by up to 0.17 at the ratios below."""
from __future__ import annotations

import numpy as np
import pytest

from rayvr.gl import shaders
from rayvr.gl.gpu_layout import SSBO

IN_BINDING, OUT_BINDING = max(SSBO.values()) + 1, max(SSBO.values()) + 2  # clear of the scene's buffers

KERNEL = """#version 430
layout(local_size_x = 64) in;
#include "common/mis.glsl"
layout(std430, binding = IN_BINDING) readonly buffer Pairs { vec2 pairs[]; };
layout(std430, binding = OUT_BINDING) writeonly buffer Weights { float weights[]; };
uniform uint pair_count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < pair_count) weights[i] = power_heuristic(pairs[i].x, pairs[i].y);
}
"""


def power_heuristic(a, b):
    """Veach's power heuristic in float64; a technique that cannot make the sample (pdf 0) gets 0,
    and against one that cannot, 1."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        w = a * a / (a * a + b * b)
    return np.where(a > 0, np.where(b > 0, w, 1.0), 0.0)


def gpu_weights(gl, tmp_path, pairs):
    (tmp_path / "mis_weights.comp").write_text(KERNEL)
    prog = shaders.compute(gl.ctx, "mis_weights.comp", {"IN_BINDING": IN_BINDING, "OUT_BINDING": OUT_BINDING},
                           root=tmp_path)
    src = gl.ctx.buffer(np.ascontiguousarray(pairs, np.float32).tobytes())
    out = gl.ctx.buffer(reserve=4 * len(pairs))
    try:
        src.bind_to_storage_buffer(IN_BINDING)
        out.bind_to_storage_buffer(OUT_BINDING)
        prog["pair_count"].value = len(pairs)
        prog.run((len(pairs) + 63) // 64)
        return np.frombuffer(out.read(), np.float32).astype(np.float64)
    finally:
        src.release()
        out.release()
        prog.release()


def test_numpy_power_heuristic_is_the_textbook_one():
    """The reference itself, by hand: 2 against 1 gives 4/5 (balance: 2/3), 1 against 3 gives 1/10."""
    assert power_heuristic(2.0, 1.0) == pytest.approx(0.8)
    assert power_heuristic(1.0, 3.0) == pytest.approx(0.1)
    assert power_heuristic(0.0, 1.0) == 0.0 and power_heuristic(1.0, 0.0) == 1.0


def test_glsl_mis_weights_are_the_power_heuristic(gl, tmp_path):
    rng = np.random.default_rng(7)
    ratios = [(1.0, 1.0), (2.0, 1.0), (1.0, 2.0), (1.0, 3.0), (5.0, 0.5), (0.3, 0.7), (100.0, 1.0), (1.0, 100.0)]
    spread = 10.0 ** rng.uniform(-3, 3, size=(24, 2))  # pdfs from near-delta lobes to wide ones
    extremes = [(1e-20, 1e-20), (1e-20, 3e-20), (1e30, 2e30), (1e30, 1e-30)]  # squares under/overflow float32
    finite = np.array(ratios + [tuple(p) for p in spread] + extremes)
    got = gpu_weights(gl, tmp_path, finite)
    want = power_heuristic(finite[:, 0], finite[:, 1])
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-7)
    # the two techniques' weights of one sample add up to 1 (the estimator stays unbiased)
    swapped = gpu_weights(gl, tmp_path, finite[:, ::-1])
    np.testing.assert_allclose(got + swapped, 1.0, rtol=0, atol=2e-6)

    # a technique that cannot make the sample (pdf 0, or not a number) gets 0; against one that
    # cannot, or against an infinitely wide pdf's 0 density, 1
    special = np.array([(0.0, 1.0), (1.0, 0.0), (0.0, 0.0), (np.inf, 1.0), (1.0, np.inf), (np.nan, 1.0), (-1.0, 1.0)])
    np.testing.assert_array_equal(gpu_weights(gl, tmp_path, special), [0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0])
