"""`rayvr bench ssrt --quick` runs end to end (CI smoke test; figures come from the GPU machine)."""
from conftest import needs_flip, quick_bench


@needs_flip
def test_bench_ssrt_quick_writes_quadtree_dda_and_hiz_rows(tmp_path):
    result = quick_bench("ssrt", tmp_path)
    rows = result["rows"]
    frames = {r["tracer"] for r in rows if r["tracer"].startswith("frame:")}
    assert {r["tracer"] for r in rows} - frames == {"quadtree", "dda", "hiz"}
    assert {"frame:reflections", "frame:ssr", "frame:ssr:layers2:rays", "frame:ssr:layers2:peel",
            "frame:ssr:adapt"} <= frames and any(f.startswith("frame:ssr:gamma") for f in frames)
    peel = next(r for r in rows if r["tracer"] == "frame:ssr:layers2:peel")
    assert "second_layer" in peel["pass_ms"] and peel["layer2_agrees_with_rays"] > 0.95
    assert {r["start_level"] for r in rows if r["tracer"] == "quadtree"} == {16, 6, 4}
    matched = result["meta"]["matched_error"]
    assert matched and all(0 <= r["quadtree_pixel_agreement"] <= 1 for r in matched)
    assert result["meta"]["gl_renderer"]
    lossless = next(r for r in rows if r["tracer"] == "quadtree" and r["gamma_norm"] == 1.0)
    merged = next(r for r in rows if r["tracer"] == "quadtree" and r["gamma_norm"] < 1.0 and r["start_level"] == 16)
    assert merged["nodes_mean"] < lossless["nodes_mean"]  # merged planes skip nodes
    assert all(r["status_agrees_with_quadtree"] > 0.9 for r in rows if r["tracer"] == "dda")
    hiz = [r for r in rows if r["tracer"] == "hiz"]
    assert hiz and all(r["grays_s"] > 0 and r["iterations_mean"] > 0 and r["build_ms_per_layer"] > 0 for r in hiz)
    assert all(r["status_agrees_with_quadtree"] > 0.9 for r in hiz)
    ssr = next(r for r in rows if r["tracer"] == "frame:ssr")
    assert 0 <= ssr["flip_vs_reflections_on_mirrors"] < 1 and ssr["mirror_ms"] > 0 and "quadtree" in ssr["pass_ms"]
