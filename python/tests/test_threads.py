"""Long calls release the GIL: a thread pool runs analyses and deviations at once, and
each gives what it gives alone."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np

import imunoise
from conftest import white_gyro


def test_thread_pool_equals_serial():
    records = [white_gyro(1e-3 * (k + 1), 100.0, 60_000, seed=k) for k in range(4)]
    serial = [imunoise.analyze(r, rate=100.0) for r in records]
    curves = [imunoise.oadev(r, rate=100.0, data_type="freq", taus="all") for r in records]
    with ThreadPoolExecutor(max_workers=4) as pool:
        parallel = list(pool.map(lambda r: imunoise.analyze(r, rate=100.0), records))
        parallel_curves = list(
            pool.map(lambda r: imunoise.oadev(r, rate=100.0, data_type="freq", taus="all"), records)
        )
    assert parallel == serial
    for ours, alone in zip(parallel_curves, curves):
        for a, b in zip(ours, alone):
            np.testing.assert_array_equal(a, b)
