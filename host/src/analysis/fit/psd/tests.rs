use super::*;
use crate::sim::noise::{AxisNoise, NoiseTerms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const RATE: f64 = 100.0;

/// `len` samples at [`RATE`] of the simulator's noise with the given terms.
fn series(terms: NoiseTerms, len: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut axis = AxisNoise::new(terms, RATE, len as f64 / RATE, &mut rng);
    axis.take(len, &mut rng)
}

/// White, flicker and random-walk terms drawn per seed: N log-uniform in [5e-4, 2e-3],
/// the white/flicker crossover `f = B^2 / (2 pi N^2)` in [0.01, 0.02] Hz and the
/// flicker/random-walk crossover `f = K^2 / (2 pi B^2)` in [1.5, 3] mHz, so on 3 h at
/// 100 Hz (spectrum from ~4e-4 Hz) each term owns 0.5 to 1.5 decades. The crossover with
/// white noise stays low because the simulated flicker falls below `B^2 / (2 pi f)` above
/// about 1 Hz at 100 Hz (3-6 % at 0.2-2 Hz, 18 % at 7 Hz): with more flicker there, the
/// fitted N (relative s.d. 0.1 %) would measure the simulator, not the fit.
fn drawn_terms(seed: u64) -> NoiseTerms {
    let mut rng = ChaCha8Rng::seed_from_u64(9000 + seed);
    let n: f64 = 10f64.powf(rng.random_range(-3.3..-2.7));
    let f_bn: f64 = 10f64.powf(rng.random_range(-2.0..-1.7));
    let f_bk: f64 = 10f64.powf(rng.random_range(-2.82..-2.52));
    let b = (f_bn * 2.0 * PI * n * n).sqrt();
    let k = (f_bk * 2.0 * PI * b * b).sqrt();
    NoiseTerms {
        n,
        b,
        k,
        ..NoiseTerms::default()
    }
}

fn readouts(t: &PsdNoiseTerms) -> [PsdReadout; 3] {
    [t.n, t.b, t.k]
}

#[test]
fn readouts_of_white_flicker_and_random_walk_cover_the_truth() {
    const SEEDS: u64 = 30;
    let fits: Vec<(NoiseTerms, PsdNoiseTerms)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..SEEDS)
            .map(|seed| {
                s.spawn(move || {
                    let truth = drawn_terms(seed);
                    let y = series(truth, 3 * 3600 * 100, seed);
                    (truth, fit_psd(&y, RATE, &PsdFitOptions::default()).unwrap())
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut covered = [0; 3];
    let mut resolved = [0; 3];
    for (truth, fit) in &fits {
        for (i, (r, t)) in readouts(fit)
            .iter()
            .zip([truth.n, truth.b, truth.k])
            .enumerate()
        {
            covered[i] += usize::from(r.lo <= t && t <= r.hi);
            resolved[i] += usize::from(r.resolved());
        }
    }
    println!("68.3 % intervals: N, B, K covered {covered:?}, resolved {resolved:?} of {SEEDS}");
    // Each term owns part of the band: it must be told from 0 in nearly every record.
    for (term, r) in ["N", "B", "K"].iter().zip(resolved) {
        assert!(r >= 27, "{term} resolved in {r} of {SEEDS}");
    }
    // Coverage of 68.3 % intervals over 30 seeds: binomial s.d. 8.5 %, so 2.5 s.d. is
    // [47 %, 90 %], 14 to 27 seeds.
    for (term, c) in ["N", "B", "K"].iter().zip(covered) {
        assert!((14..=27).contains(&c), "{term} covered in {c} of {SEEDS}");
    }
}

#[test]
fn white_noise_claims_no_flicker_or_random_walk() {
    const SEEDS: u64 = 40;
    let opts = PsdFitOptions {
        confidence: 0.95,
        ..PsdFitOptions::default()
    };
    let (mut claimed, mut n_covered, mut chi2) = ([0; 3], 0, 0.0);
    for seed in 0..SEEDS {
        let truth = NoiseTerms {
            n: drawn_terms(seed).n,
            ..NoiseTerms::default()
        };
        let fit = fit_psd(&series(truth, 2 * 3600 * 100, 500 + seed), RATE, &opts).unwrap();
        for (i, r) in readouts(&fit).iter().enumerate() {
            claimed[i] += usize::from(r.resolved());
        }
        n_covered += usize::from(fit.n.lo <= truth.n && truth.n <= fit.n.hi);
        chi2 += fit.reduced_chi2 / SEEDS as f64;
        assert!(fit.b.lo == 0.0 || fit.b.resolved());
    }
    println!(
        "white only, 95 %: resolved N, B, K {claimed:?} of {SEEDS}, N covered {n_covered}, mean reduced chi2 {chi2:.3}"
    );
    assert_eq!(claimed[0], SEEDS as usize);
    // A zero term is claimed when its estimate exceeds z sd: one-sided 2.5 %, 1 of 40
    // expected; 5 or more has binomial probability 0.7 %.
    assert!(claimed[1] <= 4 && claimed[2] <= 4, "{claimed:?}");
    // N covered in 38 of 40 expected; 34 or fewer has probability 0.6 %.
    assert!(n_covered >= 35, "N covered in {n_covered} of {SEEDS}");
    // The points' degrees of freedom describe their scatter: the mean reduced chi-square
    // of 40 fits of ~45 points (s.d. of one ~ 0.2, of the mean ~ 0.04) is near 1.
    assert!((chi2 - 1.0).abs() < 0.15, "mean reduced chi2 {chi2}");
}

#[test]
fn hann_kernels_match_their_closed_forms() {
    let w = Taper::new(Window::Hann, 1024);
    // Hann's transform is 1/2, -1/4, -1/4: powers 1/4, 1/16, 1/16 of total 3/8.
    let s = window_smoothing(&w);
    assert!((s[0] - 2.0 / 3.0).abs() < 1e-12 && (s[1] - 1.0 / 6.0).abs() < 1e-12);
    assert!(s[2..].iter().all(|&v| v == 0.0));
    // Ordinate correlations c(1) = 2/3, c(2) = 1/6 (squared 4/9, 1/36).
    let c = ordinate_correlation(&w);
    assert!((c[0] - 1.0).abs() < 1e-12);
    assert!((c[1] - 4.0 / 9.0).abs() < 1e-12 && (c[2] - 1.0 / 36.0).abs() < 1e-12);
    assert!(c[3..].iter().all(|&v| v == 0.0));
    // 50 % overlap: rho(1) = (1/6)^2, so K_eff = K / (1 + 2 (1 - 1/K) / 36).
    let k = 15.0;
    let expected = k / (1.0 + 2.0 * (1.0 - 1.0 / k) / 36.0);
    assert!((effective_segments(&w, 512, 15) - expected).abs() < 1e-9);
    assert_eq!(effective_segments(&w, 1024, 3), 3.0);
}

#[test]
fn chi2_quantiles_join_smoothly() {
    // The Wilson-Hilferty branch against statrs at the switch.
    for p in [0.025, 0.1585, 0.8415, 0.975] {
        let exact = ChiSquared::new(WILSON_HILFERTY_DOF).unwrap().inverse_cdf(p);
        let z = Normal::standard().inverse_cdf(p);
        let a = 2.0 / (9.0 * WILSON_HILFERTY_DOF);
        let approx = WILSON_HILFERTY_DOF * (1.0 - a + z * a.sqrt()).powi(3);
        assert!(
            (approx / exact - 1.0).abs() < 1e-5,
            "p {p}: {approx} vs {exact}"
        );
        assert!(chi2_quantile(1e6, p).unwrap().is_finite());
    }
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let opts = PsdFitOptions::default();
    assert!(matches!(
        fit_psd(&[], 1.0, &opts),
        Err(PsdFitError::Psd(PsdError::Empty))
    ));
    assert!(matches!(
        fit_psd(&[1.0, f64::NAN, 2.0], 1.0, &opts),
        Err(PsdFitError::Psd(PsdError::NonFinite { index: 1, .. }))
    ));
    let bad = PsdFitOptions {
        confidence: 1.0,
        ..opts.clone()
    };
    assert_eq!(
        fit_psd(&[1.0; 64], 1.0, &bad),
        Err(PsdFitError::BadConfidence(1.0))
    );
    // Constant data: every ordinate is 0, nothing to fit.
    assert!(matches!(
        fit_psd(&[1.0; 4096], 10.0, &opts),
        Err(PsdFitError::TooFewPoints(0))
    ));
    // Records too short for a spectrum worth fitting, and just long enough.
    let white = NoiseTerms {
        n: 1e-3,
        ..NoiseTerms::default()
    };
    assert!(matches!(
        fit_psd(&series(white, 8, 1), RATE, &opts),
        Err(PsdFitError::TooFewPoints(1))
    ));
    let t = fit_psd(&series(white, 16, 1), RATE, &opts).unwrap();
    assert!(
        readouts(&t)
            .iter()
            .all(|r| r.lo <= r.value && r.value <= r.hi)
    );
}

/// White noise through the MPU-6050's 98 Hz gyro DLPF at 200 Hz (the filter reaching past
/// half the rate, so its folded gain tilts the whole band): with the filter from the
/// settings, N is the DC white level within three half-widths of its interval, over seeds;
/// without it, the flat-band fit is several half-widths off.
#[test]
fn a_known_filter_is_modelled_so_n_is_the_white_level() {
    use crate::analysis::low_pass::LowPass;
    use crate::sim::dlpf::Sensor;
    use protocol::mpu6050::SensorSettings;
    let settings = SensorSettings::for_rate_and_bandwidth(200.0, 98.0).unwrap();
    let lp = LowPass::mpu6050(&settings, Sensor::Gyro).unwrap();
    let n0 = 1e-3;
    let mut worst_plain: f64 = 0.0;
    for seed in 0..3 {
        let mut rng = ChaCha8Rng::seed_from_u64(300 + seed);
        let y = lp.white_through(n0, 200 * 1800, &mut rng);
        let opts = PsdFitOptions {
            low_pass: Some(lp.clone()),
            ..PsdFitOptions::default()
        };
        let with = fit_psd(&y, 200.0, &opts).unwrap().n;
        let half = (with.hi - with.lo) / 2.0;
        assert!(
            (with.value - n0).abs() < 3.0 * half,
            "seed {seed}: N {} [{}, {}] against {n0}",
            with.value,
            with.lo,
            with.hi
        );
        let plain = fit_psd(&y, 200.0, &PsdFitOptions::default()).unwrap().n;
        let plain_half = (plain.hi - plain.lo) / 2.0;
        worst_plain = worst_plain.max((plain.value - n0).abs() / plain_half);
    }
    assert!(
        worst_plain > 3.0,
        "the flat band alone: {worst_plain:.1} half-widths"
    );
}

/// A spectrum the three terms cannot describe (a Gauss-Markov process of 2 s, sixteen times
/// the white PSD below its corner, flat where flicker and the random walk rise) has a reduced
/// chi-square well above 1, and every interval is widened by its square root: each term's
/// degrees of freedom `2 theta^2 / sd^2` shrink by the squared ratio against those of the
/// same noise without the process. On a spectrum they describe, the ratio is 1.
#[test]
fn lack_of_fit_widens_the_intervals_by_the_birge_ratio() {
    use crate::sim::noise::GaussMarkov;
    let white = NoiseTerms {
        n: 1e-3,
        ..NoiseTerms::default()
    };
    let bump = NoiseTerms {
        gauss_markov: Some(GaussMarkov {
            sigma: 2e-3,
            tau_c: 2.0,
        }),
        ..white
    };
    let len = 3600 * 100;
    let plain = fit_psd(&series(white, len, 7), RATE, &PsdFitOptions::default()).unwrap();
    let poor = fit_psd(&series(bump, len, 7), RATE, &PsdFitOptions::default()).unwrap();
    assert_eq!(plain.birge_ratio, plain.reduced_chi2.max(1.0).sqrt());
    assert!(plain.birge_ratio < 1.3, "{}", plain.reduced_chi2);
    assert!(poor.reduced_chi2 > 4.0, "{}", poor.reduced_chi2);
    assert_eq!(poor.birge_ratio, poor.reduced_chi2.sqrt());
    assert!(poor.n.resolved(), "{:?}", poor.n);
    // N's own degrees of freedom: its band is the white one in both records, so without the
    // widening they would be alike; with it, the poor fit's fall by the squared ratio.
    let shrink = plain.n.dof / poor.n.dof;
    let expected = (poor.birge_ratio / plain.birge_ratio).powi(2);
    assert!(
        shrink > 0.5 * expected && shrink < 2.0 * expected,
        "dof {} against {}: x{shrink:.2}, expected about x{expected:.2}",
        plain.n.dof,
        poor.n.dof
    );
}
