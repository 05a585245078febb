"""quality/metric_pool.py: metrics judged in worker processes give the numbers computed inline,
in submission order, with the back-pressure bound holding the queue."""
import numpy as np

from rayvr.quality import metric_pool, metrics


def test_worker_processes_give_the_inline_numbers_in_order(monkeypatch):
    rng = np.random.default_rng(3)
    ref = rng.integers(0, 256, (40, 60, 3), dtype=np.uint8)
    tests = [np.clip(ref.astype(int) + rng.integers(-k, k + 1, ref.shape), 0, 255).astype(np.uint8)
             for k in (2, 8, 20, 40, 60)]
    monkeypatch.setenv("RAYVR_METRIC_WORKERS", "0")
    inline = [metric_pool.judge(metrics.psnr, ref, t).result() for t in tests]
    assert inline == sorted(inline, reverse=True)  # more noise, lower PSNR: the inputs differ as meant
    monkeypatch.setenv("RAYVR_METRIC_WORKERS", "2")
    futures = [metric_pool.judge(metrics.psnr, ref, t) for t in tests]
    assert len(metric_pool._pending) <= 2 * metric_pool.PENDING_PER_WORKER
    assert [f.result() for f in futures] == inline
    assert metric_pool._pool is not None  # they ran in the worker processes
    metric_pool.shutdown()
    assert metric_pool._pool is None
