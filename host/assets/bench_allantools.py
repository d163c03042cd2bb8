#!/usr/bin/env python3
"""Reference timing for `imunoise bench`: allantools' overlapping Allan deviation on the same
data and taus as imunoise. Usage: bench_allantools.py DATA.npy FACTORS.txt RATE_HZ OUT.json
(DATA: 1-D float64 rate samples; FACTORS: averaging factors, one per line). Writes
{"seconds": ..., "taus": [...], "devs": [...], "ns": [...], "version": ...}."""
import json
import sys
import time

import allantools
import numpy as np


def main():
    data_path, factors_path, rate, out_path = sys.argv[1:5]
    y = np.load(data_path)
    rate = float(rate)
    factors = np.loadtxt(factors_path, dtype=np.int64, ndmin=1)
    taus = factors / rate
    start = time.perf_counter()
    taus_out, devs, _errs, ns = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
    seconds = time.perf_counter() - start
    with open(out_path, "w") as f:
        json.dump(
            {
                "seconds": seconds,
                "taus": [float(t) for t in taus_out],
                "devs": [float(d) for d in devs],
                "ns": [int(n) for n in ns],
                "version": getattr(allantools, "__version__", "unknown"),
            },
            f,
        )


if __name__ == "__main__":
    main()
