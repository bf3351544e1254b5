// vtgen shards as Foxglove sees them: read with @mcap/core (McapIndexedReader, zstd through
// @foxglove/wasm-zstd), every channel's schema parsed and every message decoded the way Foxglove
// does it (protobufjs from the embedded FileDescriptorSet; JSON with Foxglove's JSON Schema rules),
// every sample checked against datasets/FORMAT.md, the /scene/models 3D models checked as the
// 3D panel will place them, and datasets/foxglove-layout.json held against the shards.
//
// Datasets: VTGEN_DATASET=<dataset dir or shard .mcap>[:<another>...], or VTGEN_BIN=<vtgen binary>
// to generate VTGEN_SCENES (default scenes/tiny-hand.yaml:scenes/tiny-gripper.yaml:scenes/tiny.yaml:
// scenes/tiny-episode.yaml) into a temp dir.
//
// Episode shards (FORMAT.md, "Episodes": `vtgen.shard` has `episode`) are checked as Foxglove
// plays them: each chunk is a camera frame (its messages at the chunk's first log time are the
// sample) followed by the touch and /episode/state streams up to the next frame.
// VTGEN_ALLOW_NO_SCENE_MODELS=1 turns a missing /scene/models topic into a skipped check.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync, statSync } from "node:fs";
import { tmpdir } from "node:os";
import { basename, delimiter, dirname, join, relative, resolve } from "node:path";
import { after, before, describe, it, type TestContext } from "node:test";
import { fileURLToPath } from "node:url";

import {
  CALIBRATION_SCHEMAS,
  FOXGLOVE_RENDERABLE_SCHEMAS,
  IMAGE_SCHEMAS,
  enumValue,
  toNanos,
} from "../src/foxglove.js";
import {
  BASE_TOPICS,
  EPISODE_METADATA_KEY,
  EPISODE_RECORD_KEYS,
  EPISODE_STATE_TOPIC,
  EPISODE_TOPICS,
  FORCE_FIELDS,
  FORCE_STRIDE,
  MARKER_FIELDS,
  MARKER_STRIDE,
  SAMPLE_INFO_EPISODE_KEYS,
  STATE_RECORD_KEYS,
  episodeTiming,
  isEpisodeStreamTopic,
  type EpisodeTiming,
  POINT_FIELDS,
  POINT_PAD_FIELD,
  POINT_STRIDE,
  NOISE_TOPICS,
  OPTICAL_INFO_KEYS,
  SAMPLE_INFO_KEYS,
  SAMPLE_INFO_ROBOT_KEYS,
  SAMPLE_PERIOD_NS,
  SCENE_SCHEMA,
  SCENE_TOPIC,
  SHARD_METADATA_KEYS,
  TACTILE_FORCE_INFO_KEYS,
  TACTILE_RESOLUTION,
  forcePadOfTopic,
  forcePadsOf,
  imageSpec,
  markersPadOfTopic,
  markersPadsOf,
  opticalOfTopic,
  opticalPadsOf,
  padOfTopic,
  padsOf,
  robotTopics,
} from "../src/format.js";
import { checkSceneModels, obj, only, tfTree, unitQuaternion, type ModelInfo, type Obj, type Sample } from "../src/checks.js";
import { forceSum, readForceFields, readMarkerFlow } from "../src/force.js";
import { frameReferences, loadLayout, plotSeries, topicReferences, valueAtPath, type LayoutFile } from "../src/layout.js";
import { readOpticalImages } from "../src/optical.js";
import { frameTimeOf, readShard, type Decoded, type ShardData } from "../src/shard.js";

// dist/test/foxglove.test.js -> datasets/ts -> datasets -> repository root
const here = dirname(fileURLToPath(import.meta.url));
const tsRoot = resolve(here, "..", "..");
const repoRoot = resolve(tsRoot, "..", "..");
const layoutPath = process.env.VTGEN_LAYOUT ?? join(repoRoot, "datasets", "foxglove-layout.json");
const allowNoSceneModels = process.env.VTGEN_ALLOW_NO_SCENE_MODELS === "1";

type Dataset = { name: string; root: string | undefined; shards: string[]; robot: boolean | undefined };

// The readers know no robot: these are the UR5e + Allegro's (scenes/tiny-hand.yaml's robot), for
// the checks of its shards only.
/** The UR5e + Allegro's 12 pads, in the order of its pad index. */
const ALLEGRO_PADS = ["ff", "mf", "rf", "th"].flatMap((f) => ["proximal", "medial", "distal"].map((p) => `${f}_${p}`));
/** The UR5e + Allegro's joints in `joint_positions`: 6 arm + 16 hand. */
const ALLEGRO_JOINT_COUNT = 22;
/** Whether `pads` are the UR5e + Allegro's, in its order. */
const isAllegro = (pads: readonly string[]): boolean =>
  pads.length === ALLEGRO_PADS.length && pads.every((p, k) => p === ALLEGRO_PADS[k]);


// ---- which datasets --------------------------------------------------------------------------

let tempDir: string | undefined;

function datasetFrom(path: string): Dataset {
  const abs = resolve(path);
  if (statSync(abs).isFile()) {
    // a bare shard: <root>/<split>/shard-NNNNN.mcap; the dataset root may be there or not
    const root = dirname(dirname(abs));
    return {
      name: basename(abs),
      root: existsSync(join(root, "manifest.json")) ? root : undefined,
      shards: [abs],
      robot: robotOf(root),
    };
  }
  const manifest = JSON.parse(readFileSync(join(abs, "manifest.json"), "utf8")) as {
    splits: Record<string, { shards: { file: string; sha256: string | null }[] }>;
  };
  const shards: string[] = [];
  for (const split of Object.values(manifest.splits)) {
    for (const shard of split.shards) {
      if (shard.sha256 != null) {
        shards.push(join(abs, shard.file));
      }
    }
  }
  return { name: basename(abs), root: abs, shards, robot: robotOf(abs) };
}

function robotOf(root: string): boolean | undefined {
  const config = join(root, "config.json");
  if (!existsSync(config)) {
    return undefined;
  }
  const value = JSON.parse(readFileSync(config, "utf8")) as Obj;
  return value.robot != undefined;
}

