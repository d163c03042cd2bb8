//! `imunoise bench`: our engine against the reference tool on the same generated data.
//!
//! 1. Overlapping Allan deviation of 10^7 white-noise rate samples at 100 Hz, at the taus of
//!    `analyze --taus per-decade:14`: allantools' `oadev` (`scripts/bench_allantools.py`, run
//!    with `python3`) against imunoise's engine (in process, best of three) and against a whole
//!    `imunoise analyze` of the same data as a `.npy` file (a child process, best of three:
//!    reading, line search, Allan curve with intervals, fit, PSD and its fit, output), their
//!    ratios, and the largest relative difference of the deviations; the engine's peak memory
//!    and the whole analysis's peak resident memory (Linux), each over the input's size; and
//!    the same for the streamed analysis (`--memory-budget 1`).
//! 2. A full `analyze` (six channels, oadev with CIs, PSD, fit) of an 8-hour 200 Hz record.
//! 3. The simulator's cost per noise term: an hour of six axes at 1 kHz.
//! 4. Decoding a large capture file (target: at least 100 MB/s).
//! 5. The model workflow on three 3-hour 100 Hz records with hidden effects (target: each
//!    under 30 s).
//! 6. The streamed analysis (`analyze` of an .npy beyond `--memory-budget`: streaming Allan
//!    accumulators, a streamed Welch PSD, the noise fit) over 24 h of six axes at 1 kHz, fed
//!    in blocks: throughput and peak memory, against the memory the record read whole needs.
//! 7. A ROS 1 bag of 8 hours of `sensor_msgs/Imu` at 200 Hz, generated: `imunoise import`
//!    and `imunoise analyze` of the session timed, beside the 215 s that allan_variance_ros
//!    is reported to take for an 8-hour bag on a 16-core Ryzen 9 3950X (its GitHub issue #15,
//!    "How long should this take to run?", a Release build).

use anyhow::{Context, Result, bail};
use imunoise::analysis::pipeline::{self, Options};
use imunoise::analysis::taus::{self, TauGrid};
use imunoise::analysis::{Estimator, allan, into_phase};
use imunoise::input;
use imunoise::record::{Channel, Record};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

const REFERENCE_SCRIPT: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/bench_allantools.py"
));

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Samples for the Allan deviation comparison
    #[arg(long, default_value_t = 10_000_000)]
    pub samples: usize,
    /// Tau grid of the Allan comparison (as `analyze --taus`)
    #[arg(long, default_value = "per-decade:14")]
    pub taus: TauGrid,
    /// Hours of 200 Hz six-axis data for the full-analysis benchmark
    #[arg(long, default_value_t = 8.0)]
    pub hours: f64,
    /// Size of the capture for the decoding benchmark, MB
    #[arg(long, default_value_t = 200)]
    pub capture_mb: usize,
    /// Python interpreter with allantools and numpy installed
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Skip allantools (time imunoise only)
    #[arg(long)]
    pub no_reference: bool,
    /// Hours of 1 kHz six-axis data for the streaming benchmark
    #[arg(long, default_value_t = 24.0)]
    pub stream_hours: f64,
    /// Hours of 200 Hz Imu messages in the ROS bag benchmark
    #[arg(long, default_value_t = 8.0)]
    pub bag_hours: f64,
}

