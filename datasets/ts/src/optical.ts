// The optical tactile images of one sample (FORMAT.md, `/tactile/<pad>/image` and
// `/tactile/<pad>/reference`): per pad with an optical (GelSight/DIGIT-style) sensor, the sensor's
// RGB image and its no-contact reference image, read into a sample's `tactileImages` and
// `tactileReferences` the way the Python (`tactile_images`, `tactile_references`) and Rust
// (`TactileData::optical`) readers read them.
import type { Sample } from "./checks.js";
import { PAD_OPTICAL_ENCODING, padImageTopic, padReferenceTopic } from "./format.js";
import { readPadStream, type PadStream } from "./pads.js";

/** An 8-bit RGB image: `height` rows of `width * 3` bytes (R, G, B), packed (no row padding). */
export type RgbImage = { width: number; height: number; data: Uint8Array };

/** A sample's optical tactile images, by pad in pad order; both maps empty without an optical pad. */
export type OpticalImages = {
  tactileImages: Map<string, RgbImage>;
  tactileReferences: Map<string, RgbImage>;
};

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

/** `/tactile/<pad>/image`: an optical pad's RGB image (`rgb8`, not empty; each sensor its own size);
 * `/sample/info` `tactile.optical` lists the optical pads. */
export const PAD_IMAGE: PadStream<RgbImage> = {
  suffix: "/image",
  what: "optical images",
  decode: decodeRgb8,
  listed: { key: "optical", padsAre: "optical pads" },
};

/** `/tactile/<pad>/reference`: an optical pad's no-contact image, beside its image. */
export const PAD_REFERENCE: PadStream<RgbImage> = {
  suffix: "/reference",
  what: "reference images",
  decode: decodeRgb8,
  needs: { suffix: "/image", padsAre: "optical pads" },
};

/**
 * The optical images of one sample, read by {@link readPadStream}: the pads are its
 * `/tactile/<pad>/image` topics in the order of their channels (the writer adds them in the
 * robot's pad order). Each image needs its `/tactile/<pad>/reference` of the same size, both
 * `rgb8`. When `pads` (the sample's pads, from its `/tactile/<pad>/depth` channels) is given, every
 * optical pad must be one of them; when `/sample/info` has `tactile.optical`, it must list exactly
 * these pads, each at its `image_size` (`[width, height]`). Throws an Error naming `where` and the
 * topic otherwise.
 *
 * `first`: in an episode (FORMAT.md, "Episodes") the references are written once, with frame 0;
 * the other frames take a missing reference from `first`, frame 0's sample.
 */
export function readOpticalImages(sample: Sample, where: string, pads?: readonly string[], first?: Sample): OpticalImages {
  const { values: tactileImages, listed } = readPadStream(sample, where, PAD_IMAGE, pads);
  // An episode frame's missing references are frame 0's.
  const withReferences = new Map(sample);
  for (const pad of tactileImages.keys()) {
    const topic = padReferenceTopic(pad);
    const frame0 = first?.get(topic);
    if (!sample.has(topic) && frame0 != undefined) {
      withReferences.set(topic, frame0);
    }
  }
  const references = readPadStream(withReferences, where, PAD_REFERENCE, pads).values;
  const tactileReferences = new Map<string, RgbImage>();
  for (const [pad, image] of tactileImages) {
    const imageTopic = padImageTopic(pad);
    const referenceTopic = padReferenceTopic(pad);
    const reference = references.get(pad);
    if (reference == undefined) {
      throw new Error(`${where}: ${imageTopic} without its ${referenceTopic}${first != undefined ? " (nor has the episode's frame 0)" : ""}`);
    }
    if (reference.width !== image.width || reference.height !== image.height) {
      throw new Error(
        `${where}: ${referenceTopic} is ${reference.width}x${reference.height}, its image ${image.width}x${image.height}`,
      );
    }
    const sensor = listed?.[pad] as Record<string, unknown> | undefined;
    const size = sensor?.image_size;
    if (size != undefined && JSON.stringify(size) !== JSON.stringify([image.width, image.height])) {
      throw new Error(
        `${where}: ${imageTopic} is ${image.width}x${image.height}, but /sample/info ` +
          `tactile.optical.${pad}.image_size is ${JSON.stringify(size)} ([width, height])`,
      );
    }
    tactileReferences.set(pad, reference);
  }
  return { tactileImages, tactileReferences };
}
