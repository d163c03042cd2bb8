use super::*;
use crate::analysis::{Deviation, Estimator, phase_from_rate};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};

const RATE: f64 = 100.0;

fn model(c: [f64; TERMS], tau: f64) -> f64 {
    let theta = c.map(|x| x * x);
    basis(tau).iter().zip(theta).map(|(a, t)| a * t).sum()
}

fn log_taus(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

fn values(fit: &NoiseFit) -> [Term; TERMS] {
    [fit.q, fit.n, fit.b, fit.k, fit.r]
}

#[test]
fn exact_curves_are_recovered() {
    // Points so precise (edf 1e10 / tau) that every term of the cases is detected.
    let tau = log_taus(0.01, 1e4, 40);
    let edf: Vec<f64> = tau.iter().map(|t| 1e10 / t).collect();
    let cases: [[f64; TERMS]; 5] = [
        [2e-5, 1e-3, 4e-5, 2e-5, 3e-8],
        [0.0, 1e-3, 0.0, 2e-5, 0.0],
        [0.0, 1e-3, 4e-5, 2e-5, 0.0],
        [0.0, 3e-2, 0.0, 0.0, 0.0],
        [1e-4, 0.0, 1e-3, 0.0, 1e-7],
    ];
    for c in cases {
        let avar: Vec<f64> = tau.iter().map(|&t| model(c, t)).collect();
        let fit = fit_allan(&tau, &avar, &edf).unwrap();
        let peak = avar.iter().cloned().fold(0.0, f64::max);
        for (j, (term, truth)) in values(&fit).iter().zip(c).enumerate() {
            if truth > 0.0 {
                assert!(
                    (term.value / truth - 1.0).abs() < 1e-6,
                    "case {c:?} term {j}: {} vs {truth}",
                    term.value
                );
                assert!(term.lo <= term.value && term.value <= term.hi);
            } else {
                // A zero term contributes nothing visible anywhere on the curve.
                let most = tau
                    .iter()
                    .map(|&t| basis(t)[j] * term.value * term.value)
                    .fold(0.0, f64::max);
                assert!(most <= 1e-9 * peak, "case {c:?} term {j}: {}", term.value);
                assert_eq!(term.lo, 0.0);
            }
        }
        assert!(fit.reduced_chi2 < 1e-12);
    }
}

#[test]
fn bad_inputs_are_errors() {
    let t = [1.0, 2.0];
    assert_eq!(
        fit_allan(&t, &[1.0], &[1.0, 1.0]),
        Err(FitError::LengthMismatch {
            tau: 2,
            avar: 1,
            edf: 2
        })
    );
    assert_eq!(fit_allan(&[], &[], &[]), Err(FitError::TooFewPoints(0)));
    assert!(matches!(
        fit_allan(&t, &[1.0, f64::NAN], &[1.0, 1.0]),
        Err(FitError::NotPositive {
            what: "avar",
            index: 1,
            ..
        })
    ));
    assert!(matches!(
        fit_allan(&[0.0, 1.0], &[1.0, 1.0], &[1.0, 1.0]),
        Err(FitError::NotPositive {
            what: "tau",
            index: 0,
            ..
        })
    ));
    let opts = FitOptions {
        confidence: 1.0,
        ..FitOptions::default()
    };
    assert_eq!(
        fit_allan_with(&t, &[1.0, 1.0], &[1.0, 1.0], &opts),
        Err(FitError::BadConfidence(1.0))
    );
}

#[test]
fn underdetermined_curves_do_not_panic() {
    // Two points, five unknowns: a solution exists; unseparable terms get hi = infinity
    // or a finite bound, never a panic or NaN.
    let fit = fit_allan(&[1.0, 2.0], &[1e-6, 6e-7], &[100.0, 50.0]).unwrap();
    for t in values(&fit) {
        assert!(
            t.value.is_finite() && t.lo <= t.value && t.value <= t.hi,
            "{t:?}"
        );
    }
    // One term may explain both points within their scatter (relative s.d. 0.14 and 0.2).
    assert!((fit.avar(1.0) / 1e-6 - 1.0).abs() < 0.3, "{fit:?}");
    assert!(serde_json::to_string(&fit).is_ok());
    // Extreme dynamic range of tau.
    let tau = log_taus(1e-4, 1e6, 30);
    let avar: Vec<f64> = tau
        .iter()
        .map(|&t| model([0.0, 1.0, 0.0, 1e-3, 0.0], t))
        .collect();
    let fit = fit_allan(&tau, &avar, &vec![3.0; 30]).unwrap();
    assert!((fit.n.value - 1.0).abs() < 1e-6 && (fit.k.value / 1e-3 - 1.0).abs() < 1e-6);
}

/// Fraction of seeds whose interval contains the truth, per term, and the median relative
/// half-width `(hi - lo) / (2 truth)` per term (NaN for zero terms).
fn coverage(fits: &[NoiseFit], truth: [f64; TERMS]) -> ([f64; TERMS], [f64; TERMS]) {
    let mut cover = [0.0; TERMS];
    let mut width = [f64::NAN; TERMS];
    for j in 0..TERMS {
        let inside = fits
            .iter()
            .filter(|f| {
                let t = values(f)[j];
                t.lo <= truth[j] && truth[j] <= t.hi
            })
            .count();
        cover[j] = inside as f64 / fits.len() as f64;
        if truth[j] > 0.0 {
            let mut w: Vec<f64> = fits
                .iter()
                .map(|f| (values(f)[j].hi - values(f)[j].lo) / (2.0 * truth[j]))
                .collect();
            w.sort_by(f64::total_cmp);
            width[j] = w[w.len() / 2];
        }
    }
    (cover, width)
}

#[test]
fn chi_squared_perturbed_curves_are_covered() {
    // Octave taus of a 100 Hz, 2^20-sample record; edf ~ 1.5 T / tau (white-noise-like).
    let truth = [0.0, 1e-3, 1.5e-3, 1.7e-4, 0.0];
    let tau: Vec<f64> = (0..18).map(|k| (1u64 << k) as f64 / RATE).collect();
    let t_rec = (1u64 << 20) as f64 / RATE;
    let edf: Vec<f64> = tau.iter().map(|t| (1.5 * t_rec / t).max(2.0)).collect();
    let opts = FitOptions {
        confidence: 0.95,
        ..FitOptions::default()
    };
    let fits: Vec<NoiseFit> = (0..50)
        .map(|seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            let avar: Vec<f64> = tau
                .iter()
                .zip(&edf)
                .map(|(&t, &e)| {
                    let x: f64 = ChiSquared::new(e).unwrap().sample(&mut rng);
                    model(truth, t) * x / e
                })
                .collect();
            fit_allan_with(&tau, &avar, &edf, &opts).unwrap()
        })
        .collect();
    let (cover, width) = coverage(&fits, truth);
    println!("independent chi2: coverage {cover:?}, median half-width {width:?}");
    for (j, c) in cover.iter().enumerate() {
        assert!(*c >= 0.9, "term {j}: 95 % intervals cover {c}");
    }
    // Not absurdly wide: N is pinned by the short-tau points (edf ~ 1e6 at tau0: relative
    // s.d. of one AVAR point 1.4e-3, of N half that); even with the correlation inflation
    // the 95 % half-width stays below 1 %. K lives on the last few octaves (edf ~ 2..50):
    // one point at edf 20 alone gives a 95 % half-width of ~ 0.6 in K^2, ~ 0.3 in K.
    assert!(width[N] < 0.01, "N half-width {}", width[N]);
    assert!(width[K] < 0.4, "K half-width {}", width[K]);
    assert!(width[B] < 1.0, "B half-width {}", width[B]);
}

