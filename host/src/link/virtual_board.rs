//! The virtual board: the firmware's portable code (`firmware::Firmware`, the very code the
//! RP2040 runs) driving simulated chips (`sim::device`) on a simulated I2C bus
//! ([`SharedBus`]) in-process, emitting the bytes a real board would send over USB: an
//! MPU-6050 alone ([`VirtualBoard::new`]) or a GY-85's ITG-3200 and ADXL345
//! ([`VirtualBoard::gy85`]). Time is the bus's clock, which is also the firmware's clock; it
//! advances with the wall clock times a speed factor, or as fast as the host reads
//! (`Speed::Max`).
//!
//! Faults ([`VirtualBoard::with_faults`], the model file's `[faults]` table): the sensors'
//! own ([`crate::sim::device::Faults`]: its sample clock's offset and drift, I2C outages,
//! sensor resets, a clone's WHO_AM_I) and board reboots (watchdog, brown-out) at listed
//! times. A reboot replaces the firmware with a freshly started one (as at power-up: `init`
//! resets and sets up the sensor), loses whatever the host had not yet read (the USB
//! buffers), and leaves the board idle until the host sends Start again; the sensor is not
//! powered down, so its clock, faults and state go on. A sensor that does not answer at
//! start-up is not fatal, as on the board: the firmware logs it ([`VirtualBoard::boot_error`])
//! and reports it on the next Configure or Start.

use super::shared_bus::SharedBus;
use crate::sim::boards;
use crate::sim::device::SimBus;
use crate::sim::imu::ImuModel;
use crate::sim::model_file::FaultPlan;
use firmware::{BoardConfig, Firmware};
use protocol::ErrorCode;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

pub use super::transport::Speed;

struct NoDelay;
impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _: u32) {}
}

/// Emulated time the board advances per step: shorter than the firmware's drain interval at
/// every supported rate, so steps never make it late.
const STEP: Duration = Duration::from_millis(5);

/// Bytes the emulated USB link buffers towards the host before it refuses frames (the
/// firmware then drops and counts batches, as on a real board whose host stops reading).
pub const LINK_BUFFER: usize = 1 << 20;

/// The firmware on the simulated bus.
pub struct VirtualBoard {
    sensor: SharedBus,
    firmware: Firmware<SharedBus, SharedBus>,
    board_id: u64,
    /// What the last start-up's `init` returned.
    boot_result: Result<(), ErrorCode>,
    /// Reboot times, us, sorted.
    reboots_at_us: VecDeque<u64>,
    reboots: u32,
    outbox: VecDeque<u8>,
    speed: Speed,
    /// Wall time and emulated time at the last speed reference point.
    wall_origin: Instant,
    emulated_origin_us: u64,
}

impl VirtualBoard {
    /// A board whose sensor follows `model` (seeded), with the given board id; an error if
    /// the sensor does not start.
    pub fn new(model: ImuModel, seed: u64, board_id: u64, speed: Speed) -> Result<Self, ErrorCode> {
        let board = Self::with_faults(model, seed, board_id, speed, &FaultPlan::default());
        board.boot_result.map(|()| board)
    }

    /// A board whose sensor follows `model` (seeded), with `faults` set before the board
    /// starts (so that its start-up meets them, e.g. a clone's WHO_AM_I). Like the board, it
    /// starts whatever the sensor answers ([`VirtualBoard::boot_error`]).
    pub fn with_faults(
        model: ImuModel,
        seed: u64,
        board_id: u64,
        speed: Speed,
        faults: &FaultPlan,
    ) -> Self {
        Self::on_bus(
            boards::mpu6050(model, seed, faults),
            board_id,
            speed,
            faults,
        )
    }

