//! How much evidence a Gauss-Markov process of minutes leaves once the flicker and
//! random-walk levels are unknown: on the family's Gauss-Markov records and on the same
//! records without the process (the families draw the baseline first, so seed s of
//! [`Kind::None`] is seed s of [`Kind::GaussMarkov`] less its process), the likelihood ratio
//! of a first-order Gauss-Markov term (correlation time searched over a grid, sigma free)
//! - **knowing the levels** (the generator's B and K): the most any test could see;
//! - **searching B and K** on each side of the ratio, as a test that stays calibrated
//!   without knowing them must.
//!
//! The likelihood is that of the record's full-resolution cosine transform up to 1 Hz, where
//! every term of the model is diagonal (see [`super::ramp_power`]): a first-order process of
//! variance s^2 and `phi = exp(-tau0 / tau_c)` has coefficient variance `s^2 (1 - phi^2) /
//! (1 - 2 phi cos w + phi^2)` at `w = pi k / n`, the same form as each pole of the flicker
//! bank. Nothing is averaged away: neither block means nor an Allan curve limit this test,
//! so what it cannot see no test of the record can.
//!
//! Measured (3 h at 50 Hz, seeds 100..110; `--nocapture` prints the table): knowing the
//! levels, every process has a ratio of 42 to 726; searching them, 3.1 to 31 (median 14),
//! against 0 to 1.9 (median 0.4) on the same records without it. Flicker at a free level
//! bends to the process's spectrum everywhere but in the bins below its corner
//! (`1 / (2 pi tau_c)`, 5 to 16 cycles per record), where the process is flat and flicker
//! still rises as 1/f; those few bins hold what evidence is left. Block means of 54 s
//! (200 blocks) kept 3.2 to 16 of it, so the evidence also lies at periods of a minute and
//! less, where the Allan curve sees it too.
//!
//! What is left is enough for a test of its own. Calibrated by a parametric bootstrap (24
//! coefficient vectors drawn from the levels the record shows without the process, each
//! put through the same two searches: `the_full_resolution_test_against_its_bootstrap`,
//! ignored by default, minutes in `--release`), its p-value (a scaled chi-square matched to
//! the draws, as the workflow's views take theirs) is below the workflow's threshold for
//! seven candidates (7.1e-3) on 8 of the 10 records: 7e-11 to 2.7e-3, with 9.5e-3 (seed
//! 104) and 6.8e-2 (seed 108) the two misses. On the same records without the process it is
//! 0.16 to 1.0, and its null has a mean of 0.4 to 1.3 and a largest draw of 1.6 to 5.8 on
//! every record: nearly pivotal, where the Allan curve's misfit drop, drawn from a baseline
//! whose B and K absorbed the bump, spreads far wider (on one 4 h record, 7.8 +- 21). The
//! workflow's Allan test misses seeds 107 and 108; this test names 107 (p = 2.4e-5) and
//! misses 104 and 108: the two views miss different records, and only seed 108 (a process
//! whose known-level ratio is 42, a tenth of the others') is missed by both.

use super::families::{self, Kind, STUDY_SHAPE};
use super::gls::nelder_mead_n;
use super::ramp_power::{coefficient_variances, dct2};
use crate::sim::noise::NoiseTerms;

/// Log-levels searched, relative to the white level at the first coefficient.
const LOG_LEVEL_RANGE: (f64, f64) = (-30.0, 30.0);
/// Correlation times tried, as fractions of the record: from a third of a percent to a third.
const GRID_FRACTIONS: (f64, f64) = (0.003, 0.33);
const GRID_POINTS: usize = 16;

/// The record's cosine coefficients and the model's unit variances per coefficient.
struct Coefficients {
    c: Vec<f64>,
    fixed: Vec<f64>,
    flicker: Vec<f64>,
    walk: Vec<f64>,
    /// Unit-sigma Gauss-Markov variances, one column per correlation time of the grid.
    gauss_markov: Vec<(f64, Vec<f64>)>,
}

