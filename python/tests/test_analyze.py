"""The whole analysis from Python: the document of `imunoise analyze --json`, its N on
white noise of known density, and the ways to hand over channels."""

import numpy as np
import pytest

import imunoise
from conftest import white_gyro

RATE = 100.0
DENSITY = 2e-3  # rad/s/sqrt(Hz)


@pytest.fixture(scope="module")
def gyro():
    return white_gyro(DENSITY, RATE, 200_000, seed=7)


def test_document_has_the_cli_shape(gyro):
    doc = imunoise.analyze(gyro, rate=RATE)
    for key in ("tool", "rate_hz", "samples", "channels", "conventions", "input", "kalibr"):
        assert key in doc
    assert doc["rate_hz"] == RATE and doc["samples"] == gyro.size
    channel = doc["channels"][0]
    assert channel["name"] == "c0"
    assert set(channel["deviations"]) == {"oadev"}


def test_white_noise_density_within_its_interval(gyro):
    n = imunoise.analyze(gyro, rate=RATE)["channels"][0]["noise"]["N"]
    # The interval is 68.3 % two-sided: three half-widths make a miss a 3-sigma event.
    half = (n["hi"] - n["lo"]) / 2
    assert abs(n["value"] - DENSITY) < 3 * half, n
    assert half < 0.01 * DENSITY, "200 000 samples pin N to better than 1 %"


def test_two_d_array_dict_and_names_agree(gyro):
    other = white_gyro(3e-3, RATE, gyro.size, seed=8)
    by_array = imunoise.analyze(np.c_[gyro, other], rate=RATE, names=["gx", "ax"])
    by_dict = imunoise.analyze({"gx": gyro, "ax": other}, rate=RATE)
    assert by_array["channels"] == by_dict["channels"]
    gx, ax = by_array["channels"]
    assert (gx["name"], gx["unit"], ax["unit"]) == ("gx", "rad/s", "m/s^2")
    single = imunoise.analyze({"gx": gyro}, rate=RATE)["channels"][0]
    assert single == gx


def test_options_are_the_cli_options(gyro):
    doc = imunoise.analyze(
        gyro,
        rate=RATE,
        estimators=["adev", "totdev", "adev"],
        taus="octave",
        confidence=0.95,
        bandwidth="off",
        data_type="rate",
    )
    assert doc["confidence"] == 0.95
    assert list(doc["channels"][0]["deviations"]) == ["adev", "totdev"]
    m = doc["channels"][0]["deviations"]["adev"]["m"]
    assert m == [2**k for k in range(len(m))]


def test_fit_filter_and_kalibr(gyro):
    names = ["gx", "gy", "gz", "ax", "ay", "az"]
    six = np.column_stack([white_gyro(DENSITY, RATE, 50_000, seed=s) for s in range(6)])
    fits = imunoise.fit(six, RATE, names=names)
    assert list(fits) == names and fits["gx"]["noise"]["N"]["unit"] == "rad/s/sqrt(Hz)"
    filt = imunoise.filter_noise(six, RATE, period=0.01, names=names)
    assert filt["period_s"] == 0.01 and len(filt["channels"]) == 6
    yaml = imunoise.kalibr(six, RATE, names=names)
    assert "gyroscope_noise_density" in yaml and "accelerometer_random_walk" in yaml
    with pytest.raises(ValueError, match="no Kalibr YAML"):
        imunoise.kalibr({"temp": gyro}, RATE)


def test_psd_of_white_noise(gyro):
    freq, density = imunoise.psd(gyro, RATE)
    assert freq[0] == 0.0 and freq[-1] == RATE / 2
    # One-sided PSD of white noise is 2 N^2; the mean of thousands of bins is within 2 %.
    assert abs(density[1:-1].mean() / (2 * DENSITY**2) - 1) < 0.02


def test_load_a_table_and_analyze_the_record(tmp_path, gyro):
    path = tmp_path / "gyro.csv"
    np.savetxt(path, np.c_[gyro[:5000], gyro[5000:10000]], delimiter=",", header="gx,gy", comments="")
    record = imunoise.load(path, rate=RATE)
    assert list(record.channels) == ["gx", "gy"] and record.rate == RATE
    np.testing.assert_allclose(record.channels["gy"], gyro[5000:10000], rtol=1e-15)
    doc = imunoise.analyze(record)
    assert doc["source"] == str(path) and doc["rate_hz"] == RATE
    npy = tmp_path / "x.npy"
    np.save(npy, gyro[:4000])
    assert imunoise.load(npy, rate=50.0).channels["c0"].size == 4000


def test_model_fits_the_white_gyro():
    gyro = white_gyro(DENSITY, RATE, 30_000, seed=11)
    doc = imunoise.model({"gx": gyro}, rate=RATE, realisations=6)
    assert doc["channel"] == "gx" and doc["realisations"] == 6
    n = doc["baseline_fit"]["n"]
    # The 68.3 % interval of the baseline fit; three half-widths as above.
    assert abs(n["value"] - DENSITY) < 3 * (n["hi"] - n["lo"]) / 2, n
    with pytest.raises(ValueError, match="nope"):
        imunoise.model({"gx": gyro}, rate=RATE, column="nope", realisations=2)
