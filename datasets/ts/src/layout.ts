// A Foxglove layout file (what "Import layout" reads and "Export layout" writes): `configById`
// (panel id -> panel config, the id being `<PanelType>!<suffix>`), `layout` (a mosaic tree of
// panel ids), `globalVariables`, `userNodes`, `playbackConfig`. This module checks the structure
// and lists what each panel refers to, so a test can hold the references against a shard.
import { readFile } from "node:fs/promises";

export type MosaicNode = string | { direction: "row" | "column"; first: MosaicNode; second: MosaicNode; splitPercentage?: number };

export type LayoutFile = {
  configById: Record<string, Record<string, unknown>>;
  layout: MosaicNode;
  globalVariables: Record<string, unknown>;
  userNodes: Record<string, unknown>;
  playbackConfig: { speed: number } & Record<string, unknown>;
};

/** How a panel uses a topic: the check that the shard's schema fits depends on it. */
export type TopicUse = "image" | "calibration" | "scene" | "raw";

export type Reference = { panel: string; topic: string; use: TopicUse };
export type FrameReference = { panel: string; frame: string };

const PANEL_TYPES = new Set(["3D", "Image", "RawMessages", "Plot", "Table", "StateTransitions", "Tab"]);

export async function loadLayout(path: string): Promise<LayoutFile> {
  const value: unknown = JSON.parse(await readFile(path, "utf8"));
  return checkLayout(value);
}

function isObject(value: unknown): value is Record<string, unknown> {
  return typeof value === "object" && value != null && !Array.isArray(value);
}

export function checkLayout(value: unknown): LayoutFile {
  if (!isObject(value)) {
    throw new Error("layout: not a JSON object");
  }
  for (const key of ["configById", "globalVariables", "userNodes", "playbackConfig"]) {
    if (!isObject(value[key])) {
      throw new Error(`layout: "${key}" must be an object`);
    }
  }
  const layout = value as unknown as LayoutFile;
  if (typeof layout.playbackConfig.speed !== "number" || !(layout.playbackConfig.speed > 0)) {
    throw new Error("layout: playbackConfig.speed must be a positive number");
  }
  const leaves = mosaicLeaves(layout.layout);
  const ids = Object.keys(layout.configById);
  for (const leaf of leaves) {
    if (!(leaf in layout.configById)) {
      throw new Error(`layout: panel ${leaf} is in the layout tree but has no configById entry`);
    }
  }
  for (const id of ids) {
    if (!leaves.includes(id)) {
      throw new Error(`layout: configById entry ${id} is not in the layout tree (Foxglove drops it)`);
    }
    const type = panelType(id);
    if (!PANEL_TYPES.has(type)) {
      throw new Error(`layout: panel ${id} has unknown type ${type}`);
    }
    if (!isObject(layout.configById[id])) {
      throw new Error(`layout: config of ${id} is not an object`);
    }
  }
  if (new Set(leaves).size !== leaves.length) {
    throw new Error("layout: a panel id appears twice in the layout tree");
  }
  return layout;
}

export function panelType(id: string): string {
  const bang = id.indexOf("!");
  if (bang <= 0 || bang === id.length - 1) {
    throw new Error(`layout: panel id ${id} is not <PanelType>!<suffix>`);
  }
  return id.slice(0, bang);
}

export function mosaicLeaves(node: unknown): string[] {
  if (typeof node === "string") {
    return [node];
  }
  if (!isObject(node)) {
    throw new Error(`layout: a layout tree node must be a panel id or a split, got ${JSON.stringify(node)}`);
  }
  if (node.direction !== "row" && node.direction !== "column") {
    throw new Error(`layout: split direction must be "row" or "column", got ${JSON.stringify(node.direction)}`);
  }
  if (node.splitPercentage != undefined) {
    const p = node.splitPercentage;
    if (typeof p !== "number" || !(p > 0 && p < 100)) {
      throw new Error(`layout: splitPercentage must be in (0, 100), got ${JSON.stringify(p)}`);
    }
  }
  return [...mosaicLeaves(node.first), ...mosaicLeaves(node.second)];
}

/** The topic of a Foxglove message path: `/sample/info.occlusion.level` -> `/sample/info`. */
export function topicOfPath(path: string): string {
  const match = /^\/[A-Za-z0-9_/]*[A-Za-z0-9_]/.exec(path);
  if (match == undefined) {
    throw new Error(`layout: ${JSON.stringify(path)} does not start with a topic name`);
  }
  return match[0];
}

