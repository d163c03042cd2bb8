//! The faults a test can inject into the simulated device: NACKs, bus errors, a wrong
//! identity, a stuck FIFO count, the sample oscillator's offset and drift, I2C outages and
//! device resets.

/// The sensor's sample oscillator against the caller's (the board's) clock: its rate is
/// `1 + (ppm + drift_ppm_per_hour * t_hours) * 1e-6` of nominal at board time `t_hours`
/// (hours since time 0). The default is an ideal oscillator.
///
/// The rate must stay positive: `ppm > -1e6`; with a negative drift, once the rate would
/// reach zero the sensor makes no more samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorClock {
    /// Constant frequency offset, ppm (+3000: 0.3 % fast).
    pub ppm: f64,
    /// Linear change of the offset, ppm per hour of board time.
    pub drift_ppm_per_hour: f64,
}

impl SensorClock {
    /// Linear and quadratic coefficients of the phase in us: `phase(t) = c1 t + c2 t^2`.
    fn coefficients(&self) -> (f64, f64) {
        let c1 = 1.0 + self.ppm * 1e-6;
        let c2 = self.drift_ppm_per_hour * 1e-6 / (2.0 * 3600e6);
        (c1, c2)
    }

    /// The oscillator's phase at board time `t_us`: nominal microseconds elapsed on the
    /// sensor since board time 0 (the integral of the rate).
    pub fn phase_us(&self, t_us: f64) -> f64 {
        let (c1, c2) = self.coefficients();
        c1 * t_us + c2 * t_us * t_us
    }

    /// The board time at which the phase reaches `phase_us` (the inverse of
    /// [`SensorClock::phase_us`] on its rising branch); infinity if it never does.
    pub fn time_at_phase_us(&self, phase_us: f64) -> f64 {
        let (c1, c2) = self.coefficients();
        let t = if c2 == 0.0 {
            phase_us / c1
        } else {
            // The root of c2 t^2 + c1 t - phase = 0 on the rising branch, in the form that
            // keeps its precision when c2 t is small against c1.
            let disc = c1 * c1 + 4.0 * c2 * phase_us;
            if disc < 0.0 {
                return f64::INFINITY;
            }
            2.0 * phase_us / (c1 + disc.sqrt())
        };
        if t.is_finite() && t >= 0.0 {
            t
        } else {
            f64::INFINITY
        }
    }
}

/// A window of board time in which the device does not answer at all, us.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Outage {
    pub at_us: u64,
    pub for_us: u64,
}

impl Outage {
    pub fn contains(&self, t_us: u64) -> bool {
        t_us >= self.at_us && t_us - self.at_us < self.for_us
    }
}

/// Injected faults. The counts are numbers of coming transactions affected (`u32::MAX`:
/// all of them); each affected transaction fails without any effect on the device.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Faults {
    /// The address byte is not acknowledged.
    pub nack_address: u32,
    /// The first written byte is not acknowledged (transactions without a write are not
    /// affected and do not consume the count).
    pub nack_data: u32,
    /// The transaction ends in a bus error.
    pub bus_error: u32,
    /// WHO_AM_I reads this instead of 0x68.
    pub who_am_i: Option<u8>,
    /// FIFO_COUNT reads this whatever the FIFO holds.
    pub stuck_fifo_count: Option<u16>,
    /// The sample oscillator's offset and drift. A change while sampling keeps the
    /// progress towards the next sample (the phase is continuous).
    pub clock: SensorClock,
    /// Windows in which every transaction is NACKed at the address (the count
    /// `nack_address` is not consumed); sampling and the FIFO go on.
    pub i2c_outages: Vec<Outage>,
    /// Device resets (as by PWR_MGMT_1 bit 7), each once when the clock passes its time, us;
    /// any order (they are sorted when the clock moves), removed as they happen. A time
    /// already past fires at the next clock move. [`super::SimMpu6050::schedule_reset`] adds one.
    pub resets_at_us: Vec<u64>,
}

impl Faults {
    /// Whether `t_us` falls in one of the outages.
    pub fn in_outage(&self, t_us: u64) -> bool {
        self.i2c_outages.iter().any(|o| o.contains(t_us))
    }
}

/// Consume one count of a fault, if set (`u32::MAX` is never used up).
pub fn take(count: &mut u32) -> bool {
    if *count == 0 {
        return false;
    }
    if *count != u32::MAX {
        *count -= 1;
    }
    true
}
