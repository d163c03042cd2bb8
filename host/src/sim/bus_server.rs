//! The simulated chips of a board's I2C bus ([`SimBus`]: an MPU-6050 alone, or a GY-85's
//! ITG-3200 and ADXL345) served over a byte stream, one line per I2C bus event, so that a
//! bus model outside this process (the emulated RP2040 of `tests/emu/`) drives **these**
//! chips: one device model, register-exact, whose samples come with the caller's clock.
//!
//! Requests (ASCII, one per line; `T` is the caller's time in microseconds, decimal; every
//! request first moves the bus clock to `T`, making the samples due):
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
//! | `o T US [ADDR]`| an I2C outage from T for US us | `a`                                    |
//! | `x T [ADDR]`   | a sensor reset at T            | `a`                                    |
//!
//! A start goes to the chip at its address; an address no chip has is not acknowledged, and
//! the bytes of such a transaction neither (a read gives the pull-ups' 255). Faults reach
//! the chip at `ADDR`, or every chip without it. A malformed request, or one naming an
//! address no chip has, gets `! <reason>` and changes nothing. The reply is flushed at once
//! (the caller waits for it); requests without a reply are not, so a stop costs no round
//! trip.
//!
//! The journal ([`write_journal`]) records what the chips did, for comparison with what the
//! host received, each line ending with the chip's address (decimal): `reset,T,ADDR` for a
//! FIFO reset, `sample,T,F,ax,ay,az,temp,gx,gy,gz,ADDR` for a sample made at `T` (raw
//! counts, those the chip does not measure 0; `F` = 1 if it went into the chip's FIFO).

use super::device::{JournalEntry, Outage, SimBus, SimI2cError};
use std::io::{self, BufRead, Write};

