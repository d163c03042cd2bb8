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
//! levels, every process has a ratio of 57 to 477; searching them, 3.4 to 33 (median 15),
//! against 0 to 4.3 (median 0.5) on the same records without it. Flicker at a free level
//! bends to the process's spectrum everywhere but in the bins below its corner
//! (`1 / (2 pi tau_c)`, 5 to 16 cycles per record), where the process is flat and flicker
//! still rises as 1/f; those few bins hold what evidence is left.
//!
//! What is left is enough for a test of its own on most records. Calibrated by a parametric
//! bootstrap (48 coefficient vectors drawn from the levels the record shows without the
//! process, each put through the same two searches: `the_view_against_its_bootstrap`, on
//! the view's banded likelihood ([`super::cosine`]), ignored by default), its p-value (a
//! scaled chi-square matched to the draws, as the workflow's views take theirs) is below the
//! workflow's threshold for seven candidates (7.1e-3) on 7 of the 10 records: 4.1e-9 to
//! 5.4e-4, with 1.8e-2 (seed 102), 2.6e-2 (seed 100) and 5.2e-2 (seed 108) the misses. Seed
//! 108's process has a known-level ratio of 57, against 208 to 477 for the others; seeds 100
//! and 102 keep only 5.1 and 6.4 of their 323 and 477 once the levels are searched, the
//! least of any record but 108 (the flicker then fits their corners). On the same records
//! without the process the p-value is 0.027 to 1.0, and the null has a mean of 0.58 to 1.20
//! and a largest draw of 2.6 to 7.1 on every record: nearly pivotal, where the Allan curve's
//! misfit drop, drawn from a baseline whose B and K absorbed the bump, spreads far wider (on
//! one 4 h record, 7.8 +- 21). On the three missed records the workflow's first round names
//! the baseline's bias instability by the Allan curve, and the process is not named after
//! it either (cosine-view p of 0.024 to 0.30 against the final model).

use super::cosine::CosineLikelihood;
use super::evidence::scaled_chi_square_p;
use super::families::{self, Hidden, Kind, STUDY_SHAPE};

/// The view of a generated record under its generator's white level, and its B^2 and K^2.
fn view(hidden: &Hidden) -> (CosineLikelihood, [f64; 2]) {
    let terms = &hidden.terms;
    let view = CosineLikelihood::new(
        &hidden.record.channels[0].values,
        STUDY_SHAPE.rate_hz,
        terms,
        None,
        &[],
    )
    .expect("a 3 h record has coefficients to spare");
    (view, [terms.b * terms.b, terms.k * terms.k])
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
        let (with, known) = view(&hidden);
        let (oracle, (searched, _, _)) = (with.ratio_known(known), with.ratio(known));
        let (without, _) = view(&plain);
        let (null, _, _) = without.ratio(known);
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
#[ignore = "a parametric bootstrap of the view on twenty 3 h records: minutes in --release"]
fn the_view_against_its_bootstrap() {
    for kind in [Kind::GaussMarkov, Kind::None] {
        for seed in 100..110 {
            let (view, known) = view(&families::generate(kind, STUDY_SHAPE, seed));
            let verdict = view.test(known, 48, 5000);
            let p = scaled_chi_square_p(verdict.statistic, &verdict.null);
            let max = verdict.null.iter().copied().fold(0.0, f64::max);
            let mean = verdict.null.iter().sum::<f64>() / verdict.null.len() as f64;
            eprintln!(
                "{kind:?} {seed}: LR {:.1} at tau_c {:.0} s, null mean {mean:.2} max {max:.1}, p {p:.1e}",
                verdict.statistic, verdict.tau_c
            );
        }
    }
}
