// Checks shared by the shard test and its self-test: the /tf tree as Foxglove builds it, and the
// /scene/models entities as Foxglove's 3D panel holds them while playing and after a seek.
import assert from "node:assert/strict";

import { toNanos } from "./foxglove.js";
import { SCENE_TOPIC } from "./format.js";
import { FOXGLOVE_GLTF_UP, bounds, compose, multiplyMat, parseGlb, sceneVertices } from "./glb.js";
import type { Decoded } from "./shard.js";

export type Obj = Record<string, unknown>;
export const obj = (v: unknown): Obj => v as Obj;

export const near = (a: number, b: number, tol: number): boolean => Math.abs(a - b) <= tol;

export function unitQuaternion(q: unknown, what: string): void {
  const { x, y, z, w } = obj(q) as { x: number; y: number; z: number; w: number };
  const n = Math.hypot(x, y, z, w);
  assert.ok(near(n, 1, 1e-6), `${what}: quaternion norm ${n}, Foxglove needs a unit quaternion`);
}

export type Sample = Map<string, Decoded[]>;

export function only(sample: Sample, topic: string): Obj {
  const list = sample.get(topic);
  assert.ok(list != undefined && list.length === 1, `${topic}: expected one message in the sample`);
  return list[0]!.value;
}

export type Tree = { parent: Map<string, string>; frames: Set<string> };

/** The /tf of one sample as Foxglove's transform tree sees it: one parent per frame, all under world. */
export function tfTree(sample: Sample, where: string): Tree {
  const parent = new Map<string, string>();
  for (const message of sample.get("/tf") ?? []) {
    for (const tf of (message.value.transforms ?? []) as Obj[]) {
      const child = String(tf.child_frame_id);
      const par = String(tf.parent_frame_id);
      assert.ok(child !== "" && par !== "", `${where}: a transform without frame ids`);
      assert.ok(!parent.has(child), `${where}: frame ${child} has two parents in /tf`);
      unitQuaternion(tf.rotation, `${where}: /tf ${par} -> ${child}`);
      parent.set(child, par);
    }
  }
  const frames = new Set<string>([...parent.keys(), ...parent.values()]);
  for (const frame of frames) {
    let f = frame;
    for (let steps = 0; f !== "world"; steps++) {
      const p = parent.get(f);
      assert.ok(p != undefined, `${where}: frame ${frame} does not reach world in /tf (stops at ${f})`);
      assert.ok(steps < 1000, `${where}: /tf has a cycle through ${frame}`);
      f = p;
    }
  }
  return { parent, frames };
}

/** Foxglove's entity state after applying SceneUpdate messages in order. */
export function applySceneUpdates(updates: Obj[], state = new Map<string, Obj>()): Map<string, Obj> {
  for (const update of updates) {
    for (const deletion of (update.deletions ?? []) as Obj[]) {
      // foxglove.SceneEntityDeletion.Type: MATCHING_ID = 0, ALL = 1
      if (deletion.type === 1) {
        state.clear();
      } else {
        state.delete(String(deletion.id));
      }
    }
    for (const entity of (update.entities ?? []) as Obj[]) {
      state.set(String(entity.id), entity);
    }
  }
  return state;
}

export type ModelInfo = { id: string; extents: [number, number, number] };

/** Vertices of a ModelPrimitive in its entity's frame, placed as Foxglove places the glTF. */
export function modelVertices(model: Obj, where: string): Float64Array {
  assert.equal(model.url, "", `${where}: the model is expected embedded (data), not at a url`);
  assert.equal(model.media_type, "model/gltf-binary", `${where}: media_type`);
  const data = model.data as Uint8Array;
  assert.ok(data.byteLength > 0, `${where}: empty model data`);
  const pose = obj(model.pose);
  const position = obj(pose.position) as { x: number; y: number; z: number };
  const orientation = obj(pose.orientation) as { x: number; y: number; z: number; w: number };
  const scale = obj(model.scale) as { x: number; y: number; z: number };
  unitQuaternion(orientation, `${where}: model pose`);
  assert.ok(
    scale.x > 0 && scale.y > 0 && scale.z > 0,
    `${where}: model scale ${JSON.stringify(scale)} (an unset scale decodes as 0: an invisible model)`,
  );
  const outer = multiplyMat(
    compose(
      [position.x, position.y, position.z],
      [orientation.x, orientation.y, orientation.z, orientation.w],
      [scale.x, scale.y, scale.z],
    ),
    FOXGLOVE_GLTF_UP,
  );
  const vertices = sceneVertices(parseGlb(data), outer);
  assert.ok(vertices.length > 0, `${where}: the glTF has no vertices`);
  return vertices;
}