/// Serve `bus` on `input`/`output` until `input` ends; the journal, if kept, is written
/// to `journal` as events happen. Returns the number of requests served.
pub fn serve(
    bus: &mut SimBus,
    input: impl BufRead,
    mut output: impl Write,
    mut journal: Option<&mut dyn Write>,
) -> io::Result<u64> {
    let mut served = 0;
    for line in input.lines() {
        let line = line?;
        let request = parse(&line);
        let reply = answer(bus, request, &line);
        if let Some(journal) = journal.as_deref_mut() {
            write_journal(&bus.take_journals(), journal)?;
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
pub fn handle(bus: &mut SimBus, line: &str) -> Option<String> {
    answer(bus, parse(line), line)
}

/// The reply to a parsed request, or the refusal of one that did not parse.
fn answer(
    bus: &mut SimBus,
    request: Result<(u64, Request), &'static str>,
    line: &str,
) -> Option<String> {
    match request.and_then(|r| chips_exist(bus, r)) {
        Ok(request) => respond(bus, request),
        Err(reason) => Some(format!("! {reason}: {line:?}")),
    }
}

/// `request`, unless it names a chip the bus does not have.
fn chips_exist(
    bus: &SimBus,
    (time_us, request): (u64, Request),
) -> Result<(u64, Request), &'static str> {
    let named = match request {
        Request::Outage { chip, .. } | Request::SensorReset { chip } => chip,
        _ => None,
    };
    match named {
        Some(address) if !bus.addresses().contains(&address) => Err("no chip at that address"),
        _ => Ok((time_us, request)),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Request {
    Start {
        repeated: bool,
        address: u8,
    },
    Write(u8),
    Read,
    Stop,
    Clock,
    FlushJournal,
    /// Faults reach `chip` (an address), or every chip.
    Outage {
        for_us: u64,
        chip: Option<u8>,
    },
    SensorReset {
        chip: Option<u8>,
    },
}

fn parse(line: &str) -> Result<(u64, Request), &'static str> {
    let mut words = line.split_ascii_whitespace();
    let verb = words.next().ok_or("empty request")?;
    let time_us = words
        .next()
        .ok_or("no time")?
        .parse::<u64>()
        .map_err(|_| "time is not a whole number of microseconds")?;
    let byte = |word: Option<&str>| -> Result<u8, &'static str> {
        word.ok_or("no byte")?
            .parse::<u8>()
            .map_err(|_| "byte is not 0..=255")
    };
    let address = |word: Option<&str>| {
        byte(word).and_then(|a| {
            if a < 0x80 {
                Ok(a)
            } else {
                Err("address is not 7-bit")
            }
        })
    };
    let request = match verb {
        "s" | "S" => Request::Start {
            repeated: verb == "S",
            address: address(words.next())?,
        },
        "w" => Request::Write(byte(words.next())?),
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
            chip: words.next().map(|w| address(Some(w))).transpose()?,
        },
        "x" => Request::SensorReset {
            chip: words.next().map(|w| address(Some(w))).transpose()?,
        },
        _ => return Err("unknown request (s, S, w, r, p, t, f, o, x)"),
    };
    if words.next().is_some() {
        return Err("more words than the request takes");
    }
    Ok((time_us, request))
}

fn respond(bus: &mut SimBus, (time_us, request): (u64, Request)) -> Option<String> {
    bus.set_time_us(time_us);
    let ack = |result: Result<(), SimI2cError>| match result {
        Ok(()) => "a".to_string(),
        Err(SimI2cError::NoAcknowledge(_)) => "n".to_string(),
        Err(SimI2cError::Bus) => "e".to_string(),
    };
    match request {
        Request::Start { repeated, address } => Some(ack(bus.bus_start(address, repeated))),
        Request::Write(b) => Some(ack(bus.bus_write(b))),
        Request::Read => Some(bus.bus_read().to_string()),
        Request::Stop => {
            bus.bus_stop();
            None
        }
        Request::Clock => None,
        // serve() writes the journal out before this reply goes.
        Request::FlushJournal => Some("a".to_string()),
        Request::Outage { for_us, chip } => {
            for address in targets(bus, chip) {
                if let Some(c) = bus.chip_at(address) {
                    c.faults_mut().i2c_outages.push(Outage {
                        at_us: time_us,
                        for_us,
                    });
                }
            }
            Some("a".to_string())
        }
        Request::SensorReset { chip } => {
            for address in targets(bus, chip) {
                if let Some(c) = bus.chip_at(address) {
                    c.schedule_reset(time_us);
                }
            }
            // Due now: make it happen before the next request sees the chips.
            bus.set_time_us(time_us + 1);
            Some("a".to_string())
        }
    }
}

/// The addresses a fault reaches: `chip`'s, or every chip's.
fn targets(bus: &SimBus, chip: Option<u8>) -> Vec<u8> {
    chip.map_or_else(|| bus.addresses(), |a| vec![a])
}

/// Journal entries, each with its chip's address, as CSV lines (module documentation).
pub fn write_journal(entries: &[(u8, JournalEntry)], out: &mut dyn Write) -> io::Result<()> {
    for (address, entry) in entries {
        match entry {
            JournalEntry::FifoReset { time_us } => writeln!(out, "reset,{time_us},{address}")?,
            JournalEntry::Sample {
                time_us,
                raw,
                in_fifo,
            } => writeln!(
                out,
                "sample,{time_us},{},{},{},{},{},{},{},{},{address}",
                u8::from(*in_fifo),
                raw.accel[0],
                raw.accel[1],
                raw.accel[2],
                raw.temp,
                raw.gyro[0],
                raw.gyro[1],
                raw.gyro[2],
            )?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::boards;
    use crate::sim::imu::ImuModel;
    use crate::sim::model_file::FaultPlan;
    use embedded_hal::i2c::I2c;
    use protocol::mpu6050::reg;
    use protocol::{adxl345, itg3200};

    fn device() -> SimBus {
        boards::mpu6050(ImuModel::default(), 7, &FaultPlan::default())
    }

    fn gy85() -> SimBus {
        boards::gy85(ImuModel::default(), 7, &FaultPlan::default())
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
        let peek = d.mpu6050().map(|m| m.peek(reg::PWR_MGMT_1));
        assert_eq!(peek, Some(0x40), "asleep, as at power-up");
    }

    #[test]
    fn wrong_address_and_bad_requests() {
        let mut d = device();
        assert_eq!(handle(&mut d, "s 0 105").as_deref(), Some("n"));
        assert_eq!(handle(&mut d, "s 0 104").as_deref(), Some("a"));
        let first = d.mpu6050().map(|m| m.peek(0).to_string());
        assert_eq!(handle(&mut d, "r 0"), first);
        for bad in [
            "",
            "q 0",
            "w 0 256",
            "s 0 200",
            "r soon",
            "o 0",
            "o 0 -1",
            "o 0 5 200",
            "o 0 5 83",
            "x 0 105",
            "p 0 1",
        ] {
            let reply = handle(&mut d, bad).unwrap();
            assert!(reply.starts_with("! "), "{bad:?} -> {reply}");
        }
        assert_eq!(handle(&mut d, "p 5"), None);
        assert_eq!(d.time_us(), 5);
    }

    #[test]
    fn journal_lines() {
        let mut d = device();
        d.keep_journals();
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
                .all(|l| l.ends_with(",104")
                    && (l.split(',').count() == 11 || l.starts_with("reset,"))),
            "{journal}"
        );
    }

    /// A GY-85's bus: each start reaches the chip at its address (WHO_AM_I and DEVID read
    /// through the lines), a third address is not acknowledged and its bytes go nowhere.
    #[test]
    fn each_address_reaches_its_chip() {
        let mut bus = gy85();
        let read_id = |bus: &mut SimBus, address: u8| {
            let replies: Vec<Option<String>> = [
                format!("s 0 {address}"),
                "w 0 0".to_string(),
                format!("S 0 {address}"),
                "r 0".to_string(),
            ]
            .iter()
            .map(|l| handle(bus, l))
            .collect();
            handle(bus, "p 0");
            replies
        };
        let ok = |id: u8| {
            vec![
                Some("a".into()),
                Some("a".into()),
                Some("a".into()),
                Some(id.to_string()),
            ]
        };
        assert_eq!(
            read_id(&mut bus, itg3200::DEFAULT_ADDRESS),
            ok(itg3200::WHO_AM_I_VALUE)
        );
        assert_eq!(
            read_id(&mut bus, adxl345::DEFAULT_ADDRESS),
            ok(adxl345::DEVID_VALUE)
        );
        let nobody = read_id(&mut bus, 0x1D);
        assert_eq!(
            nobody,
            [
                Some("n".into()),
                Some("n".into()),
                Some("n".into()),
                Some("255".into())
            ]
        );
    }

    /// A fault naming an address reaches that chip only; without one, every chip.
    #[test]
    fn faults_reach_the_chip_named() {
        let mut bus = gy85();
        let (gyro, accel) = (itg3200::DEFAULT_ADDRESS, adxl345::DEFAULT_ADDRESS);
        let start = |bus: &mut SimBus, t: u64, address: u8| {
            let reply = handle(bus, &format!("s {t} {address}"));
            handle(bus, &format!("p {t}"));
            reply.unwrap_or_default()
        };
        assert_eq!(
            handle(&mut bus, &format!("o 100 1000 {accel}")).as_deref(),
            Some("a")
        );
        assert_eq!(
            (start(&mut bus, 500, gyro), start(&mut bus, 500, accel)),
            ("a".into(), "n".into())
        );
        assert_eq!(start(&mut bus, 1100, accel), "a");
        assert_eq!(handle(&mut bus, "o 2000 1000").as_deref(), Some("a"));
        assert_eq!(
            (start(&mut bus, 2500, gyro), start(&mut bus, 2500, accel)),
            ("n".into(), "n".into())
        );
        assert_eq!(
            handle(&mut bus, &format!("x 4000 {gyro}")).as_deref(),
            Some("a")
        );
        assert_eq!(bus.resets(), 1);
        assert_eq!(handle(&mut bus, "x 5000").as_deref(), Some("a"));
        assert_eq!(bus.resets(), 3);
    }

    /// Every chip's samples are in the journal, each line with its chip's address.
    #[test]
    fn journal_lines_say_which_chip() {
        let mut bus = gy85();
        bus.keep_journals();
        let mut journal = Vec::new();
        // The ADXL345 powers up in standby: POWER_CTL's Measure bit starts it.
        let measure = format!(
            "s 0 {a}\nw 0 {}\nw 0 {}\np 0\nt 20000\nf 20000\n",
            adxl345::reg::POWER_CTL,
            adxl345::reg::bits::MEASURE,
            a = adxl345::DEFAULT_ADDRESS
        );
        serve(&mut bus, measure.as_bytes(), io::sink(), Some(&mut journal)).unwrap();
        let journal = String::from_utf8(journal).unwrap();
        let from = |address: u8| {
            journal
                .lines()
                .filter(|l| l.starts_with("sample,") && l.ends_with(&format!(",{address}")))
                .count()
        };
        // Power-up rates: the ITG-3200 at 8 kHz (every register 0), the ADXL345 at 100 Hz.
        assert_eq!(from(itg3200::DEFAULT_ADDRESS), 160, "{journal}");
        assert_eq!(from(adxl345::DEFAULT_ADDRESS), 2, "{journal}");
        assert_eq!(journal.lines().count(), 162);
    }
}
