// The simulated chips' journal (host/src/sim/bus_server.rs): what each chip really made,
// to hold a capture against.

import fs from 'node:fs';

/**
 * The chips, each with its address, which of its samples a stream can hold (those put in
 * its FIFO, or every one for a chip without a FIFO), and its journal counts in the column
 * order of `imunoise export --units counts`.
 */
export const CHIPS = {
  mpu6050: { address: 0x68, fifo: true, counts: ([ax, ay, az, temp, gx, gy, gz]) => [gx, gy, gz, ax, ay, az, temp] },
  itg3200: { address: 0x68, fifo: false, counts: ([, , , temp, gx, gy, gz]) => [gx, gy, gz, temp] },
  adxl345: { address: 0x53, fifo: true, counts: ([ax, ay, az]) => [ax, ay, az] },
};

/**
 * FIFO epochs of one chip: each FIFO reset opens one (and power-up the first); its samples
 * are those the chip could stream afterwards, in order, each { t: us, counts }.
 */
export function readJournal(file, chip = CHIPS.mpu6050) {
  const epochs = [];
  let current = null;
  const open = (resetUs) => {
    current = { resetUs, samples: [] };
    epochs.push(current);
  };
  for (const line of fs.readFileSync(file, 'utf8').split('\n')) {
    if (!line) continue;
    const f = line.split(',');
    if (Number(f.at(-1)) !== chip.address) continue;
    if (f[0] === 'reset') open(Number(f[1]));
    else if (f[0] === 'sample' && (f[2] === '1' || !chip.fifo)) {
      if (!current) open(0);
      current.samples.push({ t: Number(f[1]), counts: chip.counts(f.slice(3, 10).map(Number)) });
    }
  }
  return epochs;
}

/**
 * `imunoise export --units counts` output: rows { index, counts } and the gap comments; of
 * a board with several sensors, those of sensor `sensor`.
 */
export function readCounts(text, sensor = null) {
  const rows = [];
  const gaps = [];
  let current = null;
  for (const line of text.split('\n')) {
    const heading = /^# sensor (\d+):/.exec(line);
    if (heading) current = Number(heading[1]);
    if (sensor !== null && current !== sensor) continue;
    if (!line || line.startsWith('index')) continue;
    const gap = /^# gap: (\d+) samples lost at index (\d+)/.exec(line);
    if (gap) gaps.push({ lost: Number(gap[1]), at: Number(gap[2]) });
    if (line.startsWith('#')) continue;
    const [index, ...counts] = line.split(',').map(Number);
    rows.push({ index, counts });
  }
  return { rows, gaps };
}

const same = (a, b) => a.length === b.length && a.every((v, i) => v === b[i]);

/**
 * Hold received rows against the journal: the epoch whose sample 0 is the first row's
 * sample (a start resets the FIFO, so sample i of the run is sample i of that epoch), and
 * every row against the epoch's sample at the row's index.
 */
export function compare(rows, epochs) {
  if (rows.length === 0) return { epoch: null, mismatches: 0, checked: 0 };
  const first = rows[0];
  const epoch = epochs.findLast((e) => e.samples[first.index] && same(e.samples[first.index].counts, first.counts));
  if (!epoch) return { epoch: null, mismatches: rows.length, checked: rows.length };
  let mismatches = 0;
  let firstMismatch = null;
  for (const row of rows) {
    const truth = epoch.samples[row.index];
    if (!truth || !same(truth.counts, row.counts)) {
      mismatches++;
      firstMismatch ??= { row, truth: truth?.counts };
    }
  }
  return { epoch, mismatches, firstMismatch, checked: rows.length };
}

/**
 * Hold received rows against a chip's samples when the stream's index 0 is not the first
 * sample of an epoch (a chip without a FIFO reset to mark it): where the first rows are, in
 * the latest place they all match, then every row against the sample at its index from
 * there.
 */
export function compareFrom(rows, samples) {
  if (rows.length === 0) return { offset: null, mismatches: 0, checked: 0 };
  const probe = rows.slice(0, 16);
  const base = rows[0].index;
  let offset = null;
  for (let p = samples.length - 1; p >= 0 && offset === null; p--) {
    if (probe.every((r) => samples[p + r.index - base] && same(samples[p + r.index - base].counts, r.counts))) offset = p - base;
  }
  if (offset === null) return { offset, mismatches: rows.length, checked: rows.length };
  let mismatches = 0;
  let firstMismatch = null;
  for (const row of rows) {
    const truth = samples[offset + row.index];
    if (!truth || !same(truth.counts, row.counts)) {
      mismatches++;
      firstMismatch ??= { row, truth: truth?.counts };
    }
  }
  return { offset, mismatches, firstMismatch, checked: rows.length };
}
