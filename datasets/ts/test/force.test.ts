// The force field and marker flow reader (src/force.ts): hand-made samples (decoded messages as
// shard.ts groups them) for the layout, the pad order and each way of getting a field or a marker
// cloud wrong; then shards the Rust generator wrote with force fields (the MuJoCo backend), read
// with @mcap/core, every pad's cells held to the force /sample/info gives it, every optical pad's
// markers to their rest grid.
//
// Generated data: VTGEN_FORCE_DATASETS=<dataset dir>[:<another>...] reads datasets generated with
// robot.tactile.force_field; else VTGEN_MUJOCO_BIN=<vtgen built with --features mujoco> (run with the
// LD_LIBRARY_PATH of `eval "$(scripts/mujoco-setup)"`) generates scenes/tiny-gripper.yaml with
// `--set 'robot.tactile.force_field={resolution: 8}' --set robot.physics.backend=mujoco`. Without
// either the generated-data test is skipped (the default test binary has no MuJoCo).
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { delimiter, dirname, join, resolve } from "node:path";
import { after, describe, it } from "node:test";
import { fileURLToPath } from "node:url";

import type { Sample } from "../src/checks.js";
import {
  cellCentre,
  decodeForceField,
  decodeMarkerFlow,
  forceSum,
  readForceFields,
  readMarkerFlow,
  type ForceField,
  type MarkerFlow,
} from "../src/force.js";
import {
  FORCE_STRIDE,
  MARKER_STRIDE,
  PAD_FORCE_INFO_KEYS,
  TACTILE_FORCE_INFO_KEYS,
  forcePadOfTopic,
  forcePadsOf,
  isEpisodeStreamTopic,
  markersPadOfTopic,
  markersPadsOf,
  opticalPadsOf,
  padForceTopic,
  padImageTopic,
  padMarkersTopic,
  padsOf,
  robotTopics,
} from "../src/format.js";
import { readShard, type Decoded } from "../src/shard.js";

type Cell = { x: number; y: number; pressure: number; shear: [number, number]; slip: number };

function decoded(topic: string, channelId: number, value: Record<string, unknown>): Decoded {
  return { topic, channelId, logTime: 0n, publishTime: 0n, sequence: 0, value };
}

/** A decoded foxglove.PointCloud of force cells, packed as FORMAT.md lays them out. */
function cloud(cells: readonly Cell[]): Record<string, unknown> {
  const data = new Uint8Array(cells.length * FORCE_STRIDE);
  const view = new DataView(data.buffer);
  cells.forEach((c, k) => {
    const at = k * FORCE_STRIDE;
    [c.x, c.y, 0, c.pressure, c.shear[0], c.shear[1]].forEach((v, j) => view.setFloat32(at + 4 * j, v, true));
    view.setUint32(at + 24, c.slip, true);
  });
  return { frame_id: "x_pad", point_stride: FORCE_STRIDE, data };
}

/** An r x r grid over a `length` x `width` pad: cell k has pressure 10 k (Pa), shear (k, -2k), and
 * slips where k is odd; `seed` shifts the values, so two pads differ. */
function grid(r: number, seed = 0, length = 0.02, width = 0.015): Cell[] {
  const cells: Cell[] = [];
  for (let v = 0; v < r; v++) {
    for (let u = 0; u < r; u++) {
      const k = v * r + u + seed;
      const [x, y] = cellCentre(u, v, r, length, width);
      cells.push({ x, y, pressure: 10 * k, shear: [k, -2 * k], slip: k % 2 });
    }
  }
  return cells;
}

/** A sample of a robot with `pads` (depth channels 10, 11, ...) whose pads `forced` have a force
 * field of `r` x `r` cells (channels after the depth ones, in pad order), messages in reverse;
 * `info`: its /sample/info `tactile` keys (default: `forces` listing `forced`; null: no tactile). */
