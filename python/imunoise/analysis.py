"""The whole imunoise analysis from Python: records from files and stores, the analysis
document of ``imunoise analyze --json``, and the parts of it a notebook asks for most (the
noise fit, the PSD, the Kalman-filter numbers, Kalibr's imu.yaml)."""

import json
from dataclasses import dataclass, field

from . import _imunoise
from ._arrays import channels, samples, sample_rate

__all__ = [
    "Record",
    "load",
    "load_session",
    "analyze",
    "fit",
    "psd",
    "filter_noise",
    "kalibr",
    "model",
]


@dataclass
class Record:
    """A record read from a file or a stored session.

    Attributes
    ----------
    channels : dict of str -> numpy.ndarray
        Each channel's samples in SI units (rad/s, m/s^2, degC; a channel of unknown
        quantity as the input gave it).
    rate : float
        Sample rate, Hz.
    source : str
        Where it came from (the path, or the session's id and name).
    settings : dict or None
        The filters a capture's sensor settings give, ``{"gyro": ..., "accel": ...}``, each
        the MPU-6050 settings whose chain filters those channels (a GY-85's ITG-3200 gives
        ``gyro``; its ADXL345's filter is detected, ``accel`` None); the analysis then
        models them. None when the input states no settings.
    notes : list of str
        What the reader has to say (losses, the run chosen).
    input : dict
        How the file was read (compression, the time column's rate and jitter, units from
        column names, warnings): the document's ``input``.
    """

    channels: dict
    rate: float
    source: str
    settings: dict = None
    notes: list = field(default_factory=list)
    input: dict = field(default_factory=dict)


def _record(parts):
    names, columns, rate, source, settings, notes, report = parts
    return Record(
        channels=dict(zip(names, columns)),
        rate=rate,
        source=source,
        settings=None if settings is None else json.loads(settings),
        notes=list(notes),
        input=json.loads(report),
    )


def load(path, *, rate=None, names=None, ignore_time=False, longest_run=False, topic=None):
    """Read a record from a file: a capture (``.imucap``), a text or CSV table (optional
    header, optional time column), or a NumPy ``.npy``, any of them gzipped, or a ROS bag
    (``.bag``, ``.mcap``, a rosbag2 directory or its ``.db3``; ``topic`` names its
    sensor_msgs/Imu topic when it has several); the same readers and options as
    ``imunoise analyze FILE``.

    ``rate`` (Hz) is needed when the file has no time column and no rate in its header;
    ``names`` names the channels of a headerless file; ``ignore_time`` treats a time column
    as absent; ``longest_run`` reads the longest gap-free run of a capture with gaps, or of
    a time column with samples missing (otherwise refused). Raises ``OSError`` for a file that cannot be read and
    ``ValueError`` (naming the file, line and field) for one whose content is wrong.
    """
    return _record(
        _imunoise.load(
            str(path),
            rate=rate,
            names=names,
            ignore_time=ignore_time,
            longest_run=longest_run,
            topic=topic,
        )
    )


def load_session(
    key, *, store=None, rate=None, names=None, ignore_time=False, longest_run=False, topic=None
):
    """Read a stored session by id or name from the store at ``store`` (default:
    ``$IMUNOISE_STORE``, else the platform data directory), as ``imunoise analyze ID``
    does. Raises ``ValueError`` for a missing store or session."""
    return _record(
        _imunoise.load_session(
            str(key),
            store=None if store is None else str(store),
            rate=rate,
            names=names,
            ignore_time=ignore_time,
            longest_run=longest_run,
            topic=topic,
        )
    )


def _unpack(data, rate, names):
    """Names, columns, rate and what a Record adds (settings, input report, source) as
    keywords for the extension."""
    extra = {"settings": None, "source": "arrays"}
    if isinstance(data, Record):
        if names is not None:
            raise TypeError("names: not with a Record, whose channels are named")
        rate = data.rate if rate is None else rate
        extra = {
            "settings": None if data.settings is None else json.dumps(data.settings),
            "source": data.source,
        }
        data = data.channels
    if rate is None:
        raise TypeError("rate: the sample rate in Hz is needed for arrays")
    names, columns = channels(data, names)
    return names, columns, sample_rate(rate), extra


def _keywords(options):
    """The options as the extension takes them: one estimator becomes a list, a bandwidth
    text ("42", "off")."""
    options = dict(options)
    if isinstance(options.get("estimators"), str):
        options["estimators"] = [options["estimators"]]
    if options.get("bandwidth") is not None:
        options["bandwidth"] = str(options["bandwidth"])
    return options


def _run(data, rate, names, options):
    """The extension's analysis of ``data``: (document text, Kalibr YAML, why no YAML)."""
    names, columns, rate, extra = _unpack(data, rate, names)
    if isinstance(data, Record):
        extra["input"] = json.dumps(data.input)
    return _imunoise.analyze(names, columns, rate, **extra, **_keywords(options))


