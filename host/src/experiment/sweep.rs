//! The experiment of the MPU-6050 settings study this project follows
//! (docs/signal_chain.md, Sources): one session per sensor setting (rate and DLPF
//! bandwidth), captured from a board (or the virtual board), analysed and stored; then the
//! gyro's N per setting beside the study's Table 2, the datasheet and the folding
//! prediction. The tables are [`crate::report::sweep_table`], the page
//! [`crate::report::sweep_page`].

use crate::analysis::fit::Term;
use crate::analysis::pipeline::{self, AnalysisError, ChannelResult, Options};
use crate::analysis::units::{self, rad_to_deg};
use crate::capture::CaptureError;
use crate::link::Link;
use crate::link::board::{Board, BoardError};
use crate::link::plan::{Plan as BoardPlan, Request};
use crate::link::setup::{StartError, start_board_for};
use crate::recorder::live::LiveOptions;
use crate::recorder::{self, Ending, Progress, RecordError, RecordOptions};
use crate::report::plot::{Figure, PlotError};
use crate::report::sweep_page::{self, GyroNoise, Published, Setting, SweepPage};
use crate::report::{json, sweep_table};
use crate::sim::chain::white_noise_inflation;
use crate::sim::dlpf::{DlpfDesign, Sensor};
use crate::store::{self, Store, StoreError};
use protocol::mpu6050::Hz;
use protocol::{SensorKind, SensorSettings};
use std::sync::atomic::{AtomicBool, Ordering};

/// One setting's session and analysis.
pub struct SweepRow {
    /// The setting asked for (a GY-85's gyro has the MPU-6050's DLPF table and divider, so
    /// its settings are these too; its accelerometer runs at the same rate).
    pub settings: SensorSettings,
    /// The chip that measured the rates (the datasheet noise and the published values
    /// beside the sweep are that chip's).
    pub gyro: SensorKind,
    pub session_id: i64,
    pub session_name: String,
    pub lost: u64,
    pub results: Vec<ChannelResult>,
    /// The analysis as `analyze --json` gives it (and as stored with the session).
    pub document: serde_json::Value,
}

/// One row of [`document`].
#[derive(serde::Serialize)]
struct RowDocument<'a> {
    /// The setting as `settings` shows it, and its output rate (Hz) and gyro bandwidth (Hz,
    /// absent when the DLPF is off).
    settings: String,
    rate_hz: f64,
    gyro_bandwidth_hz: Option<f64>,
    session_id: i64,
    session_name: &'a str,
    samples_lost: u64,
    analysis: &'a serde_json::Value,
}

/// The sweep as JSON (`sweep --json`): `{"settings": [row, ...]}`, each row a setting, its
/// session and its analysis document.
pub fn document(rows: &[SweepRow]) -> serde_json::Value {
    let rows: Vec<RowDocument> = rows
        .iter()
        .map(|r| RowDocument {
            settings: r.settings.to_string(),
            rate_hz: r.settings.output_rate_hz(),
            gyro_bandwidth_hz: DlpfDesign::for_setting(r.settings.dlpf, Sensor::Gyro).bandwidth_hz,
            session_id: r.session_id,
            session_name: &r.session_name,
            samples_lost: r.lost,
            analysis: &r.document,
        })
        .collect();
    serde_json::to_value(SweepDocument { settings: rows }).unwrap_or_default()
}

#[derive(serde::Serialize)]
struct SweepDocument<'a> {
    settings: Vec<RowDocument<'a>>,
}

/// What a sweep captures.
#[derive(Debug, Clone)]
pub struct Plan<'a> {
    /// The settings, in the order they are captured.
    pub settings: &'a [SensorSettings],
    /// Data per setting, s.
    pub seconds: f64,
    /// Session names are `PREFIX-<rate>hz-<bandwidth>hz` (with -2, -3... when taken).
    pub prefix: &'a str,
    /// The command that asked for the sweep, kept with each stored analysis.
    pub command: &'a [String],
    /// Each capture's live view and stop rule (`seconds` is then the cap per setting).
    pub live: Option<LiveOptions>,
}

