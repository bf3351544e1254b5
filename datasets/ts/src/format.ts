// The parts of datasets/FORMAT.md (format version 1) this reader checks.

// The robot is data: a dataset's pads, joints and grasp frame are the robot description's (a hand
// may have a dozen pads, a parallel gripper 2), so the checks read them from the shard: the pads
// are its `/tactile/<pad>/depth` channels, in channel order (the writer adds them in the pads'
// order, the order of the point cloud's pad index, POINT_PAD_FIELD).

/** The depth image topic of pad `pad`. */
export const padDepthTopic = (pad: string): string => `/tactile/${pad}/depth`;

/** The pad of a `/tactile/<pad>/depth` topic, or undefined. */
export function padOfTopic(topic: string): string | undefined {
  const m = /^\/tactile\/([^/]+)\/depth$/.exec(topic);
  return m?.[1];
}

// A pad with an optical (GelSight/DIGIT-style) sensor adds two RGB images to every sample, after
// the depth images, in the pads' order: the sensor's image and its no-contact reference image
// (without noise, the same size). Only such pads have them (a gripper: both pads; a hand: the pads
// configured optical); /sample/info `tactile.optical` lists them with their parameters.

/** The optical image topic of pad `pad`. */
export const padImageTopic = (pad: string): string => `/tactile/${pad}/image`;
/** The no-contact reference image topic of pad `pad`'s optical sensor. */
export const padReferenceTopic = (pad: string): string => `/tactile/${pad}/reference`;

/** The pad and kind of a `/tactile/<pad>/image` or `/tactile/<pad>/reference` topic, or undefined. */
export function opticalOfTopic(topic: string): { pad: string; kind: "image" | "reference" } | undefined {
  const m = /^\/tactile\/([^/]+)\/(image|reference)$/.exec(topic);
  return m == undefined ? undefined : { pad: m[1]!, kind: m[2] as "image" | "reference" };
}

/** The optical pads of a shard: its `/tactile/<pad>/image` channels, by channel id (pad order). */
export function opticalPadsOf(channels: Iterable<{ id: number; topic: string }>): string[] {
  return [...channels]
    .filter((c) => opticalOfTopic(c.topic)?.kind === "image")
    .sort((a, b) => a.id - b.id)
    .map((c) => opticalOfTopic(c.topic)!.pad);
}

// With `robot.tactile.force_field` (the MuJoCo backend) every pad adds its contact force field
// (FORMAT.md, "Force fields") after the optical images, in pad order: a foxglove.PointCloud in the
// pad frame, one 28-byte cell (FORCE_FIELDS) per cell of an R x R grid over the pad, row-major with
// rows along the pad's y; /sample/info `tactile.forces.<pad>.force_n` is the force it sums to.

/** The force field topic of pad `pad`. */
export const padForceTopic = (pad: string): string => `/tactile/${pad}/force`;

/** The pad of a `/tactile/<pad>/force` topic, or undefined. */
export function forcePadOfTopic(topic: string): string | undefined {
  const m = /^\/tactile\/([^/]+)\/force$/.exec(topic);
  return m?.[1];
}

/** The pads with a force field in a shard: its `/tactile/<pad>/force` channels, by channel id (pad order). */
export function forcePadsOf(channels: Iterable<{ id: number; topic: string }>): string[] {
  return [...channels]
    .filter((c) => forcePadOfTopic(c.topic) != undefined)
    .sort((a, b) => a.id - b.id)
    .map((c) => forcePadOfTopic(c.topic)!);
}

// With force fields each optical pad whose sensor has markers also adds its marker flow (FORMAT.md,
// `/tactile/<pad>/markers`) after the force fields, in pad order: a foxglove.PointCloud in the pad
// frame, one 20-byte point (MARKER_FIELDS) per printed marker in the rest grid's order (rows along
// the pad's y): where the gel has moved it (z = 0), then its rest position.

/** The marker flow topic of pad `pad`. */
export const padMarkersTopic = (pad: string): string => `/tactile/${pad}/markers`;