    /// A GY-85 board: an ITG-3200 at 0x68 following `model`'s `[gyro]` (and temperature)
    /// and an ADXL345 at 0x53 following its `[accel]`, each with its own noise from `seed`.
    /// `faults` reach both chips (clock, I2C outages and resets; a WHO_AM_I only the
    /// ITG-3200's) and the board.
    pub fn gy85(
        model: ImuModel,
        seed: u64,
        board_id: u64,
        speed: Speed,
        faults: &FaultPlan,
    ) -> Self {
        Self::on_bus(boards::gy85(model, seed, faults), board_id, speed, faults)
    }

    /// The firmware started on `bus`, with the board's reboots from `faults`.
    fn on_bus(bus: SimBus, board_id: u64, speed: Speed, faults: &FaultPlan) -> Self {
        let sensor = SharedBus::new(bus);
        let (firmware, boot_result) = boot(&sensor, board_id);
        let emulated_origin_us = sensor.lock().time_us();
        let mut board = VirtualBoard {
            sensor,
            firmware,
            board_id,
            boot_result,
            reboots_at_us: VecDeque::new(),
            reboots: 0,
            outbox: VecDeque::new(),
            speed,
            wall_origin: Instant::now(),
            emulated_origin_us,
        };
        for &t in &faults.board_resets_us {
            board.schedule_reboot(t);
        }
        board
    }

    /// A reboot (watchdog, brown-out) when emulated time passes `t_us` (module
    /// documentation); a time already past reboots at the next step.
    pub fn schedule_reboot(&mut self, t_us: u64) {
        let i = self.reboots_at_us.partition_point(|&r| r <= t_us);
        self.reboots_at_us.insert(i, t_us);
    }

    /// Reboots so far (not counting power-up).
    pub fn reboots(&self) -> u32 {
        self.reboots
    }

    /// The error the firmware's start-up (`init`) logged at power-up or the last reboot.
    pub fn boot_error(&self) -> Option<ErrorCode> {
        self.boot_result.err()
    }

    /// Whether the firmware is streaming samples.
    pub fn streaming(&self) -> bool {
        self.firmware.streaming()
    }

    /// The simulated bus and its chips, to inject faults or read their state.
    pub fn sensor(&self) -> &SharedBus {
        &self.sensor
    }

    /// Emulated time, microseconds since the board started.
    pub fn time_us(&self) -> u64 {
        self.sensor.lock().time_us()
    }

    /// Bytes from the host (commands).
    pub fn write(&mut self, bytes: &[u8]) {
        let outbox = &mut self.outbox;
        self.firmware
            .handle_bytes(bytes, &mut |frame| push_frame(outbox, frame));
    }

    /// Bytes for the host: what the board has sent, advancing emulated time as the speed
    /// allows; waits at most `timeout` (wall time) for something to send. Returns 0 when
    /// nothing came in that time (e.g. the board is not streaming).
    pub fn read(&mut self, buf: &mut [u8], timeout: Duration) -> usize {
        let deadline = Instant::now() + timeout;
        loop {
            if !self.outbox.is_empty() {
                let n = buf.len().min(self.outbox.len());
                for (dst, src) in buf.iter_mut().zip(self.outbox.drain(..n)) {
                    *dst = src;
                }
                return n;
            }
            match self.speed {
                Speed::Max => {
                    if !self.firmware.streaming() {
                        // The host waited `timeout` for nothing: on a real board that much
                        // time passes, and a host that watches for silence must see it.
                        self.advance(timeout);
                        return 0;
                    }
                    self.step(STEP);
                }
                Speed::Factor(f) => {
                    let target = self.emulated_origin_us
                        + (self.wall_origin.elapsed().as_secs_f64() * f * 1e6) as u64;
                    let now = self.time_us();
                    if target > now {
                        let dt = Duration::from_micros(target - now).min(STEP);
                        self.step(dt);
                        continue;
                    }
                    if Instant::now() >= deadline {
                        return 0;
                    }
                    std::thread::sleep(Duration::from_millis(1).min(deadline - Instant::now()));
                }
            }
            if Instant::now() >= deadline && self.outbox.is_empty() {
                return 0;
            }
        }
    }