/// What happens during a sweep, for a caller to show.
pub enum Event<'a> {
    /// Setting `index` (from 0) of `count` begins on the link `link`, its sensors set as
    /// `plan` says.
    Setting {
        index: usize,
        count: usize,
        plan: &'a BoardPlan,
        link: &'a str,
    },
    /// A capture of `samples` samples into the store begins.
    Capturing { samples: u64 },
    /// How the capture goes.
    Progress(&'a Progress),
    /// The capture ended.
    Captured,
    /// The board did not take Stop after a capture (it may be gone; the session says how it
    /// ended).
    StopFailed(&'a BoardError),
}

/// Why a sweep ended before its last setting was analysed.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error(transparent)]
    Board(#[from] BoardError),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    #[error("{link}: {error}; session {session} kept as incomplete")]
    LinkFailed {
        link: String,
        error: std::io::Error,
        session: i64,
    },
    /// The stop flag was raised (Ctrl-C) at setting `at` (from 0) of `count`; `made` names
    /// the sessions made so far and what became of them.
    #[error(
        "sweep stopped by the user at setting {}/{count}; sessions made: {}",
        .at + 1,
        .made.join(", ")
    )]
    Stopped {
        at: usize,
        count: usize,
        made: Vec<String>,
    },
    #[error("session {0} vanished")]
    Vanished(i64),
    #[error("session {0}: no samples decoded")]
    NothingDecoded(i64),
    /// A capture's samples could not be made a record; `what` names the session.
    #[error("{what}")]
    Decode { what: String, source: CaptureError },
}

/// Capture, store and analyse each setting of `plan` in turn on the board at `link`, until
/// `stop` is raised.
pub fn sweep(
    store: &Store,
    link: &mut dyn Link,
    plan: &Plan,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Event),
) -> Result<Vec<SweepRow>, SweepError> {
    let settings = plan.settings;
    let mut rows: Vec<SweepRow> = Vec::new();
    for (i, s) in settings.iter().enumerate() {
        // Stopped while the last setting was analysed: no new session.
        if stop.load(Ordering::Relaxed) {
            return Err(stopped(store, &rows, None, i, settings));
        }
        let name = format!(
            "{}-{}hz-{}hz",
            plan.prefix,
            Hz(s.output_rate_hz()),
            Hz(bandwidth(s))
        );
        let (info, board_plan) = start_board_for(link, &Request::of(s))?;
        on(Event::Setting {
            index: i,
            count: settings.len(),
            plan: &board_plan,
            link: &link.describe(),
        });
        let gyro = info
            .sensor_list()
            .iter()
            .map(|sensor| sensor.kind)
            .find(|kind| *kind != SensorKind::Adxl345)
            .unwrap_or(SensorKind::Mpu6050);
        let options = RecordOptions {
            name: Some(unique_name(store, &name)?),
            notes: Some(format!("imunoise sweep {}", settings.len())),
            duration_s: Some(plan.seconds),
            keep_samples: true,
            watch: Some(board_plan),
            live: plan.live.clone(),
        };
        on(Event::Capturing {
            samples: (plan.seconds * s.output_rate_hz()) as u64,
        });
        let outcome =
            recorder::record(link, store, &options, stop, &mut |p| on(Event::Progress(p)));
        on(Event::Captured);
        if let Err(e) = Board::new(link).stop() {
            on(Event::StopFailed(&e));
        }
        let outcome = outcome?;
        match outcome.ending {
            Ending::LinkFailed(error) => {
                return Err(SweepError::LinkFailed {
                    link: link.describe(),
                    error,
                    session: outcome.session_id,
                });
            }
            Ending::Stopped => {
                return Err(stopped(store, &rows, Some(outcome.session_id), i, settings));
            }
            Ending::SourceEnded | Ending::DurationReached | Ending::RuleMet(_) => {}
        }
        let session = store
            .get(outcome.session_id)?
            .ok_or(SweepError::Vanished(outcome.session_id))?;
        let capture = outcome
            .capture
            .ok_or(SweepError::NothingDecoded(session.id))?;
        let record = match capture.to_record(&session.name, true) {
            Ok(record) => record,
            Err(source) => {
                let what = format!("session {}", session.name);
                return Err(SweepError::Decode { what, source });
            }
        };
        let analysis = Options::default();
        let results = pipeline::analyze(&record, &analysis, &|| {})?;
        let document = json::document(&record, &analysis, &results);
        let provenance = store::provenance(plan.command, &analysis);
        store.add_analysis(session.id, &provenance, &document)?;
        rows.push(SweepRow {
            settings: *s,
            gyro,
            session_id: session.id,
            session_name: session.name.clone(),
            lost: outcome.counts.samples_lost,
            results,
            document,
        });
    }
    Ok(rows)
}

