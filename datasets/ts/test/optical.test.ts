// Self-test of the optical tactile image reader with hand-made samples (decoded messages as
// shard.ts groups them): the images and references of the optical pads, in channel order, only for
// the pads that have them; each way of getting them wrong (another encoding, a missing reference, a
// size that differs from the reference or from /sample/info, a pad the info does not list) fails.
import assert from "node:assert/strict";
import { describe, it } from "node:test";

import type { Sample } from "../src/checks.js";
import {
  PAD_OPTICAL_ENCODING,
  imageSpec,
  opticalOfTopic,
  opticalPadsOf,
  padImageTopic,
  padReferenceTopic,
  robotTopics,
} from "../src/format.js";
import { decodeRgb8, readOpticalImages } from "../src/optical.js";
import type { Decoded } from "../src/shard.js";

const W = 5;
const H = 3;

function decoded(topic: string, channelId: number, value: Record<string, unknown>): Decoded {
  return { topic, channelId, logTime: 0n, publishTime: 0n, sequence: 0, value };
}

/** A decoded foxglove.RawImage: `data` holds `height` rows `step` bytes apart (padding 0xab). */
function rawImage(pixels: Uint8Array, width: number, height: number, options: { encoding?: string; pad?: number; pad_id?: string } = {}): Record<string, unknown> {
  const row = width * 3;
  const step = row + (options.pad ?? 0);
  const data = new Uint8Array(step * height).fill(0xab);
  for (let y = 0; y < height; y++) {
    data.set(pixels.subarray(y * row, (y + 1) * row), y * step);
  }
  return { frame_id: `${options.pad_id ?? "x"}_pad`, width, height, encoding: options.encoding ?? "rgb8", step, data };
}

const pixels = (seed: number, width = W, height = H): Uint8Array =>
  Uint8Array.from({ length: width * height * 3 }, (_, i) => (i * 37 + seed * 11) % 256);

const sensorInfo = (width = W, height = H) => ({
  image_size: [width, height],
  sensing_area_mm: [18.6, 14.3],
  gel_thickness_mm: 1.5,
  elastic_spread_mm: 0.5,
  lights: [{ direction: [0, 0.8, -0.6], color: [1, 0.1, 0.1], falloff: 0.25 }],
  ambient: 0.15,
  background: [0.8, 0.7, 0.75],
  vignetting: 0.3,
  markers: null,
  noise_std: 1,
});

/**
 * A sample of a robot with pads `pads` (depth channels 10, 11, ...) whose `optical` pads have an
 * image and a reference (channels after the depth ones, in pad order as the writer adds them).
 * Messages are put into the map in reverse, so the reader must order the pads by channel.
 */
function sample(pads: string[], optical: string[], options: { info?: Record<string, unknown> | null; encoding?: string; pad?: number } = {}): Sample {
  const entries: [string, Decoded[]][] = [];
  let channel = 10;
  for (const pad of pads) {
    entries.push([`/tactile/${pad}/depth`, [decoded(`/tactile/${pad}/depth`, channel++, { encoding: "32FC1" })]]);
  }
  optical.forEach((pad, k) => {
    for (const [topic, seed] of [[padImageTopic(pad), 2 * k], [padReferenceTopic(pad), 2 * k + 1]] as const) {
      const value = rawImage(pixels(seed), W, H, { encoding: options.encoding, pad: options.pad, pad_id: pad });
      entries.push([topic, [decoded(topic, channel++, value)]]);
    }
  });
  const info =
    options.info === null ? {} : { tactile: { pads: {}, ...(options.info ?? { optical: Object.fromEntries(optical.map((p) => [p, sensorInfo()])) }) } };
  entries.push(["/sample/info", [decoded("/sample/info", 7, info)]]);
  return new Map(entries.reverse());
}

