//! The virtual board: the firmware's portable code (`firmware::Firmware`, the very code the
//! RP2040 runs) driving the simulated MPU-6050 (`sim::device`) in-process, emitting the bytes
//! a real board would send over USB. Time is the simulated sensor's clock, which is also the
//! firmware's clock; it advances with the wall clock times a speed factor, or as fast as the
//! host reads (`Speed::Max`).

use crate::sim::device::{SimI2cError, SimMpu6050};
use crate::sim::imu::ImuModel;
use embedded_hal::i2c::{ErrorType, I2c, Operation};
use firmware::{BoardConfig, Clock, Firmware};
use protocol::ErrorCode;
use protocol::mpu6050::DEFAULT_ADDRESS;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub use super::transport::Speed;

/// The simulated sensor shared by the firmware (as its I2C bus and its clock) and the board
/// (which moves time).
#[derive(Clone)]
pub struct SharedSensor(Arc<Mutex<SimMpu6050>>);

impl SharedSensor {
    pub fn new(sensor: SimMpu6050) -> Self {
        SharedSensor(Arc::new(Mutex::new(sensor)))
    }

    /// The sensor; a poisoned lock (a panic elsewhere) still yields it, since its state is
    /// plain registers and FIFO bytes.
    pub fn lock(&self) -> MutexGuard<'_, SimMpu6050> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl ErrorType for SharedSensor {
    type Error = SimI2cError;
}

impl I2c for SharedSensor {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), SimI2cError> {
        self.lock().transaction(address, ops)
    }
}

/// The simulated device has no pins to hold low: clearing the bus ends any transaction it is
/// in, which is what nine clocks and a STOP do to a real one.
impl firmware::BusClear for SharedSensor {
    fn clear_bus(&mut self) {
        self.lock().bus_stop();
    }
}

impl Clock for SharedSensor {
    fn now_us(&mut self) -> u64 {
        self.lock().time_us()
    }
}

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

/// The firmware on the simulated sensor.
pub struct VirtualBoard {
    sensor: SharedSensor,
    firmware: Firmware<SharedSensor, SharedSensor>,
    outbox: VecDeque<u8>,
    speed: Speed,
    /// Wall time and emulated time at the last speed reference point.
    wall_origin: Instant,
    emulated_origin_us: u64,
}

impl VirtualBoard {
    /// A board whose sensor follows `model` (seeded), with the given board id.
    pub fn new(model: ImuModel, seed: u64, board_id: u64, speed: Speed) -> Result<Self, ErrorCode> {
        let sensor = SharedSensor::new(SimMpu6050::new(model, seed));
        let mut firmware = Firmware::new(
            sensor.clone(),
            sensor.clone(),
            BoardConfig {
                address: DEFAULT_ADDRESS,
                board_id,
            },
        );
        firmware.init(&mut NoDelay)?;
        let emulated_origin_us = sensor.lock().time_us();
        Ok(VirtualBoard {
            sensor,
            firmware,
            outbox: VecDeque::new(),
            speed,
            wall_origin: Instant::now(),
            emulated_origin_us,
        })
    }

    /// The simulated sensor, to inject faults or read its state.
    pub fn sensor(&self) -> &SharedSensor {
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

    /// Advance emulated time by `dt` and let the firmware run.
    fn step(&mut self, dt: Duration) {
        self.sensor.lock().advance(dt);
        let outbox = &mut self.outbox;
        self.firmware.poll(&mut |frame| push_frame(outbox, frame));
    }
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

    #[test]
    fn real_time_runs_at_the_speed_factor() {
        let mut b = board(Speed::Factor(10.0));
        send(&mut b, 1, Command::Start);
        let t0 = b.time_us();
        let wall = Instant::now();
        let mut buf = [0u8; 4096];
        while wall.elapsed() < Duration::from_millis(300) {
            b.read(&mut buf, Duration::from_millis(50));
        }
        let emulated = (b.time_us() - t0) as f64 / 1e6;
        let elapsed = wall.elapsed().as_secs_f64();
        // 10 emulated seconds per wall second, within a step and scheduling slack.
        assert!(
            (emulated / elapsed - 10.0).abs() < 1.5,
            "{emulated} s in {elapsed} s"
        );
    }
}
