// The chips on the emulated I2C bus (an MPU-6050, or a GY-85's ITG-3200 and ADXL345) are
// imunoise's own simulated ones (host/src/sim), served by `imunoise sim-device --stdio` in a
// child process, one line per bus event (protocol: host/src/sim/bus_server.rs). The
// emulator waits for each reply synchronously (blocking reads on named pipes), so emulated
// time stands still during a round trip and every event is stamped with the emulated time
// at which the firmware caused it.

import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

export class SimDevice {
  /**
   * @param {object} o
   * @param {string} o.imunoise path of the imunoise binary
   * @param {string} o.dir a private folder for the two named pipes
   * @param {string} [o.board] the chips on the bus: 'mpu6050' (default) or 'gy85'
   * @param {number} o.seed the device's random seed
   * @param {string} [o.model] a noise model file (default: the built-in example)
   * @param {string} [o.journal] where the chips write every FIFO reset and sample they made
   */
  constructor({ imunoise, dir, board = 'mpu6050', seed, model, journal }) {
    if (!fs.existsSync(imunoise)) throw new Error(`no imunoise binary at ${imunoise}`);
    const requests = path.join(dir, 'i2c-requests');
    const replies = path.join(dir, 'i2c-replies');
    for (const fifo of [requests, replies]) fs.rmSync(fifo, { force: true });
    execFileSync('mkfifo', [requests, replies]);
    const args = ['sim-device', '--stdio', '--board', board, '--seed', String(seed)];
    if (model) args.push('--model', model);
    if (journal) args.push('--journal', journal);
    // The shell opens the pipes in the order this process opens their other ends.
    this.child = spawn('sh', ['-c', 'exec "$0" "$@" <"$REQUESTS" >"$REPLIES"', imunoise, ...args], {
      env: { ...process.env, REQUESTS: requests, REPLIES: replies },
      stdio: ['ignore', 'ignore', 'inherit'],
    });
    this.exited = new Promise((resolve) => this.child.on('exit', (code) => resolve(code)));
    this.requestFd = fs.openSync(requests, 'w');
    this.replyFd = fs.openSync(replies, 'r');
    this.buffer = Buffer.alloc(4096);
    this.pending = '';
    this.events = 0;
    /** The last requests, for a log when the firmware stalls on the bus. */
    this.recent = [];
  }

  /** A request without a reply. */
  send(line) {
    fs.writeSync(this.requestFd, `${line}\n`);
    this.events++;
    this.recent.push(line);
    if (this.recent.length > 24) this.recent.shift();
  }

  /** A request and its one-line reply. */
  ask(line) {
    this.send(line);
    for (;;) {
      const nl = this.pending.indexOf('\n');
      if (nl >= 0) {
        const reply = this.pending.slice(0, nl);
        this.pending = this.pending.slice(nl + 1);
        if (reply.startsWith('!')) throw new Error(`sim-device refused ${JSON.stringify(line)}: ${reply}`);
        return reply;
      }
      const n = fs.readSync(this.replyFd, this.buffer, 0, this.buffer.length, null);
      if (n === 0) throw new Error('sim-device exited');
      this.pending += this.buffer.toString('latin1', 0, n);
    }
  }

  /** Close the pipes; the device writes the rest of its journal and exits. */
  async close() {
    fs.closeSync(this.requestFd);
    fs.closeSync(this.replyFd);
    const code = await this.exited;
    if (code !== 0) throw new Error(`sim-device exited with status ${code}`);
  }
}

/** Attach `device` to an rp2040js I2C controller: each bus event becomes one request. */
export function attachI2c(i2c, device, nowUs) {
  let repeated = false;
  i2c.onStart = (isRepeated) => {
    repeated = isRepeated;
    i2c.completeStart();
  };
  i2c.onConnect = (address) => {
    const reply = device.ask(`${repeated ? 'S' : 's'} ${nowUs()} ${address}`);
    if (reply === 'e') i2c.arbitrationLost();
    else i2c.completeConnect(reply === 'a');
  };
  i2c.onWriteByte = (byte) => i2c.completeWrite(device.ask(`w ${nowUs()} ${byte}`) === 'a');
  i2c.onReadByte = () => i2c.completeRead(Number(device.ask(`r ${nowUs()}`)));
  i2c.onStop = () => {
    device.send(`p ${nowUs()}`);
    i2c.completeStop();
  };
}
