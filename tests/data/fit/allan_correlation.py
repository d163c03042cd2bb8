#!/usr/bin/env python3
"""Correlation between overlapping Allan variance estimates at octave-spaced taus.

Justifies the correlation kernels of host/src/analysis/fit/allan.rs (fit_allan_with): for each
pure noise type, 300 records of 2^16 samples, overlapping AVAR at m = 1, 2, 4, ...; prints
the median correlation between estimates 1, 2 and 3 octaves apart (tau ratio 2, 4, 8).
Run: python3 allan_correlation.py   (numpy; ~1 min)
"""
import numpy as np

rng = np.random.default_rng(1)
M = 2 ** 16
MS = [2 ** k for k in range(0, 12)]
F = np.fft.rfftfreq(M)
FLICKER = np.zeros_like(F)
FLICKER[1:] = 1 / np.sqrt(F[1:])


def oavar(y, m):
    x = np.concatenate([[0], np.cumsum(y - y.mean())])
    d = x[2 * m:] - 2 * x[m:-m] + x[:-2 * m]
    return np.mean(d ** 2) / (2 * m * m)


def series(kind):
    w = rng.standard_normal(M)
    if kind == "quantization (white PM)":
        return np.diff(np.concatenate([[0], w]))
    if kind == "white rate (N)":
        return w
    if kind == "flicker (B)":
        return np.fft.irfft(np.fft.rfft(w) * FLICKER, M)
    if kind == "rate random walk (K)":
        return np.cumsum(w)
    return np.cumsum(np.cumsum(w))  # rate ramp-like (R)


for kind in ["quantization (white PM)", "white rate (N)", "flicker (B)",
             "rate random walk (K)", "rate ramp (R)"]:
    records = (series(kind) for _ in range(300))
    est = np.array([[oavar(y, m) for m in MS] for y in records])
    c = np.corrcoef(est.T)
    lags = [np.median([c[i, i + lag] for i in range(1, len(MS) - lag - 1)]) for lag in (1, 2, 3)]
    print(f"{kind:26s} ratio 2: {lags[0]:.2f}  4: {lags[1]:.2f}  8: {lags[2]:.2f}")