/**
 * /scene/models as the 3D and Image panels hold it at every sample: playing forward (every update
 * applied in order) and after a seek (Foxglove clears the scene and replays only the latest message
 * of the topic at or before the new time). In both, the sample's object must be the one entity in
 * frame `object`, its glTF mesh (turned z-up as Foxglove turns it) must span the object's model
 * extents from models_info.json, centred, and (with a robot) there must be robot entities too.
 * Every entity: frame in /tf, frame_locked (so it follows /tf), lifetime 0, visible models.
 */
export function checkSceneModels(
  samples: Map<bigint, Sample>,
  updates: Decoded[],
  robot: boolean,
  models: Map<string, ModelInfo> | undefined,
): void {
  const times = [...samples.keys()];
  assert.ok(updates.length > 0, `no ${SCENE_TOPIC} message`);
  assert.equal(updates[0]!.logTime, times[0], `${SCENE_TOPIC} must be in the shard's first sample`);
  const playing = new Map<string, Obj>();
  let next = 0;
  for (const time of times) {
    const sample = samples.get(time)!;
    const where = `sample @ ${time}`;
    const info = only(sample, "/sample/info");
    const tree = tfTree(sample, where);
    const upTo: Obj[] = [];
    while (next < updates.length && updates[next]!.logTime <= time) {
      upTo.push(updates[next]!.value);
      next++;
    }
    applySceneUpdates(upTo, playing);
    const latest = updates.filter((u) => u.logTime <= time).at(-1)!;
    const afterSeek = applySceneUpdates([latest.value]);
    for (const [mode, state] of [["playing", playing], ["after a seek", afterSeek]] as const) {
      const ctx = `${where} (${mode})`;
      const entities = [...state.values()];
      const objects = entities.filter((e) => e.frame_id === "object");
      assert.equal(objects.length, 1, `${ctx}: ${objects.length} entities in frame object, expected the sample's object alone`);
      if (robot) {
        assert.ok(entities.some((e) => e.frame_id !== "object"), `${ctx}: no robot entities`);
      }
      for (const entity of entities) {
        const id = `${ctx}: entity ${String(entity.id)}`;
        assert.ok(tree.frames.has(String(entity.frame_id)), `${id}: frame ${String(entity.frame_id)} is not in /tf`);
        assert.ok(
          entity.frame_locked === true || entity.frame_id === "world",
          `${id}: frame_locked must be true, or Foxglove leaves it where its frame was at the message time`,
        );
        // An absent lifetime decodes to 0 in Foxglove: the entity lives until replaced.
        assert.equal(entity.lifetime == undefined ? 0n : toNanos(entity.lifetime), 0n, `${id}: lifetime must be 0 (forever)`);
        for (const model of (entity.models ?? []) as Obj[]) {
          modelVertices(model, id);
        }
      }
      const objectModels = (objects[0]!.models ?? []) as Obj[];
      assert.ok(objectModels.length > 0, `${ctx}: the object entity has no ModelPrimitive`);
      const model = models?.get(String(info.object_id));
      if (model == undefined) {
        continue;
      }
      const parts = objectModels.map((m) => modelVertices(m, `${ctx}: object model`));
      const { min, max } = bounds(Float64Array.from(parts.flatMap((a) => Array.from(a))));
      for (let k = 0; k < 3; k++) {
        const half = model.extents[k]! / 2;
        assert.ok(
          near(min[k]!, -half, 2e-4) && near(max[k]!, half, 2e-4),
          `${ctx}: ${model.id} mesh as Foxglove draws it spans [${min[k]!.toFixed(4)}, ${max[k]!.toFixed(4)}] ` +
            `on axis ${"xyz"[k]}, models_info.json says ±${half.toFixed(4)} ` +
            `(glTF is y-up: Foxglove turns every glTF +90° about x)`,
        );
      }
    }
  }
}
