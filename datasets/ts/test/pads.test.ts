// Self-test of the one per-pad stream reader (src/pads.ts) that the optical images, their
// references, the force fields and the marker flow all go through: the same checks, with the same
// errors, whatever the stream.
import assert from "node:assert/strict";
import { describe, it } from "node:test";

import type { Sample } from "../src/checks.js";
import { PAD_FORCE, PAD_MARKERS } from "../src/force.js";
import { PAD_IMAGE, PAD_REFERENCE } from "../src/optical.js";
import { padOf, padTopic, padsInChannelOrder, readPadStream, type PadStream } from "../src/pads.js";
import type { Decoded } from "../src/shard.js";

function decoded(topic: string, channelId: number, value: Record<string, unknown>): Decoded {
  return { topic, channelId, logTime: 0n, publishTime: 0n, sequence: 0, value };
}

/** A stream whose values are its messages' `n`, every pad's the same `n` (`same`). */
const COUNTS: PadStream<number> = {
  suffix: "/count",
  what: "counts",
  decode: (value, where) => {
    if (typeof value.n !== "number") {
      throw new Error(`${where}: no n`);
    }
    return value.n;
  },
  listed: { key: "counts", padsAre: "pads" },
  same: { aspect: "value", of: (n) => String(n) },
};

/** `/tactile/<pad>/count` of `n` for each pad (channels 20, 21, ... in that order), put into the map
 * in reverse; `/sample/info` `tactile.counts` lists `listed`. */
function sample(counts: [string, number][], listed?: string[]): Sample {
  const entries: [string, Decoded[]][] = counts.map(([pad, n], k) => [padTopic(pad, "/count"), [decoded(padTopic(pad, "/count"), 20 + k, { n })]]);
  if (listed != undefined) {
    const info = { tactile: { counts: Object.fromEntries(listed.map((p) => [p, {}])) } };
    entries.push(["/sample/info", [decoded("/sample/info", 7, info)]]);
  }
  return new Map(entries.reverse());
}

describe("readPadStream (pads.ts)", () => {
  it("names the pad of a per-pad topic", () => {
    assert.equal(padTopic("left", "/force"), "/tactile/left/force");
    assert.equal(padOf("/tactile/left/force", "/force"), "left");
    assert.equal(padOf("/tactile/left/force", "/markers"), undefined);
    assert.equal(padOf("/tactile/a/b/force", "/force"), undefined);
    assert.equal(padOf("/tactile//force", "/force"), undefined);
  });

  it("reads the pads in channel order, not name order", () => {
    const s = sample([["right", 3], ["left", 3]], ["left", "right"]);
    assert.deepEqual(padsInChannelOrder(s, "/count"), ["right", "left"]);
    const { values, listed } = readPadStream(s, "here", COUNTS, ["right", "left"]);
    assert.deepEqual([...values], [["right", 3], ["left", 3]]);
    assert.deepEqual(Object.keys(listed!).sort(), ["left", "right"]);
    assert.equal(readPadStream(sample([]), "here", COUNTS).values.size, 0);
  });

  it("checks the pads against /sample/info, the sample's pads and each other", () => {
    assert.throws(
      () => readPadStream(sample([["a", 1]], ["a", "b"]), "here", COUNTS),
      /^Error: here: \/sample\/info tactile\.counts lists the pads \[a, b\], the sample has counts of \[a\] \(\/tactile\/<pad>\/count\)$/,
    );
    assert.throws(
      () => readPadStream(sample([["a", 1]]), "here", COUNTS, ["b"]),
      /^Error: here: counts of a, which are not pads of the sample \(no \/tactile\/<pad>\/depth; pads: b\)$/,
    );
    assert.throws(
      () => readPadStream(sample([["a", 1], ["b", 2]]), "here", COUNTS),
      /^Error: here: the pads' counts differ in value: a 1, b 2$/,
    );
  });

  it("refuses a topic with more than one message, naming it", () => {
    const s = sample([["a", 1]]);
    s.get("/tactile/a/count")!.push(decoded("/tactile/a/count", 20, { n: 1 }));
    assert.throws(() => readPadStream(s, "sample 4", COUNTS), /^Error: sample 4: 2 messages on \/tactile\/a\/count, expected one$/);
  });

  it("names the topic of a message that does not decode", () => {
    const s = sample([["a", 1]]);
    s.set("/tactile/a/count", [decoded("/tactile/a/count", 20, {})]);
    assert.throws(() => readPadStream(s, "sample 4", COUNTS), /^Error: sample 4 \/tactile\/a\/count: no n$/);
  });

  it("is what every per-pad stream of the readers goes through, with the same errors", () => {
    const streams = [PAD_IMAGE, PAD_REFERENCE, PAD_FORCE, PAD_MARKERS] as PadStream<unknown>[];
    assert.deepEqual(streams.map((s) => s.suffix), ["/image", "/reference", "/force", "/markers"]);
    for (const stream of streams) {
      const s: Sample = new Map([[padTopic("a", stream.suffix), [decoded(padTopic("a", stream.suffix), 20, {})]]]);
      assert.throws(
        () => readPadStream(s, "here", stream, ["b"]),
        new RegExp(`^Error: here: ${stream.what} of a, which are not pads of the sample \\(no /tactile/<pad>/depth; pads: b\\)$`),
      );
    }
    // Markers and references need the pad's optical image.
    for (const stream of [PAD_REFERENCE, PAD_MARKERS] as PadStream<unknown>[]) {
      const s: Sample = new Map([[padTopic("a", stream.suffix), [decoded(padTopic("a", stream.suffix), 20, {})]]]);
      assert.throws(
        () => readPadStream(s, "here", stream, ["a"]),
        new RegExp(`^Error: here: ${stream.what} of a, which are not optical pads of the sample \\(no /tactile/<pad>/image\\)$`),
      );
    }
  });
});