impl Coefficients {
    fn of(x: &[f64], terms: &NoiseTerms) -> Coefficients {
        let rate_hz = STUDY_SHAPE.rate_hz;
        let tau0 = 1.0 / rate_hz;
        let n = x.len();
        let kmax = ((n as f64 * tau0 * 2.0) as usize).min(n / 2);
        let [fixed, flicker, walk] = coefficient_variances(terms, rate_hz, n, kmax);
        let duration = n as f64 * tau0;
        let (lo, hi) = GRID_FRACTIONS;
        let gauss_markov = (0..GRID_POINTS)
            .map(|i| {
                let tau_c = duration * lo * (hi / lo).powf(i as f64 / (GRID_POINTS - 1) as f64);
                let phi = (-tau0 / tau_c).exp();
                let v = (1..=kmax)
                    .map(|k| {
                        let w = std::f64::consts::PI * k as f64 / n as f64;
                        (1.0 - phi * phi) / (1.0 - 2.0 * phi * w.cos() + phi * phi)
                    })
                    .collect();
                (tau_c, v)
            })
            .collect();
        Coefficients {
            c: dct2(x, kmax),
            fixed,
            flicker,
            walk,
            gauss_markov,
        }
    }

    /// Twice the negative log-likelihood with the given levels of the unit columns.
    fn nll(&self, columns: &[&[f64]], levels: &[f64]) -> f64 {
        (0..self.c.len())
            .map(|k| {
                let v = self.fixed[k]
                    + columns
                        .iter()
                        .zip(levels)
                        .map(|(col, l)| col[k] * l)
                        .sum::<f64>();
                v.ln() + self.c[k] * self.c[k] / v
            })
            .sum()
    }

    /// The least of [`Coefficients::nll`] over the columns' levels, searched in logs from
    /// `start` (levels) and from each level a thousandth of it.
    fn least(&self, columns: &[&[f64]], start: &[f64]) -> f64 {
        self.likeliest(columns, start).0
    }

