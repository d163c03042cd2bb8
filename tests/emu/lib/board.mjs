// The emulated board: the release firmware ELF on rp2040js, its I2C0 wired to the simulated
// chips (sim-device.mjs: an MPU-6050, or a GY-85's ITG-3200 and ADXL345), its USB CDC
// bridged to a pseudo-terminal made by socat, and its defmt log (the RTT up-buffer in
// emulated RAM) decoded by defmt-print.
//
// rp2040js quirks handled here (docs/ARCHITECTURE.md, "Testing architecture"):
// - no bootrom: the flash image is loaded directly, VTOR set past boot2, SP and PC taken
//   from the vector table (the firmware is built with `--features emulator`, which avoids
//   the ROM's float and integer routines);
// - the firmware arms its OUT endpoint before enumeration ends and rp2040js drops that
//   request: arms are remembered per endpoint and served when bytes arrive from the host;
// - a host that does not read: the pty fills, socat stops reading, and the harness then
//   holds back IN transfers, as a USB host controller NAKs them, so the firmware sees real
//   back-pressure.

import { Simulator, USBCDC } from 'rp2040js';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import { readElf } from './elf.mjs';
import { SimDevice, attachI2c } from './sim-device.mjs';

const FLASH_START = 0x10000000;
const RAM_START = 0x20000000;
/// The vector table follows the 256-byte second-stage bootloader.
const VECTOR_TABLE = FLASH_START + 0x100;
/// USB DPRAM: EP0 IN buffer control (EPn IN at + 8n) and its AVAILABLE bit (RP2040
/// datasheet, 4.1.2.5).
const EP0_IN_BUFFER_CONTROL = 0x80;
const BUF_AVAILABLE = 1 << 10;

export class EmulatedBoard {
  /**
   * @param {object} o
   * @param {string} o.elf the firmware (built with --features emulator)
   * @param {string} o.imunoise the imunoise binary (serves the simulated chips)
   * @param {string} o.dir a private working folder
   * @param {string} o.pty path of the pseudo-terminal link the host opens
   * @param {string} [o.board] the chips on the bus: 'mpu6050' (default) or 'gy85'
   * @param {number} [o.seed] the simulated chips' seed
   * @param {string} [o.model] the simulated chips' noise model file
   * @param {string} [o.journal] where the simulated chips write what they made
   * @param {string} [o.defmtPrint] the defmt-print binary ('' to show raw RTT bytes' count only)
   * @param {(line: string) => void} [o.log] where the firmware's log lines go
   */
  constructor(o) {
    this.options = o;
    this.log = o.log ?? ((line) => process.stderr.write(`${line}\n`));
    const elf = readElf(fs.readFileSync(o.elf));
    this.rttAddress = elf.symbols.get('_SEGGER_RTT');
    this.functions = [...elf.symbols].filter(([, a]) => a >= FLASH_START && a < RAM_START).sort((a, b) => a[1] - b[1]);

    this.sim = new Simulator();
    const mcu = this.sim.rp2040;
    this.mcu = mcu;
    // rp2040js reports every register it does not model (USB PHY trims, I2C hold time...);
    // only its errors matter here.
    const quiet = () => {};
    mcu.logger = {
      debug: quiet,
      info: quiet,
      warn: quiet,
      error: (component, message) => this.log(`[rp2040js] ${component}: ${message}`),
    };
    for (const { address, data } of elf.segments) {
      if (address >= FLASH_START && address + data.length <= FLASH_START + mcu.flash.length) {
        mcu.flash.set(data, address - FLASH_START);
      }
    }
    mcu.core.VTOR = VECTOR_TABLE;
    mcu.core.SP = mcu.readUint32(VECTOR_TABLE);
    mcu.core.PC = mcu.readUint32(VECTOR_TABLE + 4) & ~1;

    this.device = new SimDevice({
      imunoise: o.imunoise,
      dir: o.dir,
      board: o.board,
      seed: o.seed ?? 1,
      model: o.model,
      journal: o.journal,
    });
    attachI2c(mcu.i2c[0], this.device, () => this.nowUs());

    this.toDevice = [];
    this.fromHost = [];
    this.bytesToHost = 0;
    this.hostBlocked = true; // until the pty exists
    this.holdUntilUs = 0;
    /** The IN buffer-control offset whose transfer waits for the host, if any. */
    this.heldIn = null;
    this.usbConnected = new Promise((resolve) => this.setupUsb(resolve));
    this.startDefmt();
  }

  /** Emulated time since power-up, whole microseconds (the firmware's timer reads the same). */
  nowUs() {
    return Math.floor(this.sim.clock.nanos / 1000);
  }