// ---- test-only scaffolding: series, a plain overlapping AVAR and textbook edf ----

/// White rate noise of Allan coefficient `n` plus rate random walk of coefficient `k`,
/// sampled at RATE: y = n sqrt(rate) w1 + b, b[i+1] = b[i] + k sqrt(tau0) w2.
fn white_plus_rrw(len: usize, n: f64, k: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (sw, sb) = (n * RATE.sqrt(), k / RATE.sqrt());
    let mut bias = 0.0;
    (0..len)
        .map(|_| {
            let w1: f64 = StandardNormal.sample(&mut rng);
            let w2: f64 = StandardNormal.sample(&mut rng);
            bias += sb * w2;
            sw * w1 + bias
        })
        .collect()
}

/// Test-only overlapping AVAR (IEEE Std 1139-2008 formula) at the given averaging factors.
fn oavar(y: &[f64], ms: &[usize]) -> Vec<f64> {
    let tau0 = 1.0 / RATE;
    let x = phase_from_rate(y, tau0);
    ms.iter()
        .map(|&m| {
            let terms = x.len() - 2 * m;
            let s: f64 = (0..terms)
                .map(|i| (x[i + 2 * m] - 2.0 * x[i + m] + x[i]).powi(2))
                .sum();
            s / (2.0 * (m as f64 * tau0).powi(2) * terms as f64)
        })
        .collect()
}

