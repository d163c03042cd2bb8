//! `imunoise sweep`: the experiment of the MPU-6050 settings study this project follows
//! (docs/signal_chain.md, Sources). One session per sensor setting (rate and DLPF
//! bandwidth), captured from the board (or the virtual board), analysed and stored; then the
//! table of N, B, K per axis per setting with intervals, the study's Table 2 beside the
//! sweep's gyro N and the folding prediction, and the Allan curves of all settings on one
//! figure.

use crate::analysis::fit::Term;
use crate::analysis::pipeline::{self, ChannelResult, Options};
use crate::analysis::units::{self, NoiseTerm, rad_to_deg};
use crate::cli::analyze::check_plot;
use crate::cli::capture::{
    PortSpec, VirtualBoardArgs, open_port, show, start_board, stop_board, stop_on_ctrl_c,
    streamable,
};
use crate::cli::output;
use crate::cli::settings::aliases;
use crate::cli::simulate::parse_duration;
use crate::cli::stored::{open_store, provenance};
use crate::link::replay::Speed;
use crate::recorder::{self, Ending, RecordOptions};
use crate::report::plot::{self, Figure};
use crate::report::sweep_page::GyroNoise;
use crate::report::{self, json, sig, sig_interval};
use crate::sim::chain::white_noise_inflation;
use crate::sim::dlpf::{DlpfDesign, Sensor};
use crate::store::Store;
use anyhow::{Context, Result, anyhow, bail};
use protocol::SensorSettings;
use protocol::mpu6050::Hz;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// The board: a serial port or `sim` for the virtual board
    #[arg(long)]
    pub port: String,
    /// Settings as RATE:BANDWIDTH, comma-separated (the settings study's four by default)
    #[arg(long, default_value = "200:256,200:42,50:256,50:42")]
    pub settings: String,
    /// Data per setting: 30m, 2h, ...
    #[arg(long, default_value = "30m")]
    pub duration: String,
    /// Speed of the virtual board: max, or a factor (1 = real time)
    #[arg(long, default_value = "1")]
    pub speed: Speed,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
    /// Session names are PREFIX-<rate>hz-<bandwidth>hz
    #[arg(long, default_value = "sweep")]
    pub prefix: String,
    /// Write the figure (Allan deviation of every setting) to PATH.svg or .png
    #[arg(long, value_name = "PATH")]
    pub plot: Option<PathBuf>,
    /// Write an HTML report (the table and the figures) to PATH
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// One setting's session and analysis.
pub struct SweepRow {
    pub settings: SensorSettings,
    pub session_id: i64,
    pub session_name: String,
    pub lost: u64,
    pub results: Vec<ChannelResult>,
}

/// "200:256,200:42" to settings, each checked against the settings model.
pub fn parse_settings(text: &str) -> Result<Vec<SensorSettings>> {
    text.split(',')
        .map(|pair| {
            let (rate, bw) = pair.split_once(':').ok_or_else(|| {
                anyhow!("--settings '{pair}': expected RATE:BANDWIDTH, e.g. 200:42")
            })?;
            let parse = |v: &str| {
                v.trim()
                    .parse::<f64>()
                    .map_err(|_| anyhow!("--settings '{pair}': '{v}' is not a number"))
            };
            let (rate, bw) = (parse(rate)?, parse(bw)?);
            let settings = SensorSettings::for_rate_and_bandwidth(rate, bw)
                .map_err(|e| anyhow!("--settings {rate}:{bw}: {e}"))?;
            streamable(&settings).map_err(|e| anyhow!("--settings {rate}:{bw}: {e}"))?;
            Ok(settings)
        })
        .collect()
}

