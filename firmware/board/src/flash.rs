//! The flash chip's 64-bit unique id, the board's id and USB serial number.
//!
//! The id is read with the SPI command 0x4B through the RP2040's SSI, which can only be done
//! while the flash is out of execute-in-place mode: the code that does it runs from RAM and
//! calls the bootrom to leave XIP, then the second-stage bootloader (copied to RAM) to
//! return to it. Adapted from `flash_unique_id` of rp2040-flash 0.6.0 (MIT OR Apache-2.0,
//! https://github.com/jannic/rp2040-flash), cut to that one function: the crate depends on
//! rp2040-hal 0.11, and linking it next to our rp2040-hal 0.12 defines the HAL's divider
//! and float intrinsics twice. The emulator has no flash chip behind the SSI, so its image
//! leaves this module out (the board id is 0 there).
#![cfg(not(feature = "emulator"))]

use rp2040_hal::rom_data;

/// Read the 8-byte unique id of the flash chip (Winbond W25Q parts, as on the Pico, have one;
/// others may return anything).
///
/// # Safety
///
/// Nothing may access flash while this runs: interrupts off, the other core idle or
/// running from RAM, no DMA from flash.
pub unsafe fn unique_id(out: &mut [u8; 8]) {
    let mut boot2 = [0u32; 256 / 4];
    // SAFETY: the second-stage bootloader is the first 256 bytes of flash (memory.x), and
    // `boot2` is a word-aligned buffer of that size; XIP is still on, so flash is readable.
    unsafe { rom_data::memcpy44(boot2.as_mut_ptr(), 0x1000_0000 as *const u32, 256) };
    // The bootloader's code is Thumb: its entry is the buffer's address with bit 0 set.
    let entry = boot2.as_ptr().cast::<u8>().wrapping_add(1);
    // SAFETY: `entry` points at a copy of the bootloader, a function that takes and returns
    // nothing and puts the flash back into XIP mode.
    let enter_xip = unsafe { core::mem::transmute::<*const u8, unsafe extern "C" fn()>(entry) };
    let routines = Routines {
        connect_internal_flash: rom_data::connect_internal_flash::ptr(),
        flash_exit_xip: rom_data::flash_exit_xip::ptr(),
        enter_xip,
    };
    // Read unique id: the command byte, then 4 dummy bytes, then the id.
    let cmd = [0x4Bu8];
    let command = SpiCommand {
        cmd_addr: cmd.as_ptr(),
        cmd_addr_len: cmd.len() as u32,
        dummy_len: 4,
        data: out.as_mut_ptr(),
        data_len: out.len() as u32,
    };
    // SAFETY: the caller keeps flash idle; `command` and `routines` (with `cmd`, `out` and
    // `boot2`) outlive the call.
    unsafe { read_flash(&command, &routines) };
}

/// The routines [`read_flash`] calls, at the byte offsets its assembly loads them from.
#[repr(C)]
struct Routines {
    /// Offset 0.
    connect_internal_flash: unsafe extern "C" fn(),
    /// Offset 4.
    flash_exit_xip: unsafe extern "C" fn(),
    /// Offset 8: the copied second-stage bootloader.
    enter_xip: unsafe extern "C" fn(),
}

const _: () = assert!(core::mem::offset_of!(Routines, connect_internal_flash) == 0);
const _: () = assert!(core::mem::offset_of!(Routines, flash_exit_xip) == 4);
const _: () = assert!(core::mem::offset_of!(Routines, enter_xip) == 8);

/// One SPI read, at the byte offsets the assembly of [`read_flash`] loads its fields from.
#[repr(C)]
struct SpiCommand {
    /// Offset 0: the command (and address) bytes.
    cmd_addr: *const u8,
    /// Offset 4.
    cmd_addr_len: u32,
    /// Offset 8: bytes clocked in and discarded after the command.
    dummy_len: u32,
    /// Offset 12: where the reply goes.
    data: *mut u8,
    /// Offset 16.
    data_len: u32,
}

