// Self-test of the checks with hand-made messages: a /scene/models that Foxglove shows right
// passes, and each way of getting it wrong (z-up glTF, not frame-locked, zero scale, one mesh for
// a shard of two objects, an update that is not complete on its own) fails; Foxglove's JSON Schema
// rules and the layout structure checks reject what Foxglove rejects.
import assert from "node:assert/strict";
import { describe, it } from "node:test";

import { checkSceneModels, type ModelInfo, type Obj, type Sample } from "../src/checks.js";
import { checkJsonSchema } from "../src/foxglove.js";
import { checkLayout, plotSeries, topicOfPath, topicReferences, valueAtPath } from "../src/layout.js";
import type { Decoded } from "../src/shard.js";

/** A GLB of an axis-aligned box centred at the origin; `yUp` stores object-frame (x, y, z) as glTF (x, z, -y). */
function boxGlb(extents: [number, number, number], yUp: boolean): Uint8Array {
  const [hx, hy, hz] = extents.map((e) => e / 2) as [number, number, number];
  const positions: number[] = [];
  for (const x of [-hx, hx]) {
    for (const y of [-hy, hy]) {
      for (const z of [-hz, hz]) {
        positions.push(...(yUp ? [x, z, -y] : [x, y, z]));
      }
    }
  }
  const bin = new Uint8Array(new Float32Array(positions).buffer);
  const min = [0, 1, 2].map((k) => Math.min(...positions.filter((_, i) => i % 3 === k)));
  const max = [0, 1, 2].map((k) => Math.max(...positions.filter((_, i) => i % 3 === k)));
  const json = {
    asset: { version: "2.0" },
    scene: 0,
    scenes: [{ nodes: [0] }],
    nodes: [{ mesh: 0 }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 }, mode: 0 }] }],
    accessors: [{ bufferView: 0, componentType: 5126, count: 8, type: "VEC3", min, max }],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: bin.byteLength }],
    buffers: [{ byteLength: bin.byteLength }],
  };
  let text = JSON.stringify(json);
  while (text.length % 4 !== 0) text += " ";
  const jsonBytes = new TextEncoder().encode(text);
  const total = 12 + 8 + jsonBytes.byteLength + 8 + bin.byteLength;
  const out = new Uint8Array(total);
  const view = new DataView(out.buffer);
  view.setUint32(0, 0x46546c67, true);
  view.setUint32(4, 2, true);
  view.setUint32(8, total, true);
  view.setUint32(12, jsonBytes.byteLength, true);
  view.setUint32(16, 0x4e4f534a, true);
  out.set(jsonBytes, 20);
  const binAt = 20 + jsonBytes.byteLength;
  view.setUint32(binAt, bin.byteLength, true);
  view.setUint32(binAt + 4, 0x004e4942, true);
  out.set(bin, binAt + 8);
  return out;
}

const stamp = (t: bigint) => ({ seconds: String(t / 1_000_000_000n), nanos: Number(t % 1_000_000_000n) });
const ZERO = { seconds: "0", nanos: 0 };
const IDENTITY = { position: { x: 0, y: 0, z: 0 }, orientation: { x: 0, y: 0, z: 0, w: 1 } };

const BOX: ModelInfo = { id: "box", extents: [0.08, 0.1, 0.03] };
const CAN: ModelInfo = { id: "can", extents: [0.068, 0.068, 0.102] };
const MODELS = new Map([BOX, CAN].map((m) => [m.id, m]));

function entity(t: bigint, id: string, frame: string, glb: Uint8Array, overrides: Obj = {}): Obj {
  return {
    timestamp: stamp(t),
    frame_id: frame,
    id,
    lifetime: ZERO,
    frame_locked: true,
    models: [{ pose: IDENTITY, scale: { x: 1, y: 1, z: 1 }, color: null, override_color: false, url: "", media_type: "model/gltf-binary", data: glb }],
    ...overrides,
  };
}

function decoded(topic: string, t: bigint, value: Obj): Decoded {
  return { topic, channelId: 0, logTime: t, publishTime: t, sequence: 0, value };
}