pub fn run(args: &BenchArgs) -> Result<()> {
    if args.samples < 100 {
        bail!("--samples at least 100");
    }
    println!(
        "imunoise bench ({} threads)\n",
        rayon::current_num_threads()
    );
    let dir = std::env::temp_dir().join(format!("imunoise-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let compared = allan_comparison(args, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    compared?;
    full_analysis(args.hours)?;
    simulator_terms();
    decode_throughput(args.capture_mb);
    model_workflow()?;
    streaming(args.stream_hours)?;
    crate::cli::bench_rosbag::run(args.bag_hours)
}

/// The rate of section 1's record, Hz.
const COMPARISON_RATE_HZ: f64 = 100.0;

/// Section 1: allantools' oadev against the engine and against a whole `analyze`, on one
/// record written to `dir`.
fn allan_comparison(args: &BenchArgs, dir: &Path) -> Result<()> {
    let y = white(args.samples, 1);
    let factors = taus::factors(args.taus, allan::max_factor(Estimator::Oadev, y.len() + 1));
    println!(
        "1. Overlapping Allan deviation, {} white-noise samples at {COMPARISON_RATE_HZ} Hz, {} taus ({})",
        y.len(),
        factors.len(),
        args.taus
    );
    let data = dir.join("y.npy");
    input::write_npy(&data, &y)?;
    let input_bytes = std::fs::metadata(&data)?.len() as f64;
    let ours = time_oadev(&y, &factors);
    println!("   engine:         {:>8.3} s (best of 3)", ours.seconds);
    match peak_over_input(&y, &factors) {
        Some(ratio) => {
            println!("   engine peak memory: {ratio:.2} x the input, the input included (VmHWM)")
        }
        None => println!("   engine peak memory: not measurable on this OS"),
    }
    drop(y);
    // The streamed analysis first, then the whole one, before any other child process: the
    // peak resident memory of the children so far is then each one's (the streamed one holds
    // less).
    // A child spawned by vfork shares this process's memory until it execs, and Linux keeps
    // that memory's high-water mark as the child's peak: reset it to what is resident now
    // (the record was dropped above), so the peak is the child's own.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
    let streamed = time_analyze(&data, args.taus, dir, &["--memory-budget", "1"])?;
    let streamed_rss = children_peak_rss().map(|bytes| bytes / input_bytes);
    println!(
        "   streamed analyze: {:>6.3} s (best of 3; the same with --memory-budget 1: no line search, no roll-off detection, PSD by Welch only)",
        streamed.seconds
    );
    if let Some(r) = streamed_rss {
        println!("   streamed analyze peak memory: {r:.2} x the input, resident (getrusage)");
    }
    let whole = time_analyze(&data, args.taus, dir, &[])?;
    println!(
        "   whole analyze:  {:>8.3} s (best of 3; `imunoise analyze y.npy --rate {COMPARISON_RATE_HZ} --estimator oadev --taus {}`)",
        whole.seconds, args.taus
    );
    let rss_ratio = children_peak_rss().map(|bytes| bytes / input_bytes);
    match rss_ratio {
        Some(r) => println!(
            "   whole analyze peak memory: {r:.2} x the input ({:.0} MB .npy), resident (getrusage)",
            input_bytes / 1e6
        ),
        None => println!("   whole analyze peak memory: not measurable on this OS"),
    }
    let agree = |name: &str, devs: &[f64], reference: &[f64]| {
        let max_rel = devs
            .iter()
            .zip(reference)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0, f64::max);
        println!("   {name} against allantools: largest relative difference {max_rel:.1e}");
    };
    if args.no_reference {
        println!("   allantools: skipped (--no-reference)");
        return Ok(());
    }
    match run_reference(&args.python, dir, &data, &factors) {
        Ok((seconds, devs, version)) => {
            println!("   allantools:     {seconds:>8.3} s (version {version})");
            agree("engine", &ours.devs, &devs);
            agree("analyze", &whole.devs, &devs);
            println!("   ratios:");
            println!(
                "     whole analyze vs allantools oadev: {:>6.1} x faster (target 10)",
                seconds / whole.seconds
            );
            println!(
                "     engine vs allantools oadev:        {:>6.1} x faster (target 25)",
                seconds / ours.seconds
            );
            if let Some(r) = rss_ratio {
                println!("     whole analyze peak RSS / input:    {r:>6.2} (target 1.5)");
            }
            println!(
                "     streamed analyze vs allantools:    {:>6.1} x faster",
                seconds / streamed.seconds
            );
            if let Some(r) = streamed_rss {
                println!("     streamed analyze peak RSS / input: {r:>6.2}");
            }
        }
        Err(e) => println!("   allantools: not run ({e:#})"),
    }
    Ok(())
}

/// Best of three runs of this executable's `analyze` on `data` with `extra` arguments, with
/// its oadev curve.
fn time_analyze(data: &Path, grid: TauGrid, dir: &Path, extra: &[&str]) -> Result<Timed> {
    let exe = std::env::current_exe().context("finding the imunoise executable")?;
    let json = dir.join("analysis.json");
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        let out = Command::new(&exe)
            .arg("--store")
            .arg(dir.join("store"))
            .arg("analyze")
            .arg(data)
            .args(["--rate", &COMPARISON_RATE_HZ.to_string()])
            .args(["--estimator", "oadev", "--taus", &grid.to_string()])
            .args(extra)
            .arg("--json")
            .arg(&json)
            .stdout(std::process::Stdio::null())
            .output()
            .context("running imunoise analyze")?;
        let seconds = start.elapsed().as_secs_f64();
        if !out.status.success() {
            let stderr = String::from_utf8_lossy(&out.stderr);
            bail!("imunoise analyze failed: {}", stderr.trim());
        }
        best = best.min(seconds);
    }
    let document: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
    let devs = document["channels"][0]["deviations"]["oadev"]["dev"]
        .as_array()
        .context("no oadev curve in the analysis")?
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    Ok(Timed {
        seconds: best,
        devs,
    })
}