/** Every topic a panel reads, and how. */
export function topicReferences(layout: LayoutFile): Reference[] {
  const refs: Reference[] = [];
  for (const [panel, config] of Object.entries(layout.configById)) {
    const type = panelType(panel);
    if (type === "3D" || type === "Image") {
      const topics = (config.topics ?? {}) as Record<string, Record<string, unknown> | undefined>;
      for (const [topic, settings] of Object.entries(topics)) {
        refs.push({ panel, topic, use: "scene" });
        if (typeof settings?.cameraInfoTopic === "string") {
          refs.push({ panel, topic: settings.cameraInfoTopic, use: "calibration" });
        }
      }
      const imageMode = (config.imageMode ?? {}) as Record<string, unknown>;
      if (type === "Image" && typeof imageMode.imageTopic !== "string") {
        throw new Error(`layout: Image panel ${panel} has no imageMode.imageTopic`);
      }
      if (typeof imageMode.imageTopic === "string") {
        refs.push({ panel, topic: imageMode.imageTopic, use: "image" });
      }
      if (typeof imageMode.calibrationTopic === "string") {
        refs.push({ panel, topic: imageMode.calibrationTopic, use: "calibration" });
      }
      for (const topic of Object.keys((imageMode.annotations ?? {}) as Record<string, unknown>)) {
        refs.push({ panel, topic, use: "scene" });
      }
    } else if (type === "RawMessages") {
      if (typeof config.topicPath !== "string" || config.topicPath === "") {
        throw new Error(`layout: Raw Messages panel ${panel} has no topicPath`);
      }
      refs.push({ panel, topic: topicOfPath(config.topicPath), use: "raw" });
    } else if (type === "Plot") {
      for (const series of (config.paths ?? []) as { value?: string }[]) {
        if (typeof series.value === "string") {
          refs.push({ panel, topic: topicOfPath(series.value), use: "raw" });
        }
      }
    }
  }
  return refs;
}

/** Every coordinate frame a 3D or Image panel names (follow frame, per-frame settings). */
export function frameReferences(layout: LayoutFile): FrameReference[] {
  const refs: FrameReference[] = [];
  for (const [panel, config] of Object.entries(layout.configById)) {
    const type = panelType(panel);
    if (type !== "3D" && type !== "Image") {
      continue;
    }
    if (typeof config.followTf === "string") {
      refs.push({ panel, frame: config.followTf });
    }
    for (const key of Object.keys((config.transforms ?? {}) as Record<string, unknown>)) {
      if (key.startsWith("frame:")) {
        refs.push({ panel, frame: key.slice("frame:".length) });
      }
    }
    const layers = (config.layers ?? {}) as Record<string, { frameId?: unknown } | undefined>;
    for (const layer of Object.values(layers)) {
      if (typeof layer?.frameId === "string") {
        refs.push({ panel, frame: layer.frameId });
      }
    }
  }
  return refs;
}

/** A Plot panel's series: its topic and the message path after the topic (`.a.b[2]`). */
export type PlotSeries = { panel: string; topic: string; path: string };

/** Every series of every Plot panel. */
export function plotSeries(layout: LayoutFile): PlotSeries[] {
  const out: PlotSeries[] = [];
  for (const [panel, config] of Object.entries(layout.configById)) {
    if (panelType(panel) !== "Plot") {
      continue;
    }
    for (const series of (config.paths ?? []) as { value?: unknown }[]) {
      if (typeof series.value !== "string") {
        throw new Error(`layout: Plot panel ${panel} has a series without a string "value"`);
      }
      const topic = topicOfPath(series.value);
      out.push({ panel, topic, path: series.value.slice(topic.length) });
    }
  }
  return out;
}

/**
 * The value a Foxglove message path (the part after the topic: `.field`, `[index]`, in any
 * sequence, e.g. `.T_world_object.position[2]`) picks out of a decoded message; undefined when a
 * field or index is missing. Throws on syntax this subset does not cover (filters, slices,
 * variables), so a layout that uses them is noticed.
 */
export function valueAtPath(message: unknown, path: string): unknown {
  let value: unknown = message;
  let rest = path;
  while (rest.length > 0) {
    const field = /^\.([A-Za-z_][A-Za-z0-9_]*)/.exec(rest);
    const index = /^\[(\d+)\]/.exec(rest);
    if (field != undefined) {
      value = typeof value === "object" && value != null && !Array.isArray(value) ? (value as Record<string, unknown>)[field[1]!] : undefined;
      rest = rest.slice(field[0].length);
    } else if (index != undefined) {
      value = Array.isArray(value) ? value[Number(index[1])] : undefined;
      rest = rest.slice(index[0].length);
    } else {
      throw new Error(`message path ${JSON.stringify(path)}: ${JSON.stringify(rest)} is not .field or [index]`);
    }
  }
  return value;
}