/// Textbook edf of the overlapping AVAR (Howe, Allan & Barnes 1981; NIST SP 1065 Table 6)
/// for white FM and random-walk FM, `np` phase points, factor m; mixed by each process's
/// share of the AVAR: 1/edf = f_w / edf_w + f_k / edf_k.
fn edf_mix(np: usize, m: usize, share_white: f64) -> f64 {
    let (n, m) = (np as f64, m as f64);
    let white =
        (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0);
    let rrw =
        (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m) / (n - 3.0).powi(2);
    1.0 / (share_white / white + (1.0 - share_white) / rrw)
}

fn series_fits(confidence: f64, seeds: u64) -> (Vec<NoiseFit>, [f64; TERMS]) {
    let (n, k) = (1e-3, 2e-4);
    let truth = [0.0, n, 0.0, k, 0.0];
    let len = 1 << 18;
    let ms: Vec<usize> = (0..16).map(|e| 1usize << e).collect();
    let tau: Vec<f64> = ms.iter().map(|&m| m as f64 / RATE).collect();
    let edf: Vec<f64> = ms
        .iter()
        .zip(&tau)
        .map(|(&m, &t)| {
            let share = (n * n / t) / model(truth, t);
            edf_mix(len + 1, m, share)
        })
        .collect();
    let opts = FitOptions {
        confidence,
        ..FitOptions::default()
    };
    let fits = (0..seeds)
        .map(|seed| {
            let y = white_plus_rrw(len, n, k, 500 + seed);
            let avar = oavar(&y, &ms);
            fit_allan_with(&tau, &avar, &edf, &opts).unwrap()
        })
        .collect();
    (fits, truth)
}

#[test]
fn time_series_fits_are_covered() {
    // 2^18 samples at 100 Hz (44 min) of white (N = 1e-3) + rate random walk (K = 2e-4),
    // octave taus 0.01 .. 328 s: the real correlated-estimate situation.
    let (fits, truth) = series_fits(0.95, 50);
    let (cover, width) = coverage(&fits, truth);
    let neff = fits.iter().map(|f| f.effective_points).sum::<f64>() / fits.len() as f64;
    println!(
        "series, 95 %: coverage {cover:?}, median half-width {width:?}, mean n_eff {neff:.1} of {}",
        fits[0].points
    );
    for (j, c) in cover.iter().enumerate() {
        assert!(*c >= 0.9, "term {j}: 95 % intervals cover {c}");
    }
    // Widths: N from ~1e5-edf points (relative s.d. of N ~ 0.3 %): below 2 %. K from the
    // last octaves (edf 2..20): a single point at edf 10 gives a 95 % half-width ~ 0.45
    // in K; the combined fit must do better than 0.5.
    assert!(width[N] < 0.02, "N half-width {}", width[N]);
    assert!(width[K] < 0.5, "K half-width {}", width[K]);
}