  setupUsb(onConnected) {
    const usb = this.mcu.usbCtrl;
    const cdc = new USBCDC(usb);
    this.cdc = cdc;
    this.armed = new Map();
    usb.onEndpointRead = (endpoint, size) => {
      this.armed.set(endpoint, size);
      this.flushToDevice();
    };
    cdc.onDeviceConnected = () => {
      this.log(`[emu] USB CDC enumerated at ${(this.nowUs() / 1e6).toFixed(3)} s (emulated)`);
      this.flushToDevice();
      onConnected();
    };
    cdc.onSerialData = (data) => this.toHost(data);
    // A host that does not take data NAKs the IN tokens: the buffer the firmware handed
    // over stays AVAILABLE (so the firmware cannot queue more) until the host reads.
    // rp2040js starts a transfer as soon as AVAILABLE is written, so such a write is held
    // back here and replayed when the host takes data again.
    const dpramUpdated = usb.DPRAMUpdated.bind(usb);
    this.startIn = (offset) => dpramUpdated(offset, this.mcu.usbDPRAMView.getUint32(offset, true));
    usb.DPRAMUpdated = (offset, value) => {
      const inControl = EP0_IN_BUFFER_CONTROL + 8 * cdc.inEndpoint;
      if (cdc.inEndpoint > 0 && offset === inControl && value & BUF_AVAILABLE && this.inHeld()) {
        this.heldIn = offset;
        return;
      }
      dpramUpdated(offset, value);
    };
  }

  /** The function the core is executing (the nearest symbol at or below PC). */
  where() {
    const pc = this.mcu.core.PC;
    let name = '?';
    for (const [symbol, address] of this.functions) {
      if ((address & ~1) > pc) break;
      name = symbol;
    }
    return `PC 0x${pc.toString(16)} in ${name}`;
  }

  /** The link's state in words (for logs). */
  state() {
    return `${(this.nowUs() / 1e6).toFixed(2)} s emulated, ${this.where()}; ${this.device.events} I2C events; to host ${this.bytesToHost} B, from host ${this.fromHost.length} B; host blocked ${this.hostBlocked}, IN held ${this.heldIn !== null}, OUT armed ${JSON.stringify([...this.armed])}, ${this.toDevice.length} B waiting for the board; last I2C ${JSON.stringify(this.device.recent.slice(-12))}; I2C0 state ${this.mcu.i2c[0].state} busy ${this.mcu.i2c[0].busy} stop ${this.mcu.i2c[0].stop} txFIFO ${this.mcu.i2c[0].txFIFO.itemCount} rxFIFO ${this.mcu.i2c[0].rxFIFO.itemCount} enable ${this.mcu.i2c[0].enable} abort ${this.mcu.i2c[0].abortSource}`;
  }

  /** Host -> board bytes, into the OUT endpoint whenever the firmware has it armed. */
  flushToDevice() {
    const endpoint = this.cdc.outEndpoint;
    if (endpoint < 0 || !this.armed.has(endpoint) || this.toDevice.length === 0) return;
    const size = this.armed.get(endpoint);
    this.armed.delete(endpoint);
    const chunk = this.toDevice.splice(0, size);
    this.mcu.usbCtrl.endpointReadDone(endpoint, Uint8Array.from(chunk));
  }

  /** Bytes as if the host had written them (tests inject frames with this). */
  inject(bytes) {
    for (const b of bytes) this.toDevice.push(b);
    this.flushToDevice();
  }

  toHost(data) {
    this.bytesToHost += data.length;
    if (!this.serial) return;
    if (!this.serial.stdin.write(Buffer.from(data))) this.block();
  }

  block() {
    if (this.hostBlocked) return;
    this.hostBlocked = true;
    this.serial.stdin.once('drain', () => this.unblock());
  }

  unblock() {
    this.hostBlocked = false;
    this.releaseIn();
  }

  /** Whether IN transfers are being refused (NAKed) now. */
  inHeld() {
    return this.hostBlocked || this.nowUs() < this.holdUntilUs;
  }

  releaseIn() {
    if (this.heldIn !== null && !this.inHeld()) {
      const offset = this.heldIn;
      this.heldIn = null;
      this.startIn(offset);
    }
  }

  /**
   * Refuse IN transfers for `us` emulated microseconds, as a USB host whose buffers are full
   * does (tests: a host that stops reading, reproducibly in emulated time).
   */
  holdIn(us) {
    this.holdUntilUs = this.nowUs() + us;
  }