pub fn run(args: &SweepArgs, store: Option<&Path>) -> Result<()> {
    let settings = parse_settings(&args.settings)?;
    let seconds = parse_duration(&args.duration).map_err(|e| anyhow!("--duration: {e}"))?;
    if let Some(path) = &args.plot {
        check_plot(path)?;
    }
    if let Some(path) = &args.report {
        output::check_folder(path, "--report")?;
    }
    let store = open_store(store)?;
    let spec = PortSpec {
        port: &args.port,
        speed: args.speed,
        model: args.virtual_board.model.as_deref(),
        seed: args.virtual_board.seed,
    };
    let rows = sweep(&store, &spec, &settings, seconds, &args.prefix)?;
    print!("{}", table(&rows));
    if let Some(path) = &args.plot {
        plot::write(path, &figures(&rows))?;
        println!("wrote figure: {}", path.display());
    }
    if let Some(path) = &args.report {
        std::fs::write(path, html(&rows, "imunoise sweep")?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote HTML report: {}", path.display());
    }
    Ok(())
}

/// Capture, store and analyse each setting in turn on one board.
pub fn sweep(
    store: &Store,
    spec: &PortSpec,
    settings: &[SensorSettings],
    seconds: f64,
    prefix: &str,
) -> Result<Vec<SweepRow>> {
    let mut link = open_port(spec)?;
    let stop = stop_on_ctrl_c()?;
    let mut rows: Vec<SweepRow> = Vec::new();
    for (i, s) in settings.iter().enumerate() {
        // Ctrl-C while the last setting was analysed: no new session.
        if stop.load(Ordering::Relaxed) {
            bail!(stopped(store, &rows, None, i, settings));
        }
        let name = format!(
            "{prefix}-{}hz-{}hz",
            Hz(s.output_rate_hz()),
            Hz(bandwidth(s))
        );
        eprintln!(
            "setting {}/{}: {s} for {} s ({})",
            i + 1,
            settings.len(),
            seconds,
            link.describe()
        );
        start_board(link.as_mut(), *s)?;
        let options = RecordOptions {
            name: Some(unique_name(store, &name)?),
            notes: Some(format!("imunoise sweep {}", settings.len())),
            duration_s: Some(seconds),
            keep_samples: true,
            watch: Some(*s),
            live: None,
        };
        let bar = report::progress::bar((seconds * s.output_rate_hz()) as u64, "capturing");
        let outcome = recorder::record(link.as_mut(), store, &options, &stop, &mut |p| {
            show(&bar, p)
        });
        bar.finish_and_clear();
        stop_board(link.as_mut());
        let outcome = outcome?;
        match &outcome.ending {
            Ending::LinkFailed(e) => bail!(
                "{}: {e}; session {} kept as incomplete",
                link.describe(),
                outcome.session_id
            ),
            Ending::Stopped => bail!(stopped(store, &rows, Some(outcome.session_id), i, settings)),
            Ending::SourceEnded | Ending::DurationReached | Ending::RuleMet(_) => {}
        }
        let session = store
            .get(outcome.session_id)?
            .ok_or_else(|| anyhow!("session {} vanished", outcome.session_id))?;
        let capture = outcome
            .capture
            .ok_or_else(|| anyhow!("session {}: no samples decoded", session.id))?;
        let record = capture
            .to_record(&session.name, true)
            .with_context(|| format!("session {}", session.name))?;
        let analysis = Options::default();
        let results = pipeline::analyze(&record, &analysis, &|| {})?;
        let document = json::document(&record, &analysis, &results);
        store.add_analysis(session.id, &provenance(&analysis), &document)?;
        rows.push(SweepRow {
            settings: *s,
            session_id: session.id,
            session_name: session.name.clone(),
            lost: outcome.counts.samples_lost,
            results,
        });
    }
    Ok(rows)
}

/// What a sweep stopped by the user (Ctrl-C) at setting `at` leaves: the sessions made so
/// far, and `cut` (the session of setting `at`, shorter than asked for and not analysed).
fn stopped(
    store: &Store,
    rows: &[SweepRow],
    cut: Option<i64>,
    at: usize,
    settings: &[SensorSettings],
) -> String {
    let mut made: Vec<String> = rows
        .iter()
        .map(|r| format!("{} '{}' (analysed)", r.session_id, r.session_name))
        .collect();
    if let Some(id) = cut {
        let name = store
            .get(id)
            .ok()
            .flatten()
            .map_or_else(String::new, |s| format!(" '{}'", s.name));
        made.push(format!("{id}{name} (cut short, not analysed)"));
    }
    if made.is_empty() {
        made.push("none".into());
    }
    format!(
        "sweep stopped by the user at setting {}/{}; sessions made: {}",
        at + 1,
        settings.len(),
        made.join(", ")
    )
}

/// The gyro bandwidth of a setting, Hz (what the settings study names settings by).
fn bandwidth(s: &SensorSettings) -> f64 {
    s.dlpf.row().map_or(0.0, |r| r.gyro_bandwidth_hz)
}

/// `name`, or `name-2`, `name-3`... if taken.
fn unique_name(store: &Store, name: &str) -> Result<String> {
    let taken: Vec<String> = store.list()?.into_iter().map(|s| s.name).collect();
    Ok((1..)
        .map(|i| {
            if i == 1 {
                name.to_string()
            } else {
                format!("{name}-{i}")
            }
        })
        .find(|n| !taken.contains(n))
        .unwrap_or_else(|| name.to_string()))
}

/// N, B, K per axis per setting, conventional units, with intervals; then the study's
/// Table 2 beside the gyro N ([`paper_table`]).
pub fn table(rows: &[SweepRow]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\nNoise terms per setting (IEEE-952 fit to the overlapping Allan variance, 68.3 % intervals)"
    );
    let _ = writeln!(
        out,
        "{:<16} {:<5} {:>30} {:>30} {:>30}",
        "setting", "axis", "N", "B", "K"
    );
    for row in rows {
        let label = format!(
            "{}/{} Hz{}",
            Hz(row.settings.output_rate_hz()),
            Hz(bandwidth(&row.settings)),
            if aliases(&row.settings) { "*" } else { "" }
        );
        for r in &row.results {
            let Ok(fit) = &r.fit else { continue };
            if r.kind == units::SensorKind::Other {
                continue;
            }
            let cell = |term: NoiseTerm, t: &crate::analysis::fit::Term| {
                let c = |v| units::conventional(r.kind, term, v);
                let [value, lo, hi] =
                    sig_interval(c(t.value).value, c(t.lo).value, c(t.hi).value, 3);
                format!("{value} [{lo}..{hi}] {}", c(t.value).unit)
            };
            let _ = writeln!(
                out,
                "{:<16} {:<5} {:>30} {:>30} {:>30}",
                label,
                r.name,
                cell(NoiseTerm::N, &fit.n),
                cell(NoiseTerm::B, &fit.b),
                cell(NoiseTerm::K, &fit.k)
            );
        }
    }
    let _ = writeln!(
        out,
        "* bandwidth above half the output rate: noise above the Nyquist frequency folds back"
    );
    for row in rows {
        let _ = writeln!(
            out,
            "session {} '{}': {} samples lost",
            row.session_id, row.session_name, row.lost
        );
    }
    out + &paper_table(&paper_comparison(rows))
}

