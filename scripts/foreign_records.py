#!/usr/bin/env python3
"""Hidden-effect records made outside imunoise, and what `imunoise model` names in them.

The model workflow judges every record against realisations of its own simulator, and the
family studies (`host/src/model/families.rs`) build their records with that simulator too. A
record from another lab's generator could differ from both in ways no effect explains. This
script builds the families' kinds with numpy and scipy only, by other methods:

- white rate noise of density N: per-sample standard deviation N sqrt(f_s);
- flicker of level B: white noise shaped in the frequency domain to the one-sided PSD
  B^2 / (pi f) (IEEE 952 Table C.1: two-sided B^2 / (2 pi f)) over four times the record's
  length, the first quarter kept (power below 1 / T, no wrap-around);
- rate random walk K: the running sum of white increments of variance K^2 / f_s;
- a Gauss-Markov process: the exact first-order autoregression (scipy.signal.lfilter);
- a low-pass filter: scipy.signal.butter's second-order Butterworth (bilinear, -3 dB at the
  cutoff) on the white noise only, so that flicker and the random walk reach the stopband;
- a comb of two to four lines (`comb`, after `lowpass` in a kind such as `lowpass+comb`):
  pure sinusoids of random phase, or resonances 2-50 mHz wide made as second-order
  autoregressions driven by white noise (pole radius exp(-pi w / f_s) for a full width w at
  half maximum), each 20-100 times the (filtered) white PSD at its peak, where the filter
  passes a tenth of the power or more, and forty widths apart.

Levels and effect strengths are drawn from the families' ranges: N log-uniform 5e-5..5e-4,
B = N x 0.03..0.12, the random walk crossing N at 0.1..0.3 of the record; the Gauss-Markov
process (tau_c 1-3 % of the record), slow sinusoid (period 5-20 % of it), ramp (at T/4) and
temperature coupling (warm-up and a cycle, at T/8) raising the Allan deviation 2-3.5 times
(ramps 3-5) where they show; the filter's cutoff 3-30 % of the rate.

Usage (numpy and scipy installed; the imunoise executable built with `cargo build --release`):

    python3 scripts/foreign_records.py --imunoise target/release/imunoise \
        --kinds none,none_temp,gm,sin,ramp,temp,lowpass --seeds 1-10 --out /tmp/foreign

A kind may join effects with "+" (`--kinds gm+sin,gm+temp,lowpass+gm`): each effect's
strength is drawn against the baseline alone, as for the single kinds, so where one effect
puts more power than the baseline at the other's frequencies it can hide the other.

Beside each record's verdict it prints each deterministic effect's known-noise evidence:
2 ln of the likelihood ratio the effect leaves with its shape and the record's noise
spectrum known (`known_noise_evidence`), the most any test could see. A calibrated test
that searches the noise levels, as `model` must, needs well over 10 to name an effect at
its threshold, so a miss at a few units is the record's limit, not the workflow's.

It prints, per kind, how many records were named exactly right (B and K aside, as in the
family study) and, for the filter, how often `analyze`'s 68.3 % cutoff interval holds the
truth.
"""
import argparse
import json
import pathlib
import subprocess

import numpy as np
from scipy.fft import dct
from scipy.signal import butter, freqz, lfilter

EXPECTED = {
    "none": [],
    "none_temp": [],
    "gm": ["gauss_markov"],
    "sin": ["sinusoid"],
    "ramp": ["rate_ramp"],
    "temp": ["temperature"],
    "lowpass": ["low_pass"],
    # One sinusoid per line drawn: `expected` reads the count from the record's truth.
    "comb": [],
}


def expected(kind, truth):
    """The effect kinds `model` should name in a record of `kind` ("gm", "gm+sin", ...)."""
    lines = ["sinusoid"] * int(truth.get("lines", 0))
    return sorted([e for part in kind.split("+") for e in EXPECTED[part]] + lines)


