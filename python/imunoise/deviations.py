"""Allan-family deviations with allantools' interface.

``oadev``, ``adev``, ``mdev``, ``hdev``, ``ohdev``, ``tdev`` and ``totdev`` take the same
arguments as the allantools functions of the same names and return the same
``(taus, devs, errs, ns)``, so that a notebook changes only its import. The sums are the
imunoise engine's (``host/src/analysis/allan.rs``, NIST SP 1065 section 5.2), run without the
GIL. The intervals and equivalent degrees of freedom the engine also computes are in
:func:`imunoise.analyze`.
"""

import numpy as np

from . import _imunoise
from ._arrays import samples, sample_rate

__all__ = ["adev", "oadev", "mdev", "hdev", "ohdev", "tdev", "totdev"]


def _taus_to_factors(taus, rate, n_phase):
    """Averaging factors m (tau = m / rate) chosen by allantools' ``tau_generator``.

    ``None`` or an empty list means "octave"; "octave" is 2^k up to the phase length,
    "decade" 1, 2, 4 x 10^k, "log10" ten log-spaced taus per decade, "all" every m; an
    array (or one number) is a list of taus in seconds. Each tau becomes
    m = round(tau * rate) (half to even, as numpy rounds), and only 0 < m < N (N phase
    points) are kept, sorted and without repeats. The grids are built with the same
    numpy expressions as allantools, so the same taus give the same m.
    """
    if taus is None or (isinstance(taus, (list, tuple)) and len(taus) == 0):
        taus = "octave"
    if isinstance(taus, str):
        tau0 = 1.0 / rate
        if taus == "all":
            grid = tau0 * np.linspace(1.0, n_phase, n_phase)
        elif taus == "octave":
            top = int(np.floor(np.log2(n_phase)))
            grid = tau0 * np.logspace(0, top, top + 1, base=2.0)
        elif taus == "decade":
            top = int(np.floor(np.log10(n_phase)))
            grid = np.array(
                [mult * tau0 * 10.0**k for k in range(top + 1) for mult in (1.0, 2.0, 4.0)]
            )
        elif taus == "log10":
            top = np.log10(n_phase)
            grid = tau0 * np.logspace(0, top, int(10 * top), base=10.0)
        else:
            raise ValueError(
                f"taus {taus!r}: one of 'octave', 'decade', 'log10', 'all', "
                "or an array of taus in seconds"
            )
    else:
        try:
            grid = np.atleast_1d(np.asarray(taus, dtype=np.float64))
        except (TypeError, ValueError) as e:
            raise TypeError(f"taus: an array of taus in seconds or a grid name ({e})") from None
        if grid.ndim != 1:
            raise ValueError(f"taus: a one-dimensional array, not of shape {grid.shape}")
    m = np.round(grid * rate)
    return np.unique(m[(m > 0) & (m < n_phase)])


def _deviation(estimator, data, rate, data_type, taus):
    rate = sample_rate(rate)
    if data_type not in ("phase", "freq"):
        raise ValueError(f"data_type {data_type!r}: 'phase' or 'freq'")
    y = samples(data, "data")
    n_phase = len(y) if data_type == "phase" else len(y) + 1
    factors = _taus_to_factors(taus, rate, n_phase)
    m, devs, ns = _imunoise.deviation(
        estimator, y, rate, data_type == "phase", factors.astype(np.int64).tolist()
    )
    # allantools drops the taus with a single term (remove_small_ns).
    keep = ns > 1
    if not keep.any():
        raise ValueError(
            f"{estimator}: no tau has two terms on {len(y)} samples "
            f"(taus asked: {taus!r}); a longer record or shorter taus"
        )
    ns = ns[keep].astype(np.float64)
    devs = devs[keep]
    return m[keep] / float(rate), devs, devs / np.sqrt(ns), ns


_DOC = """{title} (NIST SP 1065 eq. {eq}), allantools-compatible.

Parameters
----------
data : array_like, one-dimensional
    Phase (``data_type="phase"``, allantools' default) or fractional frequency / rate
    (``data_type="freq"``), one sample every ``1 / rate`` seconds. A contiguous float64
    array is read where it lies, without a copy; anything else (another dtype, a strided
    view, a list) is first converted to a contiguous float64 copy. Every sample must be
    finite: NaN raises ``ValueError`` (allantools trims NaN at the ends of frequency data).
rate : float
    Sample rate in Hz.
data_type : {{"phase", "freq"}}
    Frequency data become phase by the mean-removed cumulative sum (``len(data) + 1``
    points), as allantools' ``frequency2phase`` does.
taus : None, "octave", "decade", "log10", "all", or array of float
    allantools' rules: None is "octave"; an array is taus in seconds, each rounded to
    m = round(tau * rate); taus with m outside 1..N-1 (N phase points) are dropped.

Returns
-------
taus, devs, errs, ns : numpy.ndarray
    The taus kept (m / rate), the deviations, ``devs / sqrt(ns)`` and the number of
    terms in each sum ({terms}), all float64; taus with a single term are left out, as
    allantools leaves them out.

Raises
------
ValueError
    A rate that is not positive, non-finite samples, an unknown ``data_type`` or grid
    name, or no tau with two terms.
TypeError
    Data that is not an array of numbers.
"""


def _estimator(name, title, eq, terms):
    def estimator(data, rate=1.0, data_type="phase", taus=None):
        return _deviation(name, data, rate, data_type, taus)

    estimator.__name__ = estimator.__qualname__ = name
    estimator.__doc__ = _DOC.format(title=title, eq=eq, terms=terms)
    return estimator


adev = _estimator("adev", "Allan deviation", "7", "floor((N-1)/m) - 1")
oadev = _estimator("oadev", "Overlapping Allan deviation", "11", "N - 2m")
mdev = _estimator("mdev", "Modified Allan deviation", "14", "N - 3m + 1")
hdev = _estimator("hdev", "Hadamard deviation", "17", "floor((N-1)/m) - 2")
ohdev = _estimator("ohdev", "Overlapping Hadamard deviation", "18", "N - 3m")
tdev = _estimator("tdev", "Time deviation, tau mdev / sqrt(3)", "15", "N - 3m + 1, as mdev")
totdev = _estimator(
    "totdev",
    "Total deviation on the reflected extension, m up to N - 1",
    "25",
    "N - 2 at every tau",
)