function datasets(): Dataset[] {
  const given = process.env.VTGEN_DATASET;
  if (given != undefined && given !== "") {
    return given.split(delimiter).filter((p) => p !== "").map(datasetFrom);
  }
  const bin = process.env.VTGEN_BIN;
  if (bin == undefined || bin === "") {
    throw new Error("set VTGEN_DATASET to a dataset (or shard), or VTGEN_BIN to a vtgen binary to generate one");
  }
  tempDir = mkdtempSync(join(tmpdir(), "vtgen-foxglove-"));
  const scenes = (
    process.env.VTGEN_SCENES ?? "scenes/tiny-hand.yaml:scenes/tiny-gripper.yaml:scenes/tiny.yaml:scenes/tiny-episode.yaml"
  ).split(delimiter);
  return scenes.map((scene) => {
    const out = join(tempDir!, basename(scene, ".yaml"));
    execFileSync(bin, ["generate", resolve(repoRoot, scene), "--out", out, "--quiet"], { stdio: "inherit" });
    return datasetFrom(out);
  });
}

const all = datasets();
after(() => {
  if (tempDir != undefined && process.env.VTGEN_KEEP !== "1") {
    rmSync(tempDir, { recursive: true, force: true });
  }
});

// ---- helpers ---------------------------------------------------------------------------------

function isRobot(dataset: Dataset, shard: ShardData): boolean {
  return dataset.robot ?? shard.topics.has("/tactile/points");
}

/** The topics of every sample: with a robot, `/tactile/points`, the depth image of each of its
 * pads (`pads`, read from the shard: the robot's, not a fixed list), the image and reference
 * image of each pad with an optical sensor (`optical`, read from the shard too), the force
 * field of each pad of `forces` (with `robot.tactile.force_field`, read from the shard) and the
 * marker flow of each pad of `markers` (with force fields, the optical pads whose sensor has
 * markers, read from the shard). */
function expectedTopics(
  robot: boolean,
  pads: readonly string[],
  noisy = false,
  optical: readonly string[] = [],
  episode = false,
  forces: readonly string[] = [],
  markers: readonly string[] = [],
): Record<string, string> {
  return {
    ...BASE_TOPICS,
    ...(robot ? robotTopics(pads, optical, forces, markers) : {}),
    ...(noisy ? NOISE_TOPICS : {}),
    ...(episode ? EPISODE_TOPICS : {}),
  };
}

/** publish_time and every timestamp inside a message equal its log time (FORMAT.md). */
function checkStamps(m: Decoded, where: string): void {
  const t = m.logTime;
  assert.equal(m.publishTime, t, `${where} ${m.topic}: publish_time != log_time`);
  const v = m.value;
  if ("timestamp" in v) {
    assert.equal(toNanos(v.timestamp), t, `${where} ${m.topic}: timestamp != log_time`);
  }
  for (const tf of (v.transforms ?? []) as Obj[]) {
    assert.equal(toNanos(tf.timestamp), t, `${where} ${m.topic}: transform timestamp != log_time`);
  }
  for (const entity of (v.entities ?? []) as Obj[]) {
    assert.equal(toNanos(entity.timestamp), t, `${where} ${m.topic}: entity timestamp != log_time`);
  }
}

/** `t` (ns) is physics step `s`'s time, to the nanosecond the rounding allows. */
function atStep(t: bigint, s: number, timing: EpisodeTiming, what: string): void {
  const want = timing.stepNs(s);
  assert.ok(Math.abs(Number(t) - want) <= 1, `${what}: log time ${t} ns, step ${s} is at ${want.toFixed(1)} ns`);
}

/** The physics step of log time `t` (ns). */
const stepOf = (t: bigint, timing: EpisodeTiming): number => Math.round(Number(t) / timing.stepNs(1));

/** The frame (its sample) whose chunk holds log time `t`. */
function frameOf(shard: ShardData, t: bigint): Sample {
  const frame = frameTimeOf([...shard.frames.keys()], t);
  assert.ok(frame != undefined, `log time ${t} is before the shard's first chunk`);
  return shard.frames.get(frame)!;
}

/** Row-major 3x3 rotation of a quaternion (x, y, z, w). */
function rotation(q: number[]): number[] {
  const [x, y, z, w] = q as [number, number, number, number];
  return [
    1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
    2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
    2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
  ];
}

/** Two poses `{position, orientation}` agree: positions within `tp`, rotations (not quaternion
 * signs) within `tr` per matrix entry. */
function samePose(a: Obj, b: Obj, tp: number, tr: number, what: string): void {
  const pa = a.position as number[];
  const pb = b.position as number[];
  pa.forEach((v, k) => assert.ok(Math.abs(v - pb[k]!) <= tp, `${what}: position ${JSON.stringify(pa)} != ${JSON.stringify(pb)}`));
  const ra = rotation(a.orientation as number[]);
  const rb = rotation(b.orientation as number[]);
  const worst = Math.max(...ra.map((v, k) => Math.abs(v - rb[k]!)));
  assert.ok(worst <= tr, `${what}: rotations differ by ${worst.toExponential(2)} (> ${tr})`);
}

/** Where in a /tactile/points point its pad index (field POINT_PAD_FIELD) is. */
const PAD_INDEX_OFFSET = POINT_FIELDS.find(([name]) => name === POINT_PAD_FIELD)![1];

/** The pad index of every point of a /tactile/points message. */
function padIndices(cloud: Obj): number[] {
  const data = cloud.data as Uint8Array;
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const out: number[] = [];
  for (let i = 0; i + POINT_STRIDE <= data.byteLength; i += POINT_STRIDE) {
    out.push(view.getUint32(i + PAD_INDEX_OFFSET, true));
  }
  return out;
}

/** The child of the world -> X transform of /tf whose pose is `/sample/info` `T_world_palm` (the
 * robot's grasp frame: `palm` for the Allegro, named by the robot description otherwise). */
function graspFrame(sample: Map<string, Decoded[]>, info: Obj): string | undefined {
  const palm = obj(info.T_world_palm) as { position: number[]; orientation: number[] };
  const same = (a: number[], b: number[]): boolean => a.length === b.length && a.every((v, k) => Math.abs(v - b[k]!) <= 1e-12);
  for (const tf of (only(sample, "/tf").transforms ?? []) as Obj[]) {
    const t = obj(tf.translation) as { x: number; y: number; z: number };
    const r = obj(tf.rotation) as { x: number; y: number; z: number; w: number };
    if (tf.parent_frame_id === "world" && same([t.x, t.y, t.z], palm.position) && same([r.x, r.y, r.z, r.w], palm.orientation)) {
      return String(tf.child_frame_id);
    }
  }
  return undefined;
}

function schemaOf(shard: ShardData, topic: string): string | undefined {
  const info = shard.topics.get(topic);
  if (info == undefined) {
    return undefined;
  }
  return info.channel.messageEncoding === "json" ? "json" : info.schema?.name;
}

