// The simulated device's journal (host/src/sim/bus_server.rs): what the MPU-6050 really
// made, to hold a capture against.

import fs from 'node:fs';

/**
 * FIFO epochs: each FIFO reset opens one; its samples are those the device appended to the
 * FIFO afterwards, in order, each { t: us, counts: [gx, gy, gz, ax, ay, az, temp] } (the
 * column order of `imunoise export --units counts`).
 */
export function readJournal(file) {
  const epochs = [];
  let current = null;
  for (const line of fs.readFileSync(file, 'utf8').split('\n')) {
    if (!line) continue;
    const f = line.split(',');
    if (f[0] === 'reset') {
      current = { resetUs: Number(f[1]), samples: [] };
      epochs.push(current);
    } else if (f[0] === 'sample' && f[2] === '1' && current) {
      const [ax, ay, az, temp, gx, gy, gz] = f.slice(3).map(Number);
      current.samples.push({ t: Number(f[1]), counts: [gx, gy, gz, ax, ay, az, temp] });
    }
  }
  return epochs;
}

/** `imunoise export --units counts` output: rows { index, counts } and the gap comments. */
export function readCounts(text) {
  const rows = [];
  const gaps = [];
  for (const line of text.split('\n')) {
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
