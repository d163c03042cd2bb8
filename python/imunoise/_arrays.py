"""Turning what a caller passes into what the extension module takes: contiguous float64
arrays (borrowed without a copy when they already are), a rate, named channels."""

import math

import numpy as np


def samples(data, what):
    """``data`` as a one-dimensional, contiguous float64 array: the same array when it
    already is one, else a converted copy."""
    array = _numeric(data, what)
    if array.ndim != 1:
        raise ValueError(f"{what}: a one-dimensional array, not of shape {array.shape}")
    if array.size == 0:
        raise ValueError(f"{what}: the array is empty")
    return np.ascontiguousarray(array, dtype=np.float64)


def _numeric(data, what):
    try:
        array = np.asarray(data)
    except (TypeError, ValueError) as e:
        raise TypeError(f"{what}: an array of numbers ({e})") from None
    if array.dtype.kind not in "biuf":
        raise TypeError(
            f"{what}: an array of real numbers, not of dtype {array.dtype} "
            "(complex, text and objects are refused)"
        )
    return array


def sample_rate(rate):
    """``rate`` as a positive, finite float (Hz)."""
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise TypeError(f"rate {rate!r}: a sample rate in Hz (a number)") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"rate {rate!r}: the sample rate must be a positive, finite number of Hz")
    return value


def channels(data, names):
    """Channel names and contiguous float64 columns from a 1-D array (one channel), a 2-D
    array (columns are channels) or a dict name -> 1-D array. Unnamed channels are c0,
    c1, ... as the file readers name them."""
    if isinstance(data, dict):
        if names is not None:
            raise TypeError("names: not with a dict, whose keys are the names")
        if not data:
            raise ValueError("data: the dict has no channels")
        names = [str(k) for k in data]
        return names, [samples(v, f"data[{k!r}]") for k, v in data.items()]
    array = _numeric(data, "data")
    if array.ndim == 1:
        columns = [samples(array, "data")]
    elif array.ndim == 2:
        if array.shape[0] == 0 or array.shape[1] == 0:
            raise ValueError(f"data: the array of shape {array.shape} is empty")
        # A column of a C-ordered array is strided: each becomes one contiguous copy.
        columns = [samples(array[:, i], f"data[:, {i}]") for i in range(array.shape[1])]
    else:
        raise ValueError(
            f"data: a 1-D array, a 2-D array (columns are channels) or a dict of 1-D "
            f"arrays, not an array of shape {array.shape}"
        )
    if names is None:
        names = [f"c{i}" for i in range(len(columns))]
    elif isinstance(names, str):
        names = [names]
    names = [str(n) for n in names]
    if len(names) != len(columns):
        raise ValueError(f"names: {len(names)} names for {len(columns)} channels")
    return names, columns