#[test]
fn time_series_one_sigma_intervals_are_not_inflated_absurdly() {
    // 68.3 % intervals should cover about 68 %: at least 50 % (binomial 50 seeds:
    // 68 +- 2 x 6.6) and, if the correlation inflation were absurd, they would cover
    // (nearly) all seeds.
    let (fits, truth) = series_fits(0.683, 50);
    let (cover, _) = coverage(&fits, truth);
    println!("series, 68.3 %: coverage {cover:?}");
    for j in [N, K] {
        assert!(
            cover[j] >= 0.5 && cover[j] <= 0.96,
            "term {j}: coverage {}",
            cover[j]
        );
    }
}

#[test]
fn slope_readouts_of_white_plus_rrw() {
    // N = 1e-3, K = 1.7e-3: the curves cross at tau = sqrt(3) N / K ~ 1 s.
    let (n, k) = (1e-3, 1.7e-3);
    let len = 1 << 20;
    let y = white_plus_rrw(len, n, k, 42);
    let ms: Vec<usize> = (0..36)
        .map(|i| (2f64.powf(i as f64 / 2.0)).round() as usize)
        .collect();
    let tau: Vec<f64> = ms.iter().map(|&m| m as f64 / RATE).collect();
    let adev: Vec<f64> = oavar(&y, &ms).iter().map(|v| v.sqrt()).collect();
    let r = slope_readouts(&tau, &adev);
    let rn = r.n.expect("a -1/2 region");
    let rk = r.k.expect("a +1/2 region");
    println!("{r:?}");
    // N: the run reaches slope -0.4 where K adds ~5 % to adev; statistically the short-tau
    // points have edf > 1e4 (< 1 %). Allow 6 %.
    assert!((rn.value / n - 1.0).abs() < 0.06, "N {}", rn.value);
    assert!(rn.tau_max < 1.0);
    // K: long-tau points (edf ~ 3..100, adev s.d. ~ 5..40 %); the run averages several.
    assert!((rk.value / k - 1.0).abs() < 0.3, "K {}", rk.value);
    assert!(rk.tau_min > 1.0);
    // The minimum lies at the crossover, where adev = sqrt(2) * N / sqrt(tau_c).
    let b = r.b.expect("an interior minimum");
    assert!(b.tau > 0.3 && b.tau < 3.0, "{b:?}");
}

/// White (n), flicker (b) and random-walk (k) rate noise shaped in the frequency domain:
/// one-sided PSD 2 n^2 + b^2 / (pi f) + 2 k^2 / (2 pi f)^2 (IEEE 952 Table C.1, doubled).
fn shaped(len: usize, n: f64, b: f64, k: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let w: Vec<f64> = (0..len).map(|_| StandardNormal.sample(&mut rng)).collect();
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(len);
    let inv = planner.plan_fft_inverse(len);
    let mut input = w;
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut input, &mut spec).unwrap();
    for (j, c) in spec.iter_mut().enumerate() {
        let f = j as f64 * RATE / len as f64;
        // Unit-variance white noise has one-sided PSD 2 / RATE.
        let gain = if j == 0 {
            0.0
        } else {
            let rrw = 2.0 * k * k / (2.0 * PI * f).powi(2);
            ((2.0 * n * n + b * b / (PI * f) + rrw) * RATE / 2.0).sqrt()
        };
        *c *= gain;
    }
    let last = spec.len() - 1;
    spec[last].im = 0.0;
    let mut out = inv.make_output_vec();
    inv.process(&mut spec, &mut out).unwrap();
    out.iter().map(|v| v / len as f64).collect()
}

