//! Time: the board's clock, and the sensor's sample grid seen through it.
//!
//! The MPU-6050 makes sample k of a run at `t0 + phase + k * period` on its own oscillator
//! (the gyro PLL). The FIFO says how many samples arrived, never when, and an overflow
//! destroys the count. [`SampleGrid`] keeps the grid in board microseconds: every drain
//! (`n` samples produced by a FIFO_COUNT read between board times `before` and `after`)
//! bounds the phase, `T(before) - n*P < phase <= T(after) - (n-1)*P`; intersecting the
//! bounds of all drains pins it down. Then "how many samples had the sensor produced by
//! time t" has one answer, which is what makes the loss count after an overflow exact
//! (see [`crate::acquire`]).
//!
//! The period starts at the nominal value from the settings (an integer number of
//! microseconds for every MPU-6050 rate: 125 or 1000 us times 1 + SMPLRT_DIV). If the
//! sensor's oscillator is off (the datasheet allows about +-1 %), the bounds eventually
//! contradict each other; the period is then re-measured from the first and the latest drain
//! (error under one period over the whole run: a relative 1e-6 after 20 minutes at 1 kHz)
//! and the phase bounds restart from the latest drain.
//!
//! Fixed point (1/65536 us) in i128: exact for the nominal periods, no float on the M0+.

/// A monotonic microsecond clock (the board's timer; in tests, the simulated sensor's).
pub trait Clock {
    fn now_us(&mut self) -> u64;
}

impl<C: Clock + ?Sized> Clock for &mut C {
    fn now_us(&mut self) -> u64 {
        (**self).now_us()
    }
}

/// Fixed-point scale: 1 us = 2^16 units.
const SCALE_BITS: u32 = 16;

/// How far the measured period may stray from the nominal one before the sensor's count is
/// declared implausible (the MPU-6050's clock is specified to a few percent).
pub const MAX_RATE_ERROR_PERCENT: i128 = 5;

/// The sample grid of one run, in board time.
#[derive(Debug, Clone)]
pub struct SampleGrid {
    t0_us: u64,
    nominal: i128,
    period: i128,
    /// Bounds on the time of sample 1 after `t0` (exclusive, inclusive), scaled.
    lo: i128,
    hi: i128,
    /// The first drain that saw a sample, and the latest: (board time scaled, samples).
    first: Option<(i128, u64)>,
    remeasured: u32,
}

/// The grid contradicts the count by more than the sensor's clock tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Implausible;

impl SampleGrid {
    /// A grid for samples every `period_us`, counted from a FIFO reset done between
    /// `t0_us` and `reset_done_us` (sample 1 is the first one after the reset: it comes
    /// within one of the sensor's periods, which may be up to [`MAX_RATE_ERROR_PERCENT`]
    /// longer than the nominal one).
    pub fn new(t0_us: u64, reset_done_us: u64, period_us: u32) -> Self {
        let period = i128::from(period_us) << SCALE_BITS;
        let reset_len = i128::from(reset_done_us.saturating_sub(t0_us)) << SCALE_BITS;
        SampleGrid {
            t0_us,
            nominal: period,
            period,
            lo: -1,
            hi: period * (100 + MAX_RATE_ERROR_PERCENT) / 100 + reset_len,
            first: None,
            remeasured: 0,
        }
    }

    /// A grid like [`SampleGrid::new`] whose period starts at one already measured (a run
    /// resumed after a fault on the same sensor), if it is within the clock tolerance.
    pub fn with_period(t0_us: u64, reset_done_us: u64, period_us: u32, measured: i128) -> Self {
        let mut grid = SampleGrid::new(t0_us, reset_done_us, period_us);
        let tolerance = grid.nominal * MAX_RATE_ERROR_PERCENT / 100;
        if measured > 0 && (measured - grid.nominal).abs() <= tolerance {
            grid.period = measured;
        }
        grid
    }

    /// The period in use, nanoseconds (rounded).
    pub fn period_ns(&self) -> u32 {
        u32::try_from((self.period * 1000 + (1 << (SCALE_BITS - 1))) >> SCALE_BITS)
            .unwrap_or(u32::MAX)
    }

    fn scaled(&self, t_us: u64) -> i128 {
        (i128::from(t_us) - i128::from(self.t0_us)) << SCALE_BITS
    }

    /// Times the period had to be re-measured (diagnostic).
    pub fn remeasured(&self) -> u32 {
        self.remeasured
    }

    /// The period in use, in 1/65536 us.
    pub fn period_scaled(&self) -> i128 {
        self.period
    }

