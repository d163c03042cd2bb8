//! Driving a board through a calibration procedure: turn it (the virtual board is turned by
//! script; a real one by an [`Operator`], a person asked by the caller), wait for it to be
//! still (watching the stream, saying what moves), capture, and check the capture again
//! (still throughout, and whatever the procedure asks, e.g. the orientation).
//! Every capture is a stored session, so the raw data behind a calibration are kept.

use super::Sensor;
use super::gravity::STANDARD;
use super::still::{Motion, TooShortToJudge, find_motion};
use crate::capture::{CaptureError, StreamDecoder};
use crate::link::board::{Board as BoardLink, BoardError};
use crate::link::plan::Plan;
use crate::link::shared_bus::SharedBus;
use crate::link::{Link, Opened, start_board};
use crate::record::Record;
use crate::recorder::{self, Progress, RecordError, RecordOptions};
use crate::sim::imu::{GravityAxis, TrueInput};
use crate::store::{Board, Store, StoreError};
use protocol::SensorSettings;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// Attempts at one position before giving up (each failure says why).
pub const ATTEMPTS: usize = 5;

/// Before a capture, the sensor must be still for this long (three 1 s windows, the least
/// the stillness test judges); it is watched for at most `STILL_ROUNDS` such stretches.
pub const STILL_S: f64 = 3.0;
pub const STILL_ROUNDS: usize = 20;

/// A board that sends nothing for this long (wall time) is gone.
pub const SILENCE: Duration = Duration::from_secs(5);

/// Emulated time the virtual board is left after a turn, as a person would wait before
/// saying the board is in place: the DLPF's step response has long settled.
const SIM_SETTLE: Duration = Duration::from_secs(1);

/// The person at a real board, and the one told what the rig does.
pub trait Operator {
    /// Put the board as `instruction` says and hold it still; return once that is done. An
    /// error ends the procedure.
    fn pose(&mut self, instruction: &str) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;

    /// What the rig does and sees, as it happens.
    fn event(&mut self, event: Event<'_>);
}

/// What happens on the rig, for an [`Operator`] to show.
pub enum Event<'a> {
    /// The virtual board was turned by script as the instruction says.
    Turned(&'a str),
    /// The rig begins watching the board for stillness (nothing is stored).
    Watching,
    /// The rig stopped watching.
    Watched,
    /// The board moved while it was watched; the rig watches again.
    NotStill(&'a Motion),
    /// A capture into the store begins.
    Capturing,
    /// How the capture goes.
    Progress(&'a Progress),
    /// The capture ended.
    Captured,
    /// Attempt `attempt` (of [`ATTEMPTS`]) was refused, for `why`; the rig tries again
    /// while attempts remain.
    Retry { attempt: usize, why: &'a str },
    /// The board did not take Stop after a capture (it may be gone; the session says how it
    /// ended).
    StopFailed(&'a BoardError),
}

/// Why a procedure on the rig failed.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    #[error(transparent)]
    Board(#[from] BoardError),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error("session {0} vanished")]
    Vanished(i64),
    #[error("session {0}: nothing decoded")]
    NothingDecoded(i64),
    /// A capture's samples could not be made a record; `what` names the session.
    #[error("{what}")]
    Decode { what: String, source: CaptureError },
    #[error("{what}: the board runs at {rate_hz} Hz, not the {asked_hz} Hz asked")]
    WrongRate {
        what: String,
        rate_hz: f64,
        asked_hz: f64,
    },
    #[error("{link}")]
    Read {
        link: String,
        source: std::io::Error,
    },
    #[error("{link}: no data for {} s", SILENCE.as_secs())]
    Silent { link: String },
    /// The stillness test could not judge what the board sent while watched.
    #[error("{0}")]
    Watch(TooShortToJudge),
    #[error(
        "the board did not keep still for {} s in {} tries",
        STILL_S,
        STILL_ROUNDS
    )]
    NeverStill,
    /// The stillness test could not judge a capture (too short for its windows).
    #[error("{0}")]
    TooShort(TooShortToJudge),
    #[error(
        "{instruction}: no still capture in the right orientation after {} attempts",
        ATTEMPTS
    )]
    NoGoodCapture { instruction: String },
    #[error(transparent)]
    Operator(Box<dyn std::error::Error + Send + Sync>),
}

/// A board on the rig, its operator, and the sessions captured from it.
pub struct Rig<O: Operator> {
    link: Box<dyn Link>,
    /// The virtual board's sensor, turned by script; None for a real board.
    sensor: Option<SharedBus>,
    settings: SensorSettings,
    /// The board and its settings, as the first capture's Info announced them.
    pub board: Option<Board>,
    /// The sessions captured, by name.
    pub sessions: Vec<String>,
    operator: O,
}

impl<O: Operator> Rig<O> {
    /// The rig on an opened port, capturing at `settings`, with `operator` at the board.
    pub fn new(opened: Opened, settings: SensorSettings, operator: O) -> Self {
        Rig {
            link: opened.link,
            sensor: opened.sensor,
            settings,
            board: None,
            sessions: Vec::new(),
            operator,
        }
    }

