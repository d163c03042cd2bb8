//! A simulated ADXL345 accelerometer at register level, on the shared bus behaviour
//! ([`super::RegisterChip`]) and sample timing ([`super::SampledChip`]).
//!
//! What is modelled (ADXL345 data sheet rev. G, [`protocol::adxl345::reg`]):
//! - DEVID (0x00) reads 0xE5. The chip powers up in standby (POWER_CTL 0, BW_RATE 0x0A,
//!   everything else 0) and samples only while POWER_CTL bit 3 (MEASURE) is set; a change of
//!   BW_RATE or DATA_FORMAT while measuring restarts sampling. There is no reset command;
//!   an injected reset restores the power-on state.
//! - The signal chain per axis ([`AccelChain`]): the model's accelerometer noise at four
//!   times the output rate, a two-pole low-pass of bandwidth rate / 2 (the data sheet's
//!   table 7 gives only the bandwidth: the shape is the MPU-6050 DLPF's design with a group
//!   delay of 0.25 / bandwidth, near the least it allows), decimation by 4, and counts at
//!   256 LSB per g (full resolution) or `256 >> range` (10-bit), clipped to the range.
//! - The white noise follows the data sheet's noise against rate: the model's N is the
//!   density at 100 Hz in normal power on x and y; at another setting it is scaled by
//!   `noise_lsb_rms(setting) / noise_lsb_rms(100 Hz) * sqrt(100 Hz / rate)` (the same LSB rms
//!   below 100 Hz, sqrt(2) more per doubling above, 1.8 LSB rms in low power) and on z by
//!   1.1 / 0.75 ([`Adxl345Settings::noise_lsb_rms`]). The N meant is the output's: the input
//!   is lowered by what the filter and the decimation fold back
//!   ([`crate::sim::chain::white_noise_inflation`]).
//! - FIFO_CTL bits 7:6: bypass (the data registers hold the newest sample; INT_SOURCE bit 0,
//!   OVERRUN, when a sample replaces one not read), FIFO (samples kept until 32, then new
//!   ones dropped with OVERRUN) and stream (the newest 32 kept, the oldest dropped with
//!   OVERRUN); trigger mode is taken as stream. FIFO_STATUS bits 5:0 give the samples held.
//!   In the FIFO modes a read of DATAX0 moves the oldest sample into the data registers
//!   (the data sheet: "each time data is read from the FIFO, the oldest ... data are placed
//!   into the DATAX, DATAY and DATAZ registers"), so a burst of six bytes from DATAX0 reads
//!   one sample; bytes of it not read in that burst are lost, as on the chip.
//! - INT_SOURCE bit 7 (DATA_READY) is set while a sample waits (in bypass) or the FIFO is not
//!   empty. OVERRUN, a data-related interrupt, clears as the data registers are read until
//!   its condition no longer holds (the data sheet's "Interrupts"): in bypass when the data
//!   registers are read, in the FIFO modes when a read leaves the FIFO below full.
//! - Faults ([`super::Faults`]): NACKs, bus errors, a wrong DEVID, a stuck FIFO_STATUS count, the
//!   oscillator's offset and drift, outages and resets.
//!
//! Not modelled: tap, activity and free-fall detection, offsets (OFSX..OFSZ), self-test,
//! the interrupt pins and INT_MAP, sleep and auto-sleep, the watermark bit, SPI.

use super::core::{ChipCore, SimChip};
use super::{JournalEntry, RegisterChip, SampledChip, Sampler};
use crate::sim::chain::{AxisChain, quantize, white_noise_inflation};
use crate::sim::dlpf::DlpfDesign;
use crate::sim::imu::{ImuModel, RawSample, TrueInput, deterministic};
use protocol::adxl345::reg::bits::{ENTRIES_MASK, FULL_RES, MEASURE, OVERRUN, RANGE_MASK};
use protocol::adxl345::{self, Adxl345Settings, FIFO_DEPTH, reg};
use protocol::mpu6050::STANDARD_GRAVITY;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::VecDeque;

/// Internal samples per output sample.
const OVERSAMPLING: u64 = 4;
/// INT_SOURCE bit 7.
const DATA_READY: u8 = 1 << 7;
/// FIFO_CTL bits 7:6.
const FIFO_MODE_SHIFT: u8 = 6;

/// The three axes' chains at one setting (module documentation).
#[derive(Debug, Clone)]
pub struct AccelChain {
    model: ImuModel,
    axes: [AxisChain; 3],
    rate_hz: f64,
    n: u64,
}