function sample(pads: string[], forced: string[], r = 3, info?: Record<string, unknown> | null): Sample {
  const entries: [string, Decoded[]][] = [];
  let channel = 10;
  for (const pad of pads) {
    entries.push([`/tactile/${pad}/depth`, [decoded(`/tactile/${pad}/depth`, channel++, { encoding: "32FC1" })]]);
  }
  forced.forEach((pad, k) => {
    entries.push([padForceTopic(pad), [decoded(padForceTopic(pad), channel++, cloud(grid(r, 100 * k)))]]);
  });
  const tactile = info === null ? {} : { tactile: { pads: {}, ...(info ?? { forces: Object.fromEntries(forced.map((p) => [p, {}])) }) } };
  entries.push(["/sample/info", [decoded("/sample/info", 7, tactile)]]);
  return new Map(entries.reverse());
}

describe("force field topics (format.ts)", () => {
  it("names a pad's force topic, parses it back and lists the pads by channel", () => {
    assert.equal(padForceTopic("left"), "/tactile/left/force");
    assert.equal(forcePadOfTopic("/tactile/ff_distal/force"), "ff_distal");
    assert.equal(forcePadOfTopic("/tactile/ff_distal/depth"), undefined);
    assert.equal(forcePadOfTopic("/tactile/a/b/force"), undefined);
    const channels = [
      { id: 17, topic: "/tactile/left/force" },
      { id: 16, topic: "/tactile/right/force" },
      { id: 11, topic: "/tactile/left/depth" },
    ];
    assert.deepEqual(forcePadsOf(channels), ["right", "left"]);
    assert.deepEqual(Object.keys(robotTopics(["right", "left"], ["right"], ["right", "left"])), [
      "/tactile/points",
      "/tactile/right/depth",
      "/tactile/left/depth",
      "/tactile/right/image",
      "/tactile/right/reference",
      "/tactile/right/force",
      "/tactile/left/force",
    ]);
    assert.equal(robotTopics(["left"], [], ["left"])["/tactile/left/force"], "foxglove.PointCloud");
    assert.ok(isEpisodeStreamTopic("/tactile/left/force"), "a touch reading between frames carries its force fields");
  });
});