  /** Make the pseudo-terminal: socat joins a new pty (at `pty`) to its stdin and stdout. */
  async openPty() {
    const { pty } = this.options;
    fs.rmSync(pty, { force: true });
    const socat = spawn('socat', ['-d', '-d', `PTY,raw,echo=0,link=${pty}`, 'STDIO'], {
      stdio: ['pipe', 'pipe', 'pipe'],
    });
    this.serial = socat;
    socat.stdout.on('data', (bytes) => {
      for (const b of bytes) this.fromHost.push(b);
      this.inject(bytes);
    });
    socat.stdin.on('error', () => {});
    socat.on('exit', (code, signal) => {
      if (!this.closing) this.log(`[emu] socat exited (${code ?? signal}): the pty is gone`);
    });
    await new Promise((resolve, reject) => {
      let text = '';
      socat.stderr.on('data', (chunk) => {
        text += chunk;
        if (/ E /.test(chunk)) this.log(`[socat] ${String(chunk).trim()}`);
        if (/PTY is (\S+)/.test(text) && fs.existsSync(pty)) resolve();
      });
      socat.on('exit', (code) => reject(new Error(`socat exited (${code}): ${text.trim()}`)));
      socat.on('error', reject);
    });
    this.unblock();
    return fs.realpathSync(pty);
  }

  /** defmt-print decodes the RTT bytes against the ELF; its lines go to the log. */
  startDefmt() {
    const { defmtPrint, elf } = this.options;
    if (!defmtPrint || this.rttAddress === undefined) return;
    const child = spawn(defmtPrint, ['-e', elf, 'stdin'], { stdio: ['pipe', 'pipe', 'pipe'] });
    const relay = (stream) => {
      let partial = '';
      stream.on('data', (chunk) => {
        const lines = (partial + chunk).split('\n');
        partial = lines.pop();
        for (const line of lines) if (line.trim()) this.log(`[firmware] ${line}`);
      });
    };
    relay(child.stdout);
    relay(child.stderr);
    child.stdin.on('error', () => {});
    this.defmt = child;
    this.defmtExited = new Promise((resolve) => child.on('exit', resolve));
  }

  /**
   * Move the RTT up-buffer 0's new bytes to defmt-print. The control block (SEGGER RTT):
   * "SEGGER RTT\0..." (16 bytes), MaxNumUpBuffers, MaxNumDownBuffers (u32 each), then each
   * up-buffer: sName, pBuffer, SizeOfBuffer, WrOff, RdOff, Flags (u32 each).
   */
  pollRtt() {
    if (!this.defmt || this.rttAddress === undefined) return;
    const ram = this.mcu.sramView;
    const cb = this.rttAddress - RAM_START;
    if (ram.getUint32(cb, true) !== 0x47474553) return; // "SEGG": not initialised yet
    const up = cb + 24;
    const buffer = ram.getUint32(up + 4, true) - RAM_START;
    const size = ram.getUint32(up + 8, true);
    const write = ram.getUint32(up + 12, true);
    let read = ram.getUint32(up + 16, true);
    if (size === 0 || write === read) return;
    const bytes = [];
    while (read !== write) {
      bytes.push(this.mcu.sram[buffer + read]);
      read = (read + 1) % size;
    }
    ram.setUint32(up + 16, read, true);
    this.defmt.stdin.write(Buffer.from(bytes));
  }

  /**
   * Run the emulator until `until()` is true (checked between slices) or `maxEmulatedS`
   * more emulated seconds pass. Slices of `sliceUs` emulated microseconds alternate with
   * the event loop, so pty and pipe I/O keep flowing.
   */
  async run({ until = () => false, maxEmulatedS = Infinity, sliceUs = 2000 } = {}) {
    const { core } = this.mcu;
    const clock = this.sim.clock;
    const endNs = clock.nanos + maxEmulatedS * 1e9;
    const cycleNs = 1e9 / 125e6;
    while (!until() && clock.nanos < endNs) {
      const sliceEnd = Math.min(endNs, clock.nanos + sliceUs * 1000);
      while (clock.nanos < sliceEnd) {
        if (core.waiting) {
          const skip = clock.nanosToNextAlarm;
          clock.tick(skip > 0 ? Math.min(skip, sliceEnd - clock.nanos) : cycleNs);
        } else {
          clock.tick(core.executeInstruction() * cycleNs);
        }
      }
      this.pollRtt();
      this.releaseIn();
      await new Promise((resolve) => setImmediate(resolve));
    }
  }

  /** Stop everything; the device's journal is complete after this. */
  async close() {
    this.closing = true;
    this.serial?.kill();
    this.pollRtt();
    if (this.defmt) {
      this.defmt.stdin.end();
      await this.defmtExited;
    }
    await this.device.close();
  }
}