    /// Put the sensor in `input`: the virtual board is turned (and left to settle); the
    /// operator is asked to turn a real one.
    fn pose(&mut self, input: TrueInput, instruction: &str) -> Result<(), RigError> {
        match &self.sensor {
            Some(sensor) => {
                let mut s = sensor.lock();
                s.set_input(Some(input));
                s.advance(SIM_SETTLE);
                self.operator.event(Event::Turned(instruction));
                Ok(())
            }
            None => self.operator.pose(instruction).map_err(RigError::Operator),
        }
    }

    fn stop_board(&mut self) {
        if let Err(e) = BoardLink::new(self.link.as_mut()).stop() {
            self.operator.event(Event::StopFailed(&e));
        }
    }

    /// Capture `seconds` of samples into a new session noted with `note`; its record.
    pub fn capture(&mut self, store: &Store, seconds: f64, note: &str) -> Result<Record, RigError> {
        let info = start_board(self.link.as_mut(), self.settings)?;
        let options = RecordOptions {
            name: None,
            notes: Some(note.to_string()),
            duration_s: Some(seconds),
            keep_samples: true,
            watch: Some(Plan::mpu6050(self.settings)),
            live: None,
        };
        let stop = AtomicBool::new(false);
        self.operator.event(Event::Capturing);
        let outcome = recorder::record(self.link.as_mut(), store, &options, &stop, &mut |p| {
            self.operator.event(Event::Progress(p))
        });
        self.operator.event(Event::Captured);
        self.stop_board();
        let outcome = outcome?;
        let session = store
            .get(outcome.session_id)?
            .ok_or(RigError::Vanished(outcome.session_id))?;
        self.board = self.board.take().or_else(|| session.board.clone());
        self.sessions.push(session.name.clone());
        let capture = outcome
            .capture
            .ok_or(RigError::NothingDecoded(session.id))?;
        let what = format!("session {} '{}'", session.id, session.name);
        let record = match capture.to_record(&what, false) {
            Ok(record) => record,
            Err(source) => return Err(RigError::Decode { what, source }),
        };
        let asked_hz = info.settings.output_rate_hz();
        if (record.rate_hz - asked_hz).abs() > 1e-9 {
            return Err(RigError::WrongRate {
                what,
                rate_hz: record.rate_hz,
                asked_hz,
            });
        }
        Ok(record)
    }

    /// Watch the board (samples not stored) until `STILL_S` seconds in a row are still,
    /// saying what moved while they are not.
    fn wait_until_still(&mut self, steady: &[Sensor]) -> Result<(), RigError> {
        for _ in 0..STILL_ROUNDS {
            self.operator.event(Event::Watching);
            let record = self.peek(STILL_S);
            self.operator.event(Event::Watched);
            match find_motion(&record?, steady).map_err(RigError::Watch)? {
                None => return Ok(()),
                Some(motion) => self.operator.event(Event::NotStill(&motion)),
            }
        }
        Err(RigError::NeverStill)
    }

    /// `seconds` of samples straight from the board, not stored.
    fn peek(&mut self, seconds: f64) -> Result<Record, RigError> {
        start_board(self.link.as_mut(), self.settings)?;
        let wanted = (seconds * self.settings.output_rate_hz()).ceil() as u64;
        let mut decoder = StreamDecoder::new(true);
        let mut buf = vec![0u8; 1 << 16];
        let mut heard = Instant::now();
        while decoder.accounting().expected() < wanted {
            let n = self
                .link
                .read(&mut buf, Duration::from_millis(100))
                .map_err(|source| RigError::Read {
                    link: self.link.describe(),
                    source,
                })?;
            if n > 0 {
                decoder.feed(&buf[..n]);
                heard = Instant::now();
            } else if heard.elapsed() > SILENCE {
                self.stop_board();
                return Err(RigError::Silent {
                    link: self.link.describe(),
                });
            }
        }
        self.stop_board();
        let capture = decoder.finish()?;
        Ok(capture.to_record("the stillness check", true)?)
    }

