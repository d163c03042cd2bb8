//! When a simulated chip makes its samples: at its output rate on its own oscillator
//! ([`SensorClock`]), against the board's clock that the caller drives, with the injected
//! device resets in between. Shared by every chip, so each says only what a sample and a
//! reset do to its registers.
//!
//! With an ideal oscillator sample k of a run (k = 1, 2, ...) is at `start + k / f_s`; with
//! an offset and a drift, sample k is where the integral of the oscillator's rate from the
//! start reaches `k / f_s`, solved in closed form per sample, so no error accumulates over a
//! night.

use super::faults::SensorClock;
use super::port::RegisterChip;

/// The sample times of one run (from a start, a wake-up or a change of settings).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampler {
    /// The oscillator's phase at which the run's sample 0 would be (its start), us.
    phase_origin_us: f64,
    clock: SensorClock,
    rate_hz: f64,
    samples: u64,
}

impl Sampler {
    /// A run at `rate_hz` starting at board time `time_us` under `clock`.
    pub fn start(clock: SensorClock, time_us: u64, rate_hz: f64) -> Sampler {
        Sampler {
            phase_origin_us: clock.phase_us(time_us as f64),
            clock,
            rate_hz,
            samples: 0,
        }
    }

    /// Board time of the next sample, us (fractional): where the oscillator's phase reaches
    /// the origin plus (k + 1) nominal sample periods. Each sample's time is computed from
    /// the origin, so rounding does not accumulate.
    pub fn next_us(&self) -> f64 {
        let phase = self.phase_origin_us + (self.samples + 1) as f64 * 1e6 / self.rate_hz;
        self.clock.time_at_phase_us(phase)
    }

    /// Samples made in this run.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Continue under `clock` from board time `t_us` with the same progress towards the
    /// next sample.
    fn rebase(&mut self, clock: SensorClock, t_us: f64) {
        let elapsed = self.clock.phase_us(t_us) - self.phase_origin_us;
        self.phase_origin_us = clock.phase_us(t_us) - elapsed;
        self.clock = clock;
    }
}

/// A chip that makes samples on a [`Sampler`].
pub trait SampledChip: RegisterChip {
    /// The current run, if the chip is sampling.
    fn sampler_mut(&mut self) -> Option<&mut Sampler>;
    /// Make one sample (the run's count is advanced by the caller).
    fn sample(&mut self);
    /// Registers back to their power-on values.
    fn power_on_reset(&mut self);

    /// Move the clock to `t_us` (a time in the past is ignored), making the samples due and
    /// the injected resets on the way.
    fn advance_to_us(&mut self, t_us: u64) {
        let now = self.time_us();
        if t_us <= now {
            return;
        }
        let clock = self.faults().clock;
        if let Some(run) = self.sampler_mut().filter(|run| run.clock != clock) {
            run.rebase(clock, now as f64);
        }
        self.faults_mut().resets_at_us.sort_unstable();
        loop {
            let reset = self
                .faults()
                .resets_at_us
                .first()
                .copied()
                .filter(|&r| r <= t_us);
            let sample = self
                .sampler_mut()
                .map(|run| run.next_us())
                .filter(|&s| s <= t_us as f64);
            let now = self.time_us();
            match (sample, reset) {
                (Some(s), r) if r.is_none_or(|r| s < r as f64) => {
                    self.core_mut().time_us = now.max(s as u64);
                    if let Some(run) = self.sampler_mut() {
                        run.samples += 1;
                    }
                    self.sample();
                }
                (_, Some(r)) => {
                    self.core_mut().time_us = now.max(r);
                    self.faults_mut().resets_at_us.remove(0);
                    self.power_on_reset();
                }
                _ => break,
            }
        }
        self.core_mut().time_us = t_us;
    }
}
