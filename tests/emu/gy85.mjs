// The emulated-board tests with a GY-85 on the bus (run by tests/emu/run): the release
// firmware image on rp2040js, imunoise's simulated ITG-3200 (0x68) and ADXL345 (0x53) on
// its one I2C bus, and the unmodified host CLI capturing through a pseudo-terminal.
//
//   1. the image probes both chips: its log and `imunoise info` list them;
//   2. 50 Hz / 20 Hz for 10 s of emulated time: every sample each chip made arrives, in
//      order, bit-exact, none lost, and the session analyses as gx gy gz ax ay az temp;
//   3. an ADXL345 outage mid-capture: sensor 1 reports it and recovers, the gap is in its
//      stream only, and the ITG-3200's stream goes on whole.

import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { Testbed } from './lib/testbed.mjs';
import { CHIPS, compareFrom, readCounts, readJournal } from './lib/journal.mjs';

const bed = new Testbed({ board: 'gy85', seed: 11 });
const { board } = bed;
const [RATE, BANDWIDTH] = [50, 20];
const SENSORS = [
  { number: 0, name: 'ITG-3200', chip: CHIPS.itg3200 },
  { number: 1, name: 'ADXL345', chip: CHIPS.adxl345 },
];

/** Each sensor's rows of a session, held against what its chip made. */
async function received(name) {
  const text = await bed.counts(name);
  return SENSORS.map(({ number, chip }) => {
    const { rows, gaps } = readCounts(text, number);
    const [epoch] = readJournal(bed.journalFile, chip);
    return { rows, gaps, samples: epoch.samples, ...compareFrom(rows, epoch.samples) };
  });
}

before(() => bed.start());
after(() => bed.stop());

test('1. the image probes the ITG-3200 at 0x68 and the ADXL345 at 0x53', async () => {
  for (const { name, chip } of SENSORS) await bed.firmwareSays(`sensor ${name} at 0x${chip.address.toString(16)}`);
  const info = await bed.json(['info', '--port', bed.pty]);
  assert.equal(info.info.protocol_version, info.host_protocol_version);
  const listed = info.info.sensors.map((s) => [s.kind, s.address, s.id]);
  assert.deepEqual(listed, [
    ['Itg3200', 0x68, 0x68],
    ['Adxl345', 0x53, 0xe5],
  ]);
});

const SECONDS = Number(process.env.EMU_SECONDS ?? 10);

test(`2. ${RATE} Hz / ${BANDWIDTH} Hz for ${SECONDS} s: every sample of both chips, bit-exact, none lost`, async () => {
  const name = 'emu-gy85';
  await bed.capture(name, RATE, BANDWIDTH, `${SECONDS}s`);
  const show = await bed.json(['show', name]);
  assert.deepEqual(show.losses.gaps, [], 'no gap in the gyro');
  assert.deepEqual(show.losses.other_sensors, [{ sensor: 1, kind: 'ADXL345', gaps: [] }]);
  assert.deepEqual(show.losses.board_errors, []);
  const wanted = RATE * SECONDS;
  for (const [k, got] of (await received(name)).entries()) {
    const what = SENSORS[k].name;
    assert.equal(got.rows[0].index, 0, what);
    assert.equal(got.rows.at(-1).index, got.rows.length - 1, `${what}: indices 0..n-1, each once`);
    assert.ok(
      got.rows.length >= wanted && got.rows.length < wanted + 32,
      `${what}: ${got.rows.length} samples for ${wanted} wanted (rate x time, plus at most the rest of a 32-sample batch)`,
    );
    assert.notEqual(got.offset, null, `${what}: the first samples received are among those the chip made`);
    assert.equal(got.mismatches, 0, `${what}: samples differing from the chip's: ${JSON.stringify(got.firstMismatch)}`);
    // Each chip made its samples on its own exact period (no clock fault in the model).
    const span = got.samples[got.offset + got.rows.length - 1].t - got.samples[got.offset].t;
    assert.ok(Math.abs(span - ((got.rows.length - 1) * 1e6) / RATE) <= 1, `${what}: span ${span} us`);
    console.error(`[test] ${what}: ${got.checked} samples held against the chip's journal, ${got.mismatches} differ`);
  }
  const analysis = JSON.parse((await bed.imunoise(['analyze', name, '--json', '-'])).stdout);
  assert.deepEqual(
    analysis.channels.map((c) => c.name),
    ['gx', 'gy', 'gz', 'ax', 'ay', 'az', 'temp'],
  );
});

test('3. an ADXL345 outage: sensor 1 reports it and recovers, the gyro streams on', async () => {
  const name = 'emu-gy85-outage';
  await bed.capture(name, RATE, BANDWIDTH, '6s', async () => {
    await bed.emulatedTime(board.nowUs() + 1_500_000);
    board.device.ask(`o ${board.nowUs()} 1000000 ${CHIPS.adxl345.address}`);
  });
  const show = await bed.json(['show', name]);
  const faults = show.losses.board_errors.map((e) => [e.sensor, e.refused_seq, e.error]);
  assert.deepEqual(faults, [[1, null, 'SensorNotResponding']]);
  assert.deepEqual(show.losses.recoveries.map((r) => r.sensor), [1]);
  assert.deepEqual(show.losses.gaps, [], 'the gyro lost nothing');
  const [{ gaps }] = show.losses.other_sensors;
  assert.equal(gaps.length, 1, JSON.stringify(gaps));
  const lost = gaps[0][1] - gaps[0][0];
  // 1 s, plus the 0.5 s the firmware waits before it calls it a fault, plus at most one
  // backoff step.
  assert.ok(lost >= RATE && lost <= 2.5 * RATE, `outage cost ${lost} samples`);
  const [gyro, accel] = await received(name);
  assert.equal(gyro.mismatches, 0, `gyro: ${JSON.stringify(gyro.firstMismatch)}`);
  assert.equal(gyro.rows.at(-1).index, gyro.rows.length - 1, 'gyro: every index once');
  assert.deepEqual(accel.gaps, [{ lost, at: gaps[0][0] }], 'the export marks the gap');
  // Either side of the gap, every accelerometer sample is the chip's own, and the gap is the
  // time the chip's clock says passed: the first sample after it was made (lost + 1)
  // periods after the last one before it, to within the period in which the board may not
  // know whether the sample at the FIFO's restart was kept.
  const [beforeGap, afterGap] = [(r) => r.index < gaps[0][0], (r) => r.index >= gaps[0][1]].map((side) => {
    const rows = accel.rows.filter(side);
    return { rows, ...compareFrom(rows, accel.samples) };
  });
  for (const part of [beforeGap, afterGap]) {
    assert.equal(part.mismatches, 0, `accelerometer from index ${part.rows[0].index}: ${JSON.stringify(part.firstMismatch)}`);
  }
  const lastT = accel.samples[beforeGap.offset + beforeGap.rows.at(-1).index].t;
  const firstT = accel.samples[afterGap.offset + afterGap.rows[0].index].t;
  const periodUs = 1e6 / RATE;
  assert.ok(
    Math.abs(firstT - lastT - (lost + 1) * periodUs) <= 1.5 * periodUs,
    `${firstT - lastT} us between the samples around the gap, ${(lost + 1) * periodUs} us by the indices`,
  );
  console.error(`[test] ADXL345 outage of 1 s: ${lost} samples lost by sensor 1, none by sensor 0; the gap ${firstT - lastT - (lost + 1) * periodUs} us from the indices' time`);
});