function modelsInfo(root: string | undefined): Map<string, ModelInfo> | undefined {
  if (root == undefined || !existsSync(join(root, "models", "models_info.json"))) {
    return undefined;
  }
  const info = JSON.parse(readFileSync(join(root, "models", "models_info.json"), "utf8")) as { objects: ModelInfo[] };
  return new Map(info.objects.map((o) => [o.id, o]));
}

// ---- the layout ------------------------------------------------------------------------------

let layout: LayoutFile;
let layoutError: unknown;
try {
  layout = await loadLayout(layoutPath);
} catch (err) {
  layoutError = err;
}

describe("datasets/foxglove-layout.json", () => {
  it("is a Foxglove layout (configById, layout tree, globalVariables, userNodes, playbackConfig)", () => {
    if (layoutError != undefined) {
      throw layoutError;
    }
    const refs = topicReferences(layout);
    const topics = new Set(refs.map((r) => r.topic));
    for (const topic of ["/tactile/points", SCENE_TOPIC, "/camera/rgb", "/camera/calibration", "/camera/depth", "/camera/mask", "/sample/info"]) {
      assert.ok(topics.has(topic), `the layout does not show ${topic}`);
    }
    assert.ok([...topics].some((t) => /^\/tactile\/\w+_\w+\/depth$/.test(t)), "the layout shows no pad depth image");
    assert.ok(
      refs.some((r) => r.use === "image" && opticalOfTopic(r.topic)?.kind === "image"),
      "the layout shows no optical pad image (/tactile/<pad>/image)",
    );
    assert.ok(
      plotSeries(layout).some((series) => series.topic === EPISODE_STATE_TOPIC),
      `the layout plots nothing of ${EPISODE_STATE_TOPIC} (episodes)`,
    );
    const threeD = Object.entries(layout.configById).filter(([id]) => id.startsWith("3D!"));
    assert.equal(threeD.length, 1, "one 3D panel");
    assert.ok(["camera", "world"].includes(String(threeD[0]![1].followTf)), "the 3D panel follows camera or world");
  });
});

// ---- per dataset and shard ---------------------------------------------------------------------