/// What a sweep stopped at setting `at` leaves: the sessions made so far, and `cut` (the
/// session of setting `at`, shorter than asked for and not analysed).
fn stopped(
    store: &Store,
    rows: &[SweepRow],
    cut: Option<i64>,
    at: usize,
    settings: &[SensorSettings],
) -> SweepError {
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
    SweepError::Stopped {
        at,
        count: settings.len(),
        made,
    }
}

/// The gyro bandwidth of a setting, Hz (what the settings study names settings by).
fn bandwidth(s: &SensorSettings) -> f64 {
    s.dlpf.row().map_or(0.0, |r| r.gyro_bandwidth_hz)
}

/// `name`, or `name-2`, `name-3`... if taken.
fn unique_name(store: &Store, name: &str) -> Result<String, StoreError> {
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

/// N, B, K per axis per setting, with intervals; then the study's Table 2 beside the gyro N
/// ([`paper_comparison`]).
pub fn table(rows: &[SweepRow]) -> String {
    sweep_table::table(&settings_of(rows), &paper_comparison(rows))
}

/// Table 2 of the MPU-6050 settings study (docs/signal_chain.md, Sources): gyro ARW at
/// (output rate Hz, gyro bandwidth Hz), read in [`sweep_table::PAPER_ARW_UNIT`].
pub const PAPER_TABLE_2: [(f64, f64, f64); 4] = [
    (200.0, 256.0, 0.00955),
    (200.0, 42.0, 0.00337),
    (50.0, 256.0, 0.01197),
    (50.0, 42.0, 0.00283),
];

/// The MPU-6050 datasheet's gyro rate noise spectral density, deg/s/sqrt(Hz), at 10 Hz
/// (InvenSense PS-MPU-6000A-00 rev. 3.4, table 6.1); one-sided, so N = this / sqrt(2).
pub const DATASHEET_GYRO_DENSITY: f64 = 0.005;

/// The ITG-3200's, deg/s/sqrt(Hz) (PS-ITG-3200A rev. 1.4, 3.1), one-sided like it.
pub const ITG3200_GYRO_DENSITY: f64 = 0.03;

/// The data sheet's gyro rate noise density of `gyro`, deg/s/sqrt(Hz), one-sided.
pub fn datasheet_density(gyro: SensorKind) -> f64 {
    match gyro {
        SensorKind::Itg3200 => ITG3200_GYRO_DENSITY,
        _ => DATASHEET_GYRO_DENSITY,
    }
}

/// The gyro's white-noise inflation by folding at a setting, N / N0
/// (`sim::chain::white_noise_inflation`: `sqrt(sum_j |H(j f_s)|^2)`, docs/signal_chain.md).
pub fn folding_prediction(s: &SensorSettings) -> f64 {
    let design = DlpfDesign::for_setting(s.dlpf, Sensor::Gyro);
    white_noise_inflation(&design, 1 + usize::from(s.smplrt_div))
}

/// The gyro's N per setting beside the study's Table 2, in deg/sqrt(s): the sweep's N is
/// the mean of the gyro axes, its interval the axes' mean half-widths divided by
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
                datasheet: datasheet_density(row.gyro) / 2f64.sqrt() * predicted,
                // The study's Table 2 is of an MPU-6050.
                published: PAPER_TABLE_2
                    .iter()
                    .filter(|_| row.gyro == SensorKind::Mpu6050)
                    .find(|p| p.0 == rate && p.1 == bw)
                    .map(|p| p.2),
                measured: simulated,
            }
        })
        .collect()
}

/// The sweep's figures: every axis's Allan deviation at every setting, as on the page.
pub fn figures(rows: &[SweepRow]) -> Vec<Figure> {
    sweep_page::figures(&settings_of(rows))
}

/// Each row as the page and the tables show a setting.
pub fn settings_of(rows: &[SweepRow]) -> Vec<Setting<'_>> {
    rows.iter()
        .map(|row| Setting {
            rate_hz: row.settings.output_rate_hz(),
            bandwidth_hz: bandwidth(&row.settings),
            folds: row.settings.aliases(),
            session_id: row.session_id,
            session_name: &row.session_name,
            samples_lost: row.lost,
            results: &row.results,
        })
        .collect()
}

