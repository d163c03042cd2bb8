// What the emulated-board test files share: one board (the release image on rp2040js, the
// simulated chips of `--board` on its I2C bus), run in the background while the tests drive
// the unmodified host CLI through its pseudo-terminal, with a store of their own.

import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { EmulatedBoard } from './board.mjs';
import { defaults } from './paths.mjs';

export class Testbed {
  /**
   * @param {object} o
   * @param {string} [o.board] the chips on the bus: 'mpu6050' (default) or 'gy85'
   * @param {number} o.seed the simulated chips' seed
   */
  constructor({ board = 'mpu6050', seed }) {
    this.dir = fs.mkdtempSync(path.join(os.tmpdir(), `imunoise-emu-${board}-`));
    this.store = path.join(this.dir, 'store');
    this.pty = path.join(this.dir, 'tty');
    this.journalFile = path.join(this.dir, 'journal.csv');
    /** The firmware's decoded log lines so far. */
    this.firmwareLog = [];
    this.finished = false;
    this.speed = { emulatedS: 0, wallS: 0 };
    this.board = new EmulatedBoard({
      elf: defaults.elf,
      imunoise: defaults.imunoise,
      dir: this.dir,
      pty: this.pty,
      board,
      seed,
      journal: this.journalFile,
      defmtPrint: defaults.defmtPrint,
      log: (line) => {
        if (line.startsWith('[firmware] ')) this.firmwareLog.push(line);
        process.stderr.write(`${line}\n`);
      },
    });
  }

  /** Open the pty and run the emulator in the background until USB is up. */
  async start() {
    await this.board.openPty();
    let lastState = performance.now();
    this.running = this.board.run({
      until: () => {
        if (process.env.EMU_VERBOSE && performance.now() - lastState > 5000) {
          lastState = performance.now();
          console.error(`[emu] ${this.board.state()}`);
        }
        return this.finished;
      },
    });
    await this.board.usbConnected;
  }

  async stop() {
    this.finished = true;
    await this.running;
    await this.board.close();
    const { emulatedS, wallS } = this.speed;
    console.error(
      `[test] emulation speed while capturing: ${emulatedS.toFixed(1)} s emulated in ${wallS.toFixed(1)} s wall = ${(emulatedS / wallS).toFixed(2)} emulated s per wall s`,
    );
    fs.rmSync(this.dir, { recursive: true, force: true });
  }

  /** Run imunoise without blocking the event loop (the emulator runs meanwhile). */
  imunoise(args, { onSpawn } = {}) {
    return new Promise((resolve, reject) => {
      const child = spawn(defaults.imunoise, [...args, '--store', this.store], {
        stdio: ['ignore', 'pipe', 'pipe'],
      });
      let stdout = '';
      let stderr = '';
      child.stdout.on('data', (d) => (stdout += d));
      child.stderr.on('data', (d) => (stderr += d));
      child.on('error', reject);
      child.on('exit', (code) => {
        if (code !== 0) reject(new Error(`imunoise ${args.join(' ')} exited ${code}:\n${stderr}`));
        else resolve({ stdout, stderr });
      });
      onSpawn?.(child);
    });
  }

  async json(args) {
    return JSON.parse((await this.imunoise([...args, '--json'])).stdout);
  }

  /** Resolves once the emulated clock passes `us`. */
  emulatedTime(us) {
    return new Promise((resolve) => {
      const check = () => (this.board.nowUs() >= us ? resolve() : setTimeout(check, 20));
      check();
    });
  }

  /**
   * Resolves once the firmware's log has a line containing `text`; rejects if the emulated
   * clock first passes `withinUs` more microseconds (the log reaches defmt-print a slice
   * after the firmware writes it, and defmt-print's output comes later still).
   */
  firmwareSays(text, withinUs = 5_000_000) {
    const deadline = this.board.nowUs() + withinUs;
    return new Promise((resolve, reject) => {
      const check = () => {
        const line = this.firmwareLog.find((l) => l.includes(text));
        if (line) resolve(line);
        else if (this.board.nowUs() > deadline) {
          reject(new Error(`the firmware's log has no "${text}":\n${this.firmwareLog.join('\n')}`));
        } else setTimeout(check, 20);
      };
      check();
    });
  }

  /** Capture with the given options, timing it in emulated and wall seconds. */
  async capture(name, rate, bandwidth, duration, during) {
    const startUs = this.board.nowUs();
    const wallStart = performance.now();
    let child;
    const done = this.imunoise(
      ['capture', '--port', this.pty, '--rate', String(rate), '--bandwidth', String(bandwidth), '--duration', duration, '--name', name],
      { onSpawn: (c) => (child = c) },
    );
    await during?.(child);
    const result = await done;
    const emulatedS = (this.board.nowUs() - startUs) / 1e6;
    const wallS = (performance.now() - wallStart) / 1e3;
    this.speed.emulatedS += emulatedS;
    this.speed.wallS += wallS;
    console.error(`[test] ${name}: ${emulatedS.toFixed(2)} s emulated in ${wallS.toFixed(1)} s wall`);
    return result;
  }

  /** A session's raw counts (`imunoise export --units counts`), with the journal flushed. */
  async counts(name) {
    this.board.device.ask(`f ${this.board.nowUs()}`);
    return (await this.imunoise(['export', name, '--units', 'counts'])).stdout;
  }
}