for (const dataset of all) {
  describe(`dataset ${dataset.name}`, () => {
    it("has complete shards to read", () => {
      assert.ok(dataset.shards.length > 0, "no complete shard");
      for (const shard of dataset.shards) {
        assert.ok(existsSync(shard), `${shard} is missing`);
      }
    });

    const models = modelsInfo(dataset.root);

    for (const shardPath of dataset.shards) {
      const label = dataset.root != undefined ? relative(dataset.root, shardPath) : basename(shardPath);
      describe(label, () => {
        let shard: ShardData;
        let robot = false;
        /** The robot's pads, from the shard's /tactile/<pad>/depth channels (in pad index order). */
        let pads: string[] = [];
        /** The pads with an optical sensor, from the shard's /tactile/<pad>/image channels (pad order). */
        let optical: string[] = [];
        /** The pads with a force field, from the shard's /tactile/<pad>/force channels (pad order). */
        let forces: string[] = [];
        /** The optical pads with marker flow, from the shard's /tactile/<pad>/markers channels (pad order). */
        let markers: string[] = [];
        let allegro = false;
        /** An episode shard's timing (FORMAT.md, "Episodes"); undefined for a snapshot shard. */
        let episode: EpisodeTiming | undefined;
        /** The shard's first sample (an episode's frame 0, which holds its optical references). */
        let frame0: Sample;
        before(async () => {
          shard = await readShard(shardPath);
          robot = isRobot(dataset, shard);
          pads = padsOf([...shard.channels.values()].map((c) => c.channel));
          optical = opticalPadsOf([...shard.channels.values()].map((c) => c.channel));
          forces = forcePadsOf([...shard.channels.values()].map((c) => c.channel));
          markers = markersPadsOf([...shard.channels.values()].map((c) => c.channel));
          allegro = isAllegro(pads);
          episode = shard.episode == undefined ? undefined : episodeTiming(shard.episode);
          frame0 = shard.frames.values().next().value ?? new Map();
        });
        after(() => {
          // A shard's decoded messages can be hundreds of MB (an episode's): keep one at a time.
          shard = undefined as unknown as ShardData;
          frame0 = new Map();
        });

        it("opens with McapIndexedReader: header, one zstd chunk per sample, vtgen.shard metadata", () => {
          assert.equal(shard.header.profile, "");
          assert.match(shard.header.library, /^vtgen /);
          assert.ok(shard.statistics != undefined, "no statistics record in the summary");
          const meta = shard.metadata.get("vtgen.shard");
          assert.ok(meta != undefined, "no vtgen.shard metadata record");
          for (const key of SHARD_METADATA_KEYS) {
            assert.ok(meta.has(key), `vtgen.shard has no ${key}`);
          }
          if (robot) {
            assert.ok(meta.has("grasp_stats"), "vtgen.shard has no grasp_stats (robot dataset)");
          }
          assert.equal(meta.get("format_version"), "1");
          const first = BigInt(meta.get("first_sample")!);
          const count = Number(meta.get("sample_count"));
          assert.equal(shard.chunkIndexes.length, count, "chunks != samples");
          const chunks = [...shard.chunkIndexes].sort((a, b) => (a.messageStartTime < b.messageStartTime ? -1 : a.messageStartTime > b.messageStartTime ? 1 : 0));
          chunks.forEach((c) => assert.equal(c.compression, "zstd", "chunk compression"));
          if (episode == undefined) {
            assert.ok(!meta.has(EPISODE_METADATA_KEY));
            chunks.forEach((c, k) => {
              assert.equal(c.messageStartTime, c.messageEndTime, "a chunk spans more than one sample");
              assert.equal(c.messageStartTime, (first + BigInt(k)) * SAMPLE_PERIOD_NS, `chunk ${k} log time`);
            });
            return;
          }
          // An episode: one chunk per camera frame, frame k at step k·c, time since the episode's
          // start; each chunk runs up to (not into) the next frame's.
          for (const key of EPISODE_RECORD_KEYS) {
            assert.ok(key in shard.episode!, `vtgen.shard episode has no ${key}`);
          }
          const record = shard.episode!;
          assert.equal(episode.frames, count, "episode frames != sample_count");
          assert.equal(first, BigInt(meta.get("shard_index")!) * BigInt(count), "first_sample != shard_index · frames");
          assert.equal(episode.frames, Math.floor(episode.steps / episode.camera) + 1, "frames != steps div camera period + 1");
          for (const period of [episode.tactile, episode.state]) {
            assert.ok(Number.isInteger(period) && period >= 1 && episode.camera % period === 0, `period ${period} does not divide the camera's (${episode.camera})`);
          }
          for (const [hz, period] of [["camera_hz", episode.camera], ["tactile_hz", episode.tactile], ["state_hz", episode.state]] as const) {
            const want = (record.physics_hz as number) / period;
            assert.ok(Math.abs((record[hz] as number) - want) <= 1e-9 * want, `${hz} ${String(record[hz])} != physics_hz / ${period}`);
          }
          assert.equal(chunks[0]!.messageStartTime, 0n, "frame 0 is not at the episode's start");
          chunks.forEach((c, k) => {
            atStep(c.messageStartTime, k * episode!.camera, episode!, `chunk ${k}`);
            const next = chunks[k + 1];
            if (next != undefined) {
              assert.ok(c.messageEndTime < next.messageStartTime, `chunk ${k} (to ${c.messageEndTime} ns) runs into chunk ${k + 1} (${next.messageStartTime} ns)`);
            } else {
              assert.ok(stepOf(c.messageEndTime, episode!) <= episode!.steps, `the last chunk runs past the episode's end`);
            }
          });
        });

        it("every channel's schema parses as Foxglove parses it, with the FORMAT.md schema", () => {
          const problems: string[] = [];
          for (const info of shard.channels.values()) {
            if (info.error != undefined) {
              problems.push(`${info.channel.topic}: ${info.error.message}`);
            }
          }
          assert.deepEqual(problems, []);
          const expected: Record<string, string> = {
            ...expectedTopics(robot, pads, shard.topics.has("/camera/depth_noisy"), optical, episode != undefined, forces, markers),
            [SCENE_TOPIC]: SCENE_SCHEMA,
          };
          if (episode != undefined) {
            assert.ok(shard.topics.has(EPISODE_STATE_TOPIC), `an episode shard without ${EPISODE_STATE_TOPIC}`);
          }
          for (const [topic, info] of shard.topics) {
            const want = expected[topic];
            assert.ok(want != undefined, `topic ${topic} is not in FORMAT.md`);
            if (want === "json") {
              assert.equal(info.channel.messageEncoding, "json", `${topic} message encoding`);
              assert.equal(info.schema?.encoding, "jsonschema", `${topic} schema encoding`);
            } else {
              assert.equal(info.channel.messageEncoding, "protobuf", `${topic} message encoding`);
              assert.equal(info.schema?.name, want, `${topic} schema name`);
              assert.ok(FOXGLOVE_RENDERABLE_SCHEMAS.has(want), `${want} is not a schema Foxglove draws`);
            }
          }
        });

        it("every message of every channel decodes", () => {
          assert.deepEqual(shard.decodeErrors, []);
          const stats = shard.statistics!;
          assert.equal(BigInt(shard.messages.length), stats.messageCount, "decoded messages != statistics");
          const perChannel = new Map<number, number>();
          for (const m of shard.messages) {
            perChannel.set(m.channelId, (perChannel.get(m.channelId) ?? 0) + 1);
          }
          for (const [id, count] of stats.channelMessageCounts) {
            assert.equal(BigInt(perChannel.get(id) ?? 0), count, `channel ${id} message count`);
          }
        });

        it("each sample has every FORMAT.md topic once, all stamped with its log time", () => {
          const meta = shard.metadata.get("vtgen.shard")!;
          const first = BigInt(meta.get("first_sample")!);
          const count = Number(meta.get("sample_count"));
          const times = [...shard.frames.keys()];
          assert.equal(times.length, count, "samples (chunks) != sample_count");
          if (episode == undefined) {
            assert.equal(shard.samples.size, count, "samples (distinct log times) != sample_count");
          }
          const topics = Object.keys(
            expectedTopics(robot, pads, shard.topics.has("/camera/depth_noisy"), optical, episode != undefined, forces, markers),
          );
          // An episode writes its optical references once, with frame 0.
          const later = topics.filter((topic) => opticalOfTopic(topic)?.kind !== "reference");
          let move = 0;
          times.forEach((t, k) => {
            if (episode == undefined) {
              assert.equal(t, (first + BigInt(k)) * SAMPLE_PERIOD_NS, `sample ${k} log time`);
            } else {
              atStep(t, k * episode.camera, episode, `frame ${k}`);
            }
            const sample = shard.frames.get(t)!;
            const want = episode != undefined && k > 0 ? later : topics;
            for (const topic of want) {
              assert.equal(sample.get(topic)?.length ?? 0, 1, `sample ${k}: ${topic} messages`);
            }
            for (const [topic, list] of sample) {
              assert.ok(want.includes(topic) || topic === SCENE_TOPIC, `sample ${k}: unexpected topic ${topic}`);
              assert.ok(list.length === 1, `sample ${k}: ${list.length} messages on ${topic}`);
              list.forEach((m) => checkStamps(m, `sample ${k}`));
            }
            const info = only(sample, "/sample/info");
            assert.equal(BigInt(info.index as number), first + BigInt(k), `sample ${k}: /sample/info index`);
            assert.equal(info.split, meta.get("split"), `sample ${k}: /sample/info split`);
            if (episode != undefined) {
              const frame = obj(info.episode);
              for (const key of SAMPLE_INFO_EPISODE_KEYS) {
                assert.ok(key in frame, `frame ${k}: /sample/info episode has no ${key}`);
              }
              assert.equal(info.instance, k, `frame ${k}: /sample/info instance`);
              assert.equal(frame.frame, k, `frame ${k}: /sample/info episode.frame`);
              assert.ok(Math.abs((frame.time_s as number) - Number(t) / 1e9) <= 1e-9, `frame ${k}: episode.time_s ${String(frame.time_s)}`);
              const arm = frame.arm_move as number;
              assert.ok(Number.isInteger(arm) && arm >= move, `frame ${k}: arm_move ${arm} after ${move}`);
              move = arm;
            }
          });
          if (episode == undefined) {
            return;
          }
          // The streams: at each touch instant every touch topic once, at each state instant one
          // state; between the frames nothing else; every instant of the episode present.
          const touchTopics = later.filter((topic) => isEpisodeStreamTopic(topic) && topic !== EPISODE_STATE_TOPIC);
          const touchSteps: number[] = [];
          const stateSteps: number[] = [];
          for (const [t, sample] of shard.samples) {
            const where = `@ ${t} ns`;
            if (!shard.frames.has(t)) {
              for (const [topic, list] of sample) {
                assert.ok(isEpisodeStreamTopic(topic), `${where}: ${topic} between frames (only touch and state)`);
                assert.equal(list.length, 1, `${where}: ${list.length} messages on ${topic}`);
                list.forEach((m) => checkStamps(m, where));
              }
            }
            const step = stepOf(t, episode);
            atStep(t, step, episode, where);
            if (sample.has(EPISODE_STATE_TOPIC)) {
              stateSteps.push(step);
            }
            if (touchTopics.some((topic) => sample.has(topic))) {
              for (const topic of touchTopics) {
                assert.equal(sample.get(topic)?.length ?? 0, 1, `${where}: ${topic} messages (a touch reading has every touch topic)`);
              }
              touchSteps.push(step);
            }
          }
          const grid = (period: number): number[] => Array.from({ length: Math.floor(episode!.steps / period) + 1 }, (_, j) => j * period);
          assert.deepEqual(stateSteps, grid(episode.state), "the steps with a state");
          if (robot) {
            assert.deepEqual(touchSteps, grid(episode.tactile), "the steps with a touch reading");
          }
        });

        it("a robot's pads: a depth image each, the pads /sample/info lists, in the pad index's order", () => {
          if (!robot) {
            assert.deepEqual(pads, [], "pad depth images without a robot");
            return;
          }
          assert.ok(pads.length > 0, "a robot shard without /tactile/<pad>/depth channels");
          for (const [t, sample] of shard.frames) {
            const where = `sample @ ${t}`;
            const info = only(sample, "/sample/info");
            const tactile = obj(info.tactile);
            const listed = obj(tactile.pads);
            assert.deepEqual(Object.keys(listed).sort(), [...pads].sort(), `${where}: /sample/info tactile.pads != the pad topics`);
            // The k-th pad channel is pad k of the point cloud: its points are that pad's count.
            const counts = obj(tactile.points) as Record<string, number>;
            const index = padIndices(only(sample, "/tactile/points"));
            pads.forEach((pad, k) => {
              assert.equal(index.filter((i) => i === k).length, counts[pad] ?? 0, `${where}: points of pad ${k} (${pad})`);
            });
          }
        });

        it("optical pads: an image and a reference image each, the pads /sample/info tactile.optical lists", () => {
          if (!robot) {
            assert.deepEqual(optical, [], "optical images without a robot");
            return;
          }
          if (episode != undefined) {
            // Written once, with frame 0: every image of the episode has that reference.
            for (const pad of optical) {
              const references = shard.messages.filter((m) => m.topic === `/tactile/${pad}/reference`);
              assert.deepEqual(references.map((m) => m.logTime), [0n], `/tactile/${pad}/reference: once, with frame 0`);
            }
          }
          for (const [t, sample] of shard.frames) {
            const where = `sample @ ${t}`;
            const info = only(sample, "/sample/info");
            const listed = obj(info.tactile).optical as Record<string, Obj> | undefined;
            const { tactileImages, tactileReferences } = readOpticalImages(sample, where, pads, episode != undefined ? frame0 : undefined);
            assert.deepEqual([...tactileImages.keys()], optical, `${where}: optical pads != the shard's /tactile/<pad>/image channels`);
            assert.deepEqual([...tactileReferences.keys()], optical, `${where}: reference pads`);
            if (optical.length === 0) {
              assert.ok(listed == undefined || Object.keys(listed).length === 0, `${where}: tactile.optical without optical images`);
              continue;
            }
            assert.ok(listed != undefined, `${where}: optical images but no /sample/info tactile.optical`);
            for (const pad of optical) {
              const sensor = listed[pad]!;
              for (const key of OPTICAL_INFO_KEYS) {
                assert.ok(key in sensor, `${where}: /sample/info tactile.optical.${pad} has no ${key}`);
              }
              const image = tactileImages.get(pad)!;
              const reference = tactileReferences.get(pad)!;
              assert.equal(image.data.byteLength, image.width * image.height * 3, `${where}: ${pad} image bytes`);
              assert.deepEqual([reference.width, reference.height], [image.width, image.height], `${where}: ${pad} reference size`);
            }
          }
        });

        it("force fields (robot.tactile.force_field): every pad's, in every touch reading, summing to /sample/info tactile.forces; the optical pads' markers", () => {
          if (forces.length === 0) {
            assert.deepEqual(markers, [], "FORMAT.md: marker flow comes with the force fields");
            for (const [t, sample] of shard.frames) {
              const tactile = obj(only(sample, "/sample/info").tactile ?? {});
              for (const key of TACTILE_FORCE_INFO_KEYS) {
                assert.ok(!(key in tactile), `sample @ ${t}: /sample/info tactile.${key} without /tactile/<pad>/force`);
              }
            }
            return;
          }
          assert.ok(robot, "force fields without a robot");
          assert.deepEqual(forces, pads, "FORMAT.md: every pad has a force field, channels in pad order");
          const type = shard.topics.get(`/tactile/${forces[0]!}/force`)!.parsed as { kind: "protobuf"; type: import("protobufjs").Type };
          const fieldType = type.type.lookupType("foxglove.PackedElementField");
          const fields = FORCE_FIELDS.map(([name, offset, numeric]) => [name, offset, enumValue(fieldType, "NumericType", numeric)]);
          for (const m of shard.messages.filter((x) => forcePadOfTopic(x.topic) != undefined)) {
            const where = `${m.topic} @ ${m.logTime}`;
            assert.equal(m.value.frame_id, `${forcePadOfTopic(m.topic)!}_pad`, `${where}: frame_id`);
            assert.equal(m.value.point_stride, FORCE_STRIDE, `${where}: point_stride`);
            assert.deepEqual((m.value.fields as Obj[]).map((f) => [f.name, f.offset, f.type]), fields, `${where}: cell fields`);
            assert.deepEqual(obj(obj(m.value.pose).orientation), { x: 0, y: 0, z: 0, w: 1 }, `${where}: pose`);
          }
          // The marker flow: of optical pads, in pad order, 20-byte points (x, y, z, rest_x, rest_y).
          assert.deepEqual(markers, optical.filter((pad) => markers.includes(pad)), "FORMAT.md: markers are of optical pads, channels in pad order");
          const markerFields = MARKER_FIELDS.map(([name, offset, numeric]) => [name, offset, enumValue(fieldType, "NumericType", numeric)]);
          for (const m of shard.messages.filter((x) => markersPadOfTopic(x.topic) != undefined)) {
            const where = `${m.topic} @ ${m.logTime}`;
            assert.equal(m.value.frame_id, `${markersPadOfTopic(m.topic)!}_pad`, `${where}: frame_id`);
            assert.equal(m.value.point_stride, MARKER_STRIDE, `${where}: point_stride`);
            assert.deepEqual((m.value.fields as Obj[]).map((f) => [f.name, f.offset, f.type]), markerFields, `${where}: marker fields`);
            assert.deepEqual(obj(obj(m.value.pose).orientation), { x: 0, y: 0, z: 0, w: 1 }, `${where}: pose`);
          }
          // Every touch reading (a sample; an episode's readings between frames too) has every pad's field.
          let resolution: number | undefined;
          for (const [t, group] of shard.samples) {
            if (!group.has("/tactile/points")) {
              continue;
            }
            const where = `touch @ ${t}`;
            const read = readForceFields(group, where, pads);
            assert.deepEqual([...read.keys()], pads, `${where}: force fields`);
            assert.deepEqual([...readMarkerFlow(group, where, pads).keys()], markers, `${where}: markers`);
            for (const [pad, field] of read) {
              resolution ??= field.resolution;
              assert.equal(field.resolution, resolution, `${where} ${pad}: resolution differs from the shard's first`);
            }
            if (!shard.frames.has(t)) {
              continue;
            }
            const tactile = obj(only(group, "/sample/info").tactile);
            const sensors = obj(tactile.optical ?? {}) as Record<string, Obj>;
            assert.deepEqual(markers, optical.filter((pad) => sensors[pad]?.markers != null), `${where}: markers of the optical pads whose sensors have them`);
            const listed = obj(tactile.forces) as Record<string, Obj>;
            for (const [pad, field] of read) {
              const [length, width] = obj(tactile.pads)[pad] as [number, number];
              const want = listed[pad]!.force_n as number[];
              const got = forceSum(field, length, width);
              const off = Math.hypot(got[0] - want[0]!, got[1] - want[1]!, got[2] - want[2]!);
              assert.ok(off <= 0.05 * Math.hypot(...want) + 1e-4, `${where} ${pad}: cells sum to ${JSON.stringify(got)} N, tactile.forces.${pad}.force_n is ${JSON.stringify(want)} N`);
            }
          }
        });

        it("RawImage width, height, encoding and step match the data (and FORMAT.md)", () => {
          let rgb: { width: number; height: number } | undefined;
          for (const m of shard.messages) {
            const spec = imageSpec(m.topic);
            if (spec == undefined) {
              continue;
            }
            const img = m.value as { width: number; height: number; encoding: string; step: number; data: Uint8Array; frame_id: string };
            const where = `${m.topic} @ ${m.logTime}`;
            assert.equal(img.encoding, spec.encoding, `${where}: encoding`);
            assert.ok(img.width > 0 && img.height > 0, `${where}: empty image`);
            assert.equal(img.step, img.width * spec.bytesPerPixel, `${where}: step (no padding)`);
            assert.equal(img.data.byteLength, img.step * img.height, `${where}: data length != step * height`);
            if (m.topic.startsWith("/camera/")) {
              assert.equal(img.frame_id, "camera", `${where}: frame_id`);
              rgb ??= { width: img.width, height: img.height };
              assert.deepEqual({ width: img.width, height: img.height }, rgb, `${where}: size differs from the other camera images`);
            } else if (padOfTopic(m.topic) != undefined) {
              const pad = padOfTopic(m.topic)!;
              assert.equal(img.frame_id, `${pad}_pad`, `${where}: frame_id`);
              assert.equal(img.width, TACTILE_RESOLUTION);
              assert.equal(img.height, TACTILE_RESOLUTION);
            } else {
              // An optical pad's image or reference: the size /sample/info tactile.optical gives.
              const { pad } = opticalOfTopic(m.topic)!;
              assert.equal(img.frame_id, `${pad}_pad`, `${where}: frame_id`);
              // (an episode's touch between frames: the sensor of the frame whose chunk holds it)
              const info = only(frameOf(shard, m.logTime), "/sample/info");
              const sensor = obj(obj(obj(info.tactile).optical)[pad]);
              assert.deepEqual(sensor.image_size, [img.width, img.height], `${where}: size != /sample/info tactile.optical.${pad}.image_size`);
            }
            if (img.encoding === "32FC1") {
              const view = new DataView(img.data.buffer, img.data.byteOffset, img.data.byteLength);
              for (let i = 0; i < img.data.byteLength; i += 4) {
                const d = view.getFloat32(i, true);
                assert.ok(!Number.isNaN(d) && d >= (m.topic === "/camera/depth" ? 0 : -1), `${where}: depth ${d}`);
              }
            }
          }
        });

        it("CameraCalibration, PoseInFrame and PointCloud are what Foxglove needs", () => {
          for (const [t, sample] of shard.frames) {
            const where = `sample @ ${t}`;
            const rgb = only(sample, "/camera/rgb");
            const cal = only(sample, "/camera/calibration") as {
              frame_id: string; width: number; height: number; distortion_model: string; D: number[]; K: number[]; R: number[]; P: number[];
            };
            assert.equal(cal.frame_id, rgb.frame_id, `${where}: calibration frame != image frame (Foxglove warns)`);
            assert.equal(cal.width, rgb.width, `${where}: calibration width`);
            assert.equal(cal.height, rgb.height, `${where}: calibration height`);
            assert.equal(cal.K.length, 9);
            assert.equal(cal.R.length, 9);
            assert.equal(cal.P.length, 12);
            assert.equal(cal.distortion_model, "plumb_bob");
            assert.equal(cal.D.length, 5);
            const [fx, , cx, , fy, cy] = cal.K as [number, number, number, number, number, number];
            assert.deepEqual(cal.P, [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], `${where}: P != [K | 0]`);
            assert.ok(fx > 0 && fy > 0, `${where}: focal lengths`);

            const pose = only(sample, "/object/pose");
            assert.equal(pose.frame_id, "camera");
            unitQuaternion(obj(pose.pose).orientation, `${where}: /object/pose`);
          }
          if (robot) {
            // Every touch reading's (an episode's between frames too).
            for (const message of shard.messages.filter((m) => m.topic === "/tactile/points")) {
              const where = `/tactile/points @ ${message.logTime}`;
              const cloud = message.value;
              const type = shard.topics.get("/tactile/points")!.parsed as { kind: "protobuf"; type: import("protobufjs").Type };
              const fieldType = type.type.lookupType("foxglove.PackedElementField");
              assert.equal(cloud.frame_id, "camera", `${where}: point cloud frame`);
              assert.equal(cloud.point_stride, POINT_STRIDE, `${where}: point_stride`);
              const fields = (cloud.fields as Obj[]).map((f) => [f.name, f.offset, f.type]);
              assert.deepEqual(
                fields,
                POINT_FIELDS.map(([name, offset, numeric]) => [name, offset, enumValue(fieldType, "NumericType", numeric)]),
                `${where}: point fields`,
              );
              const cpose = obj(cloud.pose);
              assert.deepEqual(obj(cpose.orientation), { x: 0, y: 0, z: 0, w: 1 }, `${where}: point cloud pose`);
              const data = cloud.data as Uint8Array;
              assert.equal(data.byteLength % POINT_STRIDE, 0, `${where}: point data length`);
              const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
              for (let i = 0; i < data.byteLength; i += POINT_STRIDE) {
                const pad = view.getUint32(i + PAD_INDEX_OFFSET, true);
                assert.ok(pad < pads.length, `${where}: pad index ${pad} of ${pads.length} pads`);
                for (let k = 0; k < 4; k++) {
                  assert.ok(Number.isFinite(view.getFloat32(i + 4 * k, true)), `${where}: non-finite point value`);
                }
              }
            }
          }
        });

        it("/tf is one tree rooted at world holding every frame a message names", () => {
          for (const [t, sample] of shard.frames) {
            const where = `sample @ ${t}`;
            const tree = tfTree(sample, where);
            const needed = new Set(["world", "camera", "object"]);
            if (robot) {
              const grasp = graspFrame(sample, only(sample, "/sample/info"));
              assert.ok(grasp != undefined, `${where}: no world -> frame transform in /tf at /sample/info T_world_palm (the grasp frame)`);
              if (allegro) {
                assert.equal(grasp, "palm", `${where}: the Allegro's grasp frame`);
              }
              pads.forEach((pad) => needed.add(`${pad}_pad`));
            }
            // (an episode frame's touch messages up to the next frame are drawn with its /tf)
            for (const list of [...sample.values(), shard.later.get(t) ?? []]) {
              for (const m of list) {
                if (typeof m.value.frame_id === "string") {
                  needed.add(m.value.frame_id);
                }
                for (const entity of (m.value.entities ?? []) as Obj[]) {
                  needed.add(String(entity.frame_id));
                }
              }
            }
            for (const frame of needed) {
              assert.ok(tree.frames.has(frame), `${where}: frame ${frame} is not in /tf`);
            }
          }
        });

        it("/sample/info has the FORMAT.md keys and repeats /object/pose", () => {
          let joints: string | undefined;
          for (const [t, sample] of shard.frames) {
            const where = `sample @ ${t}`;
            const info = only(sample, "/sample/info");
            for (const key of [...SAMPLE_INFO_KEYS, ...(robot ? SAMPLE_INFO_ROBOT_KEYS : []), ...(episode != undefined ? ["episode"] : [])]) {
              assert.ok(key in info, `${where}: /sample/info has no ${key}`);
            }
            if (episode == undefined) {
              assert.ok(!("episode" in info), `${where}: /sample/info episode in a snapshot shard`);
            }
            if (robot) {
              // The grasp holds with the description's grasp.min_touching links (>= 1; the Allegro's 2).
              const touching = info.phalanges_in_contact as string[];
              assert.ok(touching.length >= (allegro ? 2 : 1), `${where}: ${touching.length} touch links in contact`);
              // The robot's joints: as many as its URDF moves (the Allegro's 22), the same in every sample.
              const positions = obj(info.joint_positions);
              const names = Object.keys(positions).sort();
              assert.ok(names.length > 0, `${where}: no joint_positions`);
              for (const name of names) {
                assert.ok(Number.isFinite(positions[name]), `${where}: joint ${name} = ${String(positions[name])}`);
              }
              if (allegro) {
                assert.equal(names.length, ALLEGRO_JOINT_COUNT, `${where}: joint_positions`);
              }
              joints ??= names.join(",");
              assert.equal(names.join(","), joints, `${where}: other joints than the shard's first sample`);
            }
            const tco = obj(info.T_camera_object) as { position: number[]; orientation: number[] };
            const pose = obj(obj(only(sample, "/object/pose")).pose);
            const p = obj(pose.position) as { x: number; y: number; z: number };
            const q = obj(pose.orientation) as { x: number; y: number; z: number; w: number };
            assert.deepEqual(tco.position, [p.x, p.y, p.z], `${where}: T_camera_object.position`);
            assert.deepEqual(tco.orientation, [q.x, q.y, q.z, q.w], `${where}: T_camera_object.orientation`);
            if (models != undefined) {
              assert.ok(models.has(String(info.object_id)), `${where}: object ${String(info.object_id)} not in models_info.json`);
            }
          }
        });

        it("/scene/models shows Foxglove the object mesh and the robot at every sample, after a seek too", (t: TestContext) => {
          const scene = shard.topics.get(SCENE_TOPIC);
          if (scene == undefined && allowNoSceneModels) {
            t.skip(`no ${SCENE_TOPIC} in this shard (allowed by VTGEN_ALLOW_NO_SCENE_MODELS=1)`);
            return;
          }
          assert.ok(scene != undefined, `no ${SCENE_TOPIC} topic (FORMAT: the object's mesh and the robot, once per shard)`);
          const updates = shard.messages.filter((m) => m.topic === SCENE_TOPIC);
          checkSceneModels(shard.frames, updates, robot, models);
        });

        it("/episode/state (episodes): the FORMAT.md record; at a frame's instant the frame's pose, joints and contacts", () => {
          const states = shard.messages.filter((m) => m.topic === EPISODE_STATE_TOPIC);
          if (episode == undefined) {
            assert.equal(states.length, 0, `${EPISODE_STATE_TOPIC} in a snapshot shard`);
            return;
          }
          assert.ok(states.length > 0, `no ${EPISODE_STATE_TOPIC} message`);
          let joints: string | undefined;
          for (const m of states) {
            const where = `${EPISODE_STATE_TOPIC} @ ${m.logTime}`;
            const state = m.value;
            for (const key of STATE_RECORD_KEYS) {
              assert.ok(key in state, `${where}: no ${key}`);
            }
            assert.ok(Math.abs((state.time_s as number) - Number(m.logTime) / 1e9) <= 1e-9, `${where}: time_s ${String(state.time_s)}`);
            for (const key of ["T_world_object", "T_camera_object", "T_world_palm"]) {
              const pose = obj(state[key]);
              assert.equal((pose.position as number[]).length, 3, `${where}: ${key}.position`);
              const [x, y, z, w] = pose.orientation as number[];
              unitQuaternion({ x, y, z, w }, `${where}: ${key}`);
            }
            for (const key of ["linear_velocity", "angular_velocity"]) {
              const v = state[key] as number[];
              assert.ok(v.length === 3 && v.every(Number.isFinite), `${where}: ${key} ${JSON.stringify(v)}`);
            }
            const names = Object.keys(obj(state.joint_positions)).sort().join(",");
            joints ??= names;
            assert.equal(names, joints, `${where}: other joints than the first state's`);
            if (m.logTime === 0n) {
              assert.deepEqual([state.linear_velocity, state.angular_velocity], [[0, 0, 0], [0, 0, 0]], `${where}: the twist at step 0`);
            }
            const frame = shard.frames.get(m.logTime);
            if (frame == undefined) {
              continue;
            }
            // A frame's instant: the state is the frame's.
            const info = only(frame, "/sample/info");
            assert.deepEqual(state.joint_positions, info.joint_positions, `${where}: joint_positions != /sample/info's`);
            assert.deepEqual(state.phalanges_in_contact, info.phalanges_in_contact, `${where}: phalanges_in_contact != /sample/info's`);
            samePose(obj(state.T_world_palm), obj(info.T_world_palm), 1e-12, 1e-12, `${where}: T_world_palm vs /sample/info`);
            // (/episode/state's T_camera_object rotation is within ~1e-7 of /object/pose's, not equal.)
            samePose(obj(state.T_camera_object), obj(info.T_camera_object), 1e-9, 1e-6, `${where}: T_camera_object vs /sample/info`);
            const tf = ((only(frame, "/tf").transforms ?? []) as Obj[]).find((x) => x.parent_frame_id === "world" && x.child_frame_id === "object");
            assert.ok(tf != undefined, `${where}: no world -> object in /tf`);
            const tr = obj(tf.translation) as { x: number; y: number; z: number };
            const rot = obj(tf.rotation) as { x: number; y: number; z: number; w: number };
            samePose(obj(state.T_world_object), { position: [tr.x, tr.y, tr.z], orientation: [rot.x, rot.y, rot.z, rot.w] }, 1e-12, 1e-12, `${where}: T_world_object vs /tf`);
          }
        });

        it("datasets/foxglove-layout.json: every topic it shows is in the shard with a fitting schema, every frame in /tf", (t: TestContext) => {
          if (layoutError != undefined) {
            throw layoutError;
          }
          const skipped: string[] = [];
          for (const ref of topicReferences(layout)) {
            const schema = schemaOf(shard, ref.topic);
            if (schema == undefined) {
              if (!robot && ref.topic.startsWith("/tactile/")) {
                continue; // FORMAT.md: tactile topics only with a robot
              }
              if (robot && padOfTopic(ref.topic) != undefined) {
                // The layout shows a pad of each built-in robot; this robot has other pads (a
                // layout is static). At least one pad it shows must be this robot's (below).
                skipped.push(`${ref.topic} (this robot's pads: ${pads.join(", ")})`);
                continue;
              }
              if (robot && opticalOfTopic(ref.topic) != undefined) {
                // Only pads with an optical sensor have images (a config may have none).
                skipped.push(`${ref.topic} (this shard's optical pads: ${optical.join(", ") || "none"})`);
                continue;
              }
              if (robot && forcePadOfTopic(ref.topic) != undefined) {
                // Force fields only with robot.tactile.force_field (the MuJoCo backend).
                skipped.push(`${ref.topic} (this shard's force fields: ${forces.join(", ") || "none"})`);
                continue;
              }
              if (robot && markersPadOfTopic(ref.topic) != undefined) {
                // Marker flow only with force fields, on optical pads with markers.
                skipped.push(`${ref.topic} (marker flow: with force fields on optical pads with markers)`);
                continue;
              }
              if (ref.topic === SCENE_TOPIC && allowNoSceneModels) {
                skipped.push(ref.topic);
                continue;
              }
              if (episode == undefined && ref.topic in EPISODE_TOPICS) {
                skipped.push(`${ref.topic} (episodes only)`);
                continue;
              }
              assert.fail(`${ref.panel} shows ${ref.topic}, which is not in the shard`);
            }
            const fits =
              ref.use === "image" ? IMAGE_SCHEMAS.has(schema)
              : ref.use === "calibration" ? CALIBRATION_SCHEMAS.has(schema)
              : ref.use === "scene" ? FOXGLOVE_RENDERABLE_SCHEMAS.has(schema)
              : true;
            assert.ok(fits, `${ref.panel} uses ${ref.topic} (${schema}) as ${ref.use}`);
          }
          // Plot series: every message on the topic gives the series a number.
          for (const series of plotSeries(layout)) {
            if (!shard.topics.has(series.topic)) {
              continue; // skipped above, or failed
            }
            const messages = shard.messages.filter((m) => m.topic === series.topic);
            assert.ok(messages.length > 0, `${series.panel} plots ${series.topic}, which has no message`);
            for (const m of messages) {
              const value = valueAtPath(m.value, series.path);
              assert.ok(typeof value === "number" && Number.isFinite(value), `${series.panel}: ${series.topic}${series.path} @ ${m.logTime} is ${JSON.stringify(value)}, not a number`);
            }
          }
          const first = shard.frames.values().next().value as Map<string, Decoded[]>;
          const tree = tfTree(first, "first sample");
          for (const ref of frameReferences(layout)) {
            assert.ok(tree.frames.has(ref.frame), `${ref.panel} names frame ${ref.frame}, which is not in /tf`);
          }
          for (const [panel, config] of Object.entries(layout.configById)) {
            const imageMode = (config.imageMode ?? {}) as { imageTopic?: string; calibrationTopic?: string };
            if (imageMode.imageTopic == undefined || imageMode.calibrationTopic == undefined) {
              continue;
            }
            if (!shard.topics.has(imageMode.imageTopic)) {
              continue;
            }
            const image = only(first, imageMode.imageTopic);
            const cal = only(first, imageMode.calibrationTopic);
            assert.equal(image.frame_id, cal.frame_id, `${panel}: image and calibration frames differ`);
            assert.equal(image.width, cal.width, `${panel}: image and calibration sizes differ`);
          }
          if (robot) {
            const shown = topicReferences(layout).filter((r) => padOfTopic(r.topic) != undefined && shard.topics.has(r.topic));
            assert.ok(shown.length > 0, `the layout shows none of this robot's pads (${pads.join(", ")})`);
          }
          if (skipped.length > 0) {
            t.diagnostic(`not in this shard, not checked: ${[...new Set(skipped)].join(", ")}`);
          }
        });
      });
    }
  });
}
