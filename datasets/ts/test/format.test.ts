// The reader's constants (src/format.ts) against datasets/format.json, the format as the Rust
// crate that writes it describes it (a Rust test keeps that file current): a constant that drifts
// from the writer fails here, before any shard is read.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { describe, it } from "node:test";

import * as F from "../src/format.js";

type TopicEntry = { topic: string; schema: string; message_encoding: string; image_encoding?: string; required?: boolean; when: string };
type FormatJson = {
  format_version: number;
  sample_period_ns: number;
  shard_metadata: { name: string; keys: string[]; optional_keys: Record<string, string> };
  topics: TopicEntry[];
  pad_topics: TopicEntry[];
  image_encodings: Record<string, { channels: number; bytes_per_channel: number }>;
  tactile_points: { fields: { name: string; offset: number; type: string }[]; point_stride: number };
  force_cells: { fields: { name: string; offset: number; type: string }[]; point_stride: number };
  marker_points: { fields: { name: string; offset: number; type: string }[]; point_stride: number };
  records: Record<string, string[]>;
};

// Compiled to dist/test/: datasets/format.json is three folders up.
const format = JSON.parse(readFileSync(new URL("../../../format.json", import.meta.url), "utf8")) as FormatJson;
const topic = (name: string): TopicEntry => {
  const t = format.topics.find((e) => e.topic === name);
  assert.ok(t, `format.json has no topic ${name}`);
  return t;
};
/** The reader's name for a topic's schema: the protobuf schema, or `json` for a JSON topic. */
const schemaOf = (t: TopicEntry): string => (t.message_encoding === "json" ? "json" : t.schema);
const sorted = (keys: readonly string[]): string[] => [...keys].sort();
/** The pad topic of format.json whose pattern is `pattern` (`/tactile/{pad}/...`). */
const padTopic = (pattern: string): TopicEntry => {
  const t = format.pad_topics.find((e) => e.topic === pattern);
  assert.ok(t, `format.json has no pad topic ${pattern}`);
  return t;
};
const bytesPerPixel = (encoding: string): number => {
  const e = format.image_encodings[encoding];
  assert.ok(e, `format.json has no image encoding ${encoding}`);
  return e.channels * e.bytes_per_channel;
};