    /// Pose, capture and check until the `steady` sensors were still throughout and `check`
    /// (e.g. the orientation) finds nothing wrong (it returns why a capture is refused);
    /// each refused attempt is said, and kept as a session.
    pub fn measure(
        &mut self,
        store: &Store,
        seconds: f64,
        input: TrueInput,
        instruction: &str,
        steady: &[Sensor],
        check: &dyn Fn(&Record) -> Option<String>,
    ) -> Result<Record, RigError> {
        for attempt in 1..=ATTEMPTS {
            self.pose(input, instruction)?;
            self.wait_until_still(steady)?;
            let record = self.capture(store, seconds, instruction)?;
            let refusal = match find_motion(&record, steady).map_err(RigError::TooShort)? {
                Some(motion) => Some(format!("not still: {motion}")),
                None => check(&record),
            };
            match refusal {
                None => return Ok(record),
                Some(why) => self.operator.event(Event::Retry { attempt, why: &why }),
            }
        }
        Err(RigError::NoGoodCapture {
            instruction: instruction.to_string(),
        })
    }

    /// [`Rig::measure`] with the board at rest in any orientation (z up on the virtual
    /// board), both sensors still, nothing else checked.
    pub fn measure_at_rest(
        &mut self,
        store: &Store,
        seconds: f64,
        instruction: &str,
    ) -> Result<Record, RigError> {
        let rest = TrueInput::at_rest(GravityAxis::default(), STANDARD);
        self.measure(
            store,
            seconds,
            rest,
            instruction,
            &[Sensor::Gyro, Sensor::Accel],
            &|_| None,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::PortSpec;
    use crate::link::replay::Speed;

    /// What the rig told, in order, and whether it asked for a pose (and refuses it).
    #[derive(Default)]
    struct Log {
        said: Vec<String>,
        asked: Vec<String>,
    }

    impl Operator for Log {
        fn pose(
            &mut self,
            instruction: &str,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            self.asked.push(instruction.to_string());
            Err("nobody at the board".into())
        }

        fn event(&mut self, event: Event<'_>) {
            let said = match event {
                Event::Turned(i) => format!("turned: {i}"),
                Event::Watching => "watching".into(),
                Event::Watched => "watched".into(),
                Event::NotStill(m) => format!("not still: {m}"),
                Event::Capturing => "capturing".into(),
                Event::Progress(_) => return,
                Event::Captured => "captured".into(),
                Event::Retry { attempt, why } => format!("retry {attempt}: {why}"),
                Event::StopFailed(e) => format!("stop failed: {e}"),
            };
            self.said.push(said);
        }
    }

    fn virtual_board() -> Opened {
        crate::link::open(&PortSpec {
            board: crate::link::setup::SimulatedBoard::Mpu6050,
            port: crate::link::setup::VIRTUAL_PORT,
            speed: Speed::Max,
            model: None,
            seed: 3,
        })
        .unwrap()
    }

    #[test]
    fn the_virtual_board_is_turned_watched_and_captured_into_a_session() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let mut rig = Rig::new(virtual_board(), SensorSettings::default(), Log::default());
        let record = rig.measure_at_rest(&store, 4.0, "rest").unwrap();
        assert_eq!(record.len(), 400);
        assert_eq!(record.rate_hz, 100.0);
        assert_eq!(
            rig.operator.said,
            [
                "turned: rest",
                "watching",
                "watched",
                "capturing",
                "captured"
            ]
        );
        assert!(rig.operator.asked.is_empty());
        assert_eq!(rig.sessions.len(), 1);
        assert_eq!(store.list().unwrap().len(), 1);
        assert!(rig.board.is_some());
    }

    #[test]
    fn a_board_without_a_script_is_posed_by_the_operator() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let mut opened = virtual_board();
        opened.sensor = None;
        let mut rig = Rig::new(opened, SensorSettings::default(), Log::default());
        let e = rig.measure_at_rest(&store, 4.0, "put it down").unwrap_err();
        assert!(matches!(e, RigError::Operator(_)), "{e:?}");
        assert_eq!(e.to_string(), "nobody at the board");
        assert_eq!(rig.operator.asked, ["put it down"]);
        assert!(store.list().unwrap().is_empty());
    }

    #[test]
    fn a_capture_too_short_to_judge_is_said() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let mut rig = Rig::new(virtual_board(), SensorSettings::default(), Log::default());
        let e = rig.measure_at_rest(&store, 0.5, "rest").unwrap_err();
        assert!(matches!(e, RigError::TooShort(_)), "{e:?}");
    }
}