/** The pad of a `/tactile/<pad>/markers` topic, or undefined. */
export function markersPadOfTopic(topic: string): string | undefined {
  const m = /^\/tactile\/([^/]+)\/markers$/.exec(topic);
  return m?.[1];
}

/** The pads with marker flow in a shard: its `/tactile/<pad>/markers` channels, by channel id (pad order). */
export function markersPadsOf(channels: Iterable<{ id: number; topic: string }>): string[] {
  return [...channels]
    .filter((c) => markersPadOfTopic(c.topic) != undefined)
    .sort((a, b) => a.id - b.id)
    .map((c) => markersPadOfTopic(c.topic)!);
}

/** The pads of a shard: its `/tactile/<pad>/depth` channels, by channel id (the points' pad index order). */
export function padsOf(channels: Iterable<{ id: number; topic: string }>): string[] {
  return [...channels]
    .filter((c) => padOfTopic(c.topic) != undefined)
    .sort((a, b) => a.id - b.id)
    .map((c) => padOfTopic(c.topic)!);
}

export const SAMPLE_PERIOD_NS = 100_000_000n;

/** Topic -> schema name (`json` for /sample/info) of every sample. */
export const BASE_TOPICS: Record<string, string> = {
  "/camera/rgb": "foxglove.RawImage",
  "/camera/depth": "foxglove.RawImage",
  "/camera/mask": "foxglove.RawImage",
  "/camera/calibration": "foxglove.CameraCalibration",
  "/object/pose": "foxglove.PoseInFrame",
  "/tf": "foxglove.FrameTransforms",
  "/sample/info": "json",
};

/** Topics every sample of a dataset with a robot adds, with one `/tactile/<pad>/depth` per pad,
 * an image and a reference image per pad of `optical` (the pads with an optical sensor), a force
 * field per pad of `forces` (every pad, with `robot.tactile.force_field`) and the marker flow of
 * each pad of `markers` (with force fields, the optical pads whose sensor has markers). */
export function robotTopics(
  pads: readonly string[],
  optical: readonly string[] = [],
  forces: readonly string[] = [],
  markers: readonly string[] = [],
): Record<string, string> {
  return {
    "/tactile/points": "foxglove.PointCloud",
    ...Object.fromEntries(pads.map((pad) => [padDepthTopic(pad), "foxglove.RawImage"])),
    ...Object.fromEntries(
      optical.flatMap((pad) => [padImageTopic(pad), padReferenceTopic(pad)].map((topic) => [topic, "foxglove.RawImage"])),
    ),
    ...Object.fromEntries(forces.map((pad) => [padForceTopic(pad), "foxglove.PointCloud"])),
    ...Object.fromEntries(markers.map((pad) => [padMarkersTopic(pad), "foxglove.PointCloud"])),
  };
}

/** Topics of every sample when the config has a depth noise model (camera.noise.depth). */
export const NOISE_TOPICS: Record<string, string> = {
  "/camera/depth_noisy": "foxglove.RawImage",
};

/** Once per shard, in its first sample (and again where the scene changes): Foxglove's 3D models. */
export const SCENE_TOPIC = "/scene/models";
export const SCENE_SCHEMA = "foxglove.SceneUpdate";

export type ImageSpec = { encoding: string; bytesPerPixel: number };

export const IMAGE_ENCODINGS: Record<string, ImageSpec> = {
  "/camera/rgb": { encoding: "rgb8", bytesPerPixel: 3 },
  "/camera/depth": { encoding: "32FC1", bytesPerPixel: 4 },
  "/camera/depth_noisy": { encoding: "32FC1", bytesPerPixel: 4 },
  "/camera/mask": { encoding: "mono8", bytesPerPixel: 1 },
};
/** Every pad's depth image, whatever the robot names its pads. */
export const PAD_DEPTH_ENCODING: ImageSpec = { encoding: "32FC1", bytesPerPixel: 4 };
/** An optical pad's image and reference image: RGB, linear 8-bit levels, rows without padding. */
export const PAD_OPTICAL_ENCODING: ImageSpec = { encoding: "rgb8", bytesPerPixel: 3 };

