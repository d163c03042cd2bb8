//! A simulated ITG-3200 (or ITG-3205) gyro at register level, on the shared bus behaviour
//! ([`super::RegisterChip`]) and sample timing ([`super::SampledChip`]).
//!
//! What is modelled (register numbers from PS-ITG-3200A rev 1.4, [`protocol::itg3200::reg`]):
//! - WHO_AM_I (0x00) reads 0x68; the chip powers up awake on its internal oscillator, with
//!   every other register 0 (so sampling at 8 kHz until configured); PWR_MGM bit 7
//!   (H_RESET) restores the power-on state and clears itself; bit 6 (SLEEP) stops sampling.
//! - SMPLRT_DIV and DLPF_FS set the gyro's chain, the MPU-6050's gyro path ([`Imu`]: noise
//!   at the internal rate, the DLPF, decimation without anti-alias filtering), counted at
//!   14.375 LSB per deg/s; a change while awake restarts sampling.
//! - Each sample overwrites TEMP_OUT and GYRO_XOUT..GYRO_ZOUT (big-endian) and sets INT_STATUS
//!   bit 0 (RAW_DATA_RDY) if INT_CFG bit 0 (RAW_RDY_EN) is set. There is no FIFO: a sample
//!   not read before the next is lost, which the journal ([`JournalEntry::Sample`]) records
//!   so a test can hold the firmware's count of missed samples against the truth.
//! - INT_STATUS clears when read, or on any register read with INT_CFG bit 4
//!   (INT_ANYRD_2CLEAR).
//! - TEMP_OUT follows the ITG-3200's scale, `35 degC + (counts + 13200) / 280`.
//! - Faults ([`super::Faults`]) as the MPU-6050's: NACKs, bus errors, a wrong WHO_AM_I, the
//!   oscillator's offset and drift, outages and resets (the FIFO count is not used).
//!
//! Not modelled: ITG_RDY (the PLL's lock), the interrupt pin, clock source selection, the
//! standby bits, writing the chip's own address into WHO_AM_I.

use super::core::{ChipCore, SimChip};
use super::{JournalEntry, RegisterChip, SampledChip, Sampler};
use crate::sim::imu::{Imu, ImuModel, RawSample};
use protocol::itg3200::reg::bits::{H_RESET, INT_ANYRD_2CLEAR, RAW_DATA_RDY, RAW_RDY_EN, SLEEP};
use protocol::itg3200::{self, Itg3200Settings, reg};
use protocol::mpu6050::{AccelRange, Chip, GyroRange, SensorSettings};

/// The ITG-3200's identity and temperature scale in the form [`Imu`] takes.
const ITG3200_CHIP: Chip = Chip {
    who_am_i: itg3200::WHO_AM_I_VALUE,
    name: "ITG-3200",
    fifo_size: 0,
    temp_lsb_per_c: 280.0,
    temp_at_zero_c: 35.0 + 13200.0 / 280.0,
};

/// The ITG-3200's signal chain at `settings`: the MPU-6050's gyro path with this DLPF row and
/// divider (its accelerometer half is not read), counted at 14.375 LSB per deg/s, with the
/// ITG-3200's temperature formula.
pub fn gyro_chain(model: &ImuModel, settings: &Itg3200Settings, seed: u64, duration_s: f64) -> Imu {
    let chain = SensorSettings {
        dlpf: settings.dlpf,
        smplrt_div: settings.smplrt_div,
        gyro_range: GyroRange::Dps2000,
        accel_range: AccelRange::G2,
    };
    Imu::new(model, chain, seed, duration_s)
        .with_gyro_scale(itg3200::rad_s_per_lsb())
        .with_chip(ITG3200_CHIP)
}

#[derive(Debug, Clone)]
struct Run {
    imu: Imu,
    sampler: Sampler,
}

#[derive(Debug, Clone)]
pub struct SimItg3200 {
    core: ChipCore,
    regs: [u8; 128],
    model: ImuModel,
    run: Option<Run>,
}

