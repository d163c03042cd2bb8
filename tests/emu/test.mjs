// The emulated-board tests (run by tests/emu/run): the release firmware image on rp2040js,
// imunoise's simulated MPU-6050 on its I2C bus, and the unmodified host CLI capturing
// through a pseudo-terminal.
//
//   1. handshake: info and protocol version through the pty;
//   2. the settings study's four settings (docs/references.md), 10 s of emulated time
//      each: every sample the sensor put in its FIFO arrives, in order, bit-exact, none lost;
//   3. a stall (IN transfers refused for longer than the FIFO and the firmware's queue
//      hold): the firmware's loss count equals the gap the host sees, every sample after
//      the gap is the sensor's sample of that index, and streaming recovers;
//   4. refusals while streaming (Configure, an unknown command): nacked by seq, and the
//      capture goes on without a loss;
//   5. an I2C outage and a sensor reset mid-capture: the firmware reports each, brings the
//      sensor back, and numbers the samples on from where the sensor's clock is, so each
//      gap is the time lost and every sample on either side is the device's own.

import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { Testbed } from './lib/testbed.mjs';
import { COMMAND, frame, requests, varint } from './lib/frames.mjs';
import { compare, readCounts, readJournal } from './lib/journal.mjs';

const bed = new Testbed({ seed: 7 });
const { pty, journalFile } = bed;
const board = bed.board;
const json = (args) => bed.json(args);
const emulatedTime = (us) => bed.emulatedTime(us);
const capture = (...args) => bed.capture(...args);

/** A session's samples as raw counts, held against what the simulated device made. */
async function received(name) {
  const counts = readCounts(await bed.counts(name));
  return { ...counts, ...compare(counts.rows, readJournal(journalFile)) };
}

before(() => bed.start());
after(() => bed.stop());

test('1. handshake: info and protocol version through the pty', async () => {
  const info = await json(['info', '--port', pty]);
  assert.equal(info.info.protocol_version, info.host_protocol_version);
  assert.equal(info.info.who_am_i, 0x68, 'the simulated MPU-6050 answers WHO_AM_I');
  assert.equal(info.info.board_id, '0x0000000000000000', 'the emulator build reports board id 0 (no flash chip)');
  assert.equal(info.info.streaming, false);
  assert.equal(info.info.max_samples_per_batch, 32);
  assert.ok(info.status.uptime_us > 0);
});

/** Emulated seconds per setting (EMU_SECONDS shortens it while developing). */
const SECONDS = Number(process.env.EMU_SECONDS ?? 10);

for (const [rate, bandwidth] of [
  [200, 256],
  [200, 42],
  [50, 256],
  [50, 42],
]) {
  test(`2. ${rate} Hz / ${bandwidth} Hz for ${SECONDS} s: every sample, bit-exact, none lost`, async () => {
    const name = `emu-${rate}-${bandwidth}`;
    await capture(name, rate, bandwidth, `${SECONDS}s`);
    const show = await json(['show', name]);
    const wanted = rate * SECONDS;
    assert.deepEqual(show.losses.gaps, [], 'no gap in the indices');
    assert.deepEqual(show.losses.board_errors, []);
    const got = await received(name);
    assert.ok(got.epoch, 'the first sample received is a sample the device made after a FIFO reset');
    assert.equal(got.rows[0].index, 0);
    assert.equal(got.rows.at(-1).index, got.rows.length - 1, 'indices 0..n-1, each once');
    // --duration stops at rate x time samples; the batch that crosses it is kept whole.
    assert.ok(
      got.rows.length >= wanted && got.rows.length < wanted + 32,
      `${got.rows.length} samples for ${wanted} wanted (rate x time, plus at most the rest of a 32-sample batch)`,
    );
    assert.equal(got.mismatches, 0, `samples differing from the device's: ${JSON.stringify(got.firstMismatch)}`);
    // The device made its samples on its own exact period (the firmware's grid is held to
    // it): rate x time, exactly, over the samples received.
    const { samples } = got.epoch;
    const spanUs = samples[got.rows.length - 1].t - samples[0].t;
    assert.ok(Math.abs(spanUs - ((got.rows.length - 1) * 1e6) / rate) <= 1, `span ${spanUs} us`);
  });
}

