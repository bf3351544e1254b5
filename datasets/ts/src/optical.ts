// The optical tactile images of one sample (FORMAT.md, `/tactile/<pad>/image` and
// `/tactile/<pad>/reference`): per pad with an optical (GelSight/DIGIT-style) sensor, the sensor's
// RGB image and its no-contact reference image, read into a sample's `tactileImages` and
// `tactileReferences` the way the Python (`tactile_images`, `tactile_references`) and Rust
// (`TactileData::optical`) readers read them.
import type { Sample } from "./checks.js";
import { PAD_OPTICAL_ENCODING, opticalOfTopic, padImageTopic, padReferenceTopic } from "./format.js";
import type { Decoded } from "./shard.js";

/** An 8-bit RGB image: `height` rows of `width * 3` bytes (R, G, B), packed (no row padding). */
export type RgbImage = { width: number; height: number; data: Uint8Array };

/** A sample's optical tactile images, by pad in pad order; both maps empty without an optical pad. */
export type OpticalImages = {
  tactileImages: Map<string, RgbImage>;
  tactileReferences: Map<string, RgbImage>;
};

/** The message of `topic` in `sample`; an Error if there is none or more than one. */
function single(sample: Sample, topic: string, where: string): Decoded {
  const list = sample.get(topic) ?? [];
  if (list.length !== 1) {
    throw new Error(`${where}: ${list.length} messages on ${topic}, expected one`);
  }
  return list[0]!;
}

/**
 * A decoded `foxglove.RawImage` of encoding `rgb8` as an {@link RgbImage}. Rows are read `step`
 * bytes apart (a padded row is accepted, and dropped); an Error names `where` when the encoding is
 * not `rgb8`, the step is shorter than a row or the data shorter than the image.
 */
export function decodeRgb8(value: Record<string, unknown>, where: string): RgbImage {
  const { encoding, width, height, step, data } = value as {
    encoding: string; width: number; height: number; step: number; data: Uint8Array;
  };
  if (encoding !== PAD_OPTICAL_ENCODING.encoding) {
    throw new Error(`${where}: expected encoding ${PAD_OPTICAL_ENCODING.encoding}, found ${JSON.stringify(encoding)}`);
  }
  const row = width * PAD_OPTICAL_ENCODING.bytesPerPixel;
  if (!(width > 0 && height > 0)) {
    throw new Error(`${where}: empty ${width}x${height} image`);
  }
  if (step < row) {
    throw new Error(`${where}: step ${step} is smaller than a ${width}-pixel rgb8 row (${row} bytes)`);
  }
  const needed = (height - 1) * step + row;
  if (data.byteLength < needed) {
    throw new Error(`${where}: ${width}x${height} rgb8 image with step ${step} needs ${needed} bytes, data has ${data.byteLength}`);
  }
  const out = new Uint8Array(row * height);
  for (let y = 0; y < height; y++) {
    out.set(data.subarray(y * step, y * step + row), y * row);
  }
  return { width, height, data: out };
}

/**
 * The optical images of one sample: the pads are its `/tactile/<pad>/image` topics in the order of
 * their channels (the writer adds them in the robot's pad order). Each image needs its
 * `/tactile/<pad>/reference` of the same size, both `rgb8`. When `pads` (the sample's pads, from
 * its `/tactile/<pad>/depth` channels) is given, every optical pad must be one of them; when
 * `/sample/info` has `tactile.optical`, it must list exactly these pads, each at its `image_size`
 * (`[width, height]`). Throws an Error naming `where` and the topic otherwise.
 *
 * `first`: in an episode (FORMAT.md, "Episodes") the references are written once, with frame 0;
 * the other frames take a missing reference from `first`, frame 0's sample.
 */
export function readOpticalImages(sample: Sample, where: string, pads?: readonly string[], first?: Sample): OpticalImages {
  const found: { pad: string; channelId: number }[] = [];
  const references = new Set<string>();
  for (const [topic, list] of sample) {
    const optical = opticalOfTopic(topic);
    if (optical?.kind === "image") {
      found.push({ pad: optical.pad, channelId: list[0]?.channelId ?? 0 });
    } else if (optical?.kind === "reference") {
      references.add(optical.pad);
    }
  }
  found.sort((a, b) => a.channelId - b.channelId);
  const optical = found.map((f) => f.pad);
  for (const pad of references) {
    if (!optical.includes(pad)) {
      throw new Error(`${where}: ${padReferenceTopic(pad)} without its ${padImageTopic(pad)}`);
    }
  }
  const info = sample.get("/sample/info")?.[0]?.value;
  const tactile = info?.tactile as Record<string, unknown> | undefined;
  const listed = tactile?.optical as Record<string, Record<string, unknown> | undefined> | undefined;
  if (listed != undefined) {
    const names = Object.keys(listed).sort();
    const have = [...optical].sort();
    if (names.join("\n") !== have.join("\n")) {
      throw new Error(
        `${where}: /sample/info tactile.optical lists the optical pads [${names.join(", ")}], ` +
          `the sample has images of [${have.join(", ")}] (/tactile/<pad>/image)`,
      );
    }
  }
  if (pads != undefined) {
    const unknown = optical.filter((pad) => !pads.includes(pad));
    if (unknown.length > 0) {
      throw new Error(
        `${where}: optical images of ${unknown.join(", ")}, which are not pads of the sample ` +
          `(no /tactile/<pad>/depth; pads: ${pads.join(", ")})`,
      );
    }
  }
  const tactileImages = new Map<string, RgbImage>();
  const tactileReferences = new Map<string, RgbImage>();
  for (const pad of optical) {
    const imageTopic = padImageTopic(pad);
    const referenceTopic = padReferenceTopic(pad);
    const holder = sample.has(referenceTopic) ? sample : first?.has(referenceTopic) ? first : undefined;
    if (holder == undefined) {
      throw new Error(`${where}: ${imageTopic} without its ${referenceTopic}${first != undefined ? " (nor has the episode's frame 0)" : ""}`);
    }
    const image = decodeRgb8(single(sample, imageTopic, where).value, `${where} ${imageTopic}`);
    const reference = decodeRgb8(single(holder, referenceTopic, where).value, `${where} ${referenceTopic}`);
    if (reference.width !== image.width || reference.height !== image.height) {
      throw new Error(
        `${where}: ${referenceTopic} is ${reference.width}x${reference.height}, its image ${image.width}x${image.height}`,
      );
    }
    const size = listed?.[pad]?.image_size;
    if (size != undefined && JSON.stringify(size) !== JSON.stringify([image.width, image.height])) {
      throw new Error(
        `${where}: ${imageTopic} is ${image.width}x${image.height}, but /sample/info ` +
          `tactile.optical.${pad}.image_size is ${JSON.stringify(size)} ([width, height])`,
      );
    }
    tactileImages.set(pad, image);
    tactileReferences.set(pad, reference);
  }
  return { tactileImages, tactileReferences };
}