    /// [`Coefficients::least`] and the levels that reach it.
    fn likeliest(&self, columns: &[&[f64]], start: &[f64]) -> (f64, Vec<f64>) {
        // A unit log-level is the white level at the first coefficient.
        let scale: Vec<f64> = columns.iter().map(|col| self.fixed[0] / col[0]).collect();
        let f = |u: &[f64]| {
            if u.iter()
                .any(|v| !(LOG_LEVEL_RANGE.0..=LOG_LEVEL_RANGE.1).contains(v))
            {
                return f64::INFINITY;
            }
            let levels: Vec<f64> = u.iter().zip(&scale).map(|(v, s)| s * v.exp()).collect();
            self.nll(columns, &levels)
        };
        let from = |shift: f64| -> Vec<f64> {
            start
                .iter()
                .zip(&scale)
                .map(|(l, s)| ((l.max(1e-300) / s).ln() + shift).clamp(-25.0, 25.0))
                .collect()
        };
        [0.0, -7.0]
            .iter()
            .map(|&shift| {
                let coarse = nelder_mead_n(&f, &from(shift), 2.0);
                let u = nelder_mead_n(&f, &coarse, 0.5);
                let levels = u.iter().zip(&scale).map(|(v, s)| s * v.exp()).collect();
                (f(&u), levels)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((f64::INFINITY, Vec::new()))
    }

    /// The same model's coefficients drawn with the flicker and random-walk `levels`.
    fn drawn(&self, levels: &[f64], seed: u64) -> Coefficients {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let c = (0..self.c.len())
            .map(|k| {
                let v = self.fixed[k] + levels[0] * self.flicker[k] + levels[1] * self.walk[k];
                v.sqrt() * rng.sample::<f64, _>(rand_distr::StandardNormal)
            })
            .collect();
        Coefficients {
            c,
            fixed: self.fixed.clone(),
            flicker: self.flicker.clone(),
            walk: self.walk.clone(),
            gauss_markov: self.gauss_markov.clone(),
        }
    }

    /// The Gauss-Markov term's likelihood ratio with the flicker and random-walk levels
    /// `known` (B^2, K^2), and with them searched.
    fn ratios(&self, known: [f64; 2]) -> (f64, f64) {
        let base: [&[f64]; 2] = [&self.flicker, &self.walk];
        let without_known = self.nll(&base, &known);
        let without_searched = self.least(&base, &known);
        let (mut with_known, mut with_searched) = (f64::INFINITY, f64::INFINITY);
        for (_, gm) in &self.gauss_markov {
            let only: [&[f64]; 1] = [gm];
            let fixed_levels = Coefficients {
                c: self.c.clone(),
                fixed: self
                    .fixed
                    .iter()
                    .zip(&self.flicker)
                    .zip(&self.walk)
                    .map(|((f, b), k)| f + known[0] * b + known[1] * k)
                    .collect(),
                flicker: Vec::new(),
                walk: Vec::new(),
                gauss_markov: Vec::new(),
            };
            with_known = with_known.min(fixed_levels.least(&only, &[1e-3 * self.fixed[0]]));
            let all: [&[f64]; 3] = [&self.flicker, &self.walk, gm];
            with_searched =
                with_searched.min(self.least(&all, &[known[0], known[1], self.fixed[0]]));
        }
        (
            (without_known - with_known).max(0.0),
            (without_searched - with_searched).max(0.0),
        )
    }
}

#[test]
#[ignore = "twenty 3 h records searched on a grid of correlation times: 40 s in --release"]
fn a_gauss_markov_process_of_minutes_is_lost_to_the_unknown_flicker() {
    eprintln!("seed  tau_c s  LR known  LR searched  same record without it: LR searched");
    let mut searched_with = Vec::new();
    let mut searched_without = Vec::new();
    for seed in 100..110 {
        let hidden = families::generate(Kind::GaussMarkov, STUDY_SHAPE, seed);
        let plain = families::generate(Kind::None, STUDY_SHAPE, seed);
        assert_eq!(
            plain.terms.n, hidden.terms.n,
            "seed {seed}: the same baseline"
        );
        let known = [
            hidden.terms.b * hidden.terms.b,
            hidden.terms.k * hidden.terms.k,
        ];
        let with = Coefficients::of(&hidden.record.channels[0].values, &hidden.terms);
        let (oracle, searched) = with.ratios(known);
        let without = Coefficients::of(&plain.record.channels[0].values, &plain.terms);
        let (_, null) = without.ratios(known);
        let tau_c = hidden.terms.gauss_markov.map_or(0.0, |g| g.tau_c);
        eprintln!("{seed}  {tau_c:7.1}  {oracle:8.1}  {searched:11.1}  {null:11.1}");
        // Knowing the levels, every process stands out far beyond any threshold.
        assert!(oracle > 30.0, "seed {seed}: {oracle}");
        // Searching them, most of that evidence goes.
        assert!(
            searched < 0.25 * oracle,
            "seed {seed}: {searched} of {oracle}"
        );
        searched_with.push(searched);
        searched_without.push(null);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[4] + v[5]) / 2.0
    };
    // What is left still tells the records with the process from those without it.
    let (with, without) = (median(&mut searched_with), median(&mut searched_without));
    assert!(with > without + 3.0, "medians {with} and {without}");
}

#[test]
#[ignore = "a parametric bootstrap of the full-resolution test; minutes in --release"]
fn the_full_resolution_test_against_its_bootstrap() {
    use rayon::prelude::*;
    let draws = 24;
    for kind in [Kind::GaussMarkov, Kind::None] {
        for seed in 100..110 {
            let hidden = families::generate(kind, STUDY_SHAPE, seed);
            let known = [
                hidden.terms.b * hidden.terms.b,
                hidden.terms.k * hidden.terms.k,
            ];
            let c = Coefficients::of(&hidden.record.channels[0].values, &hidden.terms);
            let (_, statistic) = c.ratios(known);
            let base: [&[f64]; 2] = [&c.flicker, &c.walk];
            let (_, levels) = c.likeliest(&base, &known);
            let null: Vec<f64> = (0..draws)
                .into_par_iter()
                .map(|i| c.drawn(&levels, 5000 + i).ratios(known).1)
                .collect();
            let p = super::evidence::scaled_chi_square_p(statistic, &null);
            let max = null.iter().copied().fold(0.0, f64::max);
            let mean = null.iter().sum::<f64>() / draws as f64;
            eprintln!(
                "{kind:?} {seed}: LR {statistic:.1}, null mean {mean:.2} max {max:.1}, p {p:.1e}"
            );
        }
    }
}
