// One reader for every per-pad stream of a touch reading (FORMAT.md, `/tactile/<pad>/...`): the
// optical images and their references, the force fields and the marker flow all go through
// `readPadStream`, which finds the stream's pads in channel order and holds them against
// `/sample/info`, the reading's pads and each other; each stream kind only says what is its own
// (its topic, its decoder, the info key listing its pads, what its pads must also have, what all
// its pads' values share). The Python reader does the same (`vtdata.decoders._pad_stream`).
import type { Sample } from "./checks.js";

/** One kind of per-pad stream, `/tactile/<pad><suffix>`. */
export type PadStream<T> = {
  /** The topic's end: `/image`, `/reference`, `/force`, `/markers`, `/depth`. */
  suffix: string;
  /** What the messages are, in errors ("force fields of a, b ..."). */
  what: string;
  /** One pad's decoded message -> its value; `where` names the sample and the topic. */
  decode: (value: Record<string, unknown>, where: string) => T;
  /** The `/sample/info` `tactile` key that lists exactly the pads with this stream (`{pad: ...}`,
   * checked when the info has it) and what those pads are called in errors. */
  listed?: { key: string; padsAre: string };
  /** Another stream every pad of this one must have (markers and references: the pad's optical
   * image) and what such pads are called in errors. */
  needs?: { suffix: string; padsAre: string };
  /** What every pad's value must share ("resolution") and how a value's is written ("4x4"). */
  same?: { aspect: string; of: (value: T) => string };
};

/** `/tactile/<pad><suffix>`. */
export const padTopic = (pad: string, suffix: string): string => `/tactile/${pad}${suffix}`;

/** The pad of a `/tactile/<pad><suffix>` topic, or undefined. */
export function padOf(topic: string, suffix: string): string | undefined {
  if (!topic.startsWith("/tactile/") || !topic.endsWith(suffix)) {
    return undefined;
  }
  const pad = topic.slice("/tactile/".length, topic.length - suffix.length);
  return pad !== "" && !pad.includes("/") ? pad : undefined;
}

/** The pads of a reading's `/tactile/<pad><suffix>` topics, in the order of their channels (the
 * writer adds a robot's pad channels in its pads' order; names would sort otherwise). */
export function padsInChannelOrder(sample: Sample, suffix: string): string[] {
  const found: { pad: string; channelId: number }[] = [];
  for (const [topic, list] of sample) {
    const pad = padOf(topic, suffix);
    if (pad != undefined) {
      found.push({ pad, channelId: list[0]?.channelId ?? 0 });
    }
  }
  return found.sort((a, b) => a.channelId - b.channelId).map((f) => f.pad);
}

/** A reading's pad stream and the `/sample/info` list of its pads (undefined without one). */
export type PadValues<T> = { values: Map<string, T>; listed: Record<string, unknown> | undefined };

/**
 * Read one kind of per-pad stream of a touch reading (a sample, or an episode's touch messages of
 * one instant): `{pad: value}` with the pads in the order of their channels, empty without such
 * topics. Checked, with an Error naming `where` (the sample) and the topic: the pads are the ones
 * `/sample/info` lists for the stream (when it lists them); when `pads` (the reading's pads, from
 * its `/tactile/<pad>/depth` channels) is given, each is one of them; each has the stream the kind
 * `needs`; each topic has exactly one message, which decodes; the values agree in `same`.
 */
export function readPadStream<T>(sample: Sample, where: string, stream: PadStream<T>, pads?: readonly string[]): PadValues<T> {
  const names = padsInChannelOrder(sample, stream.suffix);
  let listed: Record<string, unknown> | undefined;
  if (stream.listed != undefined) {
    const info = sample.get("/sample/info")?.[0]?.value;
    const tactile = info?.tactile as Record<string, unknown> | undefined;
    const list = tactile?.[stream.listed.key];
    if (list != undefined && typeof list === "object" && !Array.isArray(list)) {
      listed = list as Record<string, unknown>;
      const want = Object.keys(listed).sort();
      const have = [...names].sort();
      if (want.join("\n") !== have.join("\n")) {
        throw new Error(
          `${where}: /sample/info tactile.${stream.listed.key} lists the ${stream.listed.padsAre} [${want.join(", ")}], ` +
            `the sample has ${stream.what} of [${have.join(", ")}] (/tactile/<pad>${stream.suffix})`,
        );
      }
    }
  }
  if (pads != undefined) {
    const unknown = names.filter((pad) => !pads.includes(pad));
    if (unknown.length > 0) {
      throw new Error(
        `${where}: ${stream.what} of ${unknown.join(", ")}, which are not pads of the sample ` +
          `(no /tactile/<pad>/depth; pads: ${pads.join(", ")})`,
      );
    }
  }
  if (stream.needs != undefined) {
    const { suffix, padsAre } = stream.needs;
    const without = names.filter((pad) => !sample.has(padTopic(pad, suffix)));
    if (without.length > 0) {
      throw new Error(`${where}: ${stream.what} of ${without.join(", ")}, which are not ${padsAre} of the sample (no /tactile/<pad>${suffix})`);
    }
  }
  const values = new Map<string, T>();
  for (const pad of names) {
    const topic = padTopic(pad, stream.suffix);
    const list = sample.get(topic)!;
    if (list.length !== 1) {
      throw new Error(`${where}: ${list.length} messages on ${topic}, expected one`);
    }
    values.set(pad, stream.decode(list[0]!.value, `${where} ${topic}`));
  }
  if (stream.same != undefined) {
    const { aspect, of } = stream.same;
    if (new Set([...values.values()].map(of)).size > 1) {
      const each = [...values].map(([pad, v]) => `${pad} ${of(v)}`);
      throw new Error(`${where}: the pads' ${stream.what} differ in ${aspect}: ${each.join(", ")}`);
    }
  }
  return { values, listed };
}