def comb(rng, n, rate, white_psd, gain):
    """Two to four lines of a comb (module documentation): their sum and their count."""
    tau0 = 1.0 / rate
    t_rec = n * tau0
    top = 0.45 * rate
    while gain(top) < 0.1:
        top *= 0.99
    bottom = min(0.1 * rate, 0.5 * top)
    drawn = []
    for _ in range(rng.integers(2, 5)):
        for _ in range(1000):
            freq = rng.uniform(bottom, top)
            width = 0.0 if rng.uniform() < 0.3 else log_uniform(rng, 0.002, 0.05)
            if all(abs(freq - g) > 40 * (width + v) + 20 / t_rec for g, v in drawn):
                drawn.append((freq, width))
                break
    total = np.zeros(n)
    t = np.arange(n) * tau0
    for freq, width in drawn:
        peak = log_uniform(rng, 20.0, 100.0) * white_psd * gain(freq)
        if width == 0.0:
            # A sinusoid's power A^2 / 2 in one bin of width 1 / T.
            amplitude = np.sqrt(2 * peak / t_rec)
            total += amplitude * np.sin(2 * np.pi * freq * t + rng.uniform(0, 2 * np.pi))
        else:
            r = np.exp(-np.pi * width * tau0)
            a = [1.0, -2 * r * np.cos(2 * np.pi * freq * tau0), r * r]
            # One-sided PSD 2 s^2 tau0 / |A(e^iw)|^2 at the line's own frequency.
            z = np.exp(-2j * np.pi * freq * tau0)
            denominator = abs(a[0] + a[1] * z + a[2] * z * z) ** 2
            drive = np.sqrt(peak * denominator / (2 * tau0))
            total += lfilter([1.0], a, drive * rng.standard_normal(n))
    return total, len(drawn)


def log_uniform(rng, lo, hi):
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def flicker(rng, b, n, tau0):
    """Flicker of level b over n samples, shaped over 4 n and cropped."""
    m = 4 * n
    f = np.fft.rfftfreq(m, tau0)
    psd = np.zeros(len(f))
    psd[1:] = b * b / (np.pi * f[1:])
    # Unit-variance white noise has the one-sided PSD 2 tau0.
    spectrum = np.fft.rfft(rng.standard_normal(m)) * np.sqrt(psd / (2.0 * tau0))
    return np.fft.irfft(spectrum, m)[:n]


def temperature(rng, t, t_rec):
    rise, warm = rng.uniform(2, 6), rng.uniform(600, 2400)
    swing, cycle = rng.uniform(0.5, 2), t_rec * rng.uniform(0.15, 0.4)
    start = rng.uniform(20, 30)
    return start + rise * (1 - np.exp(-t / warm)) + swing * np.sin(2 * np.pi * t / cycle)


