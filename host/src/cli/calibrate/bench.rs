//! Driving a board through a calibration procedure: turn it (the virtual board is turned by
//! script, a person is asked to turn a real one), wait for it to be still (watching the
//! stream, saying what moves), capture, and check the capture again (still throughout, in
//! the asked orientation).
//! Every capture is a stored session, so the raw data behind a calibration are kept.

use super::BoardArgs;
use crate::calibration::Sensor;
use crate::calibration::still::find_motion;
use crate::capture::StreamDecoder;
use crate::cli::capture::{
    PortSpec, board_settings, open_port, progress_bar, show, start_board, stop_board, virtual_board,
};
use crate::link::Link;
use crate::link::virtual_board::SharedSensor;
use crate::record::Record;
use crate::recorder::{self, RecordOptions};
use crate::sim::imu::{GravityAxis, TrueInput};
use crate::store::{Board, Store};
use anyhow::{Context, Result, anyhow, bail};
use protocol::SensorSettings;
use std::io::BufRead;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Attempts at one position before giving up (each failure says why).
const ATTEMPTS: usize = 5;

/// Before a capture, the sensor must be still for this long (three 1 s windows, the least
/// the stillness test judges); it is watched for at most `STILL_ROUNDS` such stretches.
const STILL_S: f64 = 3.0;
const STILL_ROUNDS: usize = 20;

/// A board that sends nothing for this long (wall time) is gone.
const SILENCE: Duration = Duration::from_secs(5);

/// Emulated time the virtual board is left after a turn, as a person would wait before
/// pressing Enter: the DLPF's step response has long settled.
const SIM_SETTLE: Duration = Duration::from_secs(1);

pub struct Bench {
    link: Box<dyn Link>,
    /// The virtual board's sensor, turned by script; None for a real board.
    sensor: Option<SharedSensor>,
    settings: SensorSettings,
    /// The board and its settings, as the first capture's Info announced them.
    pub board: Option<Board>,
    /// The sessions captured, by name.
    pub sessions: Vec<String>,
}

impl Bench {
    pub fn open(port: &str, args: &BoardArgs) -> Result<Bench> {
        let settings =
            board_settings(args.rate, args.bandwidth, args.gyro_range, args.accel_range)?;
        let spec = PortSpec {
            port,
            speed: args.speed,
            model: args.virtual_board.model.as_deref(),
            seed: args.virtual_board.seed,
        };
        let (link, sensor): (Box<dyn Link>, _) = if port == "sim" {
            let board = virtual_board(&spec)?;
            let sensor = board.sensor().clone();
            (Box::new(board), Some(sensor))
        } else {
            (open_port(&spec)?, None)
        };
        Ok(Bench {
            link,
            sensor,
            settings,
            board: None,
            sessions: Vec::new(),
        })
    }

    /// Put the sensor in `input`: the virtual board is turned (and left to settle); a
    /// person is shown `instruction` and asked to press Enter.
    fn pose(&mut self, input: TrueInput, instruction: &str) -> Result<()> {
        match &self.sensor {
            Some(sensor) => {
                let mut s = sensor.lock();
                s.set_input(Some(input));
                s.advance(SIM_SETTLE);
                eprintln!("sim: {instruction}");
                Ok(())
            }
            None => {
                eprintln!("{instruction}, hold it still, then press Enter");
                let mut line = String::new();
                let n = std::io::stdin()
                    .lock()
                    .read_line(&mut line)
                    .context("reading the answer on stdin")?;
                if n == 0 {
                    bail!(
                        "no answer on stdin (end of input): the procedure needs a person to turn the board"
                    );
                }
                Ok(())
            }
        }
    }

