"""imunoise: the noise of MEMS IMUs (Allan family, PSD, IEEE-952 terms, filter numbers).

Two APIs over the Rust engine:

- allantools-compatible deviations, ``oadev``, ``adev``, ``mdev``, ``hdev``, ``ohdev``,
  ``tdev``, ``totdev``: same arguments, same ``(taus, devs, errs, ns)``;
- the whole analysis: ``analyze`` (the document of ``imunoise analyze --json``), ``fit``,
  ``psd``, ``filter_noise``, ``kalibr``, ``model``, and records from files or a store (``load``,
  ``load_session``).

Long calls release the GIL, so a ``ThreadPoolExecutor`` runs analyses in parallel.
"""

from ._imunoise import VERSION as __version__
from .analysis import Record, analyze, filter_noise, fit, kalibr, load, load_session, model, psd
from .deviations import adev, hdev, mdev, oadev, ohdev, tdev, totdev

__all__ = [
    "Record",
    "adev",
    "analyze",
    "filter_noise",
    "fit",
    "hdev",
    "kalibr",
    "load",
    "load_session",
    "mdev",
    "model",
    "oadev",
    "ohdev",
    "psd",
    "tdev",
    "totdev",
]
