//! The firmware's ITG-3200 and ADXL345 drivers, through the generic acquisition, against
//! the simulated chips: every sample the chip made is delivered at its own index or counted
//! lost, through late polls, bus outages, an oscillator off by 0.3 % and drifting, and a
//! chip that resets itself.

use embedded_hal::i2c::{ErrorType, I2c, Operation};
use firmware::Clock;
use firmware::acquire::Acquisition;
use firmware::adxl345::{self, Adxl345};
use firmware::itg3200::{self, Itg3200};
use firmware::sensor::Sensor;
use imunoise::sim::device::{
    JournalEntry, Outage, SampledChip, SensorClock, SimAdxl345, SimChip, SimI2cError, SimItg3200,
};
use imunoise_tests::models::gy85_model as model;
use protocol::adxl345::Adxl345Settings;
use protocol::itg3200::Itg3200Settings;
use protocol::{ErrorCode, RawSample, SampleBatch, Status};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::cell::RefCell;
use std::rc::Rc;

/// One simulated chip, shared by the driver (as its bus) and the test (which moves time and
/// is the board's clock).
struct Shared<T>(Rc<RefCell<T>>);

impl<T> Clone for Shared<T> {
    fn clone(&self) -> Self {
        Shared(self.0.clone())
    }
}

impl<T: I2c<Error = SimI2cError>> ErrorType for Shared<T> {
    type Error = SimI2cError;
}

impl<T: I2c<Error = SimI2cError>> I2c for Shared<T> {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), SimI2cError> {
        self.0.borrow_mut().transaction(address, ops)
    }
}

impl<T: SimChip> Clock for Shared<T> {
    fn now_us(&mut self) -> u64 {
        self.0.borrow().time_us()
    }
}

/// What a run delivered, by index, and its status.
#[derive(Default)]
struct Delivered {
    samples: Vec<(u64, RawSample)>,
    status: Status,
    error: Option<ErrorCode>,
}

/// Drive an acquisition from now to `t_end` in steps of about `step_us` (jittered, as a
/// board's main loop is), skipping the polls that fall in `skipped` (a board busy
/// elsewhere); every sample delivered, the status, and the error that ended the run, if any.
fn run<S: Sensor, T: SampledChip>(
    dev: &mut S,
    chip: &Shared<T>,
    period_us: u32,
    t_end: u64,
    step_us: u64,
    skipped: &[(u64, u64)],
) -> Delivered {
    let mut clock = chip.clone();
    let mut out = Delivered::default();
    // As the board starts a run: certain until a loss the grid cannot pin down.
    out.status.loss_certain = true;
    let mut acq = Acquisition::start(dev, &mut clock, period_us, None).unwrap();
    let mut t = clock.now_us();
    let mut rng = ChaCha8Rng::seed_from_u64(t_end ^ step_us);
    while t < t_end {
        t += rng.random_range(step_us / 2..step_us * 3 / 2);
        chip.0.borrow_mut().advance_to_us(t);
        if skipped.iter().any(|&(a, b)| (a..b).contains(&t)) || !acq.due(t) {
            continue;
        }
        let mut emit = |b: SampleBatch| {
            for (k, s) in b.samples.iter().enumerate() {
                out.samples.push((b.first_index + k as u64, *s));
            }
        };
        if let Err(e) = acq.drain(dev, &mut clock, &mut out.status, &mut emit) {
            out.error = Some(e);
            break;
        }
    }
    out
}

/// The samples the chip made since the journal was last taken, in order.
fn made<T: SimChip>(chip: &Shared<T>) -> Vec<RawSample> {
    chip.0
        .borrow_mut()
        .take_journal()
        .into_iter()
        .filter_map(|e| match e {
            JournalEntry::Sample { raw, .. } => Some(raw),
            JournalEntry::FifoReset { .. } => None,
        })
        .collect()
}

/// Every delivered sample is the one the chip made at that index, and delivered plus lost
/// is what the chip made by the last index delivered. (A loss across a stall is certain
/// with a steady oscillator; with a drifting one the grid's bounds restart at each
/// re-measure of the period, and the board says when it cannot be sure; an ITG-3200's phase
/// is known only to its polling interval, so its losses are certain only with a steady
/// oscillator.)
fn assert_accounted(delivered: &Delivered, truth: &[RawSample], what: &str, certain: bool) {
    assert!(!delivered.samples.is_empty(), "{what}: nothing delivered");
    for &(index, sample) in &delivered.samples {
        let made = truth.get(index as usize);
        assert_eq!(made, Some(&sample), "{what}: index {index}");
    }
    let last = delivered.samples.last().map_or(0, |&(i, _)| i + 1);
    assert_eq!(
        delivered.samples.len() as u64 + delivered.status.samples_lost,
        last,
        "{what}: delivered + lost"
    );
    if certain {
        assert!(delivered.status.loss_certain, "{what}: loss certain");
    }
}

fn itg3200(clock: SensorClock) -> (Itg3200<Shared<SimItg3200>>, Shared<SimItg3200>, u32) {
    let mut sim = SimItg3200::new(model(), 7);
    sim.faults_mut().clock = clock;
    let chip = Shared(Rc::new(RefCell::new(sim)));
    let mut dev = Itg3200::new(chip.clone(), protocol::itg3200::DEFAULT_ADDRESS);
    dev.probe().unwrap();
    let settings = Itg3200Settings::for_rate_and_bandwidth(50.0, 20.0).unwrap();
    dev.configure(&settings).unwrap();
    assert_eq!(dev.read_settings().unwrap(), settings);
    chip.0.borrow_mut().keep_journal();
    made(&chip);
    (dev, chip, itg3200::period_us(&settings).unwrap())
}