/// The largest peak resident memory of the child processes waited for so far, bytes.
#[cfg(target_os = "linux")]
fn children_peak_rss() -> Option<f64> {
    use nix::sys::resource::{UsageWho, getrusage};
    // Linux reports ru_maxrss in KiB.
    let usage = getrusage(UsageWho::RUSAGE_CHILDREN).ok()?;
    Some(usage.max_rss() as f64 * 1024.0)
}

#[cfg(not(target_os = "linux"))]
fn children_peak_rss() -> Option<f64> {
    None
}

/// Six axes of `hours` at 1 kHz, generated and fed in 64 Ki-sample blocks (never held
/// whole), through the streamed analysis `analyze` uses beyond its memory budget.
fn streaming(hours: f64) -> Result<()> {
    use imunoise::analysis::bounded::Bounded;
    use imunoise::record::Quantity;
    let rate_hz = 1000.0;
    let n = (hours * 3600.0 * rate_hz).round() as usize;
    if n < 1000 {
        bail!("--stream-hours {hours}: too short");
    }
    let axes: Vec<(String, Quantity)> = ["gx", "gy", "gz", "ax", "ay", "az"]
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let q = if i < 3 {
                Quantity::AngularRate
            } else {
                Quantity::Acceleration
            };
            (a.to_string(), q)
        })
        .collect();
    let options = Options::default();
    let mut analysis = Bounded::new(&axes, n, rate_hz, &options)?;
    println!(
        "\n6. Streamed analyze (what `analyze` does with an .npy beyond --memory-budget): 6 axes x {n} samples ({hours} h at 1 kHz) of unit white noise, fed in blocks"
    );
    let baseline = resident("VmRSS:");
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    let start = Instant::now();
    const BLOCK: usize = 1 << 16;
    let mut rngs: Vec<ChaCha8Rng> = (0..6u64)
        .map(|axis| ChaCha8Rng::seed_from_u64(300 + axis))
        .collect();
    let mut block = vec![vec![0.0; BLOCK]; 6];
    let mut left = n;
    while left > 0 {
        let len = left.min(BLOCK);
        block.par_iter_mut().zip(&mut rngs).for_each(|(b, rng)| {
            for v in &mut b[..len] {
                *v = StandardNormal.sample(rng);
            }
        });
        let slices: Vec<&[f64]> = block.iter().map(|b| &b[..len]).collect();
        analysis.feed(&slices)?;
        left -= len;
    }
    let note = analysis.computation();
    let results = analysis.finish()?;
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "   imunoise:   {seconds:>8.3} s ({:.0} M samples/s, generation included)",
        6.0 * n as f64 / seconds / 1e6
    );
    println!("   computed:   {note}");
    let record_gib = 6.0 * n as f64 * 8.0 / (1u64 << 30) as f64;
    match (baseline, resident("VmHWM:"), reset) {
        (Some(b), Some(peak), true) => println!(
            "   memory:     peak resident {:.1} MiB above the process's before the analysis; the record read whole holds {record_gib:.2} GiB",
            (peak - b) / (1 << 20) as f64
        ),
        _ => println!(
            "   memory:     not measured (no /proc); the record read whole holds {record_gib:.2} GiB"
        ),
    }
    // Unit white noise at 1 kHz has N = 1 / sqrt(1000 Hz).
    let truth = 1.0 / rate_hz.sqrt();
    for r in results.iter().take(1) {
        if let Ok(fit) = &r.fit {
            println!(
                "   {}: N = {:.5e} [{:.5e} .. {:.5e}] u/sqrt(Hz), truth {truth:.5e}",
                r.name, fit.n.value, fit.n.lo, fit.n.hi
            );
        }
    }
    Ok(())
}