    /// Let `dt` of emulated time pass with the firmware running, whether or not the host
    /// reads: what the board sends queues (up to [`LINK_BUFFER`]). At a speed factor the
    /// board then waits for the wall clock to catch up before it moves on.
    pub fn advance(&mut self, dt: Duration) {
        let mut left = dt;
        while !left.is_zero() {
            let step = left.min(STEP);
            self.step(step);
            left -= step;
        }
    }

    /// Advance emulated time by `dt` and let the firmware run, rebooting on the way when a
    /// reboot falls in the step.
    fn step(&mut self, dt: Duration) {
        let dt_us = u64::try_from(dt.as_micros()).unwrap_or(u64::MAX);
        let end_us = self.time_us().saturating_add(dt_us);
        while let Some(at_us) = self.reboots_at_us.front().copied().filter(|&t| t <= end_us) {
            self.reboots_at_us.pop_front();
            self.sensor.lock().set_time_us(at_us);
            self.reboot();
        }
        self.sensor.lock().set_time_us(end_us);
        let outbox = &mut self.outbox;
        self.firmware.poll(&mut |frame| push_frame(outbox, frame));
    }

    /// The board restarts: what it had not sent is gone, and a fresh firmware starts as at
    /// power-up.
    fn reboot(&mut self) {
        self.outbox.clear();
        let (firmware, boot_result) = boot(&self.sensor, self.board_id);
        self.firmware = firmware;
        self.boot_result = boot_result;
        self.reboots += 1;
    }
}

/// The firmware as the board starts it: constructed, then `init`, whose error the board
/// logs and goes on.
fn boot(
    sensor: &SharedBus,
    board_id: u64,
) -> (Firmware<SharedBus, SharedBus>, Result<(), ErrorCode>) {
    let mut firmware = Firmware::new(
        sensor.clone(),
        sensor.clone(),
        BoardConfig {
            board_id,
            reset_reason: protocol::ResetReason::Unknown,
        },
    );
    let result = firmware.init(&mut NoDelay);
    (firmware, result)
}

impl super::Link for VirtualBoard {
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        Ok(VirtualBoard::read(self, buf, timeout))
    }

    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.write(bytes);
        Ok(())
    }

    fn describe(&self) -> String {
        "the virtual board (--port sim)".into()
    }

    /// Emulated time: what the host would see on its own clock beside a real board.
    fn clock_us(&self) -> u64 {
        self.time_us()
    }
}

