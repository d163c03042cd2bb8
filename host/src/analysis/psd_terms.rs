//! N, B and K from the power spectral density of a rate record.
//!
//! IEEE Std 952-1997 (Annex C, Table C.1) gives each noise term's **two-sided** rate PSD:
//! white rate noise `N^2`, bias instability `B^2 / (2 pi f)`, rate random walk
//! `K^2 / (2 pi f)^2`. Our spectra are one-sided (twice that; [`crate::analysis::psd`]).

use crate::analysis::fit::{longest_run, ls_slope};
use crate::analysis::psd::log_binned_arrays;
use serde::Serialize;
use std::f64::consts::PI;

/// One coefficient read from a slope region of the PSD.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PsdReadout {
    /// The coefficient, SI (N in u/sqrt(Hz), B in u, K in u*sqrt(Hz)).
    pub value: f64,
    /// Frequency range of the region used, Hz.
    pub f_min: f64,
    pub f_max: f64,
    /// Log-spaced bins in the region.
    pub bins: usize,
}

/// N, B and K read from the slope regions of a PSD; `None` when a region is absent.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PsdNoiseTerms {
    pub n: Option<PsdReadout>,
    pub b: Option<PsdReadout>,
    pub k: Option<PsdReadout>,
}

/// Bins per decade [`fit_psd`] averages the spectrum into.
pub const PSD_BINS_PER_DECADE: usize = 10;

/// N, B and K from a **one-sided** rate PSD (u^2/Hz), e.g. [`crate::analysis::psd::welch`]'s.
///
/// Conversions (IEEE Std 952-1997, Table C.1, two-sided `S2`; our one-sided `S1 = 2 S2`):
/// - white rate noise, slope 0: `S2 = N^2`, so `N^2 = S1 / 2`;
/// - bias instability (flicker), slope -1: `S2 = B^2 / (2 pi f)`, so `B^2 = pi f S1`;
/// - rate random walk, slope -2: `S2 = K^2 / (2 pi f)^2`, so `K^2 = 2 pi^2 f^2 S1`.
///
/// Method: the two lowest non-zero frequencies are dropped (with a Hann window they share
/// the main lobe of the removed segment mean), the rest is averaged into
/// [`PSD_BINS_PER_DECADE`] log bins, and each bin's local slope is the least-squares slope of
/// ln S on ln f over it and two bins either side. The white region is the longest run of
/// bins with |slope| <= 0.15; the -2 region is the longest run within 0.3 of -2 **below** the
/// white region (above it a MEMS spectrum rolls off through its low-pass filter, which also
/// has negative slopes), and the -1 region the longest run within 0.25 of -1 between the two
/// (flicker can only show between white noise and rate random walk; below the -2 region a
/// -1 slope is an artefact: window leakage or too few averages). Every region needs at least
/// 3 bins (0.3 decade). Each term's level is
/// the point-count-weighted mean over its region of the value implied by the conversion,
/// after subtracting the other identified terms' model contributions (five alternating
/// passes), which removes most of the bias from the overlap at the region edges. A region is
/// reported only if its own term is at least half the model PSD at its middle bin — the
/// crossover from a -2 to a 0 slope passes through -1 without any flicker noise.
pub fn fit_psd(freq: &[f64], one_sided_density: &[f64]) -> PsdNoiseTerms {
    let mut pts: Vec<(f64, f64)> = freq
        .iter()
        .zip(one_sided_density)
        .filter(|(f, s)| f.is_finite() && **f > 0.0 && s.is_finite() && **s > 0.0)
        .map(|(f, s)| (*f, *s))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let pts = pts.get(2..).unwrap_or_default();
    let (f, s): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
    let binned = log_binned_arrays(&f, &s, PSD_BINS_PER_DECADE);
    let logs: Vec<(f64, f64)> = binned
        .freq
        .iter()
        .zip(&binned.density)
        .map(|(f, s)| (f.ln(), s.ln()))
        .collect();
    let slopes: Vec<f64> = (0..logs.len())
        .map(|i| ls_slope(&logs[i.saturating_sub(2)..(i + 3).min(logs.len())]))
        .collect();
    let white = region(&slopes, 0..slopes.len(), 0.0, 0.15);
    let below_white = white.as_ref().map_or(slopes.len(), |w| w.start);
    let rrw = region(&slopes, 0..below_white, -2.0, 0.3);
    let above_rrw = rrw.as_ref().map_or(0, |r| r.end);
    let flicker = region(&slopes, above_rrw..below_white, -1.0, 0.25);
    let regions = [white, flicker, rrw];
    let levels = psd_levels(&binned.freq, &binned.density, &binned.count, &regions);
    let readout = |idx: usize| {
        let r = regions[idx].clone()?;
        // A region whose own term does not dominate its middle is the crossover between two
        // other terms (the -2 -> 0 transition passes through slope -1): not a detection.
        let mid = psd_model_two_sided(&levels, binned.freq[(r.start + r.end - 1) / 2]);
        let dominant = mid[idx] > 0.0 && mid[idx] >= 0.5 * mid.iter().sum::<f64>();
        dominant.then(|| PsdReadout {
            value: levels[idx].sqrt(),
            f_min: binned.freq[r.start],
            f_max: binned.freq[r.end - 1],
            bins: r.len(),
        })
    };
    PsdNoiseTerms {
        n: readout(0),
        b: readout(1),
        k: readout(2),
    }
}