describe("src/format.ts agrees with datasets/format.json", () => {
  it("the timeline and the shard metadata", () => {
    assert.equal(F.SAMPLE_PERIOD_NS, BigInt(format.sample_period_ns));
    assert.equal(F.SHARD_METADATA, format.shard_metadata.name);
    assert.deepEqual(F.SHARD_METADATA_KEYS, [...format.shard_metadata.keys, "occlusion_histogram"]);
    assert.ok("occlusion_histogram" in format.shard_metadata.optional_keys);
    assert.ok(F.EPISODE_METADATA_KEY in format.shard_metadata.optional_keys);
  });

  it("every sample's topics, in the order they are written, with their schemas", () => {
    const required = format.topics.filter((t) => t.required);
    assert.deepEqual(Object.keys(F.BASE_TOPICS), required.map((t) => t.topic));
    for (const t of required) assert.equal(F.BASE_TOPICS[t.topic], schemaOf(t), t.topic);
    const noisy = format.topics.filter((t) => t.when === "depth_noise");
    assert.deepEqual(F.NOISE_TOPICS, Object.fromEntries(noisy.map((t) => [t.topic, schemaOf(t)])));
    assert.equal(F.SCENE_SCHEMA, topic(F.SCENE_TOPIC).schema);
    assert.deepEqual(F.EPISODE_TOPICS, { [F.EPISODE_STATE_TOPIC]: schemaOf(topic(F.EPISODE_STATE_TOPIC)) });
    assert.equal(topic(F.EPISODE_STATE_TOPIC).when, "episode");
  });

  it("the robot's topics: the point cloud and each pad's images", () => {
    const pad = "{pad}";
    const [depth, image, reference] = format.pad_topics;
    assert.ok(depth && image && reference);
    assert.deepEqual(
      [F.padDepthTopic(pad), F.padImageTopic(pad), F.padReferenceTopic(pad)],
      [depth.topic, image.topic, reference.topic],
    );
    const points = topic("/tactile/points");
    assert.equal(points.when, "robot");
    assert.deepEqual(F.robotTopics(["p"], ["p"]), {
      "/tactile/points": points.schema,
      [F.padDepthTopic("p")]: depth.schema,
      [F.padImageTopic("p")]: image.schema,
      [F.padReferenceTopic("p")]: reference.schema,
    });
  });

  it("each pad's force field: a point cloud with robot.tactile.force_field, cells as force_cells lays them out", () => {
    const force = padTopic(F.padForceTopic("{pad}"));
    assert.equal(force.schema, "foxglove.PointCloud");
    assert.equal(force.message_encoding, "protobuf");
    assert.equal(force.when, "force_field");
    assert.equal(force.image_encoding, undefined);
    // Every pad topic of format.json is one the reader names.
    const patterns = [F.padDepthTopic, F.padImageTopic, F.padReferenceTopic, F.padForceTopic, F.padMarkersTopic].map((f) => f("{pad}"));
    assert.deepEqual(sorted(format.pad_topics.map((t) => t.topic)), sorted(patterns));
    assert.deepEqual(F.robotTopics(["p"], [], ["p"]), {
      "/tactile/points": topic("/tactile/points").schema,
      [F.padDepthTopic("p")]: padTopic(F.padDepthTopic("{pad}")).schema,
      [F.padForceTopic("p")]: force.schema,
    });
    assert.equal(F.forcePadOfTopic(force.topic.replace("{pad}", "th_distal")), "th_distal");
    assert.deepEqual(
      F.FORCE_FIELDS,
      format.force_cells.fields.map((f) => [f.name, f.offset, f.type]),
    );
    assert.equal(F.FORCE_STRIDE, format.force_cells.point_stride);
  });

  it("each optical pad's marker flow: a point cloud with robot.tactile.force_field, points as marker_points lays them out", () => {
    const markers = padTopic(F.padMarkersTopic("{pad}"));
    assert.equal(markers.schema, "foxglove.PointCloud");
    assert.equal(markers.message_encoding, "protobuf");
    assert.equal(markers.when, "force_field");
    assert.equal(markers.image_encoding, undefined);
    assert.equal(F.robotTopics(["p"], ["p"], [], ["p"])[F.padMarkersTopic("p")], markers.schema);
    assert.equal(F.markersPadOfTopic(markers.topic.replace("{pad}", "th_distal")), "th_distal");
    assert.deepEqual(
      F.MARKER_FIELDS,
      format.marker_points.fields.map((f) => [f.name, f.offset, f.type]),
    );
    assert.equal(F.MARKER_STRIDE, format.marker_points.point_stride);
  });

  it("image encodings and their bytes per pixel", () => {
    for (const [name, spec] of Object.entries(F.IMAGE_ENCODINGS)) {
      assert.equal(spec.encoding, topic(name).image_encoding, name);
      assert.equal(spec.bytesPerPixel, bytesPerPixel(spec.encoding), name);
    }
    const [depth, image, reference] = format.pad_topics;
    assert.equal(F.PAD_DEPTH_ENCODING.encoding, depth?.image_encoding);
    assert.equal(F.PAD_OPTICAL_ENCODING.encoding, image?.image_encoding);
    assert.equal(F.PAD_OPTICAL_ENCODING.encoding, reference?.image_encoding);
    for (const spec of [F.PAD_DEPTH_ENCODING, F.PAD_OPTICAL_ENCODING]) {
      assert.equal(spec.bytesPerPixel, bytesPerPixel(spec.encoding), spec.encoding);
    }
  });

  it("the tactile point layout", () => {
    assert.deepEqual(
      F.POINT_FIELDS,
      format.tactile_points.fields.map((f) => [f.name, f.offset, f.type]),
    );
    assert.equal(F.POINT_STRIDE, format.tactile_points.point_stride);
  });

  it("the JSON records' keys", () => {
    const r = format.records;
    // The reader requires these of /sample/info; the format may have more (all are listed there).
    for (const key of F.SAMPLE_INFO_KEYS) assert.ok(r.sample_info?.includes(key), `sample_info has no ${key}`);
    assert.deepEqual(sorted(F.SAMPLE_INFO_ROBOT_KEYS), r.sample_info_robot);
    assert.deepEqual(sorted(F.SAMPLE_INFO_EPISODE_KEYS), r.episode_frame);
    assert.deepEqual(sorted(F.EPISODE_RECORD_KEYS), r.episode);
    assert.deepEqual(sorted(F.STATE_RECORD_KEYS), r.state);
    assert.deepEqual(sorted(F.PAD_FORCE_INFO_KEYS), r.pad_force);
    for (const key of F.TACTILE_FORCE_INFO_KEYS) assert.ok(r.touch_info?.includes(key), `touch_info has no ${key}`);
  });
});