/** Samples at 0, 0.1, … s; `objects[k]` is sample k's object id. */
function samples(objects: string[]): Map<bigint, Sample> {
  const out = new Map<bigint, Sample>();
  objects.forEach((id, k) => {
    const t = BigInt(k) * 100_000_000n;
    const tf = (child: string) => ({ timestamp: stamp(t), parent_frame_id: "world", child_frame_id: child, translation: { x: 0, y: 0, z: 0 }, rotation: { x: 0, y: 0, z: 0, w: 1 } });
    out.set(
      t,
      new Map([
        ["/tf", [decoded("/tf", t, { transforms: ["camera", "object", "link_1"].map(tf) })]],
        ["/sample/info", [decoded("/sample/info", t, { object_id: id, index: k })]],
      ]),
    );
  });
  return out;
}

const update = (t: bigint, entities: Obj[], deletions: Obj[] = []) =>
  decoded("/scene/models", t, { deletions, entities });

const good = (t: bigint, model: ModelInfo) => [
  entity(t, "object", "object", boxGlb(model.extents, true)),
  entity(t, "link_1", "link_1", boxGlb([0.02, 0.02, 0.1], true)),
];

describe("checkSceneModels (what Foxglove's 3D panel will show)", () => {
  it("accepts a y-up glTF object + robot, frame-locked, once per shard", () => {
    checkSceneModels(samples(["box", "box", "box"]), [update(0n, good(0n, BOX))], true, MODELS);
  });

  it("rejects a glTF written z-up (Foxglove turns it +90° about x)", () => {
    const entities = [entity(0n, "object", "object", boxGlb(BOX.extents, false)), good(0n, BOX)[1]!];
    assert.throws(() => checkSceneModels(samples(["box"]), [update(0n, entities)], true, MODELS), /turns every glTF/);
  });

  it("rejects an entity that is not frame_locked", () => {
    const entities = [entity(0n, "object", "object", boxGlb(BOX.extents, true), { frame_locked: false }), good(0n, BOX)[1]!];
    assert.throws(() => checkSceneModels(samples(["box"]), [update(0n, entities)], true, MODELS), /frame_locked/);
  });

  it("rejects an unset (zero) model scale", () => {
    const e = entity(0n, "object", "object", boxGlb(BOX.extents, true));
    (e.models as Obj[])[0]!.scale = { x: 0, y: 0, z: 0 };
    assert.throws(() => checkSceneModels(samples(["box"]), [update(0n, [e, good(0n, BOX)[1]!])], true, MODELS), /scale/);
  });

  it("rejects a shard of two objects with the first object's mesh only", () => {
    assert.throws(() => checkSceneModels(samples(["box", "can"]), [update(0n, good(0n, BOX))], true, MODELS), /can mesh/);
  });

  it("accepts a second, complete update where the object changes (same entity id replaces it)", () => {
    const t1 = 100_000_000n;
    checkSceneModels(samples(["box", "can", "can"]), [update(0n, good(0n, BOX)), update(t1, good(t1, CAN))], true, MODELS);
  });

  it("rejects a second update that relies on the first (after a seek only the latest message is replayed)", () => {
    const t1 = 100_000_000n;
    const partial = update(t1, [entity(t1, "object", "object", boxGlb(CAN.extents, true))]);
    assert.throws(
      () => checkSceneModels(samples(["box", "can"]), [update(0n, good(0n, BOX)), partial], true, MODELS),
      /after a seek\): no robot entities/,
    );
  });

  it("rejects a second object entity under a new id without deleting the first", () => {
    const t1 = 100_000_000n;
    const second = update(t1, [entity(t1, "object-can", "object", boxGlb(CAN.extents, true)), good(t1, CAN)[1]!]);
    assert.throws(
      () => checkSceneModels(samples(["box", "can"]), [update(0n, good(0n, BOX)), second], true, MODELS),
      /\(playing\): 2 entities in frame object/,
    );
  });
});

