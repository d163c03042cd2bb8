//! imunoise board firmware: RP2040 + MPU-6050, or RP2040 + GY-85 (ITG-3200 and ADXL345).
//!
//! Wiring (3.3 V logic): the sensor board's SDA -> GPIO4 (I2C0 SDA), SCL -> GPIO5 (I2C0
//! SCL), VCC -> 3V3, GND -> GND; an MPU-6050's AD0 -> GND (address 0x68). The firmware
//! probes the bus for what is there (`firmware::slot`). The internal pull-ups are enabled,
//! but most breakouts carry their own 4.7-10 kOhm pull-ups, which 400 kHz needs. INT is not
//! used (the sensors are polled on the timer). LED: GPIO25 (the Pico's).
//!
//! Everything the board does is in the portable `firmware` crate; this file only wires the
//! RP2040 to it: clocks, I2C0 at 400 kHz, the microsecond timer as clock, USB CDC as the
//! link (frames in, frames out through a ring buffer that never blocks acquisition), the
//! flash unique id as board id, defmt over RTT for logs, the LED for state.
#![no_std]
#![no_main]

mod bus;
mod flash;
mod link;
mod log;

use core::cell::RefCell;
use defmt_rtt as _;
use panic_probe as _;

use firmware::{BoardConfig, Clock, Firmware};
use rp2040_hal as hal;

use embedded_hal::digital::OutputPin;
use hal::fugit::{ExtU32, RateExtU32};
use protocol::ResetReason;
use hal::clocks::{Clock as _, init_clocks_and_plls};
use hal::{Sio, Timer, Watchdog, gpio, pac};
use usb_device::class_prelude::UsbBusAllocator;
use usb_device::prelude::{StringDescriptors, UsbDeviceBuilder, UsbVidPid};
use usbd_serial::SerialPort;

/// The second-stage bootloader for the W25Q080 flash of the Pico and most RP2040 boards.
#[unsafe(link_section = ".boot2")]
#[used]
pub static BOOT2: [u8; 256] = rp2040_boot2::BOOT_LOADER_W25Q080;

const XTAL_FREQ_HZ: u32 = 12_000_000;
/// The watchdog's period: a main-loop turn takes well under a millisecond, a recovery
/// attempt a few.
const WATCHDOG_PERIOD_US: u32 = 1_000_000;
/// 16c0:27dd is one of the VID:PID pairs Van Ooijen Technische Informatica shares for CDC-ACM
/// devices (V-USB's free IDs), not an id of our own: other devices carry it too, and the host
/// tells ours apart by the manufacturer and product strings below, as the rules for shared
/// pairs ask. A lab with its own VID:PID (or a pid.codes allocation) changes it here and in
/// `host/src/link/serial.rs` (docs/guide/hardware.md, "USB IDs").
const USB_VID_PID: UsbVidPid = UsbVidPid(0x16c0, 0x27dd);

/// The RP2040's 64-bit microsecond timer.
struct BoardClock(Timer);

impl Clock for BoardClock {
    fn now_us(&mut self) -> u64 {
        self.0.get_counter().ticks()
    }
}

