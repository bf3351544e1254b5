// The parts of datasets/FORMAT.md (format version 1) this reader checks.

export const FINGERS = ["ff", "mf", "rf", "th"] as const;
export const PHALANGES = ["proximal", "medial", "distal"] as const;
/** `<finger>_<phalanx>` in the order of the point cloud's `phalanx` index. */
export const PADS = FINGERS.flatMap((f) => PHALANGES.map((p) => `${f}_${p}`));

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

/** Topics every sample of a dataset with a robot adds. */
export const ROBOT_TOPICS: Record<string, string> = {
  "/tactile/points": "foxglove.PointCloud",
  ...Object.fromEntries(PADS.map((pad) => [`/tactile/${pad}/depth`, "foxglove.RawImage"])),
};

/** Topics of every sample when the config has a depth noise model (camera.noise.depth). */
export const NOISE_TOPICS: Record<string, string> = {
  "/camera/depth_noisy": "foxglove.RawImage",
};

/** Once per shard, in its first sample (and again where the scene changes): Foxglove's 3D models. */
export const SCENE_TOPIC = "/scene/models";
export const SCENE_SCHEMA = "foxglove.SceneUpdate";

export const IMAGE_ENCODINGS: Record<string, { encoding: string; bytesPerPixel: number }> = {
  "/camera/rgb": { encoding: "rgb8", bytesPerPixel: 3 },
  "/camera/depth": { encoding: "32FC1", bytesPerPixel: 4 },
  "/camera/depth_noisy": { encoding: "32FC1", bytesPerPixel: 4 },
  "/camera/mask": { encoding: "mono8", bytesPerPixel: 1 },
  ...Object.fromEntries(PADS.map((pad) => [`/tactile/${pad}/depth`, { encoding: "32FC1", bytesPerPixel: 4 }])),
};

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
  "phalanges_in_contact",
  "slip_mm",
  "slip_deg",
  "penetration_mm",
  "grasp_attempts",
  "joint_positions",
  "T_world_palm",
  "tactile",
];

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

/** Point cloud fields: name, offset, Foxglove NumericType name. */
export const POINT_FIELDS: [string, number, string][] = [
  ["x", 0, "FLOAT32"],
  ["y", 4, "FLOAT32"],
  ["z", 8, "FLOAT32"],
  ["distance", 12, "FLOAT32"],
  ["phalanx", 16, "UINT32"],
];
export const POINT_STRIDE = 20;
