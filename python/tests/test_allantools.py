"""The allantools-compatible functions against allantools itself on the same data: the
same taus and term counts exactly, the deviations and errors to 1e-9 relative."""

import allantools
import numpy as np
import pytest

import imunoise

ESTIMATORS = ["adev", "oadev", "mdev", "hdev", "ohdev", "tdev", "totdev"]
# "all" on a shorter record: allantools' loops are slow there, not ours.
GRIDS = [None, "octave", "decade", "log10", "all", [0.3, 1.0, 2.5, 7.0, 40.0, 1e9], 3.0]


def same(ours, theirs):
    taus, devs, errs, ns = ours
    want_taus, want_devs, want_errs, want_ns = theirs
    np.testing.assert_array_equal(taus, want_taus)
    np.testing.assert_array_equal(ns, want_ns)
    assert ns.dtype == want_ns.dtype == np.float64
    np.testing.assert_allclose(devs, want_devs, rtol=1e-9, atol=0)
    np.testing.assert_allclose(errs, want_errs, rtol=1e-9, atol=0)


@pytest.mark.parametrize("name", ESTIMATORS)
@pytest.mark.parametrize("data_type", ["freq", "phase"])
@pytest.mark.parametrize("taus", GRIDS, ids=str)
def test_equals_allantools(white_and_walk, name, data_type, taus):
    data = white_and_walk[:2000] if taus == "all" else white_and_walk
    if data_type == "phase":
        data = np.cumsum(data)
    theirs = getattr(allantools, name)(data, rate=4.0, data_type=data_type, taus=taus)
    ours = getattr(imunoise, name)(data, rate=4.0, data_type=data_type, taus=taus)
    same(ours, theirs)


def test_default_arguments_are_allantools(white_and_walk):
    x = np.cumsum(white_and_walk)
    same(imunoise.oadev(x), allantools.oadev(x))


def test_strided_and_integer_input_are_converted(white_and_walk):
    strided = white_and_walk[::2]
    assert not strided.flags.c_contiguous
    same(
        imunoise.mdev(strided, rate=2.0, data_type="freq"),
        allantools.mdev(np.ascontiguousarray(strided), rate=2.0, data_type="freq"),
    )
    counts = np.round(white_and_walk * 100).astype(np.int16)
    same(
        imunoise.ohdev(counts, rate=2.0, data_type="freq"),
        allantools.ohdev(counts.astype(np.float64), rate=2.0, data_type="freq"),
    )
    as_list = list(white_and_walk[:500])
    same(imunoise.adev(as_list), allantools.adev(np.array(as_list)))


def test_docstrings_name_the_equation():
    assert "eq. 11" in imunoise.oadev.__doc__
    assert imunoise.totdev.__name__ == "totdev"