/** The image spec of a topic: a camera image's, any pad's depth image's or an optical pad's
 * image's; else undefined. */
export function imageSpec(topic: string): ImageSpec | undefined {
  return (
    IMAGE_ENCODINGS[topic] ??
    (padOfTopic(topic) != undefined ? PAD_DEPTH_ENCODING
    : opticalOfTopic(topic) != undefined ? PAD_OPTICAL_ENCODING
    : undefined)
  );
}

export const TACTILE_RESOLUTION = 32;

export const SAMPLE_INFO_KEYS = [
  "split",
  "index",
  "object_id",
  "object_index",
  "mask_id",
  "trajectory",
  "instance",
  "randomized",
  "visible_pixels",
  "T_world_camera",
  "T_camera_object",
  "occlusion",
];

export const SAMPLE_INFO_ROBOT_KEYS = [
  "physics_backend",
  "phalanges_in_contact", // the wire name of format version 1: the robot's touch links in contact
  "slip_mm",
  "slip_deg",
  "penetration_mm",
  "grasp_attempts",
  "joint_positions",
  "T_world_palm",
  "tactile",
];

/** The keys of an optical pad's entry in `/sample/info` `tactile.optical.<pad>` (the sensor's
 * parameters in that sample; `markers` is null without markers). */
export const OPTICAL_INFO_KEYS = [
  "image_size",
  "sensing_area_mm",
  "gel_thickness_mm",
  "elastic_spread_mm",
  "lights",
  "ambient",
  "background",
  "vignetting",
  "markers",
  "noise_std",
];

/** The keys of `/sample/info` `tactile` with `robot.tactile.force_field`: each pad's forces and
 * the whole hand's contact force (N, world frame). */
export const TACTILE_FORCE_INFO_KEYS = ["forces", "hand_force_n"];

/** The keys of a pad's `/sample/info` `tactile.forces.<pad>` entry: the force on its sensing area
 * (pad frame, N: what its field sums to), that of every contact of its link, the contacts on the
 * sensing area and the slip rule's friction coefficient. */
export const PAD_FORCE_INFO_KEYS = ["force_n", "link_force_n", "contacts", "friction"];

/** The name of the per-shard metadata record. */
export const SHARD_METADATA = "vtgen.shard";

export const SHARD_METADATA_KEYS = [
  "format_version",
  "generator",
  "seed",
  "config_sha256",
  "split",
  "shard_index",
  "first_sample",
  "sample_count",
  "occlusion_histogram",
];

/** The `/tactile/points` field holding each point's pad index (into the shard's pads, `padsOf`). */
export const POINT_PAD_FIELD = "phalanx"; // the wire name of format version 1

/** Point cloud fields: name, offset, Foxglove NumericType name. */
export const POINT_FIELDS: [string, number, string][] = [
  ["x", 0, "FLOAT32"],
  ["y", 4, "FLOAT32"],
  ["z", 8, "FLOAT32"],
  ["distance", 12, "FLOAT32"],
  [POINT_PAD_FIELD, 16, "UINT32"],
];
export const POINT_STRIDE = 20;

/** Force field cells (`/tactile/<pad>/force`): name, offset, Foxglove NumericType name. The cell's
 * centre in the pad frame (m, z = 0), the normal pressure on it (Pa, >= 0), the shear traction
 * along the pad's x and y (Pa) and slip (1 where the traction is at the friction limit). */
export const FORCE_FIELDS: [string, number, string][] = [
  ["x", 0, "FLOAT32"],
  ["y", 4, "FLOAT32"],
  ["z", 8, "FLOAT32"],
  ["pressure", 12, "FLOAT32"],
  ["shear_x", 16, "FLOAT32"],
  ["shear_y", 20, "FLOAT32"],
  ["slip", 24, "UINT32"],
];
export const FORCE_STRIDE = 28;

