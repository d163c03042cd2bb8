//! The PSD convention (docs/ARCHITECTURE.md, "Units and conventions"), end to end: white rate noise with Allan coefficient N has
//! one-sided PSD 2 N^2, so the PSD route (N = sqrt(S/2)) and the Allan routes (the five-term
//! fit and the -1/2 slope read-out) must give the same N — and the right one.

use imunoise::analysis::pipeline::{self, Options};
use imunoise::record::{Channel, Record};
use imunoise::sim::noise::{AxisNoise, NoiseTerms};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn psd_and_allan_give_the_same_white_noise_coefficient() {
    let (rate, samples, n_true) = (100.0, 360_000, 2e-3);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let terms = NoiseTerms {
        n: n_true,
        k: 1e-5,
        ..NoiseTerms::default()
    };
    let mut axis = AxisNoise::new(terms, rate, samples as f64 / rate, &mut rng);
    let record = Record {
        source: "white".into(),
        rate_hz: rate,
        channels: vec![Channel::named("gz", axis.take(samples, &mut rng))],
    };
    let r = &pipeline::analyze(&record, &Options::default(), &|| {}).unwrap()[0];
    let fit = r.fit.as_ref().unwrap().n.value;
    let slope = r.readouts.n.unwrap().value;
    let psd = r.psd_terms.as_ref().unwrap().n.value;
    // Statistical spread: the fit and the slope use 360,000 samples (relative sd of N about
    // 0.2 %); the PSD fit averages thousands of ordinates (about 0.1 %).
    // 3 % is several sigma for each; a one-sided/two-sided mix-up would be off by 41 %.
    for (route, n) in [("fit", fit), ("slope", slope), ("psd", psd)] {
        assert!(
            (n / n_true - 1.0).abs() < 0.03,
            "{route}: N = {n:e}, true {n_true:e}"
        );
    }
    assert!((psd / fit - 1.0).abs() < 0.03, "psd {psd:e} vs fit {fit:e}");
}
