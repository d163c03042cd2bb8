//! The simulated MPU-6050 served over a byte stream, one line per I2C bus event, so that a
//! bus model outside this process (the emulated RP2040 of `tests/emu/`) drives **this**
//! device: one device model, register-exact, whose FIFO fills with the caller's clock.
//!
//! Requests (ASCII, one per line; `T` is the caller's time in microseconds, decimal; every
//! request first moves the device clock to `T`, making the samples due):
//!
//! | request        | event                          | reply                                  |
//! |----------------|--------------------------------|----------------------------------------|
//! | `s T ADDR`     | start, 7-bit address (decimal) | `a` ack, `n` no ack, `e` bus error     |
//! | `S T ADDR`     | repeated start                 | as `s`                                 |
//! | `w T BYTE`     | byte written                   | `a` ack, `n` no ack                    |
//! | `r T`          | byte read                      | the byte, decimal                      |
//! | `p T`          | stop                           | none                                   |
//! | `t T`          | clock only                     | none                                   |
//! | `f T`          | flush the journal to its file  | `a` once it is written                 |
//! | `o T US`       | an I2C outage from T for US us | `a`                                    |
//! | `x T`          | a sensor reset at T            | `a`                                    |
//!
//! A malformed request gets `! <reason>` and changes nothing. The reply is flushed at once
//! (the caller waits for it); requests without a reply are not, so a stop costs no round
//! trip.
//!
//! The journal ([`write_journal`]) records what the device did, for comparison with what
//! the host received: `reset,T` for a FIFO reset, `sample,T,F,ax,ay,az,temp,gx,gy,gz` for
//! a sample made at `T` (raw counts; `F` = 1 if it went into the FIFO).

use super::device::{JournalEntry, Outage, RegisterChip, SimChip, SimI2cError, SimMpu6050};
use std::io::{self, BufRead, Write};

/// Serve `device` on `input`/`output` until `input` ends; the journal, if kept, is written
/// to `journal` as events happen. Returns the number of requests served.
pub fn serve(
    device: &mut SimMpu6050,
    input: impl BufRead,
    mut output: impl Write,
    mut journal: Option<&mut dyn Write>,
) -> io::Result<u64> {
    let mut served = 0;
    for line in input.lines() {
        let line = line?;
        let request = parse(&line);
        let reply = answer(device, request, &line);
        if let Some(journal) = journal.as_deref_mut() {
            write_journal(&device.take_journal(), journal)?;
            if matches!(request, Ok((_, Request::FlushJournal))) {
                journal.flush()?;
            }
        }
        if let Some(reply) = reply {
            writeln!(output, "{reply}")?;
            output.flush()?;
        }
        served += 1;
    }
    output.flush()?;
    if let Some(journal) = journal {
        journal.flush()?;
    }
    Ok(served)
}

/// One request; the reply, if the request has one.
pub fn handle(device: &mut SimMpu6050, line: &str) -> Option<String> {
    answer(device, parse(line), line)
}

/// The reply to a parsed request, or the refusal of one that did not parse.
fn answer(
    device: &mut SimMpu6050,
    request: Result<(u64, Request), &'static str>,
    line: &str,
) -> Option<String> {
    match request {
        Ok(request) => respond(device, request),
        Err(reason) => Some(format!("! {reason}: {line:?}")),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Request {
    Start { repeated: bool, address: u8 },
    Write(u8),
    Read,
    Stop,
    Clock,
    FlushJournal,
    Outage { for_us: u64 },
    SensorReset,
}

fn parse(line: &str) -> Result<(u64, Request), &'static str> {
    let mut words = line.split_ascii_whitespace();
    let verb = words.next().ok_or("empty request")?;
    let time_us = words
        .next()
        .ok_or("no time")?
        .parse::<u64>()
        .map_err(|_| "time is not a whole number of microseconds")?;
    let mut byte = || -> Result<u8, &'static str> {
        words
            .next()
            .ok_or("no byte")?
            .parse::<u8>()
            .map_err(|_| "byte is not 0..=255")
    };
    let request = match verb {
        "s" | "S" => Request::Start {
            repeated: verb == "S",
            address: byte().and_then(|a| {
                if a < 0x80 {
                    Ok(a)
                } else {
                    Err("address is not 7-bit")
                }
            })?,
        },
        "w" => Request::Write(byte()?),
        "r" => Request::Read,
        "p" => Request::Stop,
        "t" => Request::Clock,
        "f" => Request::FlushJournal,
        "o" => Request::Outage {
            for_us: words
                .next()
                .ok_or("no outage length")?
                .parse::<u64>()
                .map_err(|_| "outage length is not a whole number of microseconds")?,
        },
        "x" => Request::SensorReset,
        _ => return Err("unknown request (s, S, w, r, p, t, f, o, x)"),
    };
    Ok((time_us, request))
}

fn respond(device: &mut SimMpu6050, (time_us, request): (u64, Request)) -> Option<String> {
    device.set_time_us(time_us);
    let ack = |result: Result<(), SimI2cError>| match result {
        Ok(()) => "a".to_string(),
        Err(SimI2cError::NoAcknowledge(_)) => "n".to_string(),
        Err(SimI2cError::Bus) => "e".to_string(),
    };
    match request {
        Request::Start { repeated, address } => Some(ack(device.bus_start(address, repeated))),
        Request::Write(b) => Some(ack(device.bus_write(b))),
        Request::Read => Some(device.bus_read().to_string()),
        Request::Stop => {
            device.bus_stop();
            None
        }
        Request::Clock => None,
        // serve() writes the journal out before this reply goes.
        Request::FlushJournal => Some("a".to_string()),
        Request::Outage { for_us } => {
            device.faults_mut().i2c_outages.push(Outage {
                at_us: time_us,
                for_us,
            });
            Some("a".to_string())
        }
        Request::SensorReset => {
            device.schedule_reset(time_us);
            // Due now: make it happen before the next request sees the device.
            device.set_time_us(time_us + 1);
            Some("a".to_string())
        }
    }
}