test('3. a stall longer than the FIFO and the queue hold: exact loss count, then recovery', async () => {
  const before = (await json(['info', '--port', pty])).status;
  const rate = 1000;
  // The sensor's FIFO holds 73 samples (73 ms at 1 kHz) and the firmware's USB queue 4 KiB
  // (about 280 ms of batches): 600 ms without IN transfers must lose samples.
  const stallUs = 600_000;
  await capture('emu-stall', rate, 188, '4s', async (child) => {
    await emulatedTime(board.nowUs() + 1_000_000);
    // The host stops reading: its process is stopped while its USB buffers stay full.
    child.kill('SIGSTOP');
    board.holdIn(stallUs);
    await emulatedTime(board.nowUs() + stallUs);
    child.kill('SIGCONT');
  });
  const after = (await json(['info', '--port', pty])).status;
  const show = await json(['show', 'emu-stall']);
  const lost = show.losses.gaps.reduce((n, [start, end]) => n + end - start, 0);
  const dropped = after.samples_dropped - before.samples_dropped;
  const overflowLost = after.samples_lost - before.samples_lost;
  assert.ok(lost > 0, 'the stall lost samples');
  assert.equal(lost, dropped + overflowLost, "the host's gap count equals the firmware's loss report");
  const got = await received('emu-stall');
  assert.equal(got.mismatches, 0, `after the gap too, sample i is the device's sample i: ${JSON.stringify(got.firstMismatch)}`);
  assert.equal(got.rows.length + lost, got.rows.at(-1).index + 1, 'received + lost = made');
  const afterGap = got.rows.filter((r) => r.index >= show.losses.gaps.at(-1)[1]).length;
  assert.ok(afterGap >= rate, `streaming recovered: ${afterGap} samples after the gap`);
  console.error(`[test] stall of ${stallUs / 1000} ms: ${lost} samples lost (${dropped} dropped from the USB queue, ${overflowLost} in FIFO overflows), ${afterGap} received after it`);
});

test('4. Configure and an unknown command while streaming: nacked, capture goes on', async () => {
  const sentBefore = board.fromHost.length;
  const unknownSeq = 4242;
  let configureSeq;
  await capture('emu-refusals', 200, 42, '5s', async () => {
    await emulatedTime(board.nowUs() + 1_500_000);
    // The host's own Configure frame from setting up this capture, sent again while streaming.
    const configure = requests(board.fromHost.slice(sentBefore)).findLast((r) => r.command === COMMAND.Configure);
    assert.ok(configure, 'the host configured the board');
    board.inject(configure.wire);
    // An intact frame with a command variant this protocol does not have.
    board.inject(frame([...varint(unknownSeq), 99]));
    configureSeq = configure.seq;
  });
  const show = await json(['show', 'emu-refusals']);
  const refusals = show.losses.board_errors.map((e) => [e.refused_seq, e.error]);
  assert.deepEqual(refusals, [
    [configureSeq, 'Busy'],
    [unknownSeq, 'UnknownCommand'],
  ]);
  assert.deepEqual(show.losses.gaps, [], 'no sample lost');
  const got = await received('emu-refusals');
  assert.equal(got.mismatches, 0);
  assert.ok(got.rows.length >= 1000, `${got.rows.length} samples`);
  assert.ok(show.losses.board_errors[0].at_index < got.rows.length - 200, 'samples kept coming after the refusals');
});

/**
 * Rows split at the session's gaps, each piece held against the journal epoch it came from
 * (a recovery restarts the FIFO, so a piece's first index is its epoch's sample 0).
 */