/// Table 2 of the MPU-6050 settings study (docs/signal_chain.md, Sources): gyro ARW at
/// (output rate Hz, gyro bandwidth Hz). The study does not state the unit; see
/// [`PAPER_ARW_UNIT`].
pub const PAPER_TABLE_2: [(f64, f64, f64); 4] = [
    (200.0, 256.0, 0.00955),
    (200.0, 42.0, 0.00337),
    (50.0, 256.0, 0.01197),
    (50.0, 42.0, 0.00283),
];

/// The unit assumed for [`PAPER_TABLE_2`]: deg/sqrt(s), i.e. deg/s/sqrt(Hz) as the Allan
/// deviation at tau = 1 s (the two-sided density N). Why: the datasheet's rate noise
/// density, 0.005 deg/s/sqrt(Hz) one-sided ([`DATASHEET_GYRO_DENSITY`]), is N = 0.00354
/// deg/sqrt(s); the study's 200 Hz / 42 Hz value, where nothing folds, is 0.00337 (-5 %).
/// Read as deg/sqrt(h) it would be 63 times quieter than the datasheet, as rad/sqrt(s) 55
/// times noisier, and as the standard deviation of 200 Hz samples (deg/s) 15 times quieter
/// than the datasheet's 0.05 deg/s rms.
pub const PAPER_ARW_UNIT: &str = "deg/sqrt(s)";

/// The MPU-6050 datasheet's gyro rate noise spectral density, deg/s/sqrt(Hz), at 10 Hz
/// (InvenSense PS-MPU-6000A-00 rev. 3.4, table 6.1); one-sided, so N = this / sqrt(2).
pub const DATASHEET_GYRO_DENSITY: f64 = 0.005;