/// The sweep's page ([`sweep_page`]): the table per setting and axis, every axis's figure,
/// the folding prediction and the study's Table 2 beside the sweep.
pub fn html(rows: &[SweepRow], title: &str) -> Result<String, PlotError> {
    let settings = settings_of(rows);
    let gyro = paper_comparison(rows);
    let gyro_chip = rows.first().map_or(SensorKind::Mpu6050, |r| r.gyro);
    let sensor = match gyro_chip {
        SensorKind::Itg3200 => "the GY-85's ITG-3200 (its ADXL345 at the same output rate)",
        _ => "the MPU-6050",
    };
    sweep_page::page(&SweepPage {
        title,
        sensor,
        settings: &settings,
        gyro: &gyro,
        published: Published {
            source: "the settings study's Table 2",
            datasheet_density: datasheet_density(gyro_chip),
        },
        // sweep() analyses every setting with the default options.
        options: &Options::default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{Channel, Record};
    use crate::report::sweep_table;
    use crate::sim::chain::AxisChain;
    use crate::sim::noise::NoiseTerms;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn a_sweep_stopped_before_it_starts_names_what_it_made() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let mut opened = crate::link::open(&crate::link::PortSpec {
            board: crate::link::setup::SimulatedBoard::Mpu6050,
            port: crate::link::setup::VIRTUAL_PORT,
            speed: crate::link::replay::Speed::Max,
            model: None,
            seed: 1,
        })
        .unwrap();
        let settings = [SensorSettings::default(); 2];
        let plan = Plan {
            settings: &settings,
            seconds: 1.0,
            prefix: "t",
            command: &[],
            live: None,
        };
        let mut events = 0;
        let e = sweep(
            &store,
            opened.link.as_mut(),
            &plan,
            &AtomicBool::new(true),
            &mut |_| events += 1,
        )
        .err()
        .unwrap();
        assert_eq!(
            e.to_string(),
            "sweep stopped by the user at setting 1/2; sessions made: none"
        );
        assert_eq!(events, 0);
        assert!(store.list().unwrap().is_empty());
    }

    #[test]
    fn table_2_beside_the_folding_prediction_and_the_datasheet() {
        let rows: Vec<SweepRow> = PAPER_TABLE_2
            .iter()
            .map(|&(rate, bw, _)| SweepRow {
                settings: SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap(),
                gyro: SensorKind::Mpu6050,
                session_id: 0,
                session_name: String::new(),
                lost: 0,
                results: Vec::new(),
                document: serde_json::Value::Null,
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
        let text = sweep_table::paper_table(&table);
        assert!(text.contains("0.00955") && text.contains("+53 %") && text.contains("-44 %"));
        assert!(text.contains("2.83") && text.contains("0.84"), "{text}");
        assert!(text.contains("The study agrees"), "{text}");

        // A GY-85 sweep: the ITG-3200's datasheet density (0.03 deg/s/sqrt(Hz) one-sided)
        // times the same folding, and no published value (the study's is an MPU-6050's).
        let gy85: Vec<SweepRow> = rows
            .into_iter()
            .map(|r| SweepRow {
                gyro: SensorKind::Itg3200,
                ..r
            })
            .collect();
        let table = paper_comparison(&gy85);
        for (row, (fold, ..)) in table.iter().zip(expected) {
            let want = ITG3200_GYRO_DENSITY / 2f64.sqrt() * fold;
            assert!((row.datasheet / want - 1.0).abs() < 1e-3, "{row:?}");
            assert_eq!(row.published, None);
        }
        let text = sweep_table::paper_table(&table);
        assert!(
            text.contains("beside the datasheet and the folding prediction"),
            "{text}"
        );
        assert!(
            text.contains("0.0300 deg/s/sqrt(Hz) one-sided (N0 = 0.0212)"),
            "{text}"
        );
        assert!(!text.contains("The study agrees"), "{text}");
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
                    gyro: SensorKind::Mpu6050,
                    session_id: i as i64,
                    session_name: String::new(),
                    lost: 0,
                    results: pipeline::analyze(&record, &options, &|| {}).unwrap(),
                    document: serde_json::Value::Null,
                }
            })
            .collect();
        let table = paper_comparison(&rows);
        println!("{}", sweep_table::paper_table(&table));
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
}