impl SimItg3200 {
    /// A chip at 0x68 simulating `model`'s gyro (and temperature), seeded by `seed`, at time
    /// 0, just powered up.
    pub fn new(model: ImuModel, seed: u64) -> Self {
        let mut dev = SimItg3200 {
            core: ChipCore::new(itg3200::DEFAULT_ADDRESS, seed),
            regs: [0; 128],
            model,
            run: None,
        };
        dev.power_on_reset();
        dev.core.resets = 0;
        dev
    }

    /// The settings the registers hold.
    pub fn settings(&self) -> Itg3200Settings {
        Itg3200Settings::from_registers(
            self.regs[usize::from(reg::SMPLRT_DIV)],
            self.regs[usize::from(reg::DLPF_FS)],
        )
    }

    fn awake(&self) -> bool {
        self.regs[usize::from(reg::PWR_MGM)] & SLEEP == 0
    }

    /// (Re)start sampling with the current settings, or stop when asleep.
    fn restart(&mut self) {
        self.run = self.awake().then(|| {
            let seed = self.core.next_run_seed();
            let imu = gyro_chain(
                &self.model,
                &self.settings(),
                seed,
                self.core.duration_hint_s,
            );
            let sampler = Sampler::start(
                self.core.faults.clock,
                self.core.time_us,
                imu.output_rate_hz(),
            );
            Run { imu, sampler }
        });
    }
}

impl SimChip for SimItg3200 {
    fn core(&self) -> &ChipCore {
        &self.core
    }
    fn core_mut(&mut self) -> &mut ChipCore {
        &mut self.core
    }
}

impl RegisterChip for SimItg3200 {
    fn read_register(&mut self, register: u8) -> u8 {
        let status = usize::from(reg::INT_STATUS);
        let value = match register {
            reg::INT_STATUS => std::mem::take(&mut self.regs[status]),
            reg::WHO_AM_I => self.core.faults.who_am_i.unwrap_or(itg3200::WHO_AM_I_VALUE),
            r => self.regs[usize::from(r & 0x7F)],
        };
        if self.regs[usize::from(reg::INT_CFG)] & INT_ANYRD_2CLEAR != 0 {
            self.regs[status] = 0;
        }
        value
    }

    fn write_register(&mut self, register: u8, value: u8) {
        let i = usize::from(register & 0x7F);
        match register {
            reg::PWR_MGM if value & H_RESET != 0 => self.power_on_reset(),
            reg::PWR_MGM => {
                let was_awake = self.awake();
                self.regs[i] = value;
                if was_awake != self.awake() {
                    self.restart();
                }
            }
            reg::SMPLRT_DIV | reg::DLPF_FS => {
                let before = self.settings();
                self.regs[i] = value;
                if self.run.is_some() && self.settings() != before {
                    self.restart();
                }
            }
            reg::WHO_AM_I | reg::INT_STATUS => {}
            r if (reg::TEMP_OUT_H..reg::TEMP_OUT_H + 8).contains(&r) => {}
            _ => self.regs[i] = value,
        }
    }
}

impl SampledChip for SimItg3200 {
    fn sampler_mut(&mut self) -> Option<&mut Sampler> {
        self.run.as_mut().map(|run| &mut run.sampler)
    }

    /// One sample: the data registers, RAW_DATA_RDY.
    fn sample(&mut self) {
        let Some(run) = &mut self.run else { return };
        let full = run.imu.next_raw();
        self.core.samples_made += 1;
        let words = [full.temp, full.gyro[0], full.gyro[1], full.gyro[2]];
        let first = usize::from(reg::TEMP_OUT_H);
        for (k, w) in words.iter().enumerate() {
            self.regs[first + 2 * k..first + 2 * k + 2].copy_from_slice(&w.to_be_bytes());
        }
        if self.regs[usize::from(reg::INT_CFG)] & RAW_RDY_EN != 0 {
            self.regs[usize::from(reg::INT_STATUS)] |= RAW_DATA_RDY;
        }
        let raw = RawSample {
            accel: [0; 3],
            ..full
        };
        self.core.note(JournalEntry::Sample {
            time_us: self.core.time_us,
            raw,
            in_fifo: false,
        });
    }

    fn power_on_reset(&mut self) {
        self.regs = [0; 128];
        self.regs[usize::from(reg::WHO_AM_I)] = itg3200::WHO_AM_I_VALUE;
        self.reset_pointer();
        self.core.resets += 1;
        self.restart();
    }
}