_OPTIONS = """
    Options (keywords, as ``imunoise analyze``'s flags):
    data_type : "rate" (default; allantools' "freq" is accepted) or "phase".
    estimators : list of "oadev", "adev", "mdev", "hdev", "ohdev", "tdev", "totdev"
        (default ["oadev"]; the noise fit always uses oadev).
    taus : "per-decade:K" (default "per-decade:10"), "octave", "decade" or "all".
    confidence : two-sided confidence of the intervals (default 0.683).
    fit_tau_min : shortest tau of the noise fit, s.
    bandwidth : the sensor's low-pass -3 dB bandwidth in Hz, or "off" (default: a
        capture's settings, else fitted to the spectrum).
    psd_segment : Welch segment length in samples; psd_window : "hann" (default),
        "hamming", "blackman", "rectangular".
    filter_period : a Kalman filter's period, s: adds the document's ``filter``.
"""


def analyze(data, rate=None, names=None, **options):
    """The document ``imunoise analyze --json`` writes, as dicts and lists.

    ``data`` is a 1-D array (one channel), a 2-D array whose columns are channels (named by
    ``names``, default c0, c1, ...), a dict name -> 1-D array, or a :class:`Record`. A
    channel's name gives its quantity and unit (gx..gz rad/s, ax..az m/s^2, temp degC).
    Each channel is copied once into the record; the analysis runs on all cores without
    the GIL, so a thread pool runs several at once.

    ``analyze(x, rate=100.0)["channels"][0]["noise"]["N"]["value"]`` is the white-noise
    density N of channel 0, with its interval in ``lo``, ``hi``.
    """
    text, _, _ = _run(data, rate, names, options)
    return json.loads(text)


analyze.__doc__ += _OPTIONS




def fit(data, rate=None, names=None, **options):
    """The noise fit of each channel, by name: the IEEE-952 terms Q, N, B, K, R with
    intervals (``noise``; ``noise_conventional`` in deg/h, ug ...), the fit's summary
    (``fit``), the PSD route's N, B, K (``psd_noise``) and the low-pass modelled
    (``low_pass``): the channel parts of :func:`analyze`'s document. Arguments as
    :func:`analyze`."""
    keys = ("noise", "noise_conventional", "fit", "psd_noise", "low_pass", "slope_readouts")
    document = analyze(data, rate, names, **options)
    return {c["name"]: {k: c[k] for k in keys} for c in document["channels"]}


def psd(data, rate=1.0, segment=None, window="hann"):
    """Welch's one-sided PSD of a 1-D array: ``(freq, density)`` in Hz and u^2/Hz, the
    definition of ``scipy.signal.welch`` (50 % overlap, segment means removed,
    ``scaling="density"``). ``segment`` defaults to the analysis' choice for the length
    (a power of two near 1/8 of it, 256 to 2^20 samples); ``window`` is "hann",
    "hamming", "blackman" or "rectangular". White rate noise of Allan coefficient N has a
    one-sided density of 2 N^2."""
    return _imunoise.psd(
        samples(data, "data"), sample_rate(rate), 0 if segment is None else int(segment), window
    )


def filter_noise(data, rate=None, period=None, names=None, **options):
    """What a Kalman filter running every ``period`` seconds (default: the sample period)
    needs, per channel with a noise fit: the document's ``filter`` part
    (docs/guide/filter-outputs.md): white noise, random walks and a Gauss-Markov bias
    where the data support one, continuous and discrete, each ``{value, unit}``."""
    if period is None:
        base = data.rate if isinstance(data, Record) and rate is None else rate
        period = 1.0 / sample_rate(base) if base is not None else None
    if period is None:
        raise TypeError("rate: the sample rate in Hz is needed for arrays")
    return analyze(data, rate, names, filter_period=period, **options)["filter"]


def kalibr(data, rate=None, names=None, **options):
    """Kalibr's imu.yaml (text) from the gyro and accelerometer channels (gx..gz,
    ax..az). Raises ``ValueError`` with the reason when the record lacks what it needs."""
    _, yaml, why = _run(data, rate, names, options)
    if yaml is None:
        raise ValueError(f"no Kalibr YAML: {why}")
    return yaml


def model(data, rate=None, names=None, *, column=None, temp_column=None, seed=1, realisations=24, bandwidth=None):
    """The model workflow on one channel (``imunoise model``, docs/guide/model.md): the
    standard noise model fitted, simulated ``realisations`` times from ``seed``, every
    candidate effect tested against the simulated spread, the one the model misses named
    and added, repeated. Returns the document ``imunoise model --json`` writes.

    ``column`` is the channel to model (default: the first gyro channel, else the first
    accelerometer channel, else the only other channel), ``temp_column``
    its temperature (default: a channel named temp, if any); ``bandwidth`` as in
    :func:`analyze`. Data as in :func:`analyze`. It simulates the record many times over:
    expect seconds to minutes.
    """
    names, columns, rate, extra = _unpack(data, rate, names)
    text = _imunoise.model(
        names,
        columns,
        rate,
        column=column,
        temp_column=temp_column,
        seed=int(seed),
        realisations=int(realisations),
        **extra,
        **_keywords({"bandwidth": bandwidth}),
    )
    return json.loads(text)