impl AccelChain {
    pub fn new(model: &ImuModel, settings: &Adxl345Settings, seed: u64, duration_s: f64) -> Self {
        let rate_hz = settings.output_rate_hz();
        let bandwidth = settings.bandwidth_hz();
        let design = DlpfDesign::design(bandwidth, 0.25 / bandwidth, rate_hz * OVERSAMPLING as f64);
        let reference = Adxl345Settings::default().noise_lsb_rms(false);
        // The filter and the decimation fold a little noise back: the input is lowered by
        // as much, so the output's N is the data sheet's.
        let folding = white_noise_inflation(&design, OVERSAMPLING as usize);
        let axes = [0usize, 1, 2].map(|i| {
            let z = i == 2;
            // LSB rms at this setting over that at 100 Hz, as a density: rms / sqrt(rate).
            let factor = settings.noise_lsb_rms(z) / reference * (100.0 / rate_hz).sqrt() / folding;
            let mut terms = model.accel.noise;
            terms.n *= factor;
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(i as u64);
            AxisChain::new(terms, &design, duration_s, rng).with_lines(&model.accel.lines)
        });
        AccelChain {
            model: model.clone(),
            axes,
            rate_hz,
            n: 0,
        }
    }

    /// The next output sample in m/s^2.
    pub fn next_sample(&mut self) -> [f64; 3] {
        let t = self.n as f64 / self.rate_hz;
        let profile = &self.model.temperature.profile;
        let delta = profile.at(t) - self.model.temperature.reference;
        let input = TrueInput::at_rest(self.model.gravity, STANDARD_GRAVITY);
        let signal = deterministic(
            &self.model.accel,
            input.specific_force,
            delta,
            profile.rate_at(t),
        );
        let index = self.n * OVERSAMPLING;
        self.n += 1;
        [0, 1, 2].map(|i| self.axes[i].advance_to(index, signal[i]))
    }
}

/// m/s^2 to counts at the range and resolution a DATA_FORMAT value sets, clipped to the
/// range: 256 LSB per g at full resolution, `256 >> range` in 10-bit mode.
pub fn counts(a: f64, data_format: u8) -> i16 {
    let range = data_format & RANGE_MASK;
    let lsb_per_g = if data_format & FULL_RES != 0 {
        adxl345::LSB_PER_G
    } else {
        adxl345::LSB_PER_G / f64::from(1u8 << range)
    };
    let full_scale = f64::from(2u16 << range) * lsb_per_g;
    let c = quantize(a / STANDARD_GRAVITY, 1.0 / lsb_per_g);
    c.clamp(-(full_scale as i16), full_scale as i16 - 1)
}

#[derive(Debug, Clone)]
struct Run {
    chain: AccelChain,
    sampler: Sampler,
}

#[derive(Debug, Clone)]
pub struct SimAdxl345 {
    core: ChipCore,
    regs: [u8; 64],
    model: ImuModel,
    run: Option<Run>,
    fifo: VecDeque<[i16; 3]>,
}

impl SimAdxl345 {
    /// A chip at 0x53 simulating `model`'s accelerometer, seeded by `seed`, at time 0, in
    /// standby.
    pub fn new(model: ImuModel, seed: u64) -> Self {
        let mut dev = SimAdxl345 {
            core: ChipCore::new(adxl345::DEFAULT_ADDRESS, seed),
            regs: [0; 64],
            model,
            run: None,
            fifo: VecDeque::with_capacity(FIFO_DEPTH),
        };
        dev.power_on_reset();
        dev.core.resets = 0;
        dev
    }

    /// The settings the registers hold.
    pub fn settings(&self) -> Adxl345Settings {
        Adxl345Settings::from_registers(
            self.regs[usize::from(reg::BW_RATE)],
            self.regs[usize::from(reg::DATA_FORMAT)],
        )
    }

    fn measuring(&self) -> bool {
        self.regs[usize::from(reg::POWER_CTL)] & MEASURE != 0
    }

    fn fifo_mode(&self) -> u8 {
        self.regs[usize::from(reg::FIFO_CTL)] >> FIFO_MODE_SHIFT
    }

    fn restart(&mut self) {
        self.run = self.measuring().then(|| {
            let seed = self.core.next_run_seed();
            let hint = self.core.duration_hint_s;
            let chain = AccelChain::new(&self.model, &self.settings(), seed, hint);
            let sampler = Sampler::start(self.core.faults.clock, self.core.time_us, chain.rate_hz);
            Run { chain, sampler }
        });
    }

