// The contact force fields of one touch reading (FORMAT.md, `/tactile/<pad>/force` and "Force
// fields"): per pad, an R x R grid of the pressure, shear and slip the object puts on the pad's
// sensing area, read the way the Python (`tactile["forces"]`) and Rust (`TactileData::forces`)
// readers read them. With them, the optical pads' marker flow (`/tactile/<pad>/markers`): where
// the gel has moved each printed marker, and its rest position (Python `tactile["markers"]`, Rust
// `TactileData::marker_flow`).
import type { Sample } from "./checks.js";
import { FORCE_STRIDE, MARKER_STRIDE } from "./format.js";
import { readPadStream, type PadStream } from "./pads.js";

/**
 * One pad's force field: `resolution`² cells, row-major (cell `(u, v)`, column u along the pad's
 * x, row v along its y, at index `v · R + u`), in the pad frame.
 */
export type ForceField = {
  resolution: number;
  /** The cells' centres (x, y; m): `2 · R²` values. */
  position: Float32Array;
  /** The normal pressure the object puts on each cell (Pa, >= 0): `R²` values. */
  pressure: Float32Array;
  /** The shear traction on each cell along the pad's x and y (Pa): `2 · R²` values. */
  shear: Float32Array;
  /** 1 where the cell's traction is at its friction limit, else 0: `R²` values. */
  slip: Uint8Array;
};

/**
 * A decoded `foxglove.PointCloud` of `/tactile/<pad>/force` as a {@link ForceField}. The cloud must
 * be a square grid of at least one 28-byte cell (`point_stride` 28); an Error names `where`
 * otherwise.
 */
export function decodeForceField(value: Record<string, unknown>, where: string): ForceField {
  const { point_stride: stride, data } = value as { point_stride: number; data: Uint8Array };
  if (stride !== FORCE_STRIDE || data.byteLength % FORCE_STRIDE !== 0) {
    throw new Error(`${where}: expected ${FORCE_STRIDE}-byte force cells, got point stride ${stride} and ${data.byteLength} bytes of data`);
  }
  const n = data.byteLength / FORCE_STRIDE;
  const r = Math.round(Math.sqrt(n));
  if (n === 0 || r * r !== n) {
    throw new Error(`${where}: ${n} force cells, not a square R x R grid (R >= 1)`);
  }
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const field: ForceField = {
    resolution: r,
    position: new Float32Array(2 * n),
    pressure: new Float32Array(n),
    shear: new Float32Array(2 * n),
    slip: new Uint8Array(n),
  };
  for (let k = 0; k < n; k++) {
    const at = k * FORCE_STRIDE;
    field.position[2 * k] = view.getFloat32(at, true);
    field.position[2 * k + 1] = view.getFloat32(at + 4, true);
    field.pressure[k] = view.getFloat32(at + 12, true);
    field.shear[2 * k] = view.getFloat32(at + 16, true);
    field.shear[2 * k + 1] = view.getFloat32(at + 20, true);
    field.slip[k] = view.getUint32(at + 24, true) !== 0 ? 1 : 0;
  }
  return field;
}

/** `/tactile/<pad>/force`: a square grid per pad, every pad's the same resolution; `/sample/info`
 * `tactile.forces` lists the pads. */
export const PAD_FORCE: PadStream<ForceField> = {
  suffix: "/force",
  what: "force fields",
  decode: decodeForceField,
  listed: { key: "forces", padsAre: "pads" },
  same: { aspect: "resolution", of: (f) => `${f.resolution}x${f.resolution}` },
};

/**
 * The force fields of one touch reading (a sample, or an episode's touch messages of one instant),
 * read by {@link readPadStream}: the pads are its `/tactile/<pad>/force` topics in the order of
 * their channels (the writer adds them in the robot's pad order). When `pads` (the reading's pads,
 * from its `/tactile/<pad>/depth` channels) is given, each must be one of them; when `/sample/info`
 * has `tactile.forces`, it must list exactly these pads; every field has the same resolution.
 * Throws an Error naming `where` and the topic otherwise. Empty without force topics.
 */
export function readForceFields(sample: Sample, where: string, pads?: readonly string[]): Map<string, ForceField> {
  return readPadStream(sample, where, PAD_FORCE, pads).values;
}

/**
 * One optical pad's markers, in the rest grid's order (rows along the pad's y, each row along x),
 * in the pad frame: marker k's values at `2k` (x) and `2k + 1` (y).
 */
