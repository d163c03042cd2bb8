//! The Allan-family estimators, their confidence intervals and the noise identification
//! against Stable32 (tests/data/stable32, see SOURCE.md there) and against the NBS 1000-point
//! test series of NIST SP 1065.

use imunoise::analysis::allan::deviation;
use imunoise::analysis::ci::{chi2_bounds, edf};
use imunoise::analysis::noise_id::identify;
use imunoise::analysis::{Estimator, phase_from_rate};
use std::path::PathBuf;

/// Stable32's confidence factor in these files.
const CONFIDENCE: f64 = 0.683;

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/stable32")
}

/// Numbers of a data file, one per line; lines starting with '#' and blank lines skipped.
fn read_column(path: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(data_dir().join(path)).expect(path);
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| l.parse().unwrap_or_else(|e| panic!("{path}: '{l}': {e}")))
        .collect()
}

/// One row of a Stable32 table.
#[derive(Debug, Clone, Copy)]
struct Row {
    m: usize,
    tau: f64,
    n: usize,
    alpha: Option<i32>,
    /// (MinSigma, MaxSigma) when the row carries a confidence interval (MinSigma > 0).
    ci: Option<(f64, f64)>,
    sigma: f64,
}

/// Parse `AF Tau # [Alpha MinSigma] Sigma [MaxSigma]` rows: 7 columns (full), 5 (AF Tau #
/// Alpha Sigma) or 4 (AF Tau # Sigma).
fn read_table(path: &str) -> Vec<Row> {
    let text = std::fs::read_to_string(data_dir().join(path)).expect(path);
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| {
            let f: Vec<f64> = l
                .split_whitespace()
                .map(|v| v.parse().unwrap_or_else(|e| panic!("{path}: '{l}': {e}")))
                .collect();
            let (alpha, ci, sigma) = match f.len() {
                7 => (
                    Some(f[3] as i32),
                    (f[4] > 0.0).then_some((f[4], f[6])),
                    f[5],
                ),
                5 => (Some(f[3] as i32), None, f[4]),
                4 => (None, None, f[3]),
                k => panic!("{path}: {k} columns in '{l}'"),
            };
            Row {
                m: f[0] as usize,
                tau: f[1],
                n: f[2] as usize,
                alpha,
                ci,
                sigma,
            }
        })
        .collect()
}

/// The three data sets, as phase.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Set {
    /// PHASE.DAT: phase data.
    Phase,
    /// pink_frequency.txt: fractional frequency.
    Pink,
    /// ocxo_frequency.txt: frequency in Hz about 10 MHz, y = (f - 1e7) / 1e7.
    Ocxo,
    /// The same OCXO record as Stable32 saw it for the `*_octave.txt` files of the overlapping
    /// estimators: normalised to f / 1e7 (the files' header says Average = 1.000000e+00) and
    /// turned into phase by a plain running sum, which keeps the constant 1 and so loses about
    /// four of the sixteen digits (phase reaches 2e4 s while its increments are 1e-11 s). This
    /// reproduces those files' numbers (about 5e-4 above the exact ones at AF 1); the exact
    /// numbers are in the `stable32_*_alltau.txt` files, which `Set::Ocxo` matches.
    OcxoNormalised,
}

fn phase(set: Set, tau0: f64) -> Vec<f64> {
    match set {
        Set::Phase => read_column("phasedat/PHASE.DAT"),
        Set::Pink => phase_from_rate(&read_column("pink_frequency/pink_frequency.txt"), tau0),
        Set::Ocxo => {
            let f = read_column("ocxo/ocxo_frequency.txt");
            let y: Vec<f64> = f.iter().map(|f| (f - 1e7) / 1e7).collect();
            phase_from_rate(&y, tau0)
        }
        Set::OcxoNormalised => std::iter::once(0.0)
            .chain(
                read_column("ocxo/ocxo_frequency.txt")
                    .iter()
                    .scan(0.0, |x, f| {
                        *x += f / 1e7 * tau0;
                        Some(*x)
                    }),
            )
            .collect(),
    }
}