/// A field of /proc/self/status in bytes (Linux).
fn resident(key: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// The model workflow end to end on three 3-hour 100 Hz records (target: each under 30 s on
/// 2 cores): a hidden Gauss-Markov process; the same beside a sensor low-pass, whose white
/// noise every realisation must pass through the filter; a slow sinusoid beside a
/// process, which takes a round per effect and tests the first again without it.
fn model_workflow() -> Result<()> {
    use imunoise::analysis::low_pass::LowPass;
    use imunoise::sim::noise::{AxisNoise, GaussMarkov, NoiseTerms, Sinusoid};
    println!("\n5. Model workflow: 3 h at 100 Hz with hidden effects (target: each under 30 s)");
    let n = 3 * 3600 * 100;
    let rate_hz = 100.0;
    let baseline = NoiseTerms {
        n: 1e-4,
        k: 1e-7,
        ..NoiseTerms::default()
    };
    let process = |sigma: f64, tau_c: f64| Some(GaussMarkov { sigma, tau_c });
    let filter = LowPass::two_pole(10.0, rate_hz)?;
    let cases = [
        (
            "a Gauss-Markov process (tau_c 5 s)",
            NoiseTerms {
                gauss_markov: process(1e-4, 5.0),
                ..baseline
            },
            None,
        ),
        (
            "a sensor low-pass (two-pole, 10 Hz) and a process (tau_c 120 s)",
            NoiseTerms {
                n: 0.0,
                gauss_markov: process(2e-5, 120.0),
                ..baseline
            },
            Some(&filter),
        ),
        (
            "a slow sinusoid (period 15 min) and a process (tau_c 120 s)",
            NoiseTerms {
                gauss_markov: process(2e-5, 120.0),
                sinusoid: Some(Sinusoid {
                    amplitude: 2e-5,
                    freq_hz: 1.0 / 900.0,
                }),
                ..baseline
            },
            None,
        ),
    ];
    let mut slowest: f64 = 0.0;
    for (what, terms, low_pass) in cases {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut axis = AxisNoise::new(terms, rate_hz, n as f64 / rate_hz, &mut rng);
        let mut values = axis.take(n, &mut rng);
        if let Some(lp) = low_pass {
            let white = lp.white_through(baseline.n, n, &mut rng);
            values.iter_mut().zip(white).for_each(|(v, w)| *v += w);
        }
        let record = Record {
            source: "bench".into(),
            rate_hz,
            channels: vec![Channel::named("gx", values)],
        };
        let start = Instant::now();
        let outcome =
            imunoise::model::run(&record, None, None, &imunoise::model::Settings::default())?;
        let seconds = start.elapsed().as_secs_f64();
        slowest = slowest.max(seconds);
        let kinds: Vec<&str> = outcome.steps.iter().map(|s| s.effect.kind()).collect();
        println!(
            "   {what}:\n   imunoise:   {seconds:>8.3} s (found: {})",
            if kinds.is_empty() {
                "nothing".to_string()
            } else {
                kinds.join(", ")
            }
        );
    }
    println!("   slowest:    {slowest:>8.3} s (target 30 s)");
    Ok(())
}

/// Decoding a large capture (random samples in full batches), keeping the samples as
/// `replay` does and counting only as the live capture loop does.
fn decode_throughput(megabytes: usize) {
    use imunoise::capture::{Capture, CaptureWriter, StreamDecoder};
    use protocol::{DeviceMessage, RawSample, SampleBatch};
    use rand::Rng;
    println!("\n4. Decoding a {megabytes} MB capture");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut writer = CaptureWriter::new(Vec::with_capacity(megabytes << 20));
    let settings = protocol::SensorSettings::default();
    let info = protocol::DeviceInfo {
        protocol_version: protocol::PROTOCOL_VERSION,
        firmware_version: firmware::FIRMWARE_VERSION,
        board_id: 0,
        who_am_i: protocol::mpu6050::WHO_AM_I_VALUE,
        settings,
        streaming: true,
        max_samples_per_batch: protocol::MAX_SAMPLES_PER_BATCH as u16,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::mpu6050(
            protocol::mpu6050::DEFAULT_ADDRESS,
            protocol::mpu6050::WHO_AM_I_VALUE,
            settings,
        ),
    };
    let mut index = 0u64;
    let mut ok = writer.message(&DeviceMessage::Info(info)).is_ok();
    // A full batch of random samples frames to about 640 bytes.
    let batches = (megabytes * 1_000_000) / 640;
    while ok && index < (batches * protocol::MAX_SAMPLES_PER_BATCH) as u64 {
        let samples = (0..protocol::MAX_SAMPLES_PER_BATCH)
            .map(|_| RawSample {
                gyro: [rng.random(), rng.random(), rng.random()],
                accel: [rng.random(), rng.random(), rng.random()],
                temp: rng.random(),
            })
            .collect();
        let batch = SampleBatch {
            first_index: index,
            first_timestamp_us: index * 1000,
            samples,
        };
        ok = writer.message(&DeviceMessage::Samples(batch)).is_ok();
        index += protocol::MAX_SAMPLES_PER_BATCH as u64;
    }
    let bytes = writer.into_inner();
    let mb = bytes.len() as f64 / 1e6;
    let start = Instant::now();
    let decoded = Capture::decode(&bytes);
    let keeping = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut counting = StreamDecoder::new(false);
    bytes.chunks(1 << 16).for_each(|chunk| {
        counting.feed(chunk);
    });
    let counting_s = start.elapsed().as_secs_f64();
    match decoded {
        Ok(c) => println!(
            "   {mb:.0} MB, {} samples: {:.0} MB/s keeping samples, {:.0} MB/s counting only",
            c.totals().received,
            mb / keeping,
            mb / counting_s
        ),
        Err(e) => println!("   decoding failed: {e}"),
    }
}

/// One hour of six axes at 1 kHz (21.6 million samples) of each noise term alone: the
/// simulator's cost per term.
fn simulator_terms() {
    use imunoise::sim::noise::{AxisNoise, GaussMarkov, NoiseTerms, Sinusoid};
    println!("\n3. Simulator: one hour of six axes at 1 kHz, one noise term at a time");
    let one = |f: fn(&mut NoiseTerms)| {
        let mut t = NoiseTerms::default();
        f(&mut t);
        t
    };
    let cases: [(&str, NoiseTerms); 7] = [
        ("white N", one(|t| t.n = 1e-3)),
        ("flicker B", one(|t| t.b = 1e-4)),
        ("random walk K", one(|t| t.k = 1e-5)),
        ("ramp R", one(|t| t.r = 1e-6)),
        ("quantization Q", one(|t| t.q = 1e-5)),
        (
            "Gauss-Markov",
            one(|t| {
                t.gauss_markov = Some(GaussMarkov {
                    sigma: 1e-4,
                    tau_c: 100.0,
                })
            }),
        ),
        (
            "sinusoid",
            one(|t| {
                t.sinusoid = Some(Sinusoid {
                    amplitude: 1e-3,
                    freq_hz: 13.0,
                })
            }),
        ),
    ];
    for (name, terms) in cases {
        let start = Instant::now();
        let mut sum = 0.0;
        for axis in 0..6 {
            let mut rng = ChaCha8Rng::seed_from_u64(axis);
            let mut g = AxisNoise::new(terms, 1000.0, 3600.0, &mut rng);
            for _ in 0..3_600_000 {
                sum += g.next(&mut rng);
            }
        }
        // The sum keeps the generator from being optimised away.
        std::hint::black_box(sum);
        println!("   {name:>15}: {:>6.3} s", start.elapsed().as_secs_f64());
    }
}

struct Timed {
    seconds: f64,
    devs: Vec<f64>,
}

/// Best of three: rate to phase (in place) and the deviation at every factor.
fn time_oadev(y: &[f64], factors: &[usize]) -> Timed {
    let mut best = f64::INFINITY;
    let mut devs = Vec::new();
    for _ in 0..3 {
        let input = y.to_vec();
        let start = Instant::now();
        let tau0 = 1.0 / COMPARISON_RATE_HZ;
        let phase = into_phase(input, tau0);
        let d = allan::deviation(Estimator::Oadev, &phase, tau0, factors);
        best = best.min(start.elapsed().as_secs_f64());
        devs = d.dev;
    }
    Timed {
        seconds: best,
        devs,
    }
}

/// Peak resident memory while computing (input copy + phase in place + estimator), over the
/// input's size. Linux: VmHWM after resetting it through /proc/self/clear_refs.
fn peak_over_input(y: &[f64], factors: &[usize]) -> Option<f64> {
    let input_bytes = std::mem::size_of_val(y) as f64;
    let baseline = resident("VmRSS:")? - input_bytes;
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    let phase = into_phase(y.to_vec(), 1.0);
    let d = allan::deviation(Estimator::Oadev, &phase, 1.0, factors);
    drop((phase, d));
    let peak = resident("VmHWM:")?;
    // What the engine holds at its peak, its own input included (the process's baseline and
    // the benchmark's reference copy of the data excluded), relative to the input's size: the
    // rate becomes phase in place, so this is ~1.
    Some((peak - baseline - input_bytes) / input_bytes)
}

fn white(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
}

/// allantools' oadev of the rate samples in `data` at `factors` (`scripts/bench_allantools.py`):
/// its seconds, deviations and version.
fn run_reference(
    python: &str,
    dir: &Path,
    data: &Path,
    factors: &[usize],
) -> Result<(f64, Vec<f64>, String)> {
    let script = dir.join("bench_allantools.py");
    std::fs::write(&script, REFERENCE_SCRIPT)?;
    let list: String = factors.iter().map(|m| format!("{m}\n")).collect();
    std::fs::write(dir.join("factors.txt"), list)?;
    let out = Command::new(python)
        .arg(&script)
        .arg(data)
        .arg(dir.join("factors.txt"))
        .arg(COMPARISON_RATE_HZ.to_string())
        .arg(dir.join("out.json"))
        .output()
        .with_context(|| format!("running {python}"))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let last = stderr.lines().last().unwrap_or("").to_string();
        bail!("{python} failed: {last} (pip install allantools numpy)");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out.json"))?)?;
    let seconds = json["seconds"]
        .as_f64()
        .context("no seconds in the reference output")?;
    let devs = json["devs"]
        .as_array()
        .context("no devs in the reference output")?
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    let version = json["version"].as_str().unwrap_or("unknown").to_string();
    Ok((seconds, devs, version))
}

/// A six-axis record of white plus random-walk rate noise, analysed as `analyze` does.
fn full_analysis(hours: f64) -> Result<()> {
    let rate_hz = 200.0;
    let n = (hours * 3600.0 * rate_hz).round() as usize;
    if n < pipeline::MIN_SAMPLES {
        bail!("--hours {hours}: too short");
    }
    let names = ["gx", "gy", "gz", "ax", "ay", "az"];
    let channels: Vec<Channel> = names
        .par_iter()
        .enumerate()
        .map(|(i, name)| {
            let mut values = white(n, 100 + i as u64);
            let walk = white(n, 200 + i as u64);
            let mut bias = 0.0;
            for (v, w) in values.iter_mut().zip(walk) {
                bias += 1e-3 * w;
                *v = 0.01 * *v + 1e-4 * bias;
            }
            Channel::named(*name, values)
        })
        .collect();
    let record = Record {
        source: "bench".into(),
        rate_hz,
        channels,
    };
    println!(
        "\n2. Full analysis: 6 channels x {n} samples ({hours} h at 200 Hz): oadev with CIs, PSD, fit"
    );
    let start = Instant::now();
    let results = pipeline::analyze(&record, &Options::default(), &|| {})?;
    let seconds = start.elapsed().as_secs_f64();
    println!("   imunoise:   {seconds:>8.3} s");
    let fitted = results.iter().filter(|r| r.fit.is_ok()).count();
    println!("   ({fitted} of 6 channels fitted)");
    Ok(())
}