/// The gyro's white-noise inflation by folding at a setting, N / N0
/// (`sim::chain::white_noise_inflation`: `sqrt(sum_j |H(j f_s)|^2)`, docs/signal_chain.md).
pub fn folding_prediction(s: &SensorSettings) -> f64 {
    let design = DlpfDesign::for_setting(s.dlpf, Sensor::Gyro);
    white_noise_inflation(&design, 1 + usize::from(s.smplrt_div))
}

/// The gyro's N per setting beside the study's Table 2, in [`PAPER_ARW_UNIT`]: the sweep's N
/// is the mean of the gyro axes, its interval the axes' mean half-widths divided by
/// sqrt(axes) (independent axes of equal noise).
pub fn paper_comparison(rows: &[SweepRow]) -> Vec<GyroNoise> {
    rows.iter()
        .map(|row| {
            let s = &row.settings;
            let (rate, bw) = (s.output_rate_hz(), bandwidth(s));
            let predicted = folding_prediction(s);
            let gyro: Vec<Term> = row
                .results
                .iter()
                .filter(|r| r.kind == units::SensorKind::Gyro)
                .filter_map(|r| r.fit.as_ref().ok().map(|f| f.n))
                .collect();
            let simulated = (!gyro.is_empty()).then(|| {
                let count = gyro.len() as f64;
                let mean = |f: fn(&Term) -> f64| gyro.iter().map(f).sum::<f64>() / count;
                let value = mean(|t| t.value);
                let (below, above) = (value - mean(|t| t.lo), mean(|t| t.hi) - value);
                Term {
                    value: rad_to_deg(value),
                    lo: rad_to_deg(value - below / count.sqrt()),
                    hi: rad_to_deg(value + above / count.sqrt()),
                }
            });
            GyroNoise {
                rate_hz: rate,
                bandwidth_hz: bw,
                folding: predicted,
                datasheet: DATASHEET_GYRO_DENSITY / 2f64.sqrt() * predicted,
                published: PAPER_TABLE_2
                    .iter()
                    .find(|p| p.0 == rate && p.1 == bw)
                    .map(|p| p.2),
                measured: simulated,
            }
        })
        .collect()
}

/// [`paper_comparison`] as text: absolute values, and ratios to the 200 Hz / 42 Hz setting
/// (where nothing folds) when it is in the sweep.
pub fn paper_table(rows: &[GyroNoise]) -> String {
    let mut out = format!(
        "\nGyro ARW beside the settings study's Table 2, in {PAPER_ARW_UNIT} (= deg/s/sqrt(Hz), the \
         Allan deviation at 1 s; the study's unit is assumed: docs/signal_chain.md)\n"
    );
    let _ = writeln!(
        out,
        "{:<12} {:>8} {:>10} {:>8} {:>8} {:>28} | {:>8} {:>6} {:>6}",
        "setting",
        "folding",
        "datasheet",
        "study",
        "vs ds",
        "this sweep [68.3 %]",
        "folding",
        "study",
        "sweep"
    );
    let reference = rows
        .iter()
        .find(|r| r.rate_hz == 200.0 && r.bandwidth_hz == 42.0);
    let ratio = |v: Option<f64>, r: Option<f64>| match (v, r) {
        (Some(v), Some(r)) if r > 0.0 => format!("{:.2}", v / r),
        _ => "-".to_string(),
    };
    for r in rows {
        let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| sig(v, 3));
        let vs_datasheet = r.published.map_or_else(
            || "-".to_string(),
            |p| format!("{:+.0} %", (p / r.datasheet - 1.0) * 100.0),
        );
        let sweep = r.measured.map_or_else(
            || "-".to_string(),
            |t| {
                let [value, lo, hi] = sig_interval(t.value, t.lo, t.hi, 4);
                format!("{value} [{lo}..{hi}]")
            },
        );
        let _ = writeln!(
            out,
            "{:<12} {:>8.3} {:>10} {:>8} {:>8} {:>28} | {:>8} {:>6} {:>6}",
            format!("{}/{} Hz", Hz(r.rate_hz), Hz(r.bandwidth_hz)),
            r.folding,
            sig(r.datasheet, 3),
            opt(r.published),
            vs_datasheet,
            sweep,
            ratio(Some(r.folding), reference.map(|x| x.folding)),
            ratio(r.published, reference.and_then(|x| x.published)),
            ratio(
                r.measured.map(|t| t.value),
                reference.and_then(|x| x.measured.map(|t| t.value))
            ),
        );
    }
    out.push_str(
        "folding: predicted N / N0; datasheet: 0.005 deg/s/sqrt(Hz) one-sided (N0 = 0.00354) x \
         folding; vs ds: study / datasheet; after |: ratios to 200/42 Hz.\nThe study agrees with \
         datasheet x folding within 5 % at 200/42 and 50/256, not at 200/256 or 50/42; its \
         50/42 below 200/42 is impossible for any stationary input through one filter \
         (docs/signal_chain.md).\n",
    );
    out
}