function pieces(rows, gaps, epochs) {
  const bounds = [0, ...gaps.flatMap(([start, end]) => [start, end]), Infinity];
  const out = [];
  for (let k = 0; k < bounds.length; k += 2) {
    const [from, to] = [bounds[k], bounds[k + 1]];
    const part = rows.filter((r) => r.index >= from && r.index < to);
    const shifted = part.map((r) => ({ index: r.index - part[0].index, counts: r.counts }));
    out.push({ first: part[0].index, last: part.at(-1).index, ...compare(shifted, epochs) });
  }
  return out;
}

test('5. an I2C outage and a sensor reset: reported, recovered, the gaps are the time lost', async () => {
  const rate = 200;
  const periodUs = 1e6 / rate;
  await capture('emu-faults', rate, 42, '8s', async () => {
    await emulatedTime(board.nowUs() + 1_500_000);
    board.device.ask(`o ${board.nowUs()} 1000000`);
    await emulatedTime(board.nowUs() + 3_000_000);
    board.device.ask(`x ${board.nowUs()}`);
  });
  const show = await json(['show', 'emu-faults']);
  const faults = show.losses.board_errors.filter((e) => e.refused_seq === null).map((e) => e.error);
  assert.deepEqual(faults, ['SensorNotResponding', 'SensorReset']);
  assert.equal(show.losses.recoveries.length, 2);
  const gaps = show.losses.gaps;
  assert.equal(gaps.length, 2, JSON.stringify(gaps));
  const [outage, reset] = gaps.map(([start, end]) => end - start);
  // The outage: 1 s, plus the 0.5 s the firmware waits before it calls it a fault, plus at
  // most one backoff step; the reset: found within a drain or a second's read-back.
  assert.ok(outage >= rate && outage <= 2.5 * rate, `outage cost ${outage} samples`);
  assert.ok(reset <= 1.5 * rate, `reset cost ${reset} samples`);
  const rows = readCounts(await bed.counts('emu-faults')).rows;
  const epochs = readJournal(journalFile);
  const parts = pieces(rows, gaps, epochs);
  for (const part of parts) {
    assert.ok(part.epoch, `piece from index ${part.first}: found among the device's samples`);
    assert.equal(part.mismatches, 0, `piece from index ${part.first}: ${JSON.stringify(part.firstMismatch)}`);
  }
  // Each gap is the time the sensor's clock says passed: the first sample after it was made
  // (gap + 1) periods after the last one before it. Through the outage the sensor kept its
  // sampling grid, so that holds to the sample. A reset restarts the sensor's sampling at a
  // new phase: the resumed run's first index is the old grid's count when the FIFO reset
  // began, and its first sample comes within a period after the reset ended, so the two
  // differ by less than a period plus the reset's bus time (under a millisecond: four
  // register transfers at 400 kHz).
  // The outage's index is exact unless a sample fell within the bus time of the write that
  // restarted the FIFO, which the board then reports (`loss_certain` false).
  const { loss_certain: certain } = (await json(['info', '--port', pty])).status;
  const tolerancesUs = [certain ? periodUs / 2 : periodUs * 1.5, periodUs + 1000];
  for (let k = 0; k < 2; k++) {
    const before = parts[k];
    const after = parts[k + 1];
    const lastT = before.epoch.samples[before.last - before.first].t;
    const firstT = after.epoch.samples[0].t;
    const expectedUs = (after.first - before.last) * periodUs;
    assert.ok(
      Math.abs(firstT - lastT - expectedUs) <= tolerancesUs[k],
      `gap ${k}: ${firstT - lastT} us between the samples around it, ${expectedUs} us by the indices (loss count certain: ${certain})`,
    );
    console.error(`[test] gap ${k}: ${firstT - lastT - expectedUs} us from the indices' time`);
  }
  console.error(`[test] outage of 1 s: ${outage} samples lost; sensor reset: ${reset} samples lost`);
});