/// Every Stable32 result file used: (file, estimator, data set, tau0).
const FILES: &[(&str, Estimator, Set, f64)] = &[
    (
        "phasedat/phase_dat_adev.txt",
        Estimator::Adev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_adev_octave.txt",
        Estimator::Adev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_oadev.txt",
        Estimator::Oadev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_oadev_octave.txt",
        Estimator::Oadev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_mdev.txt",
        Estimator::Mdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_mdev_octave.txt",
        Estimator::Mdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_tdev.txt",
        Estimator::Tdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_tdev_octave.txt",
        Estimator::Tdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_hdev.txt",
        Estimator::Hdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_hdev_octave.txt",
        Estimator::Hdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_ohdev.txt",
        Estimator::Ohdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_ohdev_octave.txt",
        Estimator::Ohdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_totdev.txt",
        Estimator::Totdev,
        Set::Phase,
        1.0,
    ),
    (
        "phasedat/phase_dat_totdev_octave.txt",
        Estimator::Totdev,
        Set::Phase,
        1.0,
    ),
    ("pink_frequency/adev.txt", Estimator::Adev, Set::Pink, 42.0),
    (
        "pink_frequency/oadev.txt",
        Estimator::Oadev,
        Set::Pink,
        42.0,
    ),
    // This one was run with tau0 = 1 s (its Tau column equals AF).
    (
        "pink_frequency/s32_oadev_octave.txt",
        Estimator::Oadev,
        Set::Pink,
        1.0,
    ),
    ("pink_frequency/mdev.txt", Estimator::Mdev, Set::Pink, 42.0),
    ("pink_frequency/tdev.txt", Estimator::Tdev, Set::Pink, 42.0),
    ("pink_frequency/hdev.txt", Estimator::Hdev, Set::Pink, 42.0),
    (
        "pink_frequency/ohdev.txt",
        Estimator::Ohdev,
        Set::Pink,
        42.0,
    ),
    (
        "pink_frequency/totdev_alpha0.txt",
        Estimator::Totdev,
        Set::Pink,
        42.0,
    ),
    (
        "ocxo/stable32_adev_alltau.txt",
        Estimator::Adev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_oadev_alltau.txt",
        Estimator::Oadev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_mdev_alltau.txt",
        Estimator::Mdev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_tdev_alltau.txt",
        Estimator::Tdev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_hdev_alltau.txt",
        Estimator::Hdev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_ohdev_alltau.txt",
        Estimator::Ohdev,
        Set::Ocxo,
        1.0,
    ),
    (
        "ocxo/stable32_totdev_alltau.txt",
        Estimator::Totdev,
        Set::Ocxo,
        1.0,
    ),
    ("ocxo/adev_octave.txt", Estimator::Adev, Set::Ocxo, 1.0),
    (
        "ocxo/oadev_octave.txt",
        Estimator::Oadev,
        Set::OcxoNormalised,
        1.0,
    ),
    (
        "ocxo/mdev_octave.txt",
        Estimator::Mdev,
        Set::OcxoNormalised,
        1.0,
    ),
    (
        "ocxo/tdev_octave.txt",
        Estimator::Tdev,
        Set::OcxoNormalised,
        1.0,
    ),
    ("ocxo/hdev_octave.txt", Estimator::Hdev, Set::Ocxo, 1.0),
    (
        "ocxo/ohdev_octave.txt",
        Estimator::Ohdev,
        Set::OcxoNormalised,
        1.0,
    ),
    (
        "ocxo/totdev_octave.txt",
        Estimator::Totdev,
        Set::OcxoNormalised,
        1.0,
    ),
];