/// The sweep's figures for `--plot`: every axis's Allan deviation at every setting, as on
/// the page.
pub fn figures(rows: &[SweepRow]) -> Vec<Figure> {
    crate::report::sweep_page::figures(&settings_of(rows))
}

/// Each row as the page shows a setting.
fn settings_of(rows: &[SweepRow]) -> Vec<crate::report::sweep_page::Setting<'_>> {
    rows.iter()
        .map(|row| crate::report::sweep_page::Setting {
            rate_hz: row.settings.output_rate_hz(),
            bandwidth_hz: bandwidth(&row.settings),
            folds: aliases(&row.settings),
            session_id: row.session_id,
            session_name: &row.session_name,
            samples_lost: row.lost,
            results: &row.results,
        })
        .collect()
}

/// The sweep's page ([`crate::report::sweep_page`]): the table per setting and axis, every
/// axis's figure, the folding prediction and the study's Table 2 beside the sweep.
pub fn html(rows: &[SweepRow], title: &str) -> Result<String> {
    use crate::report::sweep_page::{self, Published, SweepPage};
    let settings = settings_of(rows);
    let gyro = paper_comparison(rows);
    Ok(sweep_page::page(&SweepPage {
        title,
        settings: &settings,
        gyro: &gyro,
        published: Published {
            source: "the settings study's Table 2",
            datasheet_density: DATASHEET_GYRO_DENSITY,
        },
        // sweep() analyses every setting with the default options.
        options: &Options::default(),
    })?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{Channel, Record};
    use crate::sim::chain::AxisChain;
    use crate::sim::noise::NoiseTerms;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn table_2_beside_the_folding_prediction_and_the_datasheet() {
        let rows: Vec<SweepRow> = PAPER_TABLE_2
            .iter()
            .map(|&(rate, bw, _)| SweepRow {
                settings: SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap(),
                session_id: 0,
                session_name: String::new(),
                lost: 0,
                results: Vec::new(),
            })
            .collect();
        let table = paper_comparison(&rows);
        // Folding predictions (docs/signal_chain.md), the datasheet's N = 0.005 / sqrt(2)
        // times them, and the study's values read in deg/sqrt(s) against that.
        let expected = [
            (1.768, 0.00625, 0.00955, 0.53),
            (1.006, 0.00356, 0.00337, -0.05),
            (3.535, 0.0125, 0.01197, -0.04),
            (1.418, 0.00501, 0.00283, -0.44),
        ];
        for (row, (fold, ds, paper, off)) in table.iter().zip(expected) {
            assert!((row.folding - fold).abs() < 5e-4, "{row:?}");
            assert!((row.datasheet / ds - 1.0).abs() < 2e-3, "{row:?}");
            assert_eq!(row.published, Some(paper));
            assert!((paper / row.datasheet - 1.0 - off).abs() < 0.005, "{row:?}");
            assert!(row.measured.is_none());
        }
        // The unit assumption: N of the datasheet is 0.00354 deg/sqrt(s); the study's
        // unfolded 200/42 read as deg/sqrt(h) would be 63 times below it, as rad/sqrt(s) 55
        // times above, as the standard deviation of 200 Hz samples 15 times below the
        // datasheet's 0.05 deg/s rms (N sqrt(200 Hz) = 0.050).
        let n_ds = DATASHEET_GYRO_DENSITY / 2f64.sqrt();
        let p = PAPER_TABLE_2[1].2;
        assert!((n_ds / (p / 60.0) - 63.0).abs() < 0.5);
        assert!((rad_to_deg(p) / n_ds - 54.6).abs() < 0.5);
        assert!((n_ds * 200f64.sqrt() / p - 14.8).abs() < 0.1);
        let text = paper_table(&table);
        assert!(text.contains("0.00955") && text.contains("+53 %") && text.contains("-44 %"));
        assert!(text.contains("2.83") && text.contains("0.84"), "{text}");
    }

    /// White gyro noise (N0 = 1.5e-4 rad/s/sqrt(Hz), the example model's) through the
    /// simulated chain at the four settings, 15 min each, analysed as a sweep would: N at
    /// 50 Hz is at least N at 200 Hz with the same filter, and every setting's N / N0 matches
    /// the folding prediction, both within 3 standard deviations from the fitted intervals.
    /// The fit starts at tau = 0.5 s, where no setting's filter shapes the Allan curve any
    /// more: how the fit treats the filter is `tests/tests/low_pass_fit.rs`'s subject, this
    /// test's is the folding.
    #[test]
    fn simulated_sweep_obeys_folding() {
        let n0 = 1.5e-4;
        let seconds = 900.0;
        let options = Options {
            fit_tau_min: Some(0.5),
            ..Options::default()
        };
        let rows: Vec<SweepRow> = PAPER_TABLE_2
            .iter()
            .enumerate()
            .map(|(i, &(rate, bw, _))| {
                let settings = SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap();
                let design = DlpfDesign::for_setting(settings.dlpf, Sensor::Gyro);
                let m = 1 + u64::from(settings.smplrt_div);
                let terms = NoiseTerms {
                    n: n0,
                    ..NoiseTerms::default()
                };
                let mut chain = AxisChain::new(
                    terms,
                    &design,
                    seconds,
                    ChaCha8Rng::seed_from_u64(40 + i as u64),
                );
                let y: Vec<f64> = (0..(seconds * rate) as u64)
                    .map(|k| chain.advance_to(k * m, 0.0))
                    .collect();
                let record = Record {
                    source: format!("{rate}/{bw}"),
                    rate_hz: rate,
                    channels: vec![Channel::named("gx", y)],
                };
                SweepRow {
                    settings,
                    session_id: i as i64,
                    session_name: String::new(),
                    lost: 0,
                    results: pipeline::analyze(&record, &options, &|| {}).unwrap(),
                }
            })
            .collect();
        let table = paper_comparison(&rows);
        println!("{}", paper_table(&table));
        // One standard deviation from the 68.3 % interval, in deg/sqrt(s).
        let sim = |r: &GyroNoise| {
            let t = r.measured.expect("a gyro fit");
            (t.value, (t.hi - t.lo) / 2.0)
        };
        let n0_deg = rad_to_deg(n0);
        for r in &table {
            let (n, sd) = sim(r);
            assert!(
                (n - r.folding * n0_deg).abs() < 3.0 * sd,
                "{r:?}: N / N0 {} against {}",
                n / n0_deg,
                r.folding
            );
        }
        for bw in [256.0, 42.0] {
            let at = |rate: f64| {
                sim(table
                    .iter()
                    .find(|r| r.rate_hz == rate && r.bandwidth_hz == bw)
                    .unwrap())
            };
            let ((n50, sd50), (n200, sd200)) = (at(50.0), at(200.0));
            assert!(
                n50 >= n200 - 3.0 * (sd50 * sd50 + sd200 * sd200).sqrt(),
                "{bw} Hz: N(50) {n50} < N(200) {n200}"
            );
        }
    }

    #[test]
    fn settings_parse_and_errors_name_the_pair() {
        let s = parse_settings("200:256, 50:42").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].output_rate_hz(), 50.0);
        let e = parse_settings("200-42").unwrap_err().to_string();
        assert!(e.contains("'200-42': expected RATE:BANDWIDTH"), "{e}");
        let e = parse_settings("150:42").unwrap_err().to_string();
        assert!(e.contains("--settings 150:42"), "{e}");
    }
}