/// Journal entries as CSV lines (module documentation).
pub fn write_journal(entries: &[JournalEntry], out: &mut dyn Write) -> io::Result<()> {
    for entry in entries {
        match entry {
            JournalEntry::FifoReset { time_us } => writeln!(out, "reset,{time_us}")?,
            JournalEntry::Sample {
                time_us,
                raw,
                in_fifo,
            } => writeln!(
                out,
                "sample,{time_us},{},{},{},{},{},{},{},{}",
                u8::from(*in_fifo),
                raw.accel[0],
                raw.accel[1],
                raw.accel[2],
                raw.temp,
                raw.gyro[0],
                raw.gyro[1],
                raw.gyro[2]
            )?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::imu::ImuModel;
    use embedded_hal::i2c::I2c;
    use protocol::mpu6050::reg;

    fn device() -> SimMpu6050 {
        SimMpu6050::new(ImuModel::default(), 7)
    }

    /// Bytes read through the line protocol equal those read through `I2c` on a twin
    /// device driven by the same clock: the two paths are one device.
    #[test]
    fn lines_and_transactions_are_one_device() {
        let mut served = device();
        let mut direct = device();
        let script = |t: u64| {
            vec![
                format!("s {t} 104"),
                format!("w {t} {}", reg::PWR_MGMT_1),
                format!("w {t} 0"),
                format!("p {t}"),
            ]
        };
        for line in script(10) {
            handle(&mut served, &line);
        }
        direct.set_time_us(10);
        direct.write(0x68, &[reg::PWR_MGMT_1, 0]).unwrap();

        let t = 25_000;
        let mut lines = vec![format!("s {t} 104"), format!("w {t} {}", reg::ACCEL_XOUT_H)];
        lines.extend((0..14).map(|_| format!("r {t}")));
        let replies: Vec<u8> = lines
            .iter()
            .filter_map(|l| handle(&mut served, l))
            .filter_map(|r| r.parse().ok())
            .collect();
        handle(&mut served, &format!("p {t}"));
        direct.set_time_us(t);
        let mut expected = [0u8; 14];
        direct
            .write_read(0x68, &[reg::ACCEL_XOUT_H], &mut expected)
            .unwrap();
        assert_eq!(replies.len(), 14);
        assert_eq!(replies, expected);
        assert_ne!(expected, [0; 14], "the device made samples by 25 ms");
    }

    /// A bus model scripts faults through the lines: an outage NACKs every start in its
    /// window, a reset puts the device back to its power-on state at once.
    #[test]
    fn outages_and_resets_by_request() {
        let mut d = device();
        handle(&mut d, "s 0 104");
        handle(&mut d, &format!("w 0 {}", reg::PWR_MGMT_1));
        handle(&mut d, "w 0 0");
        handle(&mut d, "p 0");
        assert_eq!(handle(&mut d, "s 999 104").as_deref(), Some("a"));
        handle(&mut d, "p 999");
        assert_eq!(handle(&mut d, "o 1000 2000").as_deref(), Some("a"));
        assert_eq!(handle(&mut d, "s 1000 104").as_deref(), Some("n"));
        assert_eq!(handle(&mut d, "s 2999 104").as_deref(), Some("n"));
        assert_eq!(handle(&mut d, "s 3000 104").as_deref(), Some("a"));
        handle(&mut d, "p 3000");
        assert_eq!(d.resets(), 0);
        assert_eq!(handle(&mut d, "x 4000").as_deref(), Some("a"));
        assert_eq!(d.resets(), 1);
        assert_eq!(d.peek(reg::PWR_MGMT_1), 0x40, "asleep, as at power-up");
    }

    #[test]
    fn wrong_address_and_bad_requests() {
        let mut d = device();
        assert_eq!(handle(&mut d, "s 0 105").as_deref(), Some("n"));
        assert_eq!(handle(&mut d, "s 0 104").as_deref(), Some("a"));
        assert_eq!(
            handle(&mut d, "r 0").as_deref(),
            Some(d.peek(0).to_string().as_str())
        );
        for bad in ["", "q 0", "w 0 256", "s 0 200", "r soon", "o 0", "o 0 -1"] {
            let reply = handle(&mut d, bad).unwrap();
            assert!(reply.starts_with("! "), "{bad:?} -> {reply}");
        }
        assert_eq!(handle(&mut d, "p 5"), None);
        assert_eq!(d.time_us(), 5);
    }

    #[test]
    fn journal_lines() {
        let mut d = device();
        d.keep_journal();
        let input = "s 0 104\nw 0 107\nw 0 0\np 0\nt 2500\nf 2500\n";
        let mut out = Vec::new();
        let mut journal = Vec::new();
        let served = serve(&mut d, input.as_bytes(), &mut out, Some(&mut journal)).unwrap();
        assert_eq!(served, 6);
        assert_eq!(String::from_utf8(out).unwrap(), "a\na\na\na\n");
        let journal = String::from_utf8(journal).unwrap();
        // Default settings: 8 kHz / (1 + 0) with the DLPF off -> a sample every 125 us.
        let samples = journal.lines().filter(|l| l.starts_with("sample,")).count();
        assert_eq!(samples, 20, "{journal}");
        assert!(
            journal
                .lines()
                .all(|l| l.split(',').count() == 10 || l.starts_with("reset,"))
        );
    }
}
