"""Shared records: seeded, so every run sees the same samples."""

import numpy as np
import pytest


@pytest.fixture(scope="session")
def white_and_walk():
    """20 000 samples of white rate noise plus a slow random walk, seed 19."""
    rng = np.random.default_rng(19)
    white = rng.normal(size=20_000)
    return white + 0.01 * np.cumsum(rng.normal(size=white.size))


def white_gyro(density, rate, n, seed):
    """White rate noise of Allan coefficient N = ``density`` at ``rate`` Hz: per-sample
    sigma N sqrt(rate) (host/src/sim/noise.rs realises it the same way)."""
    return np.random.default_rng(seed).normal(size=n) * density * np.sqrt(rate)
