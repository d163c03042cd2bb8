//! The fit on data shaped by the MPU-6050's low-pass filter: at 200 Hz with a 42 Hz DLPF the
//! shortest taus lie below N/sqrt(tau) (noise between 42 and 100 Hz is filtered out), a shape
//! no IEEE-952 term has; the fit must leave them out and still find N — the chain's
//! prediction for this setting is N0 x 1.006 (imunoise::sim::chain).

use imunoise::analysis::pipeline::{self, Options};
use imunoise::record::{Channel, Record};
use imunoise::sim::chain::white_noise_inflation;
use imunoise::sim::dlpf::{DlpfDesign, Sensor};
use imunoise::sim::imu::Imu;
use imunoise::sim::model_file;
use protocol::SensorSettings;
use std::path::Path;

#[test]
fn low_passed_white_noise_gives_the_unfiltered_n() {
    let n0 = 1.5e-4;
    let model = model_file::parse(
        &format!("[gyro]\nnoise_density = {n0}\n"),
        Path::new("white.toml"),
    )
    .unwrap();
    let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
    let seconds = 600.0;
    let mut imu = Imu::new(&model, settings, 11, seconds);
    let gx: Vec<f64> = (0..120_000).map(|_| imu.next_si().gyro[0]).collect();
    let record = Record {
        source: "200/42".into(),
        rate_hz: 200.0,
        channels: vec![Channel::named("gx", gx)],
    };
    let options = Options {
        confidence: 0.99,
        ..Options::default()
    };
    let result = &pipeline::analyze(&record, &options, &|| {}).unwrap()[0];
    let fit = result.fit.as_ref().unwrap();
    let design = DlpfDesign::for_setting(settings.dlpf, Sensor::Gyro);
    let expected = n0 * white_noise_inflation(&design, 1 + usize::from(settings.smplrt_div));
    assert!(
        fit.n.lo <= expected && expected <= fit.n.hi,
        "N {} [{}, {}], expected {expected}",
        fit.n.value,
        fit.n.lo,
        fit.n.hi
    );
    // The filtered taus were left out: the first tau is 5 ms, the fit starts later.
    assert!(fit.tau_min > 0.02, "fit starts at {} s", fit.tau_min);
    // Without leaving them out, the N would be ~28 % low (the curve at tau0 is 0.55 N/sqrt(tau0)).
    let d = &result.fit_curve.deviation;
    assert!(d.dev[0] * d.tau[0].sqrt() < 0.7 * expected);
}
