#!/usr/bin/env python3
"""Reference one-sided Welch PSDs from scipy for host/src/analysis/psd.rs's tests.

Run from this directory: python3 make_reference.py
Writes series.txt (4096 samples, 100 Hz) and one density file per case below.
"""
import numpy as np
import scipy
from scipy import signal

FS = 100.0
rng = np.random.default_rng(20240601)
n = 4096
t = np.arange(n) / FS
# White noise + a slow random walk + a tone + an offset: exercises detrending and leakage.
y = (0.3 * rng.standard_normal(n) + 0.01 * np.cumsum(rng.standard_normal(n))
     + 0.2 * np.sin(2 * np.pi * 7.3 * t) + 1.5)

CASES = [
    # file, window, nperseg, noverlap, detrend
    ("hann.txt", "hann", 512, 256, "constant"),
    ("hamming.txt", "hamming", 512, 256, "constant"),
    ("blackman.txt", "blackman", 512, 256, "constant"),
    ("rectangular.txt", "boxcar", 512, 256, "constant"),
    ("hann_nodetrend.txt", "hann", 512, 256, False),
    # overlap 0.75 of an odd length: noverlap = floor(0.75 * 333) = 249
    ("hann_overlap75_odd.txt", "hann", 333, 249, "constant"),
]

np.savetxt("series.txt", y, fmt="%.17e", header="input series, 4096 samples at 100 Hz")
for name, window, nperseg, noverlap, detrend in CASES:
    f, p = signal.welch(y, FS, window=window, nperseg=nperseg, noverlap=noverlap,
                        detrend=detrend, scaling="density", return_onesided=True)
    header = (f"scipy {scipy.__version__} signal.welch(series, fs={FS}, window={window!r}, "
              f"nperseg={nperseg}, noverlap={noverlap}, detrend={detrend!r}, "
              "scaling='density', return_onesided=True); one value per frequency "
              f"j*fs/nperseg, j=0..{len(f)-1}")
    np.savetxt(name, p, fmt="%.17e", header=header)
print("scipy", scipy.__version__, "numpy", np.__version__)