describe("optical tactile topics (format.ts)", () => {
  it("names the image and reference topics of a pad and parses them back", () => {
    assert.equal(padImageTopic("left"), "/tactile/left/image");
    assert.equal(padReferenceTopic("left"), "/tactile/left/reference");
    assert.deepEqual(opticalOfTopic("/tactile/ff_distal/image"), { pad: "ff_distal", kind: "image" });
    assert.deepEqual(opticalOfTopic("/tactile/ff_distal/reference"), { pad: "ff_distal", kind: "reference" });
    assert.equal(opticalOfTopic("/tactile/ff_distal/depth"), undefined);
    assert.equal(opticalOfTopic("/tactile/a/b/image"), undefined);
    assert.deepEqual(imageSpec("/tactile/left/image"), PAD_OPTICAL_ENCODING);
    assert.deepEqual(imageSpec("/tactile/left/reference"), { encoding: "rgb8", bytesPerPixel: 3 });
  });

  it("lists the optical pads by channel and adds their topics to a robot's", () => {
    const channels = [
      { id: 14, topic: "/tactile/left/image" },
      { id: 15, topic: "/tactile/left/reference" },
      { id: 12, topic: "/tactile/right/image" },
      { id: 11, topic: "/tactile/left/depth" },
    ];
    assert.deepEqual(opticalPadsOf(channels), ["right", "left"]);
    assert.deepEqual(Object.keys(robotTopics(["right", "left"], ["right"])), [
      "/tactile/points",
      "/tactile/right/depth",
      "/tactile/left/depth",
      "/tactile/right/image",
      "/tactile/right/reference",
    ]);
    assert.deepEqual(Object.keys(robotTopics(["left"])), ["/tactile/points", "/tactile/left/depth"]);
  });
});