/// Rows of the OCXO octave files we do not reproduce to 1e-4, with the tolerance to which we
/// do agree with Stable32. All are on the normalised-data runs (see `Set::OcxoNormalised`);
/// the matching exact-data `*_alltau` files agree with us to 1e-4 at every AF.
const LOOSER: &[(&str, usize, f64)] = &[
    // Stable32 9.2304e-12 and 9.1993e-12: we are +1.1e-4 and +1.5e-4 (8 and 7 terms); our
    // value is the same on the exact and on the normalised data.
    ("ocxo/adev_octave.txt", 2048, 2e-4),
    ("ocxo/hdev_octave.txt", 2048, 2e-4),
    // Stable32 4.2610e-11, we are +1.1e-4: rounding noise of the normalised phase, which our
    // emulation reproduces only approximately.
    ("ocxo/ohdev_octave.txt", 2, 2e-4),
    // Stable32's totdev on the normalised data departs from ours by -2.9e-4 at AF 16 growing
    // to -1.2e-2 at AF 1024 (AF 2048..8192 agree again); on the exact data
    // (stable32_totdev_alltau.txt) every AF agrees to 1e-4.
    ("ocxo/totdev_octave.txt", 16, 1e-3),
    ("ocxo/totdev_octave.txt", 32, 2e-3),
    ("ocxo/totdev_octave.txt", 64, 5e-3),
    ("ocxo/totdev_octave.txt", 128, 1e-2),
    ("ocxo/totdev_octave.txt", 256, 1.5e-2),
    ("ocxo/totdev_octave.txt", 512, 1.5e-2),
    ("ocxo/totdev_octave.txt", 1024, 1.5e-2),
];