    /// Capture `seconds` of samples into a new session noted with `note`; its record.
    pub fn capture(&mut self, store: &Store, seconds: f64, note: &str) -> Result<Record> {
        let info = start_board(self.link.as_mut(), self.settings)?;
        let options = RecordOptions {
            name: None,
            notes: Some(note.to_string()),
            duration_s: Some(seconds),
            keep_samples: true,
            watch: Some(self.settings),
            live: None,
        };
        let stop = AtomicBool::new(false);
        let bar = progress_bar();
        let outcome = recorder::record(self.link.as_mut(), store, &options, &stop, &mut |p| {
            show(&bar, p)
        });
        bar.finish_and_clear();
        stop_board(self.link.as_mut());
        let outcome = outcome?;
        let session = store
            .get(outcome.session_id)?
            .ok_or_else(|| anyhow!("session {} vanished", outcome.session_id))?;
        self.board = self.board.take().or_else(|| session.board.clone());
        self.sessions.push(session.name.clone());
        let capture = outcome
            .capture
            .ok_or_else(|| anyhow!("session {}: nothing decoded", session.id))?;
        let source = format!("session {} '{}'", session.id, session.name);
        let record = capture
            .to_record(&source, false)
            .with_context(|| source.clone())?;
        if (record.rate_hz - info.settings.output_rate_hz()).abs() > 1e-9 {
            bail!(
                "{source}: the board runs at {} Hz, not the {} Hz asked",
                record.rate_hz,
                info.settings.output_rate_hz()
            );
        }
        Ok(record)
    }

    /// Watch the board (samples not stored) until `STILL_S` seconds in a row are still,
    /// saying what moved while they are not.
    fn wait_until_still(&mut self, steady: &[Sensor]) -> Result<()> {
        for _ in 0..STILL_ROUNDS {
            let watching =
                crate::report::progress::spinner("waiting until the board is still".into());
            let record = self.peek(STILL_S);
            watching.finish_and_clear();
            let record = record?;
            match find_motion(&record, steady).map_err(anyhow::Error::msg)? {
                None => return Ok(()),
                Some(motion) => eprintln!("not still yet ({motion}); waiting"),
            }
        }
        bail!("the board did not keep still for {STILL_S} s in {STILL_ROUNDS} tries")
    }

    /// `seconds` of samples straight from the board, not stored.
    fn peek(&mut self, seconds: f64) -> Result<Record> {
        start_board(self.link.as_mut(), self.settings)?;
        let wanted = (seconds * self.settings.output_rate_hz()).ceil() as u64;
        let mut decoder = StreamDecoder::new(true);
        let mut buf = vec![0u8; 1 << 16];
        let mut heard = Instant::now();
        while decoder.accounting().expected() < wanted {
            let n = self
                .link
                .read(&mut buf, Duration::from_millis(100))
                .with_context(|| self.link.describe())?;
            if n > 0 {
                decoder.feed(&buf[..n]);
                heard = Instant::now();
            } else if heard.elapsed() > SILENCE {
                stop_board(self.link.as_mut());
                bail!(
                    "{}: no data for {} s",
                    self.link.describe(),
                    SILENCE.as_secs()
                );
            }
        }
        stop_board(self.link.as_mut());
        let capture = decoder.finish()?;
        Ok(capture.to_record("the stillness check", true)?)
    }

    /// Pose, capture and check until the `steady` sensors were still throughout and `check`
    /// (e.g. the orientation) passes; each failed attempt is said, and kept as a session.
    pub fn measure(
        &mut self,
        store: &Store,
        seconds: f64,
        input: TrueInput,
        instruction: &str,
        steady: &[Sensor],
        check: &dyn Fn(&Record) -> Result<(), String>,
    ) -> Result<Record> {
        for attempt in 1..=ATTEMPTS {
            self.pose(input, instruction)?;
            self.wait_until_still(steady)?;
            let record = self.capture(store, seconds, instruction)?;
            let verdict = match find_motion(&record, steady) {
                Err(e) => bail!("--seconds: {e}"),
                Ok(Some(motion)) => Err(format!("not still: {motion}")),
                Ok(None) => check(&record),
            };
            match verdict {
                Ok(()) => return Ok(record),
                Err(why) => eprintln!("attempt {attempt} of {ATTEMPTS}: {why}; again"),
            }
        }
        bail!("{instruction}: no still capture in the right orientation after {ATTEMPTS} attempts")
    }

    /// [`Bench::measure`] with the board at rest in any orientation (z up on the virtual
    /// board), both sensors still, nothing else checked.
    pub fn measure_at_rest(
        &mut self,
        store: &Store,
        seconds: f64,
        instruction: &str,
    ) -> Result<Record> {
        let rest = TrueInput::at_rest(
            GravityAxis::default(),
            crate::calibration::gravity::STANDARD,
        );
        self.measure(
            store,
            seconds,
            rest,
            instruction,
            &[Sensor::Gyro, Sensor::Accel],
            &|_| Ok(()),
        )
    }
}