    fn show(&mut self, sample: [i16; 3]) {
        let first = usize::from(reg::DATAX0);
        for (k, v) in sample.iter().enumerate() {
            self.regs[first + 2 * k..first + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
        }
    }

    fn set_status(&mut self, bits: u8) {
        self.regs[usize::from(reg::INT_SOURCE)] |= bits;
    }
}

impl SimChip for SimAdxl345 {
    fn core(&self) -> &ChipCore {
        &self.core
    }
    fn core_mut(&mut self) -> &mut ChipCore {
        &mut self.core
    }
}

impl RegisterChip for SimAdxl345 {
    fn read_register(&mut self, register: u8) -> u8 {
        let r = register & 0x3F;
        match r {
            reg::DEVID => self.core.faults.who_am_i.unwrap_or(adxl345::DEVID_VALUE),
            reg::FIFO_STATUS => {
                let held = self.fifo.len() as u16;
                (self.core.faults.stuck_fifo_count.unwrap_or(held) as u8) & ENTRIES_MASK
            }
            reg::INT_SOURCE => {
                let ready = if self.fifo.is_empty() { 0 } else { DATA_READY };
                self.regs[usize::from(r)] | ready
            }
            reg::DATAX0 if self.fifo_mode() != 0 => {
                if let Some(sample) = self.fifo.pop_front() {
                    self.show(sample);
                }
                if self.fifo.len() < FIFO_DEPTH {
                    self.regs[usize::from(reg::INT_SOURCE)] &= !OVERRUN;
                }
                self.regs[usize::from(r)]
            }
            reg::DATAX0 => {
                self.regs[usize::from(reg::INT_SOURCE)] &= !(DATA_READY | OVERRUN);
                self.regs[usize::from(r)]
            }
            _ => self.regs[usize::from(r)],
        }
    }

    fn write_register(&mut self, register: u8, value: u8) {
        let i = usize::from(register & 0x3F);
        match register & 0x3F {
            reg::POWER_CTL => {
                let was = self.measuring();
                self.regs[i] = value;
                if was != self.measuring() {
                    self.restart();
                }
            }
            reg::BW_RATE | reg::DATA_FORMAT => {
                let before = (self.settings(), self.regs[usize::from(reg::DATA_FORMAT)]);
                self.regs[i] = value;
                if self.run.is_some()
                    && (self.settings(), self.regs[usize::from(reg::DATA_FORMAT)]) != before
                {
                    self.restart();
                }
            }
            reg::FIFO_CTL => {
                self.regs[i] = value;
                if self.fifo_mode() == 0 {
                    self.fifo.clear();
                }
            }
            reg::DEVID | reg::INT_SOURCE | reg::FIFO_STATUS => {}
            r if (reg::DATAX0..reg::DATAX0 + 6).contains(&r) => {}
            _ => self.regs[i] = value,
        }
    }
}

impl SampledChip for SimAdxl345 {
    fn sampler_mut(&mut self) -> Option<&mut Sampler> {
        self.run.as_mut().map(|run| &mut run.sampler)
    }

    fn sample(&mut self) {
        let Some(run) = &mut self.run else { return };
        let si = run.chain.next_sample();
        self.core.samples_made += 1;
        let format = self.regs[usize::from(reg::DATA_FORMAT)];
        let sample = si.map(|a| counts(a, format));
        let mut in_fifo = self.fifo_mode() != 0;
        if in_fifo {
            if self.fifo.len() >= FIFO_DEPTH {
                self.set_status(OVERRUN);
                // FIFO mode keeps the first 32; stream (and trigger) the newest.
                if self.fifo_mode() == 1 {
                    in_fifo = false;
                } else {
                    self.fifo.pop_front();
                }
            }
            if in_fifo {
                self.fifo.push_back(sample);
            }
        } else {
            if self.regs[usize::from(reg::INT_SOURCE)] & DATA_READY != 0 {
                self.set_status(OVERRUN);
            }
            self.show(sample);
            self.set_status(DATA_READY);
        }
        self.core.note(JournalEntry::Sample {
            time_us: self.core.time_us,
            raw: RawSample {
                accel: sample,
                temp: 0,
                gyro: [0; 3],
            },
            in_fifo,
        });
    }

    fn power_on_reset(&mut self) {
        self.regs = [0; 64];
        self.regs[usize::from(reg::DEVID)] = adxl345::DEVID_VALUE;
        self.regs[usize::from(reg::BW_RATE)] = Adxl345Settings::default().bw_rate();
        self.fifo.clear();
        self.reset_pointer();
        self.core.resets += 1;
        self.run = None;
    }
}