describe("checkJsonSchema (Foxglove's JSON Schema subset)", () => {
  it("accepts vtgen's /sample/info schema", () => {
    const schema = {
      title: "vtgen.SampleInfo",
      type: "object",
      properties: {
        split: { type: "string" },
        index: { type: "integer" },
        randomized: { type: "boolean" },
        T_world_camera: { type: "object" },
        phalanges: { type: "array", items: { type: "string" } },
      },
    };
    assert.deepEqual(checkJsonSchema(schema, "vtgen.SampleInfo"), ["split", "index", "randomized", "T_world_camera", "phalanges"]);
  });

  it("rejects what Foxglove cannot decode", () => {
    assert.throws(() => checkJsonSchema({ type: "object", properties: { a: { type: "null" } } }, "x"), /not supported/);
    assert.throws(() => checkJsonSchema({ type: "object", properties: { a: {} } }, "x"), /not supported/);
    assert.throws(() => checkJsonSchema({ type: "object", properties: { a: { type: ["number", "null"] } } }, "x"), /not supported/);
    assert.throws(() => checkJsonSchema({ type: "object", properties: { a: { type: "array" } } }, "x"), /items/);
    assert.throws(() => checkJsonSchema({ properties: {} }, "x"), /"type": "object"/);
  });
});

describe("layout checks", () => {
  const base = { globalVariables: {}, userNodes: {}, playbackConfig: { speed: 1 } };

  it("reads topics from 3D, Image and Raw Messages panels", () => {
    const layout = checkLayout({
      ...base,
      configById: {
        "3D!a": { topics: { "/tactile/points": { visible: true } } },
        "Image!b": { imageMode: { imageTopic: "/camera/rgb", calibrationTopic: "/camera/calibration" } },
        "RawMessages!c": { topicPath: "/sample/info.occlusion.level" },
      },
      layout: { direction: "row", first: "3D!a", second: { direction: "column", first: "Image!b", second: "RawMessages!c" } },
    });
    assert.deepEqual(
      topicReferences(layout).map((r) => `${r.topic} ${r.use}`),
      ["/tactile/points scene", "/camera/rgb image", "/camera/calibration calibration", "/sample/info raw"],
    );
    assert.equal(topicOfPath("/tactile/ff_distal/depth"), "/tactile/ff_distal/depth");
  });

  it("reads Plot series and evaluates their message paths as Foxglove does (.field, [index])", () => {
    const layout = checkLayout({
      ...base,
      configById: {
        "Plot!p": { paths: [{ value: "/episode/state.T_world_object.position[2]" }, { value: "/episode/state.linear_velocity[0]" }] },
      },
      layout: "Plot!p",
    });
    assert.deepEqual(plotSeries(layout), [
      { panel: "Plot!p", topic: "/episode/state", path: ".T_world_object.position[2]" },
      { panel: "Plot!p", topic: "/episode/state", path: ".linear_velocity[0]" },
    ]);
    assert.deepEqual(topicReferences(layout).map((r) => `${r.topic} ${r.use}`), ["/episode/state raw", "/episode/state raw"]);
    const state = { T_world_object: { position: [0.1, 0.2, 0.3] }, linear_velocity: [1, 2, 3] };
    assert.equal(valueAtPath(state, ".T_world_object.position[2]"), 0.3);
    assert.equal(valueAtPath(state, ".linear_velocity[0]"), 1);
    assert.equal(valueAtPath(state, ".linear_velocity[3]"), undefined);
    assert.equal(valueAtPath(state, ".angular_velocity[0]"), undefined);
    assert.equal(valueAtPath(state, ".T_world_object.position.x"), undefined);
    assert.throws(() => valueAtPath(state, ".linear_velocity[:]"), /not .field or \[index\]/);
    assert.throws(() => plotSeries(checkLayout({ ...base, configById: { "Plot!p": { paths: [{}] } }, layout: "Plot!p" })), /without a string "value"/);
  });

  it("rejects a tree leaf without config, a config outside the tree, an unknown panel type", () => {
    assert.throws(() => checkLayout({ ...base, configById: {}, layout: "3D!a" }), /no configById entry/);
    assert.throws(() => checkLayout({ ...base, configById: { "3D!a": {}, "3D!b": {} }, layout: "3D!a" }), /not in the layout tree/);
    assert.throws(() => checkLayout({ ...base, configById: { "Nope!a": {} }, layout: "Nope!a" }), /unknown type/);
  });
});
