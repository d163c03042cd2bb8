"""imunoise.oadev against allantools.oadev on the same record and taus, in one run.

    python python/bench.py [--samples N] [--taus per-decade:K|octave|decade|all] [--repeat R]

Prints each side's best time of R runs, the ratio, and the largest relative difference of
the deviations. White rate noise, seed 1; rate 100 Hz, data_type "freq". The default taus,
14 per decade, are those of `imunoise bench` (tau = m / rate, m = round(10^(i/14))).
"""

import argparse
import os
import sys
import time

import allantools
import numpy as np

# The installed package, not the sources beside this script (they lack the compiled module).
sys.path = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(os.path.abspath(__file__))]
import imunoise  # noqa: E402


def best(call, repeat):
    """The shortest of ``repeat`` wall-clock times of ``call()``, and its result."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return min(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e7)
    parser.add_argument("--taus", default="per-decade:14")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    y = np.random.default_rng(1).normal(size=int(args.samples))
    taus = args.taus
    if taus.startswith("per-decade:"):
        k = int(taus.split(":")[1])
        top = np.log10(y.size / 2)
        taus = np.unique(np.round(10.0 ** (np.arange(0, top * k + 1) / k))) / 100.0
    call = dict(rate=100.0, data_type="freq", taus=taus)
    theirs_s, theirs = best(lambda: allantools.oadev(y, **call), args.repeat)
    ours_s, ours = best(lambda: imunoise.oadev(y, **call), args.repeat)
    assert np.array_equal(ours[0], theirs[0]), "the same taus"
    diff = np.max(np.abs(ours[1] / theirs[1] - 1))
    print(f"samples {y.size}, taus {args.taus} ({len(ours[0])} taus), best of {args.repeat}")
    print(f"allantools.oadev {theirs_s:8.3f} s")
    print(f"imunoise.oadev   {ours_s:8.3f} s")
    print(f"ratio            {theirs_s / ours_s:8.1f} x  (largest relative difference {diff:.1e})")


if __name__ == "__main__":
    main()