// The few panics below are at power-up, before the USB link (the only channel to the host)
// exists and before any sample is taken: a board that cannot set up its clocks or USB has
// nobody to report to, so panic-probe logs the reason over RTT. Nothing after setup panics;
// the data path reports every error to the host.
#[hal::entry]
fn main() -> ! {
    let Some(mut pac) = pac::Peripherals::take() else {
        panic!("peripherals taken twice");
    };
    let reset_reason = reset_reason(&pac.WATCHDOG, &pac.VREG_AND_CHIP_RESET);
    let mut watchdog = Watchdog::new(pac.WATCHDOG);
    let Ok(clocks) = init_clocks_and_plls(
        XTAL_FREQ_HZ,
        pac.XOSC,
        pac.CLOCKS,
        pac.PLL_SYS,
        pac.PLL_USB,
        &mut pac.RESETS,
        &mut watchdog,
    ) else {
        panic!("clock setup failed");
    };
    let board_id = board_id();
    defmt::info!(
        "imunoise board {=u64:016x}, started by {}",
        board_id,
        defmt::Debug2Format(&reset_reason)
    );

    let sio = Sio::new(pac.SIO);
    let pins = gpio::Pins::new(
        pac.IO_BANK0,
        pac.PADS_BANK0,
        sio.gpio_bank0,
        &mut pac.RESETS,
    );
    let mut led = pins.gpio25.into_push_pull_output();
    let mut timer = Timer::new(pac.TIMER, &mut pac.RESETS, &clocks);

    let sda = pins.gpio4.reconfigure::<gpio::FunctionI2C, gpio::PullUp>();
    let scl = pins.gpio5.reconfigure::<gpio::FunctionI2C, gpio::PullUp>();

    let usb_bus = UsbBusAllocator::new(hal::usb::UsbBus::new(
        pac.USBCTRL_REGS,
        pac.USBCTRL_DPRAM,
        clocks.usb_clock,
        true,
        &mut pac.RESETS,
    ));
    let mut serial = SerialPort::new(&usb_bus);
    let serial_number = link::hex16(board_id);
    let strings = StringDescriptors::default()
        .manufacturer("imunoise")
        .product("imunoise MPU-6050 logger")
        .serial_number(serial_number.as_str());
    let Ok(builder) = UsbDeviceBuilder::new(&usb_bus, USB_VID_PID).strings(&[strings]) else {
        panic!("USB strings");
    };
    let Ok(builder) = builder.max_packet_size_0(64) else {
        panic!("USB packet size");
    };
    let mut usb = builder.device_class(usbd_serial::USB_CLASS_CDC).build();

    // The bus owns RESETS from here on: clearing it re-creates the I2C peripheral.
    let i2c = bus::Bus::new(
        pac.I2C0,
        sda,
        scl,
        400.kHz(),
        pac.RESETS,
        clocks.system_clock.freq(),
        timer,
    );

    // A sensor left mid-transfer by a reset of the board alone (the sensor kept its power)
    // may hold SDA low: free the bus before the first transaction.
    let mut i2c = i2c;
    firmware::BusClear::clear_bus(&mut i2c);
    let i2c = RefCell::new(i2c);
    let mut fw = Firmware::new(
        bus::Shared(&i2c),
        BoardClock(timer),
        BoardConfig {
            board_id,
            reset_reason,
        },
    );
    match fw.init(&mut timer) {
        Ok(()) => defmt::info!("sensors ready"),
        Err(e) => defmt::warn!("sensors not ready: {}", defmt::Display2Format(&e)),
    }
    for sensor in fw.sensors().iter() {
        defmt::info!(
            "sensor {} at {=u8:#x}",
            sensor.kind.name(),
            sensor.address
        );
    }

    // From here the main loop must turn at least once a second, or the chip restarts (and
    // says so in Info): a hang anywhere, or a bus that blocks forever, costs a reboot, not
    // the night.
    watchdog.pause_on_debug(true);
    watchdog.start(WATCHDOG_PERIOD_US.micros());

    let mut tx = link::TxQueue::new();
    let mut rx = [0u8; 64];
    let mut host_present = false;
    let mut log = log::Changes::default();
    loop {
        watchdog.feed();
        if usb.poll(&mut [&mut serial])
            && let Ok(n) = serial.read(&mut rx)
        {
            fw.handle_bytes(&rx[..n], &mut |frame| tx.push_frame(frame));
        }
        // A host that closes the port drops DTR: stop streaming into nowhere.
        let dtr = serial.dtr();
        if host_present && !dtr {
            defmt::info!("host closed the port: streaming stopped");
            fw.host_left();
            tx.clear();
        }
        host_present = dtr;
        fw.poll(&mut |frame| tx.push_frame(frame));
        tx.write_to(&mut serial);
        log.report(&fw.status());
        // LED: on while streaming, a 1 Hz blink while stopped.
        let now = timer.get_counter().ticks();
        let on = fw.streaming() || (now / 500_000) % 2 == 0;
        let _ = if on { led.set_high() } else { led.set_low() };
    }
}

/// Why the chip started: the watchdog's reason register says whether it fired or was forced;
/// otherwise the chip-reset register says power-on (or brown-out), the RUN pin, or a
/// debugger.
fn reset_reason(watchdog: &pac::WATCHDOG, chip: &pac::VREG_AND_CHIP_RESET) -> ResetReason {
    let reason = watchdog.reason().read();
    let chip = chip.chip_reset().read();
    if reason.timer().bit_is_set() {
        ResetReason::Watchdog
    } else if reason.force().bit_is_set() || chip.had_psm_restart().bit_is_set() {
        ResetReason::Requested
    } else if chip.had_run().bit_is_set() {
        ResetReason::RunPin
    } else if chip.had_por().bit_is_set() {
        ResetReason::PowerOn
    } else {
        ResetReason::Unknown
    }
}

/// The flash chip's 64-bit unique id (the board's serial number). Not available in the
/// emulator, which has no flash chip behind the SSI.
#[cfg(not(feature = "emulator"))]
fn board_id() -> u64 {
    let mut id = [0u8; 8];
    // SAFETY: single core, no DMA yet, interrupts off for the duration (the ROM routine
    // runs from RAM while flash is in command mode).
    cortex_m::interrupt::free(|_| unsafe { flash::unique_id(&mut id) });
    u64::from_be_bytes(id)
}

#[cfg(feature = "emulator")]
fn board_id() -> u64 {
    0
}