/// Intervals we reproduce to 2e-3 but not 1e-3 (4 of 159). All have an EDF near 300 and
/// miss by 1e-3 to 1.7e-3 on one side or both; other rows with larger and smaller EDF agree,
/// so Stable32 probably switches to an approximate chi-squared quantile there. Not resolved.
const LOOSER_CI: &[(&str, usize)] = &[
    ("phasedat/phase_dat_oadev_octave.txt", 4),
    ("pink_frequency/s32_oadev_octave.txt", 32),
    ("ocxo/ohdev_octave.txt", 64),
    ("ocxo/totdev_octave.txt", 64),
];

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn deviations_match_stable32() {
    let mut failures = Vec::new();
    let mut rows_checked = 0;
    for &(file, est, set, tau0) in FILES {
        let x = phase(set, tau0);
        let rows = read_table(file);
        let factors: Vec<usize> = rows.iter().map(|r| r.m).collect();
        let d = deviation(est, &x, tau0, &factors);
        assert_eq!(d.m, factors, "{file}: factors");
        for (k, r) in rows.iter().enumerate() {
            rows_checked += 1;
            assert_eq!(d.n[k], r.n, "{file} AF {}: number of terms", r.m);
            assert!(rel(d.tau[k], r.tau) <= 1e-9, "{file} AF {}: tau", r.m);
            let tolerance = LOOSER
                .iter()
                .find(|u| (u.0, u.1) == (file, r.m))
                .map_or(1e-4, |u| u.2);
            if d.n[k] != r.n || rel(d.tau[k], r.tau) > 1e-9 || rel(d.dev[k], r.sigma) > tolerance {
                failures.push(format!(
                    "{file} AF {}: n {} vs {}, tau {} vs {}, dev {:.5e} vs {:.4e} ({:+.1e})",
                    r.m,
                    d.n[k],
                    r.n,
                    d.tau[k],
                    r.tau,
                    d.dev[k],
                    r.sigma,
                    d.dev[k] / r.sigma - 1.0
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {rows_checked} rows differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn confidence_intervals_match_stable32() {
    let mut failures = Vec::new();
    let mut rows_checked = 0;
    for &(file, est, set, tau0) in FILES {
        let n_phase = phase(set, tau0).len();
        for r in read_table(file) {
            let (Some((lo_want, hi_want)), Some(alpha)) = (r.ci, r.alpha) else {
                continue;
            };
            rows_checked += 1;
            // Stable32's own noise type and deviation: this isolates the EDF and the bounds.
            let e = edf(est, alpha, r.m, n_phase);
            let tolerance = if LOOSER_CI.contains(&(file, r.m)) {
                2e-3
            } else {
                1e-3
            };
            let (lo, hi) = chi2_bounds(r.sigma, e, CONFIDENCE);
            if rel(lo, lo_want) > tolerance || rel(hi, hi_want) > tolerance {
                failures.push(format!(
                    "{file} AF {} alpha {alpha}: edf {e:.4}, lo {lo:.4e} vs {lo_want:.4e} \
                     ({:+.1e}), hi {hi:.4e} vs {hi_want:.4e} ({:+.1e})",
                    r.m,
                    lo / lo_want - 1.0,
                    hi / hi_want - 1.0
                ));
            }
        }
    }
    assert!(rows_checked > 90, "{rows_checked}");
    assert!(
        failures.is_empty(),
        "{} of {rows_checked} intervals differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Files whose Alpha column is Stable32's own noise identification: not forced (`alpha0`),
/// and not `ocxo/stable32_totdev_alltau.txt`, whose Alpha column is 0 on every row (that run
/// made no intervals, so no identification).
fn noise_id_files() -> impl Iterator<Item = &'static (&'static str, Estimator, Set, f64)> {
    FILES
        .iter()
        .filter(|f| !f.0.contains("alpha0") && f.0 != "ocxo/stable32_totdev_alltau.txt")
}

#[test]
fn noise_identification_agrees_with_stable32() {
    let (mut agree, mut total) = (0, 0);
    let mut per_file = Vec::new();
    for &(file, est, set, tau0) in noise_id_files() {
        let x = phase(set, tau0);
        let (mut a, mut t) = (0, 0);
        for r in read_table(file) {
            let Some(want) = r.alpha else { continue };
            t += 1;
            a += usize::from(identify(est, &x, r.m) == Some(want));
        }
        per_file.push(format!("{file}: {a}/{t}"));
        agree += a;
        total += t;
    }
    println!("noise ID agrees with Stable32 on {agree} of {total} taus:");
    println!("{}", per_file.join("\n"));
    // Measured: 3103 of 3994 (78 %); nearly all of the misses are at factors with fewer
    // than 30 decimated points, where the B1 / R(n) ratios decide. A floor catches
    // regressions.
    assert!(agree * 100 >= total * 77, "{agree} of {total}");
}

/// The NBS 1000-point series of NIST SP 1065 §12.2 (Riley's test suite): n0 = 1234567890,
/// n(k+1) = 16807 n(k) mod 2147483647, y(k) = n(k) / 2147483647, used as fractional
/// frequency data with tau0 = 1 s.
fn nbs1000() -> Vec<f64> {
    let mut n: u64 = 1_234_567_890;
    let mut y = Vec::with_capacity(1000);
    for _ in 0..1000 {
        y.push(n as f64 / 2_147_483_647.0);
        n = 16_807 * n % 2_147_483_647;
    }
    y
}

/// SP 1065 Table 31 (page 108), values at AF 1, 10, 100, as quoted in allantools'
/// tests/nbs14/test_nbs14_1000point.py (TOTDEV is the plain reflected one, "doubly
/// reflected TOTVAR method", without bias correction).
#[test]
fn nbs_1000_point_series() {
    let y = nbs1000();
    assert_eq!(
        (y[1] * 2_147_483_647.0).round() as u64,
        395_529_916,
        "the generator's second value (SP 1065)"
    );
    let x = phase_from_rate(&y, 1.0);
    let table: [(Estimator, [f64; 3]); 6] = [
        (Estimator::Adev, [2.922319e-01, 9.965736e-02, 3.897804e-02]),
        (Estimator::Oadev, [2.922319e-01, 9.159953e-02, 3.241343e-02]),
        (Estimator::Mdev, [2.922319e-01, 6.172376e-02, 2.170921e-02]),
        (Estimator::Tdev, [1.687202e-01, 3.563623e-01, 1.253382e+00]),
        (Estimator::Hdev, [2.943883e-01, 1.052754e-01, 3.910860e-02]),
        (
            Estimator::Totdev,
            [2.922319e-01, 9.134743e-02, 3.406530e-02],
        ),
    ];
    for (est, want) in table {
        let d = deviation(est, &x, 1.0, &[1, 10, 100]);
        assert_eq!(d.m, vec![1, 10, 100], "{est}");
        for (k, w) in want.iter().enumerate() {
            assert!(
                rel(d.dev[k], *w) < 1e-6,
                "{est} AF {}: {} vs {w}",
                d.m[k],
                d.dev[k]
            );
        }
    }
}