fn adxl345(clock: SensorClock) -> (Adxl345<Shared<SimAdxl345>>, Shared<SimAdxl345>, u32) {
    let mut sim = SimAdxl345::new(model(), 8);
    sim.faults_mut().clock = clock;
    let chip = Shared(Rc::new(RefCell::new(sim)));
    let mut dev = Adxl345::new(chip.clone(), protocol::adxl345::DEFAULT_ADDRESS);
    dev.probe().unwrap();
    let settings = Adxl345Settings::for_rate(50.0, false).unwrap();
    dev.configure(&settings).unwrap();
    assert_eq!(dev.read_settings().unwrap(), settings);
    chip.0.borrow_mut().keep_journal();
    made(&chip);
    (dev, chip, adxl345::period_us(&settings).unwrap())
}

const MINUTE_US: u64 = 60_000_000;

/// 0.3 % fast and drifting 50 ppm an hour: further off than the chips' specified
/// tolerance, as a cheap board's may be.
const OFF_CLOCK: SensorClock = SensorClock {
    ppm: 3000.0,
    drift_ppm_per_hour: 50.0,
};

#[test]
fn the_itg3200_delivers_every_sample_with_a_clock_that_is_off() {
    let (mut dev, chip, period) = itg3200(OFF_CLOCK);
    let out = run(&mut dev, &chip, period, 5 * MINUTE_US, 1000, &[]);
    let truth = made(&chip);
    assert_eq!(out.error, None);
    assert_eq!(out.status.samples_lost, 0);
    assert_accounted(&out, &truth, "ITG-3200, clock off", true);
    assert!(
        out.samples.len() + 1 >= truth.len(),
        "{} of {}",
        out.samples.len(),
        truth.len()
    );
}

#[test]
fn the_itg3200_counts_the_samples_a_busy_board_let_it_replace() {
    let (mut dev, chip, period) = itg3200(SensorClock {
        ppm: 3000.0,
        drift_ppm_per_hour: 0.0,
    });
    // Three stretches without polls: 75 ms (3.75 periods), 41 ms and 1 s.
    let busy = [
        (10_000_000, 10_075_000),
        (20_000_000, 20_041_000),
        (30_000_000, 31_000_000),
    ];
    let out = run(&mut dev, &chip, period, MINUTE_US, 1000, &busy);
    let truth = made(&chip);
    assert_eq!(out.error, None);
    assert!(out.status.samples_lost >= 50, "{}", out.status.samples_lost);
    assert_accounted(&out, &truth, "ITG-3200, busy board", false);
}

#[test]
fn the_itg3200_rides_through_an_outage_and_names_a_reset() {
    let (mut dev, chip, period) = itg3200(SensorClock::default());
    chip.0.borrow_mut().faults_mut().i2c_outages.push(Outage {
        at_us: 10_000_000,
        for_us: 300_000,
    });
    let out = run(&mut dev, &chip, period, 20_000_000, 1000, &[]);
    let truth = made(&chip);
    assert_eq!(out.error, None);
    assert!(dev.i2c_errors() > 0);
    assert!(out.status.samples_lost >= 14, "{}", out.status.samples_lost);
    assert_accounted(&out, &truth, "ITG-3200, outage", true);
    // A chip that resets itself stops flagging samples: the run ends naming the reset.
    chip.0.borrow_mut().schedule_reset(25_000_000);
    let out = run(&mut dev, &chip, period, 30_000_000, 1000, &[]);
    assert_eq!(out.error, Some(ErrorCode::SensorReset));
}

#[test]
fn the_adxl345_delivers_every_sample_with_a_clock_that_is_off() {
    let (mut dev, chip, period) = adxl345(OFF_CLOCK);
    let out = run(&mut dev, &chip, period, 5 * MINUTE_US, 2000, &[]);
    let truth = made(&chip);
    assert_eq!(out.error, None);
    assert_eq!(out.status.samples_lost, 0);
    assert_accounted(&out, &truth, "ADXL345, clock off", true);
    assert!(
        out.samples.len() + 16 >= truth.len(),
        "{} of {}",
        out.samples.len(),
        truth.len()
    );
}

#[test]
fn the_adxl345_counts_what_its_fifo_dropped_and_names_a_reset() {
    let (mut dev, chip, period) = adxl345(SensorClock {
        ppm: -3000.0,
        drift_ppm_per_hour: 0.0,
    });
    // 1 s without drains: 50 samples made, 32 kept.
    let busy = [(10_000_000, 11_000_000)];
    let out = run(&mut dev, &chip, period, 20_000_000, 2000, &busy);
    let truth = made(&chip);
    assert_eq!(out.error, None);
    assert!(out.status.fifo_overflows >= 1);
    assert!(out.status.samples_lost >= 18, "{}", out.status.samples_lost);
    assert_accounted(&out, &truth, "ADXL345, stall", true);
    chip.0.borrow_mut().schedule_reset(25_000_000);
    let out = run(&mut dev, &chip, period, 30_000_000, 2000, &[]);
    assert_eq!(out.error, Some(ErrorCode::SensorReset));
}