describe("decodeForceField and readForceFields", () => {
  it("reads every cell: centre, pressure, shear, slip, row-major", () => {
    const cells = grid(3);
    const field = decodeForceField(cloud(cells), "here");
    assert.equal(field.resolution, 3);
    cells.forEach((c, k) => {
      assert.deepEqual([field.position[2 * k], field.position[2 * k + 1]], [Math.fround(c.x), Math.fround(c.y)]);
      assert.equal(field.pressure[k], c.pressure);
      assert.deepEqual([field.shear[2 * k], field.shear[2 * k + 1]], c.shear);
      assert.equal(field.slip[k], c.slip);
    });
    // Cell (u, v) = (2, 0) is point 2: the last column of the first row, at +x, -y.
    assert.ok(field.position[4]! > 0 && field.position[5]! < 0);
    const one = decodeForceField(cloud([{ x: 0, y: 0, pressure: 4, shear: [1, 2], slip: 7 }]), "here");
    assert.deepEqual([one.resolution, one.slip[0]], [1, 1]);
  });

  it("sums the cells times the cell area to the pad's force", () => {
    const field = decodeForceField(cloud(grid(2)), "here");
    // pressures 0, 10, 20, 30; shear x 0..3, y 0..-6; cell area 0.02 · 0.015 / 4.
    const area = (0.02 * 0.015) / 4;
    const [x, y, z] = forceSum(field, 0.02, 0.015);
    assert.ok(Math.abs(x - 6 * area) < 1e-15 && Math.abs(y + 12 * area) < 1e-15 && Math.abs(z + 60 * area) < 1e-15, `${x} ${y} ${z}`);
  });

  it("rejects a grid that is not square, a wrong stride and an empty cloud, naming the topic", () => {
    assert.throws(() => decodeForceField(cloud(grid(3).slice(0, 6)), "sample 2 /tactile/left/force"), /^Error: sample 2 \/tactile\/left\/force: 6 force cells, not a square R x R grid \(R >= 1\)$/);
    assert.throws(() => decodeForceField(cloud([]), "e"), /e: 0 force cells, not a square/);
    assert.throws(() => decodeForceField({ point_stride: 20, data: new Uint8Array(80) }, "s"), /s: expected 28-byte force cells, got point stride 20 and 80 bytes of data/);
    const short = cloud(grid(2));
    short.data = (short.data as Uint8Array).subarray(1);
    assert.throws(() => decodeForceField(short, "t"), /t: expected 28-byte force cells, got point stride 28 and 111 bytes/);
  });

  it("reads every pad's field in channel order (not name order), only with force topics", () => {
    const fields = readForceFields(sample(["right", "left"], ["right", "left"]), "here", ["right", "left"]);
    assert.deepEqual([...fields.keys()], ["right", "left"]);
    assert.equal(fields.get("left")!.pressure[0], 1000); // the second pad's grid: seed 100
    assert.equal(readForceFields(sample(["left"], [], 3, null), "here").size, 0);
  });

  it("holds the fields against /sample/info tactile.forces, the sample's pads and one resolution", () => {
    assert.throws(
      () => readForceFields(sample(["left", "right"], ["left"], 3, { forces: { left: {}, right: {} } }), "here"),
      /here: \/sample\/info tactile\.forces lists the pads \[left, right\], the sample has force fields of \[left\]/,
    );
    assert.throws(
      () => readForceFields(sample(["left"], ["left"]), "here", ["right"]),
      /here: force fields of left, which are not pads of the sample \(no \/tactile\/<pad>\/depth; pads: right\)/,
    );
    const mixed = sample(["left", "right"], ["left", "right"]);
    mixed.set(padForceTopic("right"), [decoded(padForceTopic("right"), 13, cloud(grid(2)))]);
    assert.throws(() => readForceFields(mixed, "here"), /here: the pads' force fields differ in resolution: left 3x3, right 2x2/);
    const bad = sample(["left"], ["left"]);
    bad.set(padForceTopic("left"), [decoded(padForceTopic("left"), 11, cloud(grid(3).slice(1)))]);
    assert.throws(() => readForceFields(bad, "sample 4"), /sample 4 \/tactile\/left\/force: 8 force cells/);
  });
});

// ---- marker flow -------------------------------------------------------------------------------

type Marker = { x: number; y: number; rest: [number, number] };

/** A decoded foxglove.PointCloud of markers, packed as FORMAT.md lays them out (z = 0). */
function markerCloud(markers: readonly Marker[]): Record<string, unknown> {
  const data = new Uint8Array(markers.length * MARKER_STRIDE);
  const view = new DataView(data.buffer);
  markers.forEach((m, k) => {
    [m.x, m.y, 0, m.rest[0], m.rest[1]].forEach((v, j) => view.setFloat32(k * MARKER_STRIDE + 4 * j, v, true));
  });
  return { frame_id: "x_pad", point_stride: MARKER_STRIDE, data };
}

/** `n` markers at rest 1 mm apart along x (rows of 4 along y), marker k moved by (k, -k) · 0.1 mm
 * plus `seed` · 1 mm, so two pads differ. */
function markerRow(n: number, seed = 0): Marker[] {
  return Array.from({ length: n }, (_, k) => {
    const rest: [number, number] = [(k % 4) * 1e-3, Math.floor(k / 4) * 1e-3];
    return { x: rest[0] + k * 1e-4 + seed * 1e-3, y: rest[1] - k * 1e-4, rest };
  });
}

/** A sample of a robot with `pads` (depth channels 10, 11, ...), optical pads `optical` (an image
 * each) of which `printed` have markers, `{pad: count}` (channels after the images, in the order
 * given), messages in reverse; `info`: its /sample/info `tactile` keys (default: `optical` listing
 * the optical pads, each sensor with markers). */
function markerSample(pads: string[], optical: string[], printed: Record<string, number>, info?: Record<string, unknown>): Sample {
  const entries: [string, Decoded[]][] = [];
  let channel = 10;
  for (const pad of pads) {
    entries.push([`/tactile/${pad}/depth`, [decoded(`/tactile/${pad}/depth`, channel++, { encoding: "32FC1" })]]);
  }
  for (const pad of optical) {
    entries.push([padImageTopic(pad), [decoded(padImageTopic(pad), channel++, { encoding: "rgb8" })]]);
  }
  Object.entries(printed).forEach(([pad, n], k) => {
    entries.push([padMarkersTopic(pad), [decoded(padMarkersTopic(pad), channel++, markerCloud(markerRow(n, k)))]]);
  });
  const sensors = Object.fromEntries(optical.map((pad) => [pad, { markers: { pitch_mm: 1.0 } }]));
  entries.push(["/sample/info", [decoded("/sample/info", 7, { tactile: { pads: {}, ...(info ?? { optical: sensors }) } })]]);
  return new Map(entries.reverse());
}

describe("marker flow topics (format.ts)", () => {
  it("names a pad's markers topic, parses it back and lists the pads by channel", () => {
    assert.equal(padMarkersTopic("left"), "/tactile/left/markers");
    assert.equal(markersPadOfTopic("/tactile/ff_distal/markers"), "ff_distal");
    assert.equal(markersPadOfTopic("/tactile/ff_distal/force"), undefined);
    assert.equal(markersPadOfTopic("/tactile/a/b/markers"), undefined);
    const channels = [
      { id: 19, topic: "/tactile/left/markers" },
      { id: 18, topic: "/tactile/right/markers" },
      { id: 17, topic: "/tactile/left/force" },
    ];
    assert.deepEqual(markersPadsOf(channels), ["right", "left"]);
    assert.deepEqual(Object.keys(robotTopics(["right", "left"], ["right", "left"], ["right", "left"], ["right", "left"])).slice(-4), [
      "/tactile/right/force",
      "/tactile/left/force",
      "/tactile/right/markers",
      "/tactile/left/markers",
    ]);
    assert.equal(robotTopics(["left"], ["left"], ["left"], ["left"])["/tactile/left/markers"], "foxglove.PointCloud");
    assert.ok(isEpisodeStreamTopic("/tactile/left/markers"), "a touch reading between frames carries its marker flow");
  });
});

describe("decodeMarkerFlow and readMarkerFlow", () => {
  it("reads every marker: where it is and its rest position, in the cloud's order", () => {
    const markers = markerRow(6);
    const flow = decodeMarkerFlow(markerCloud(markers), "here");
    assert.equal(flow.count, 6);
    markers.forEach((m, k) => {
      assert.deepEqual([flow.position[2 * k], flow.position[2 * k + 1]], [Math.fround(m.x), Math.fround(m.y)]);
      assert.deepEqual([flow.rest[2 * k], flow.rest[2 * k + 1]], m.rest.map(Math.fround));
    });
    assert.ok(flow.position[10] !== flow.rest[10], "marker 5 is moved");
    const none = decodeMarkerFlow(markerCloud([]), "here");
    assert.deepEqual([none.count, none.position.length, none.rest.length], [0, 0, 0]);
  });

  it("rejects a wrong stride and a ragged cloud, naming the topic", () => {
    assert.throws(
      () => decodeMarkerFlow({ point_stride: 28, data: new Uint8Array(84) }, "sample 2 /tactile/left/markers"),
      /^Error: sample 2 \/tactile\/left\/markers: expected 20-byte markers, got point stride 28 and 84 bytes of data$/,
    );
    const short = markerCloud(markerRow(3));
    short.data = (short.data as Uint8Array).subarray(2);
    assert.throws(() => decodeMarkerFlow(short, "t"), /^Error: t: expected 20-byte markers, got point stride 20 and 58 bytes of data$/);
  });

  it("reads every optical pad's markers in channel order (not name order), each with its count, only with marker topics", () => {
    const flows = readMarkerFlow(markerSample(["right", "left"], ["right", "left"], { right: 5, left: 8 }), "here", ["right", "left"]);
    assert.deepEqual([...flows].map(([pad, f]) => [pad, f.count]), [["right", 5], ["left", 8]]);
    assert.equal(flows.get("left")!.position[0], Math.fround(1e-3)); // the second pad's: seed 1
    assert.equal(readMarkerFlow(markerSample(["left"], ["left"], {}), "here").size, 0);
  });

  it("holds the markers against the sample's pads, its optical pads and /sample/info tactile.optical", () => {
    assert.throws(
      () => readMarkerFlow(markerSample(["left"], ["left"], { left: 4 }), "here", ["right"]),
      /^Error: here: markers of left, which are not pads of the sample \(no \/tactile\/<pad>\/depth; pads: right\)$/,
    );
    assert.throws(
      () => readMarkerFlow(markerSample(["right", "left"], ["left"], { right: 4, left: 4 }), "here", ["right", "left"]),
      /^Error: here: markers of right, which are not optical pads of the sample \(no \/tactile\/<pad>\/image\)$/,
    );
    const unprinted = { optical: { left: { markers: null } } };
    assert.throws(
      () => readMarkerFlow(markerSample(["left"], ["left"], { left: 4 }, unprinted), "here"),
      /^Error: here: markers of left, whose sensors have none \(\/sample\/info tactile\.optical\.<pad>\.markers is null\)$/,
    );
    const bad = markerSample(["left"], ["left"], { left: 4 });
    bad.set(padMarkersTopic("left"), [decoded(padMarkersTopic("left"), 12, { point_stride: 20, data: new Uint8Array(30) })]);
    assert.throws(() => readMarkerFlow(bad, "sample 4"), /^Error: sample 4 \/tactile\/left\/markers: expected 20-byte markers, got point stride 20 and 30 bytes/);
  });
});

// ---- shards the generator wrote ---------------------------------------------------------------

// dist/test/force.test.js -> datasets/ts -> datasets -> repository root
const repoRoot = resolve(dirname(fileURLToPath(import.meta.url)), "..", "..", "..", "..");
let tempDir: string | undefined;

/** The datasets with force fields to read, or why there are none. */
function forceDatasets(): { roots: string[] } | { skip: string } {
  const given = (process.env.VTGEN_FORCE_DATASETS ?? "").split(delimiter).filter((p) => p !== "");
  if (given.length > 0) {
    return { roots: given.map((p) => resolve(p)) };
  }
  const bin = process.env.VTGEN_MUJOCO_BIN;
  if (bin == undefined || bin === "") {
    return {
      skip:
        "force fields need the MuJoCo backend: set VTGEN_MUJOCO_BIN to a vtgen built with --features mujoco " +
        "(with LD_LIBRARY_PATH from scripts/mujoco-setup), or VTGEN_FORCE_DATASETS to datasets generated with robot.tactile.force_field",
    };
  }
  tempDir = mkdtempSync(join(tmpdir(), "vtgen-force-"));
  const out = join(tempDir, "tiny-gripper");
  const sets = ["robot.tactile.force_field={resolution: 8}", "robot.physics.backend=mujoco"].flatMap((s) => ["--set", s]);
  execFileSync(bin, ["generate", join(repoRoot, "scenes", "tiny-gripper.yaml"), "--out", out, "--quiet", ...sets], { stdio: "inherit" });
  return { roots: [out] };
}

const sources = forceDatasets();
after(() => {
  if (tempDir != undefined && process.env.VTGEN_KEEP !== "1") {
    rmSync(tempDir, { recursive: true, force: true });
  }
});

type Obj = Record<string, unknown>;

/** The checks of one pad's field of a frame against FORMAT.md and its /sample/info. */
function checkFrameField(field: ForceField, r: number, pad: string, tactile: Obj, where: string): boolean {
  assert.equal(field.resolution, r, `${where} ${pad}: resolution`);
  const [length, width] = (tactile.pads as Record<string, [number, number]>)[pad]!;
  for (let v = 0; v < r; v++) {
    for (let u = 0; u < r; u++) {
      const k = v * r + u;
      const [x, y] = cellCentre(u, v, r, length, width);
      assert.ok(Math.abs(field.position[2 * k]! - x) <= 1e-6 && Math.abs(field.position[2 * k + 1]! - y) <= 1e-6, `${where} ${pad}: cell (${u}, ${v}) is not at its centre`);
      const pressed = field.pressure[k]! > 0;
      assert.ok(field.pressure[k]! >= 0, `${where} ${pad}: negative pressure`);
      assert.ok(pressed || (field.slip[k] === 0 && field.shear[2 * k] === 0 && field.shear[2 * k + 1] === 0), `${where} ${pad}: shear or slip on an unpressed cell`);
    }
  }
  const entry = (tactile.forces as Record<string, Obj>)[pad]!;
  for (const key of PAD_FORCE_INFO_KEYS) {
    assert.ok(key in entry, `${where}: /sample/info tactile.forces.${pad} has no ${key}`);
  }
  const want = entry.force_n as number[];
  const got = forceSum(field, length, width);
  const tolerance = 0.05 * Math.hypot(...want) + 1e-4;
  const off = Math.hypot(got[0] - want[0]!, got[1] - want[1]!, got[2] - want[2]!);
  assert.ok(off <= tolerance, `${where} ${pad}: the cells sum to ${JSON.stringify(got)} N, tactile.forces gives force_n ${JSON.stringify(want)} N (off by ${off.toExponential(2)}, tolerance ${tolerance.toExponential(2)})`);
  return Math.hypot(...want) > 1e-3;
}

/** The rest positions of an optical sensor's markers (m, pad frame; x, y interleaved) from its
 * /sample/info `tactile.optical.<pad>` entry: a square grid of its pitch centred on the pad, as
 * many dots along each axis as fit whole in its sensing area, rows along y (written independently
 * of the generator). */
function markerGrid(sensor: Obj): number[] {
  const markers = sensor.markers as { pitch_mm: number; radius_mm: number };
  const [p, r] = [markers.pitch_mm * 1e-3, markers.radius_mm * 1e-3];
  const [nx, ny] = (sensor.sensing_area_mm as number[]).map((a) => Math.max(Math.floor((a * 1e-3 - 2 * r) / p), -1) + 1) as [number, number];
  const out: number[] = [];
  for (let j = 0; j < ny; j++) {
    for (let i = 0; i < nx; i++) {
      out.push((i - (nx - 1) / 2) * p, (j - (ny - 1) / 2) * p);
    }
  }
  return out;
}

/** The checks of one optical pad's markers against its sensor's grid; how many of them moved. */
function checkMarkers(flow: MarkerFlow, sensor: Obj, where: string): number {
  const grid = markerGrid(sensor);
  assert.equal(2 * flow.count, grid.length, `${where}: ${flow.count} markers, the sensor's grid has ${grid.length / 2}`);
  const rests = new Set<string>();
  let moved = 0;
  for (let k = 0; k < flow.count; k++) {
    const [rx, ry] = [flow.rest[2 * k]!, flow.rest[2 * k + 1]!];
    rests.add(`${rx},${ry}`);
    assert.ok(Math.abs(rx - grid[2 * k]!) <= 1e-6 && Math.abs(ry - grid[2 * k + 1]!) <= 1e-6, `${where}: marker ${k} rests at (${rx}, ${ry}), not on the grid`);
    const shift = Math.hypot(flow.position[2 * k]! - rx, flow.position[2 * k + 1]! - ry);
    assert.ok(Number.isFinite(shift) && shift < 5e-3, `${where}: marker ${k} moved ${shift} m`);
    moved += shift > 0 ? 1 : 0;
  }
  assert.equal(rests.size, flow.count, `${where}: two markers rest at one place`);
  return moved;
}

describe("force fields of generated shards", () => {
  it(
    "every pad's field, in every sample and touch reading: square, at the cell centres, summing to tactile.forces.<pad>.force_n; every optical pad's markers on their grid",
    "skip" in sources ? { skip: sources.skip } : {},
    async () => {
      assert.ok("roots" in sources);
      let checked = 0;
      let pressing = 0;
      let between = 0;
      let markers = 0;
      let moved = 0;
      for (const root of sources.roots) {
        assert.ok(existsSync(join(root, "manifest.json")), `${root}: no manifest.json`);
        const config = JSON.parse(readFileSync(join(root, "config.json"), "utf8")) as { robot: { tactile: { force_field: { resolution: number } } } };
        const r = config.robot.tactile.force_field.resolution;
        const manifest = JSON.parse(readFileSync(join(root, "manifest.json"), "utf8")) as { splits: Record<string, { shards: { file: string; sha256: string | null }[] }> };
        for (const split of Object.values(manifest.splits)) {
          for (const entry of split.shards.filter((s) => s.sha256 != null)) {
            const shard = await readShard(join(root, entry.file));
            const channels = [...shard.channels.values()].map((c) => c.channel);
            const pads = padsOf(channels);
            const optical = opticalPadsOf(channels);
            assert.deepEqual(forcePadsOf(channels), pads, `${entry.file}: the force channels are not every pad's, in pad order`);
            for (const [t, group] of shard.samples) {
              const where = `${entry.file} @ ${t}`;
              const frame = shard.frames.get(t);
              if (frame == undefined) {
                // An episode's touch reading between frames: every pad's field, no info to sum to.
                if ([...group.keys()].some((topic) => forcePadOfTopic(topic) != undefined)) {
                  const fields = readForceFields(group, where, pads);
                  assert.deepEqual([...fields.keys()], pads, `${where}: force fields`);
                  assert.ok([...fields.values()].every((f) => f.resolution === r), `${where}: resolution`);
                  assert.deepEqual([...readMarkerFlow(group, where, pads).keys()], markersPadsOf(channels), `${where}: markers`);
                  between++;
                }
                continue;
              }
              const tactile = (frame.get("/sample/info")![0]!.value.tactile ?? {}) as Obj;
              for (const key of TACTILE_FORCE_INFO_KEYS) {
                assert.ok(key in tactile, `${where}: /sample/info tactile has no ${key}`);
              }
              const fields = readForceFields(frame, where, pads);
              assert.deepEqual([...fields.keys()], pads, `${where}: force fields`);
              for (const [pad, field] of fields) {
                pressing += checkFrameField(field, r, pad, tactile, where) ? 1 : 0;
                checked++;
              }
              // Every optical pad whose sensor has markers has its marker flow, in pad order.
              const sensors = (tactile.optical ?? {}) as Record<string, Obj>;
              const printed = optical.filter((pad) => sensors[pad]!.markers !== null);
              const flows = readMarkerFlow(frame, where, pads);
              assert.deepEqual([...flows.keys()], printed, `${where}: markers`);
              for (const [pad, flow] of flows) {
                moved += checkMarkers(flow, sensors[pad]!, `${where} ${pad}`);
                markers++;
              }
            }
          }
        }
      }
      assert.ok(checked > 0, `no pad to check in ${sources.roots.join(", ")}`);
      assert.ok(pressing > 0, "no pad with a contact force: the sums would compare zeros with zeros");
      assert.ok(markers > 0, "no optical pad with markers: scenes/tiny-gripper.yaml prints them");
      assert.ok(moved > 0, "no marker moved: the flow would be the rest grid");
      console.log(
        `force fields: ${checked} pads checked (${pressing} pressed), ${markers} optical pads' markers (${moved} moved), ` +
          `${between} touch readings between frames`,
      );
    },
  );
});