const _: () = assert!(core::mem::offset_of!(SpiCommand, cmd_addr) == 0);
const _: () = assert!(core::mem::offset_of!(SpiCommand, cmd_addr_len) == 4);
const _: () = assert!(core::mem::offset_of!(SpiCommand, dummy_len) == 8);
const _: () = assert!(core::mem::offset_of!(SpiCommand, data) == 12);
const _: () = assert!(core::mem::offset_of!(SpiCommand, data_len) == 16);

/// Leave XIP, run `cmd` on the SSI in EEPROM-read mode (RP2040 datasheet 4.10), and return
/// to XIP; in RAM, since flash cannot be read meanwhile.
///
/// # Safety
///
/// As [`unique_id`]; `cmd` must describe valid buffers of its lengths (`cmd_addr_len` and
/// `data_len` at least 1).
#[inline(never)]
#[unsafe(link_section = ".data.ram_func")]
unsafe fn read_flash(cmd: *const SpiCommand, routines: *const Routines) {
    // SAFETY: the caller's contract; the routines are the bootrom's and the copied
    // bootloader, called with the C ABI whose registers are declared clobbered.
    unsafe {
        core::arch::asm!(
            // r6 and r7 are reserved by LLVM and cannot be marked clobbered: saved here (r6
            // only to keep the stack 8-byte aligned).
            "push {{r6, r7}}",
            "mov r7, r0", // cmd
            "mov r5, r1", // routines
            "ldr r4, [r5, #0]",
            "blx r4", // connect_internal_flash()
            "ldr r4, [r5, #4]",
            "blx r4", // flash_exit_xip()
            "movs r4, #0x18",
            "lsls r4, r4, #24", // 0x18000000, the SSI (RP2040 datasheet 4.10.13)
            // Disable the SSI: SSIENR = 0.
            "movs r0, #0",
            "str r0, [r4, #8]",
            // CTRLR0: TMOD = EEPROM read (0x300).
            "movs r0, #0x3",
            "lsls r0, r0, #8",
            "ldr r1, [r4, #0]",
            "orrs r1, r0",
            "str r1, [r4, #0]",
            // CTRLR1 = dummy_len + data_len - 1 (frames to receive).
            "ldr r0, [r7, #8]",
            "ldr r1, [r7, #16]",
            "add r0, r1",
            "subs r0, #1",
            "str r0, [r4, #0x04]",
            // Enable the SSI: SSIENR = 1.
            "movs r0, #1",
            "str r0, [r4, #8]",
            // The command and address bytes into DR.
            "mov r2, r4",
            "adds r2, 0x60",
            "ldr r0, [r7, #0]",
            "ldr r1, [r7, #4]",
            "10:",
            "ldrb r3, [r0]",
            "strb r3, [r2]",
            "adds r0, #1",
            "subs r1, #1",
            "bne 10b",
            // Discard the dummy bytes (wait for SR.RFNE, read DR).
            "ldr r1, [r7, #8]",
            "cmp r1, #0",
            "beq 9f",
            "4:",
            "ldr r3, [r4, #0x28]",
            "movs r2, #0x8",
            "tst r3, r2",
            "beq 4b",
            "mov r2, r4",
            "adds r2, 0x60",
            "ldrb r3, [r2]",
            "subs r1, #1",
            "bne 4b",
            // The reply from the receive FIFO into data.
            "9:",
            "ldr r0, [r7, #12]",
            "ldr r1, [r7, #16]",
            "2:",
            "ldr r3, [r4, #0x28]",
            "movs r2, #0x8",
            "tst r3, r2",
            "beq 2b",
            "mov r2, r4",
            "adds r2, 0x60",
            "ldrb r3, [r2]",
            "strb r3, [r0]",
            "adds r0, #1",
            "subs r1, #1",
            "bne 2b",
            // Disable the SSI, and CTRLR1 back to 0: the XIP set-up below does not reset it,
            // and XIP fails with it left set.
            "movs r0, #0",
            "str r0, [r4, #8]",
            "str r0, [r4, #4]",
            "ldr r4, [r5, #8]",
            "blx r4", // the bootloader: XIP on again
            "pop {{r6, r7}}",
            in("r0") cmd,
            in("r1") routines,
            out("r2") _,
            out("r3") _,
            out("r4") _,
            out("r5") _,
            clobber_abi("C"),
        );
    }
}
