#!/usr/bin/env node
// Run the emulated board by hand, until Ctrl-C:
//
//   node tests/emu/harness.mjs [--elf ELF] [--imunoise BIN] [--pty PATH] [--seed N]
//                               [--board mpu6050|gy85] [--model FILE] [--journal FILE]
//
// then, in another terminal: imunoise capture --port PATH --rate 200 --bandwidth 42
// (the GY-85's chips: --rate 50 --bandwidth 20)
// Defaults are those `tests/emu/run` builds (see docs/guide/emulated-board.md).

import os from 'node:os';
import path from 'node:path';
import fs from 'node:fs';
import { parseArgs } from 'node:util';
import { EmulatedBoard } from './lib/board.mjs';
import { defaults } from './lib/paths.mjs';

const { values } = parseArgs({
  options: {
    elf: { type: 'string', default: defaults.elf },
    imunoise: { type: 'string', default: defaults.imunoise },
    pty: { type: 'string', default: path.join(os.tmpdir(), 'imunoise-emu-tty') },
    seed: { type: 'string', default: '1' },
    board: { type: 'string', default: 'mpu6050' },
    model: { type: 'string' },
    journal: { type: 'string' },
    'defmt-print': { type: 'string', default: defaults.defmtPrint },
  },
});

const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'imunoise-emu-'));
const board = new EmulatedBoard({
  elf: values.elf,
  imunoise: values.imunoise,
  dir,
  pty: values.pty,
  board: values.board,
  seed: Number(values.seed),
  model: values.model,
  journal: values.journal,
  defmtPrint: values['defmt-print'],
});
const tty = await board.openPty();
console.error(`[emu] board on ${values.pty} (${tty}); Ctrl-C stops`);
let stop = false;
process.on('SIGINT', () => (stop = true));
const wallStart = performance.now();
let lastReport = wallStart;
await board.run({
  until: () => {
    const now = performance.now();
    if (now - lastReport > (Number(process.env.EMU_REPORT_S) || 10) * 1000) {
      lastReport = now;
      const emulated = board.nowUs() / 1e6;
      const wall = (now - wallStart) / 1e3;
      console.error(`[emu] ${(emulated / wall).toFixed(2)} emulated s per wall s; ${board.state()}`);
    }
    return stop;
  },
});
await board.close();
fs.rmSync(dir, { recursive: true, force: true });