/** Marker flow points (`/tactile/<pad>/markers`): name, offset, Foxglove NumericType name. Where
 * the marker is in the pad plane (m, z = 0), then its rest position. */
export const MARKER_FIELDS: [string, number, string][] = [
  ["x", 0, "FLOAT32"],
  ["y", 4, "FLOAT32"],
  ["z", 8, "FLOAT32"],
  ["rest_x", 12, "FLOAT32"],
  ["rest_y", 16, "FLOAT32"],
];
export const MARKER_STRIDE = 20;

// Episodes (FORMAT.md, "Episodes"): with `sampling.record`, each trajectory is one shard; each
// chunk is one camera frame: the frame's messages at its instant (every topic above, the optical
// references only in frame 0, and the state of that instant), then the touch readings and states
// up to the next frame. Log times are simulated time since the episode's start (ns).

/** The `vtgen.shard` key whose presence makes a shard an episode; its value is a JSON record. */
export const EPISODE_METADATA_KEY = "episode";

/** The keys of the `vtgen.shard` `episode` record (the rates as recorded: physics steps per period). */
export const EPISODE_RECORD_KEYS = [
  "object_id",
  "trajectory",
  "frames",
  "duration_s",
  "physics_hz",
  "camera_hz",
  "tactile_hz",
  "state_hz",
  "camera_period_steps",
  "tactile_period_steps",
  "state_period_steps",
];

/** The state stream of an episode (JSON, schema `vtgen.StateRecord`). */
export const EPISODE_STATE_TOPIC = "/episode/state";

/** Topics an episode shard adds: topic -> schema name (`json`). */
export const EPISODE_TOPICS: Record<string, string> = {
  [EPISODE_STATE_TOPIC]: "json",
};

/** The keys of an `/episode/state` record. */
export const STATE_RECORD_KEYS = [
  "time_s",
  "joint_positions",
  "T_world_object",
  "T_camera_object",
  "T_world_palm",
  "linear_velocity",
  "angular_velocity",
  "phalanges_in_contact", // the wire name of format version 1: the robot's touch links in contact
];

/** The keys of an episode frame's `/sample/info` `episode`. */
export const SAMPLE_INFO_EPISODE_KEYS = ["frame", "time_s", "arm_move"];

/** Whether `topic` may follow a frame's instant in its chunk: a touch topic (the points, a pad's
 * depth image, an optical pad's image, not its reference; a pad's force field and marker flow) or
 * the state. */
export function isEpisodeStreamTopic(topic: string): boolean {
  return (
    topic === EPISODE_STATE_TOPIC ||
    topic === "/tactile/points" ||
    padOfTopic(topic) != undefined ||
    opticalOfTopic(topic)?.kind === "image" ||
    forcePadOfTopic(topic) != undefined ||
    markersPadOfTopic(topic) != undefined
  );
}

/** An episode's timing, from its `vtgen.shard` record. */
export type EpisodeTiming = {
  frames: number;
  /** physics steps of the episode (its last step: `duration_s · physics_hz`) */
  steps: number;
  camera: number;
  tactile: number;
  state: number;
  /** nanoseconds of physics step `s` (`round(s · timestep · 1e9)`; ±1 ns: the record holds
   * `physics_hz`, not the timestep) */
  stepNs: (s: number) => number;
};

export function episodeTiming(record: Record<string, unknown>): EpisodeTiming {
  const num = (key: string): number => {
    const v = record[key];
    if (typeof v !== "number" || !Number.isFinite(v)) {
      throw new Error(`vtgen.shard episode: ${key} is not a number (${JSON.stringify(v)})`);
    }
    return v;
  };
  const hz = num("physics_hz");
  return {
    frames: num("frames"),
    steps: Math.round(num("duration_s") * hz),
    camera: num("camera_period_steps"),
    tactile: num("tactile_period_steps"),
    state: num("state_period_steps"),
    stepNs: (s: number) => (s * 1e9) / hz,
  };
}