/// Minimum number of log bins (0.3 decade) for a PSD slope region.
const MIN_PSD_REGION_BINS: usize = 3;

/// The longest run of at least [`MIN_PSD_REGION_BINS`] bins within `within` whose slopes are
/// within `tol` of `target`, as indices into `slopes`.
fn region(
    slopes: &[f64],
    within: std::ops::Range<usize>,
    target: f64,
    tol: f64,
) -> Option<std::ops::Range<usize>> {
    let start = within.start.min(within.end);
    longest_run(
        &slopes[start..within.end],
        |s| (s - target).abs() <= tol,
        false,
    )
    .filter(|r| r.len() >= MIN_PSD_REGION_BINS)
    .map(|r| r.start + start..r.end + start)
}

/// Two-sided PSD of white, flicker and random-walk terms with squared coefficients `c`.
fn psd_model_two_sided(c: &[f64; 3], f: f64) -> [f64; 3] {
    let w = 2.0 * PI * f;
    [c[0], c[1] / w, c[2] / (w * w)]
}

/// Squared coefficients (N^2, B^2, K^2) from their regions, alternating so each region's
/// estimate has the other terms' contributions removed.
fn psd_levels(
    freq: &[f64],
    one_sided: &[f64],
    count: &[usize],
    regions: &[Option<std::ops::Range<usize>>; 3],
) -> [f64; 3] {
    let mut c = [0.0; 3];
    for _ in 0..5 {
        for (t, region) in regions.iter().enumerate() {
            let Some(r) = region.clone() else { continue };
            let (mut num, mut den) = (0.0, 0.0);
            for i in r {
                let model = psd_model_two_sided(&c, freq[i]);
                let others: f64 = (0..3).filter(|&u| u != t).map(|u| model[u]).sum();
                let own_per_coef = psd_model_two_sided(&[1.0, 1.0, 1.0], freq[i])[t];
                let level = (one_sided[i] / 2.0 - others) / own_per_coef;
                num += count[i] as f64 * level;
                den += count[i] as f64;
            }
            c[t] = (num / den).max(0.0);
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::psd::{WelchOptions, welch};
    use crate::sim::noise::{AxisNoise, NoiseTerms};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    const RATE: f64 = 100.0;

    /// `len` samples at [`RATE`] of the simulator's noise with the given terms.
    fn series(terms: NoiseTerms, len: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut axis = AxisNoise::new(terms, RATE, len as f64 / RATE, &mut rng);
        axis.take(len, &mut rng)
    }

    #[test]
    fn psd_route_white_plus_rrw() {
        let (n, k) = (1e-3, 1.7e-3);
        let terms = NoiseTerms {
            n,
            k,
            ..NoiseTerms::default()
        };
        let y = series(terms, 1 << 20, 43);
        let psd = welch(&y, RATE, &WelchOptions::default()).unwrap();
        let t = fit_psd(&psd.freq, &psd.density);
        println!("{t:?}");
        let tn = t.n.expect("a flat region");
        let tk = t.k.expect("a -2 region");
        // N: thousands of averaged points (s.d. < 1 %), after removing the K contribution.
        assert!((tn.value / n - 1.0).abs() < 0.03, "N {}", tn.value);
        // K: the -2 region spans the lowest decades (few points per bin, 15 segments): 20 %.
        assert!((tk.value / k - 1.0).abs() < 0.2, "K {}", tk.value);
        assert!(tk.f_max < tn.f_min);
        // The -2 -> 0 crossover passes through slope -1 but is not flicker.
        assert!(t.b.is_none(), "{:?}", t.b);
    }

    #[test]
    fn psd_route_white_plus_flicker() {
        // B = 1e-3 and N = 3e-4: flicker dominates below f = B^2 / (2 pi N^2) = 1.8 Hz.
        let (n, b) = (3e-4, 1e-3);
        let terms = NoiseTerms {
            n,
            b,
            ..NoiseTerms::default()
        };
        let y = series(terms, 1 << 20, 10);
        let psd = welch(&y, RATE, &WelchOptions::default()).unwrap();
        let t = fit_psd(&psd.freq, &psd.density);
        println!("{t:?}");
        let tb = t.b.expect("a -1 region");
        assert!((tb.value / b - 1.0).abs() < 0.1, "B {}", tb.value);
        let tn = t.n.expect("a flat region");
        assert!((tn.value / n - 1.0).abs() < 0.1, "N {}", tn.value);
        assert!(t.k.is_none(), "{:?}", t.k);
    }

    #[test]
    fn degenerate_inputs_give_none_not_panics() {
        let t = fit_psd(&[], &[1.0]);
        assert!(t.n.is_none() && t.b.is_none() && t.k.is_none());
        let t = fit_psd(&[0.0, 1.0, 2.0], &[f64::NAN, -1.0, 0.0]);
        assert!(t.n.is_none());
    }
}
