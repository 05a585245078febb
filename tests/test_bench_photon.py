"""`rayvr bench photon --quick` runs end to end (CI smoke test; figures come from the GPU machine)."""
from conftest import needs_flip, quick_bench


@needs_flip
def test_bench_photon_quick_writes_the_papers_tables(tmp_path):
    result = quick_bench("photon", tmp_path)
    rows = result["rows"]
    assert {(r["table"], r["estimator"]) for r in rows} == {(1, "kdtree_heap"), (1, "grid_heap"), (2, "grid_heap"),
                                                            (2, "grid")}
    for r in rows:  # a timer reading llvmpipe garbles under load is left out (None), never a number
        for k in ("trace_ms", "build_ms", "sort_ms", "query_ms", "rt_photon_ms", "frame_ms"):
            assert r[k] is None or r[k] >= 0, (k, r[k])
        assert 0 <= r["flip"] < 1
        # the search replayed in numpy: the 27 cells hold every photon within r and more
        assert r["visited"] >= r["accepted"] > 0, (r["visited"], r["accepted"])
    kd = next(r for r in rows if r["estimator"] == "kdtree_heap")
    grid = next(r for r in rows if r["estimator"] == "grid_heap")
    assert kd["kd_cpu_build_ms"] > 0 and grid["kd_cpu_build_ms"] is None
    assert abs(kd["flip"] - grid["flip"]) < 0.01  # the same k nearest photons through either map
    tables = (tmp_path / "photon_tables.md").read_text()
    assert "Table 1: kd-tree vs hash grid" in tables and "Table 2: heap vs no heap" in tables