describe("readOpticalImages", () => {
  it("reads the optical pads' images and references in channel order, WxHx3 bytes", () => {
    // Not in name order: right_pad's channels come first.
    const s = sample(["right_pad", "left_pad"], ["right_pad", "left_pad"]);
    const { tactileImages, tactileReferences } = readOpticalImages(s, "here", ["right_pad", "left_pad"]);
    assert.deepEqual([...tactileImages.keys()], ["right_pad", "left_pad"]);
    assert.deepEqual([...tactileReferences.keys()], ["right_pad", "left_pad"]);
    ["right_pad", "left_pad"].forEach((pad, k) => {
      const image = tactileImages.get(pad)!;
      const reference = tactileReferences.get(pad)!;
      assert.deepEqual([image.width, image.height, image.data.byteLength], [W, H, W * H * 3]);
      assert.deepEqual(image.data, pixels(2 * k));
      assert.deepEqual(reference.data, pixels(2 * k + 1));
    });
  });

  it("reads only the pads that have an optical sensor", () => {
    const pads = ["ff_proximal", "ff_distal", "th_proximal", "th_distal"];
    const { tactileImages } = readOpticalImages(sample(pads, ["ff_distal", "th_distal"]), "here", pads);
    assert.deepEqual([...tactileImages.keys()], ["ff_distal", "th_distal"]);
  });

  it("gives empty maps without optical pads", () => {
    const { tactileImages, tactileReferences } = readOpticalImages(sample(["left", "right"], [], { info: {} }), "here");
    assert.equal(tactileImages.size, 0);
    assert.equal(tactileReferences.size, 0);
  });

  it("drops the padding of rows `step` bytes apart", () => {
    const { tactileImages } = readOpticalImages(sample(["left"], ["left"], { pad: 4 }), "here");
    assert.deepEqual(tactileImages.get("left")!.data, pixels(0));
  });

  it("rejects another encoding, naming the sample and topic", () => {
    assert.throws(
      () => readOpticalImages(sample(["left"], ["left"], { encoding: "bgr8" }), "sample 3"),
      /^Error: sample 3 \/tactile\/left\/image: expected encoding rgb8, found "bgr8"$/,
    );
  });

  it("rejects a missing reference or an image without data", () => {
    const s = sample(["left"], ["left"]);
    s.delete(padReferenceTopic("left"));
    assert.throws(() => readOpticalImages(s, "here"), /\/tactile\/left\/image without its \/tactile\/left\/reference/);
    const t = sample(["left"], ["left"], { info: null });
    t.delete(padImageTopic("left"));
    assert.throws(
      () => readOpticalImages(t, "here"),
      /^Error: here: reference images of left, which are not optical pads of the sample \(no \/tactile\/<pad>\/image\)$/,
    );
    // With /sample/info tactile.optical listing the pad, its missing image is what is named.
    const u = sample(["left"], ["left"]);
    u.delete(padImageTopic("left"));
    assert.throws(() => readOpticalImages(u, "here"), /tactile\.optical lists the optical pads \[left\], the sample has optical images of \[\]/);
    const twice = sample(["left"], ["left"]);
    twice.get(padImageTopic("left"))!.push(twice.get(padImageTopic("left"))![0]!);
    assert.throws(() => readOpticalImages(twice, "here"), /^Error: here: 2 messages on \/tactile\/left\/image, expected one$/);
    assert.throws(
      () => decodeRgb8({ ...rawImage(pixels(0), W, H), data: new Uint8Array(W * H * 3 - 1) }, "short"),
      /short: 5x3 rgb8 image with step 15 needs 45 bytes, data has 44/,
    );
    assert.throws(() => decodeRgb8({ ...rawImage(pixels(0), W, H), step: 14 }, "narrow"), /step 14 is smaller than a 5-pixel rgb8 row/);
  });

  it("takes an episode frame's references from its frame 0", () => {
    const frame0 = sample(["left", "right"], ["left", "right"]);
    const later = sample(["left", "right"], ["left", "right"]);
    later.delete(padReferenceTopic("left"));
    later.delete(padReferenceTopic("right"));
    assert.throws(() => readOpticalImages(later, "frame 3"), /frame 3: \/tactile\/left\/image without its \/tactile\/left\/reference$/);
    const { tactileReferences } = readOpticalImages(later, "frame 3", ["left", "right"], frame0);
    assert.deepEqual(tactileReferences.get("left")!.data, pixels(1));
    assert.deepEqual(tactileReferences.get("right")!.data, pixels(3));
    // A reference of its own wins; frame 0 without one is no help.
    const own = sample(["left"], ["left"]);
    own.set(padReferenceTopic("left"), [decoded(padReferenceTopic("left"), 13, rawImage(pixels(9), W, H))]);
    assert.deepEqual(readOpticalImages(own, "f", undefined, frame0).tactileReferences.get("left")!.data, pixels(9));
    const bare = sample(["left"], ["left"]);
    bare.delete(padReferenceTopic("left"));
    assert.throws(() => readOpticalImages(later, "f", undefined, bare), /without its \/tactile\/left\/reference \(nor has the episode's frame 0\)/);
  });

  it("rejects a reference of another size", () => {
    const s = sample(["left"], ["left"]);
    s.set(padReferenceTopic("left"), [decoded(padReferenceTopic("left"), 13, rawImage(pixels(1, 4, 3), 4, 3))]);
    assert.throws(() => readOpticalImages(s, "here"), /\/tactile\/left\/reference is 4x3, its image 5x3/);
  });

  it("holds the images against /sample/info tactile.optical and the sample's pads", () => {
    assert.throws(
      () => readOpticalImages(sample(["left", "right"], ["left"], { info: { optical: { left: sensorInfo(), right: sensorInfo() } } }), "here"),
      /tactile\.optical lists the optical pads \[left, right\], the sample has optical images of \[left\]/,
    );
    assert.throws(
      () => readOpticalImages(sample(["left"], ["left"], { info: { optical: { left: sensorInfo(4, 3) } } }), "here"),
      /\/tactile\/left\/image is 5x3, but \/sample\/info tactile\.optical\.left\.image_size is \[4,3\]/,
    );
    assert.throws(
      () => readOpticalImages(sample(["left"], ["left"]), "here", ["right"]),
      /optical images of left, which are not pads of the sample/,
    );
    // Without the info's optical key (or any info) the images are read all the same.
    assert.equal(readOpticalImages(sample(["left"], ["left"], { info: null }), "here").tactileImages.size, 1);
  });
});
