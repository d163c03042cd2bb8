"""Bad input raises ValueError or TypeError with a message that names what is wrong;
nothing panics."""

import numpy as np
import pytest

import imunoise

X = np.random.default_rng(1).normal(size=1000)


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda: imunoise.oadev(["a", "b"]), TypeError, "real numbers"),
        (lambda: imunoise.oadev(np.ones(10) + 1j), TypeError, "real numbers"),
        (lambda: imunoise.oadev(np.ones((3, 3))), ValueError, "one-dimensional"),
        (lambda: imunoise.oadev([]), ValueError, "empty"),
        (lambda: imunoise.oadev(np.r_[X, np.nan]), ValueError, r"data\[1000\] is NaN"),
        (lambda: imunoise.oadev(X, rate=0.0), ValueError, "positive"),
        (lambda: imunoise.oadev(X, rate="fast"), TypeError, "rate"),
        (lambda: imunoise.oadev(X, data_type="angle"), ValueError, "'phase' or 'freq'"),
        (lambda: imunoise.oadev(X, taus="weekly"), ValueError, "octave"),
        (lambda: imunoise.oadev(X, taus=[1e9]), ValueError, "no tau has two terms"),
        (lambda: imunoise.analyze(X), TypeError, "rate"),
        (lambda: imunoise.analyze(X, rate=-1.0), ValueError, "positive"),
        (lambda: imunoise.analyze(X[:5], rate=10.0), ValueError, "at least 16"),
        (lambda: imunoise.analyze(np.ones(100), rate=10.0), ValueError, "constant"),
        (lambda: imunoise.analyze(X, rate=10.0, estimators="avar"), ValueError, "unknown estimator"),
        (lambda: imunoise.analyze(X, rate=10.0, taus="x"), ValueError, "tau grid"),
        (lambda: imunoise.analyze(X, rate=10.0, confidence=2.0), ValueError, "confidence"),
        (lambda: imunoise.analyze(X, rate=10.0, bandwidth="wide"), ValueError, "bandwidth"),
        (lambda: imunoise.analyze(X, rate=10.0, psd_segment=1), ValueError, "psd_segment"),
        (lambda: imunoise.analyze(X, rate=10.0, psd_segment=-1), ValueError, "psd_segment -1"),
        (lambda: imunoise.analyze(X, rate=10.0, frobnicate=1), TypeError, "frobnicate"),
        (lambda: imunoise.analyze(X, rate=10.0, names=["a", "b"]), ValueError, "2 names for 1"),
        (lambda: imunoise.analyze({"a": X, "b": X[:500]}, rate=10.0), ValueError, "same length"),
        (lambda: imunoise.analyze(np.ones((2, 2, 2)), rate=10.0), ValueError, "shape"),
        (lambda: imunoise.filter_noise(X, rate=10.0, period=-1.0), ValueError, "filter_period"),
        (lambda: imunoise.psd(X, 10.0, segment=5000), ValueError, "segment"),
        (lambda: imunoise.psd(X, 10.0, segment=-3), ValueError, "segment -3"),
        (lambda: imunoise.psd(X, 10.0, window="kaiser"), ValueError, "window"),
        (lambda: imunoise.load("/nonexistent/imunoise.csv"), OSError, "nonexistent"),
    ],
)
def test_bad_input_is_named(call, error, message):
    with pytest.raises(error, match=message):
        call()


def test_bad_file_content_names_the_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("gx,gy\n1,2\n3,x\n")
    with pytest.raises(ValueError, match="bad.csv"):
        imunoise.load(path, rate=10.0)


def test_missing_store(tmp_path):
    with pytest.raises(ValueError, match="store"):
        imunoise.load_session("1", store=tmp_path / "none")