def record(kind, seed, rate, hours):
    """(rate samples, temperature or None, truth, known-noise evidence) for one record."""
    rng = np.random.default_rng(seed)
    n = int(rate * hours * 3600)
    tau0 = 1.0 / rate
    t_rec = n * tau0
    t = np.arange(n) * tau0
    big_n = log_uniform(rng, 5e-5, 5e-4)
    big_b = big_n * log_uniform(rng, 0.03, 0.12)
    big_k = np.sqrt(3) * big_n / (t_rec * rng.uniform(0.1, 0.3))
    white = big_n / np.sqrt(tau0) * rng.standard_normal(n)
    y = white + flicker(rng, big_b, n, tau0)
    y += np.cumsum(big_k * np.sqrt(tau0) * rng.standard_normal(n))

    def baseline_avar(tau):
        return big_n**2 / tau + 2 * np.log(2) / np.pi * big_b**2 + big_k**2 * tau / 3

    def raise_by(lo=2.0, hi=3.5):
        f = rng.uniform(lo, hi)
        return f * f - 1

    truth = {"N": big_n, "B": big_b, "K": big_k}
    temp = None
    signals = {}
    gauss_markov = None
    filter_gain = lambda f: 1.0
    # A pair such as "gm+sin" draws each effect's strength against the baseline alone, so
    # either could be named on its own; together one may hide behind the other.
    for effect in kind.split("+"):
        if effect == "gm":
            tau_c = t_rec * log_uniform(rng, 0.01, 0.03)
            peak = 1.89 * tau_c
            r = peak / tau_c
            unit = (tau_c / peak) ** 2 * (2 * r - 3 + 4 * np.exp(-r) - np.exp(-2 * r))
            sigma = np.sqrt(raise_by() * baseline_avar(peak) / unit)
            a = np.exp(-tau0 / tau_c)
            drive = sigma * np.sqrt(1 - a * a) * rng.standard_normal(n)
            start = sigma * rng.standard_normal()
            y += lfilter([1.0], [1.0, -a], drive, zi=[a * start])[0]
            truth.update(tau_c=tau_c, sigma=sigma)
            gauss_markov = (sigma, tau_c)
        elif effect == "sin":
            freq = 1.0 / (t_rec * rng.uniform(0.05, 0.2))
            peak = 0.371 / freq
            unit = np.sin(np.pi * freq * peak) ** 4 / (np.pi * freq * peak) ** 2
            amplitude = np.sqrt(raise_by() * baseline_avar(peak) / unit)
            phase = rng.uniform(0, 2 * np.pi)
            signals["sinusoid"] = amplitude * np.sin(2 * np.pi * freq * t + phase)
            y += signals["sinusoid"]
            truth.update(freq_hz=freq, amplitude=amplitude)
        elif effect == "ramp":
            tau = t_rec / 4
            slope = np.sqrt(raise_by(3.0, 5.0) * baseline_avar(tau) * 2 / tau**2)
            slope *= rng.choice([-1, 1])
            signals["rate_ramp"] = slope * t
            y += signals["rate_ramp"]
            truth.update(slope=slope)
        elif effect in ("temp", "none_temp"):
            temp = temperature(rng, t, t_rec)
            if effect == "temp":
                m = int(t_rec / 8 / tau0)
                means = temp[: (n // m) * m].reshape(-1, m).mean(axis=1)
                temp_avar = np.mean(np.diff(means) ** 2) / 2
                coeff = np.sqrt(raise_by() * baseline_avar(t_rec / 8) / temp_avar)
                coeff *= rng.choice([-1, 1])
                signals["temperature"] = coeff * (temp - temp[0])
                y += signals["temperature"]
                truth.update(coeff=coeff)
            temp = temp + 0.01 * rng.standard_normal(n)
        elif effect == "lowpass":
            cutoff = rate * log_uniform(rng, 0.03, 0.3)
            b, a = butter(2, cutoff / (rate / 2))
            y += lfilter(b, a, white) - white
            truth.update(cutoff_hz=cutoff)
            filter_gain = lambda f, b=b, a=a: float(abs(freqz(b, a, [f], fs=rate)[1][0]) ** 2)
        elif effect == "comb":
            lines, count = comb(rng, n, rate, 2 * big_n**2, filter_gain)
            y += lines
            truth.update(lines=count)
        elif effect != "none":
            raise SystemExit(f"unknown effect {effect!r} in kind {kind!r}")

    def one_sided_psd(f):
        """The record's noise PSD (u^2/Hz, one-sided; IEEE 952 Table C.1 doubled)."""
        s = 2 * big_n**2 + big_b**2 / (np.pi * f) + 2 * big_k**2 / (2 * np.pi * f) ** 2
        if gauss_markov:
            sigma, tau_c = gauss_markov
            s += 4 * sigma**2 * tau_c / (1 + (2 * np.pi * f * tau_c) ** 2)
        return s

    evidence = {name: known_noise_evidence(x, one_sided_psd, tau0)
                for name, x in signals.items()}
    return y + rng.uniform(-0.02, 0.02), temp, truth, evidence


# Highest frequency the known-noise evidence sums over, Hz: the slow effects' content lies
# far below it (as in the model's cosine view).
EVIDENCE_HIGHEST_HZ = 1.0


def known_noise_evidence(signal, one_sided_psd, tau0):
    """2 ln of the likelihood ratio a deterministic effect of known shape leaves against the
    record's noise of known spectrum: the most any test can see of it.

    On the orthonormal DCT-II of n samples, coefficient k (frequency k / (2 n tau0)) of
    stationary noise has variance close to S(f) / (2 tau0), S one-sided (exact for white
    noise and, past the mean, for a random walk), and the coefficients are nearly
    independent, so the ratio is sum_k c_k^2 / var_k over the effect's coefficients c_k,
    from k = 1 (the mean is not evidence) to 1 Hz.
    """
    n = len(signal)
    top = min(n, int(2 * n * tau0 * EVIDENCE_HIGHEST_HZ))
    c = dct(signal, type=2, norm="ortho")[1:top]
    f = np.arange(1, top) / (2 * n * tau0)
    return float(np.sum(c * c / (one_sided_psd(f) / (2 * tau0))))


def write(path, y, temp):
    if temp is None:
        path = path.with_suffix(".npy")
        np.save(path, y)
    else:
        path = path.with_suffix(".csv")
        np.savetxt(path, np.column_stack([y, temp]), delimiter=",", fmt="%.9e",
                   header="gx,temp", comments="")
    return path


def seeds_of(text):
    lo, _, hi = text.partition("-")
    return range(int(lo), int(hi or lo) + 1)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--imunoise", required=True)
    p.add_argument("--kinds", default=",".join(EXPECTED))
    p.add_argument("--seeds", default="1-10")
    p.add_argument("--rate", type=float, default=50.0)
    p.add_argument("--hours", type=float, default=3.0)
    p.add_argument("--out", default="foreign-records")
    args = p.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    store = out / "store"
    for kind in args.kinds.split(","):
        right, held, seeds = 0, 0, list(seeds_of(args.seeds))
        has_filter = "lowpass" in kind.split("+")
        for seed in seeds:
            y, temp, truth, evidence = record(kind, seed, args.rate, args.hours)
            data = write(out / f"{kind}_{seed}", y, temp)
            result = out / f"{kind}_{seed}.model.json"
            subprocess.run([args.imunoise, "--store", str(store), "model", str(data),
                            "--rate", str(args.rate), "--json", str(result)],
                           check=True, capture_output=True)
            steps = json.loads(result.read_text())["steps"]
            named = sorted(s["effect"]["kind"] for s in steps
                           if s["effect"]["kind"] not in ("bias_instability", "rate_random_walk"))
            right += named == expected(kind, truth)
            hidden = ", ".join(f"{k} {float(v):.4g}" for k, v in truth.items())
            line = f"{kind} seed {seed}: named {named}; hidden {hidden}"
            if evidence:
                line += "; known-noise evidence " + ", ".join(
                    f"{k} {v:.1f}" for k, v in evidence.items())
            if has_filter:
                analysis = out / f"{kind}_{seed}.analyze.json"
                subprocess.run([args.imunoise, "--store", str(store), "analyze", str(data),
                                "--rate", str(args.rate), "--json", str(analysis)],
                               check=True, capture_output=True)
                lp = json.loads(analysis.read_text())["channels"][0]["low_pass"]
                if lp:
                    inside = lp["cutoff_lo_hz"] <= truth["cutoff_hz"] <= lp["cutoff_hi_hz"]
                    held += inside
                    line += (f"; cutoff {lp['cutoff_hz']:.4f} [{lp['cutoff_lo_hz']:.4f}, "
                             f"{lp['cutoff_hi_hz']:.4f}] Hz")
            print(line, flush=True)
        print(f"{kind}: {right}/{len(seeds)} named exactly right", flush=True)
        if has_filter:
            print(f"{kind}: the 68.3 % cutoff interval held the truth on {held}/{len(seeds)}",
                  flush=True)


if __name__ == "__main__":
    main()