/// Queue a frame for the host unless the link's buffer is full (back-pressure).
fn push_frame(outbox: &mut VecDeque<u8>, frame: &[u8]) -> bool {
    if outbox.len() + frame.len() > LINK_BUFFER {
        return false;
    }
    outbox.extend(frame);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::device::SimChip;
    use crate::sim::noise::NoiseTerms;
    use protocol::frame::{FrameDecoder, MAX_WIRE_LEN, encode};
    use protocol::{Command, DeviceMessage, Request, SensorSettings};

    fn board(speed: Speed) -> VirtualBoard {
        let mut model = ImuModel::default();
        model.gyro.noise = NoiseTerms {
            n: 1e-3,
            ..Default::default()
        };
        VirtualBoard::new(model, 1, 42, speed).unwrap()
    }

    fn send(b: &mut VirtualBoard, seq: u16, command: Command) {
        let mut buf = [0u8; MAX_WIRE_LEN];
        let n = encode(&Request { seq, command }, &mut buf).unwrap();
        b.write(&buf[..n]);
    }

    fn messages(b: &mut VirtualBoard, reads: usize) -> Vec<DeviceMessage> {
        let mut decoder = FrameDecoder::new();
        let mut out = Vec::new();
        let mut buf = [0u8; 4096];
        for _ in 0..reads {
            let n = b.read(&mut buf, Duration::from_millis(200));
            decoder.feed::<DeviceMessage>(&buf[..n], |m| out.push(m.unwrap()));
        }
        out
    }

    #[test]
    fn info_configure_start_and_stream_at_max_speed() {
        let mut b = board(Speed::Max);
        send(&mut b, 1, Command::GetInfo);
        let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        send(&mut b, 2, Command::Configure(settings));
        send(&mut b, 3, Command::Start);
        let msgs = messages(&mut b, 200);
        assert!(
            matches!(&msgs[0], DeviceMessage::Info(i) if i.board_id == 42 && i.who_am_i == 0x68)
        );
        assert!(matches!(msgs[1], DeviceMessage::Ack { seq: 2 }));
        assert!(matches!(msgs[2], DeviceMessage::Ack { seq: 3 }));
        let mut next = 0;
        for m in &msgs[3..] {
            if let DeviceMessage::Samples(batch) = m {
                assert_eq!(batch.first_index, next, "no gap");
                next += batch.samples.len() as u64;
            }
        }
        // At max speed every read advances time until there are bytes: 200 reads of up to
        // 4 KiB carry hundreds of samples.
        assert!(next > 500, "{next} samples");
    }

    fn count_samples(msgs: &[DeviceMessage]) -> usize {
        msgs.iter()
            .map(|m| match m {
                DeviceMessage::Samples(batch) => batch.samples.len(),
                _ => 0,
            })
            .sum()
    }

    #[test]
    fn a_reboot_loses_unread_data_and_waits_for_start() {
        let mut b = board(Speed::Max);
        send(&mut b, 1, Command::Start);
        let before = messages(&mut b, 20);
        assert!(matches!(before[0], DeviceMessage::Ack { seq: 1 }));
        assert!(count_samples(&before) > 0);
        let reboot_us = b.time_us() + 300_000;
        b.schedule_reboot(reboot_us);
        // The host stops reading: the board's frames queue in its USB buffers.
        b.advance(Duration::from_millis(250));
        assert!(!b.outbox.is_empty());
        assert_eq!(b.reboots(), 0);
        let sensor_resets = b.sensor().lock().resets();
        b.advance(Duration::from_millis(100));
        assert_eq!(b.reboots(), 1);
        assert!(!b.streaming());
        assert!(b.outbox.is_empty(), "unread frames are lost");
        // The sensor was not powered down: its clock went on; the fresh firmware's start-up
        // set it up again.
        assert_eq!(b.time_us(), reboot_us + 50_000);
        assert!(b.sensor().lock().resets() > sensor_resets);
        assert_eq!(b.boot_error(), None);
        // Idle until the host starts it again.
        assert!(messages(&mut b, 5).is_empty());
        assert!(
            b.time_us() > reboot_us + 50_000,
            "not streaming: the time the host waits in vain passes on the board too"
        );
        send(&mut b, 2, Command::GetInfo);
        send(&mut b, 3, Command::Start);
        let after = messages(&mut b, 20);
        assert!(matches!(&after[0], DeviceMessage::Info(i) if i.board_id == 42));
        assert!(matches!(after[1], DeviceMessage::Ack { seq: 3 }));
        assert!(count_samples(&after) > 0);
        assert_eq!(b.reboots(), 1);
    }

    #[test]
    fn a_fault_plan_reaches_the_sensor_and_the_board() {
        let plan = FaultPlan {
            clock: crate::sim::device::SensorClock {
                ppm: 3000.0,
                drift_ppm_per_hour: 0.0,
            },
            i2c_outages: vec![crate::sim::device::Outage {
                at_us: 10_000_000,
                for_us: 1_000_000,
            }],
            sensor_resets_us: vec![20_000_000],
            board_resets_us: vec![1_000_000, 2_000_000],
            who_am_i: Some(0x70),
        };
        let model = ImuModel::default();
        let mut b = VirtualBoard::with_faults(model, 1, 42, Speed::Max, &plan);
        {
            let bus = b.sensor().lock();
            let faults = bus.mpu6050().unwrap().faults();
            assert_eq!(faults.clock, plan.clock);
            assert_eq!(faults.i2c_outages, plan.i2c_outages);
            assert_eq!(faults.resets_at_us, plan.sensor_resets_us);
        }
        send(&mut b, 1, Command::GetInfo);
        let info = messages(&mut b, 1);
        assert!(matches!(&info[0], DeviceMessage::Info(i) if i.who_am_i == 0x70));
        // Both reboots happen as emulated time passes them, each within the step it falls in.
        b.advance(Duration::from_millis(999));
        assert_eq!(b.reboots(), 0);
        b.advance(Duration::from_millis(5));
        assert_eq!(b.reboots(), 1);
        b.advance(Duration::from_secs(1));
        assert_eq!(b.reboots(), 2);
        b.advance(Duration::from_secs(5));
        assert_eq!(b.reboots(), 2);
    }

    /// A GY-85 board streams both sensors, each from index 0, and the fault plan reaches
    /// both chips.
    #[test]
    fn a_gy85_board_streams_both_sensors() {
        let plan = FaultPlan {
            clock: crate::sim::device::SensorClock {
                ppm: 100.0,
                drift_ppm_per_hour: 0.0,
            },
            ..FaultPlan::default()
        };
        let mut b = VirtualBoard::gy85(ImuModel::default(), 1, 85, Speed::Max, &plan);
        assert_eq!(b.boot_error(), None);
        {
            let mut bus = b.sensor().lock();
            assert_eq!(bus.itg3200_mut().unwrap().faults().clock, plan.clock);
            assert_eq!(bus.adxl345_mut().unwrap().faults().clock, plan.clock);
        }
        send(&mut b, 1, Command::Start);
        let msgs = messages(&mut b, 100);
        assert!(matches!(msgs[0], DeviceMessage::Ack { seq: 1 }));
        let mut next = [0u64; 2];
        for m in &msgs[1..] {
            if let Some((sensor, batch)) = m.sensor_samples() {
                let next = &mut next[usize::from(sensor)];
                assert_eq!(batch.first_index, *next, "sensor {sensor}: no gap");
                *next += batch.samples.len() as u64;
            }
        }
        // Both at their default 100 Hz, in the same emulated time: a read at Max speed ends
        // after the 5 ms step that made something, so 100 reads cover about a second.
        assert!(next[0] >= 90 && next[0].abs_diff(next[1]) <= 2, "{next:?}");
    }

    /// At a speed factor the board streams what its emulated time made: every sample from
    /// index 0 in order, as many as the output rate times the emulated time since Start,
    /// short by at most one drain's worth (20 ms: 4 samples at 200 Hz) and the sample the
    /// grid's phase may add.
    #[test]
    fn a_speed_factor_streams_what_emulated_time_made() {
        let mut b = board(Speed::Factor(1000.0));
        let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        send(&mut b, 1, Command::Configure(settings));
        send(&mut b, 2, Command::Start);
        let t0 = b.time_us();
        let mut decoder = FrameDecoder::new();
        let mut buf = [0u8; 4096];
        let mut next = 0u64;
        while next < 2000 {
            let n = b.read(&mut buf, Duration::from_millis(50));
            decoder.feed::<DeviceMessage>(&buf[..n], |m| {
                if let Ok(DeviceMessage::Samples(batch)) = m {
                    assert_eq!(batch.first_index, next, "no gap, no repeat");
                    next += batch.samples.len() as u64;
                }
            });
        }
        let made = (b.time_us() - t0) as f64 * 200.0 / 1e6;
        assert!(
            next as f64 <= made + 1.0 && next as f64 >= made - 5.0,
            "{next} samples delivered, {made} made"
        );
    }
}