    /// A FIFO count showed that `n` samples had been produced since `t0` by the time of a
    /// read that started at `before_us` and ended at `after_us`.
    pub fn observe(&mut self, before_us: u64, after_us: u64, n: u64) -> Result<(), Implausible> {
        let (tb, ta) = (self.scaled(before_us), self.scaled(after_us));
        let n_i = i128::from(n);
        let lo = self.lo.max(tb - n_i * self.period);
        let hi = if n == 0 {
            self.hi
        } else {
            self.hi.min(ta - (n_i - 1) * self.period)
        };
        if n > 0 && self.first.is_none() {
            self.first = Some((ta, n));
        }
        if lo < hi {
            self.lo = lo;
            self.hi = hi;
            return Ok(());
        }
        // Contradiction: the period is off. Re-measure it from the first drain to this one.
        let Some((t_first, n_first)) = self.first else {
            return Err(Implausible);
        };
        if n <= n_first {
            return Err(Implausible);
        }
        let spans = i128::from(n - n_first);
        let period = (ta - t_first) / spans;
        // Each end of the span is known to about a period, so a re-measure early in a run
        // is uncertain by about two periods over the span: only a period outside the
        // tolerance by more than that is implausible (then clamped into it).
        let tolerance = self.nominal * MAX_RATE_ERROR_PERCENT / 100;
        let uncertainty = 2 * self.nominal / spans;
        if (period - self.nominal).abs() > tolerance + uncertainty || period <= 0 {
            return Err(Implausible);
        }
        let period = period.clamp(self.nominal - tolerance, self.nominal + tolerance);
        self.period = period;
        self.remeasured += 1;
        self.lo = tb - n_i * period;
        self.hi = ta - (n_i - 1) * period;
        if self.lo >= self.hi {
            self.hi = self.lo + 1;
        }
        Ok(())
    }

    /// Samples produced by `t_us` for a given time of sample 1 (scaled).
    fn produced_at(&self, t: i128, first: i128) -> u64 {
        if t < first {
            return 0;
        }
        u64::try_from((t - first) / self.period + 1).unwrap_or(u64::MAX)
    }

    /// How many samples the sensor had produced by a moment between `before_us` and
    /// `after_us`: (best estimate, whether the bounds make it certain).
    pub fn produced(&self, before_us: u64, after_us: u64) -> (u64, bool) {
        let (tb, ta) = (self.scaled(before_us), self.scaled(after_us));
        let fewest = self.produced_at(tb, self.hi);
        let most = self.produced_at(ta, self.lo + 1);
        let mid = self.produced_at((tb + ta) / 2, self.mid());
        (mid, fewest == most)
    }

    fn mid(&self) -> i128 {
        (self.lo + 1 + self.hi) / 2
    }

    /// Board time when sample `index` (0-based) was made, by the grid.
    pub fn time_of(&self, index: u64) -> u64 {
        let t = self.mid() + i128::from(index) * self.period;
        let us = i128::from(self.t0_us) + (t >> SCALE_BITS);
        u64::try_from(us).unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sensor whose samples come every `period` us (fractional), first at `first`.
    fn produced(first: f64, period: f64, t: u64) -> u64 {
        if (t as f64) < first {
            0
        } else {
            ((t as f64 - first) / period).floor() as u64 + 1
        }
    }

    #[test]
    fn nominal_clock_pins_the_phase_and_predicts_exactly() {
        let mut grid = SampleGrid::new(0, 0, 1000);
        let first = 437.0;
        let mut t = 0;
        // Few drains: the phase is known to a few hundred us, and `produced` says when
        // that is not enough.
        for step in [3_100u64, 7_777, 4_001, 9_999, 12_345, 5_432, 8_765] {
            t += step;
            grid.observe(t, t, produced(first, 1000.0, t)).unwrap();
        }
        let mut uncertain = 0;
        for later in (t..t + 5_000_000).step_by(77_777) {
            let (n, certain) = grid.produced(later, later);
            let truth = produced(first, 1000.0, later);
            assert!(n.abs_diff(truth) <= 1);
            if certain {
                assert_eq!(n, truth, "t {later}");
            } else {
                uncertain += 1;
            }
        }
        assert!(uncertain > 0);
        // Drains at irregular times for a second pin it down: every moment is then exact.
        let mut step = 5_000;
        for _ in 0..100 {
            step = 3_000 + (step * 7919 + 13) % 9_000;
            t += step;
            grid.observe(t, t, produced(first, 1000.0, t)).unwrap();
        }
        for later in (t..t + 5_000_000).step_by(77_777) {
            let (n, certain) = grid.produced(later, later);
            assert_eq!(n, produced(first, 1000.0, later), "t {later}");
            assert!(certain);
        }
        assert!(grid.time_of(0).abs_diff(437) <= 10, "{}", grid.time_of(0));
        assert_eq!(grid.remeasured(), 0);
    }

    #[test]
    fn an_off_nominal_oscillator_is_measured() {
        // 1 % slow sensor at nominal 1 ms.
        let period = 1010.0;
        let first = 250.0;
        let mut grid = SampleGrid::new(0, 0, 1000);
        let mut t = 0u64;
        let mut step = 7_000u64;
        while t < 600_000_000 {
            t += step;
            step = 3_000 + (step * 7919) % 9_000; // a jittery schedule
            grid.observe(t, t, produced(first, period, t)).unwrap();
        }
        assert!(grid.remeasured() > 0);
        // Predictions over a 2 s stall are exact after ten minutes.
        let stall = t + 2_000_000;
        assert_eq!(
            grid.produced(stall, stall).0,
            produced(first, period, stall)
        );
    }

    #[test]
    fn counts_far_from_the_clock_are_implausible() {
        let mut grid = SampleGrid::new(0, 0, 1000);
        grid.observe(10_000, 10_000, 10).unwrap();
        grid.observe(20_000, 20_000, 20).unwrap();
        // A FIFO count stuck at 32 samples, read again and again.
        assert_eq!(grid.observe(21_000, 21_000, 52), Err(Implausible));
    }
}