#[test]
fn bias_instability_from_the_allan_minimum() {
    // The bathtub: white N = 1e-3 meets the flicker floor 0.664 B (B = 1e-3) at
    // tau = N^2 / (0.441 B^2) ~ 2 s, rate random walk K = 1.5e-5 reaches it at
    // 3 * 0.441 B^2 / K^2 ~ 5900 s. At the minimum (tau ~ 100 s) N and K add ~ 3 % to the
    // AVAR (the classic read-out's upward bias, ~ 1.5 % in B); the minimum of noisy,
    // correlated points (edf ~ 30..100 there, adev s.d. ~ 7..13 %) is biased low. 15 %.
    let (n, b, k) = (1e-3, 1e-3, 1.5e-5);
    let y = shaped(1 << 20, n, b, k, 9);
    let ms: Vec<usize> = (0..35)
        .map(|i| (2f64.powf(i as f64 / 2.0)).round() as usize)
        .collect();
    let tau: Vec<f64> = ms.iter().map(|&m| m as f64 / RATE).collect();
    let adev: Vec<f64> = oavar(&y, &ms).iter().map(|v| v.sqrt()).collect();
    let r = slope_readouts(&tau, &adev);
    println!("{r:?}");
    let rb = r.b.expect("an interior minimum");
    assert!((rb.value / b - 1.0).abs() < 0.15, "B {}", rb.value);
    assert!(
        rb.tau > 10.0 && rb.tau < 1000.0,
        "tau of the minimum {}",
        rb.tau
    );
    let rn = r.n.expect("a -1/2 region");
    assert!((rn.value / n - 1.0).abs() < 0.06, "N {}", rn.value);
}

#[test]
fn degenerate_inputs_give_none_not_panics() {
    let r = slope_readouts(&[], &[]);
    assert!(r.n.is_none() && r.b.is_none() && r.k.is_none());
    let r = slope_readouts(&[1.0, f64::NAN, 3.0], &[1.0, 2.0]);
    assert!(r.b.is_none());
}

/// A curve that rises as `3 Q^2 / tau^2` above white noise only from the first tau fitted,
/// while the taus left out (where a fitted low-pass lowers the white noise) lie far below
/// what that Q alone would give: [`fit_deviation`] must not claim the Q the fitted taus
/// suggest, and its bound is the shortest tau's `tau sqrt(avar_hi / 3)`.
#[test]
fn taus_left_out_bound_the_quantization() {
    let tau0 = 0.01;
    let (n, first) = (1e-3f64, 16);
    let m: Vec<usize> = (0..14).map(|i| 1usize << i).collect();
    let tau: Vec<f64> = m.iter().map(|&m| m as f64 * tau0).collect();
    // Q holds a tenth of the white noise's AVAR at the first fitted tau.
    let q = (0.1 * n * n * tau[4] / 3.0).sqrt();
    let avar = |i: usize| {
        let t = tau[i];
        if m[i] < first {
            0.3 * n * n / t
        } else {
            n * n / t + 3.0 * q * q / (t * t)
        }
    };
    let dev = Deviation {
        estimator: Estimator::Oadev,
        m: m.clone(),
        tau: tau.clone(),
        dev: (0..m.len()).map(|i| avar(i).sqrt()).collect(),
        n: vec![0; m.len()],
    };
    let n_phase = 1_000_001;
    let opts = FitOptions {
        tau_min: Some(tau[4]),
        ..FitOptions::default()
    };
    // The fitted taus alone claim the Q.
    let fitted: Vec<usize> = (4..m.len()).collect();
    let unbounded = fit_allan_with(
        &fitted.iter().map(|&i| tau[i]).collect::<Vec<_>>(),
        &fitted.iter().map(|&i| avar(i)).collect::<Vec<_>>(),
        &fitted
            .iter()
            .map(|&i| crate::analysis::ci::edf(Estimator::Oadev, 0, m[i], n_phase))
            .collect::<Vec<_>>(),
        &FitOptions::default(),
    )
    .unwrap();
    let bounded = fit_deviation(&dev, n_phase, &opts).unwrap();
    let shortest = tau0 * (0.3 * n * n / tau0 / 3.0).sqrt();
    assert!(unbounded.q.value > 0.9 * q, "{:?}", unbounded.q);
    assert_eq!(bounded.q.value, 0.0);
    assert!(
        bounded.q.hi > shortest && bounded.q.hi < 1.1 * shortest,
        "{} against {shortest}",
        bounded.q.hi
    );
}