export type MarkerFlow = {
  count: number;
  /** Where each marker is (m): `2 · count` values. */
  position: Float32Array;
  /** Each marker's rest position (m): `2 · count` values; `position − rest` is its displacement. */
  rest: Float32Array;
};

/**
 * A decoded `foxglove.PointCloud` of `/tactile/<pad>/markers` as a {@link MarkerFlow}. The cloud
 * must be whole 20-byte markers (`point_stride` 20; none is a sensor whose pitch leaves no dot
 * inside its sensing area); an Error names `where` otherwise.
 */
export function decodeMarkerFlow(value: Record<string, unknown>, where: string): MarkerFlow {
  const { point_stride: stride, data } = value as { point_stride: number; data: Uint8Array };
  if (stride !== MARKER_STRIDE || data.byteLength % MARKER_STRIDE !== 0) {
    throw new Error(`${where}: expected ${MARKER_STRIDE}-byte markers, got point stride ${stride} and ${data.byteLength} bytes of data`);
  }
  const n = data.byteLength / MARKER_STRIDE;
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const flow: MarkerFlow = { count: n, position: new Float32Array(2 * n), rest: new Float32Array(2 * n) };
  for (let k = 0; k < n; k++) {
    const at = k * MARKER_STRIDE;
    flow.position[2 * k] = view.getFloat32(at, true);
    flow.position[2 * k + 1] = view.getFloat32(at + 4, true);
    flow.rest[2 * k] = view.getFloat32(at + 12, true);
    flow.rest[2 * k + 1] = view.getFloat32(at + 16, true);
  }
  return flow;
}

/** `/tactile/<pad>/markers`: only an optical pad has them (only an optical sensor prints markers);
 * the counts may differ from pad to pad (each sensor has its own grid). */
export const PAD_MARKERS: PadStream<MarkerFlow> = {
  suffix: "/markers",
  what: "markers",
  decode: decodeMarkerFlow,
  needs: { suffix: "/image", padsAre: "optical pads" },
};

/**
 * The marker flow of one touch reading (a sample, or an episode's touch messages of one instant),
 * read by {@link readPadStream}: the pads are its `/tactile/<pad>/markers` topics in the order of
 * their channels (the writer adds them in the robot's pad order). Each must be an optical pad of
 * the reading (its `/tactile/<pad>/image` is there: only an optical sensor prints markers) and,
 * when `pads` (the reading's pads, from its `/tactile/<pad>/depth` channels) is given, one of
 * them; when `/sample/info` has `tactile.optical`, it must not give the pad's sensor `markers:
 * null`. Throws an Error naming `where` and the topic otherwise. Empty without marker topics.
 */
export function readMarkerFlow(sample: Sample, where: string, pads?: readonly string[]): Map<string, MarkerFlow> {
  const flows = readPadStream(sample, where, PAD_MARKERS, pads).values;
  const info = sample.get("/sample/info")?.[0]?.value;
  const optical = (info?.tactile as Record<string, unknown> | undefined)?.optical as Record<string, unknown> | undefined;
  if (optical != undefined) {
    const unprinted = [...flows.keys()].filter((pad) => {
      const sensor = optical[pad] as Record<string, unknown> | undefined;
      return sensor != undefined && "markers" in sensor && sensor.markers === null;
    });
    if (unprinted.length > 0) {
      throw new Error(
        `${where}: markers of ${unprinted.join(", ")}, whose sensors have none (/sample/info tactile.optical.<pad>.markers is null)`,
      );
    }
  }
  return flows;
}

/**
 * The force a field's cells add up to (N, pad frame; FORMAT.md, "Sums"): their (shear_x, shear_y,
 * −pressure) times the cell area `length · width / R²` (the pad's sensing area, `/sample/info`
 * `tactile.pads`). With the generator's fields this is `tactile.forces.<pad>.force_n`.
 */
export function forceSum(field: ForceField, length: number, width: number): [number, number, number] {
  const area = (length * width) / (field.resolution * field.resolution);
  let x = 0;
  let y = 0;
  let z = 0;
  for (let k = 0; k < field.pressure.length; k++) {
    x += field.shear[2 * k]!;
    y += field.shear[2 * k + 1]!;
    z -= field.pressure[k]!;
  }
  return [x * area, y * area, z * area];
}

/** FORMAT.md's centre of cell `(u, v)` of an R x R grid over a `length` x `width` pad (m). */
export function cellCentre(u: number, v: number, r: number, length: number, width: number): [number, number] {
  return [(((2 * u + 1) / r - 1) * length) / 2, (((2 * v + 1) / r - 1) * width) / 2];
}
