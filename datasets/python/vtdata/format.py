"""The constants of the vtgen dataset format (``datasets/FORMAT.md``, format version 1).

Every name, key, encoding and layout the reader relies on is written here once; the index, the
decoders and :class:`vtdata.Dataset` take them from this module, and so does the test suite's
synthetic writer. ``datasets/format.json``, which the Rust crate writes from its own constants,
describes the same format: ``tests/test_format.py`` checks every constant here against it.
"""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

import numpy as np

# --- identity and timeline --------------------------------------------------------------------

#: The ``format`` value of a vtgen ``manifest.json``.
MANIFEST_FORMAT = "vtgen-dataset"
#: The newest ``format_version`` this reader was written for.
FORMAT_VERSION = 1
#: Nanoseconds between two consecutive samples on the dataset timeline (10 Hz).
SAMPLE_PERIOD_NS = 100_000_000

# --- files (FORMAT.md, "Directory layout"; paths relative to the dataset root) ----------------

MANIFEST_FILE = "manifest.json"
#: Where the meshes came from, by content (with ``config.json``, the dataset's identity).
SOURCES_FILE = "sources.json"
#: The robot the dataset was made with (``robot.urdf``, ``robot.yaml``, ``meshes.json``).
ROBOT_DIR = "robot"
MODELS_DIR = "models"
MODELS_INFO_FILE = "models/models_info.json"
#: Shard ``index`` of ``split`` (:func:`shard_file`); the same pattern in Python and Rust.
SHARD_FILE = "{split}/shard-{index:05}.mcap"
#: The suffix of a shard still being written (a ``*.mcap`` file is always complete).
PARTIAL_SUFFIX = ".partial"


def shard_file(split: str, index: int) -> str:
    """The path of shard ``index`` of ``split``, relative to the dataset root."""
    return SHARD_FILE.format(split=split, index=index)


# --- the vtgen.shard metadata record of every shard (FORMAT.md, "Shard metadata") -------------

SHARD_METADATA = "vtgen.shard"
#: The keys every shard's record has (all values strings), in the order they are written.
SHARD_METADATA_KEYS = (
    "format_version",
    "generator",
    "seed",
    "config_sha256",
    "split",
    "shard_index",
    "first_sample",
    "sample_count",
)
#: Keys only some shards have (JSON values).
SHARD_METADATA_OPTIONAL_KEYS = ("occlusion_histogram", "grasp_stats", "episode")
#: The key whose presence makes a shard an episode (JSON value: the episode record).
EPISODE_METADATA_KEY = "episode"

# --- topics (FORMAT.md, "MCAP shard") ---------------------------------------------------------

TOPIC_RGB = "/camera/rgb"
TOPIC_DEPTH = "/camera/depth"
TOPIC_DEPTH_NOISY = "/camera/depth_noisy"
TOPIC_MASK = "/camera/mask"
TOPIC_CALIBRATION = "/camera/calibration"
TOPIC_POSE = "/object/pose"
TOPIC_TF = "/tf"
TOPIC_INFO = "/sample/info"
TOPIC_TACTILE_POINTS = "/tactile/points"
#: The scene's meshes as Foxglove SceneUpdate (for viewing); the reader does not decode it.
TOPIC_SCENE_MODELS = "/scene/models"
#: Episode shards: the state stream (JSON ``vtgen.StateRecord``) at the state rate.
TOPIC_EPISODE_STATE = "/episode/state"
#: Topics every sample must have, in the order they are written; other topics (later format
#: versions) are ignored.
REQUIRED_TOPICS = (
    TOPIC_RGB,
    TOPIC_DEPTH,
    TOPIC_MASK,
    TOPIC_CALIBRATION,
    TOPIC_POSE,
    TOPIC_TF,
    TOPIC_INFO,
)

MESSAGE_ENCODING_PROTOBUF = "protobuf"
MESSAGE_ENCODING_JSON = "json"
SCHEMA_RAW_IMAGE = "foxglove.RawImage"
SCHEMA_CAMERA_CALIBRATION = "foxglove.CameraCalibration"
SCHEMA_POSE_IN_FRAME = "foxglove.PoseInFrame"
SCHEMA_FRAME_TRANSFORMS = "foxglove.FrameTransforms"
SCHEMA_POINT_CLOUD = "foxglove.PointCloud"
SCHEMA_SCENE_UPDATE = "foxglove.SceneUpdate"
SCHEMA_SAMPLE_INFO = "vtgen.SampleInfo"
SCHEMA_STATE_RECORD = "vtgen.StateRecord"

#: Topic -> (schema name, message encoding) of every fixed topic (the pads' are below).
TOPIC_SCHEMAS: Dict[str, Tuple[str, str]] = {
    TOPIC_RGB: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_DEPTH: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_DEPTH_NOISY: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_MASK: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_CALIBRATION: (SCHEMA_CAMERA_CALIBRATION, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_POSE: (SCHEMA_POSE_IN_FRAME, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_TF: (SCHEMA_FRAME_TRANSFORMS, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_INFO: (SCHEMA_SAMPLE_INFO, MESSAGE_ENCODING_JSON),
    TOPIC_TACTILE_POINTS: (SCHEMA_POINT_CLOUD, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_SCENE_MODELS: (SCHEMA_SCENE_UPDATE, MESSAGE_ENCODING_PROTOBUF),
    TOPIC_EPISODE_STATE: (SCHEMA_STATE_RECORD, MESSAGE_ENCODING_JSON),
}
#: The RawImage encoding of each fixed image topic.
TOPIC_IMAGE_ENCODINGS: Dict[str, str] = {
    TOPIC_RGB: "rgb8",
    TOPIC_DEPTH: "32FC1",
    TOPIC_DEPTH_NOISY: "32FC1",
    TOPIC_MASK: "mono8",
}

# --- the pads' topics -------------------------------------------------------------------------

#: ``/tactile/<pad>/depth``: the depth image of one pad; the pad's name is the middle part.
TACTILE_DEPTH_PREFIX, TACTILE_DEPTH_SUFFIX = "/tactile/", "/depth"
#: ``/tactile/<pad>/image``: the RGB image (``rgb8``) of a pad with an optical (GelSight/DIGIT-style)
#: sensor; only such pads have it.
TACTILE_IMAGE_SUFFIX = "/image"
#: ``/tactile/<pad>/reference``: that sensor's no-contact image without noise (``rgb8``, the size of
#: its image), written with every sample beside the image (in an episode: once, with its frame 0).
TACTILE_REFERENCE_SUFFIX = "/reference"
#: ``/tactile/<pad>/force``: the pad's contact force field (FORMAT.md, "Force fields"), a
#: ``foxglove.PointCloud`` of one :data:`FORCE_CELL_DTYPE` per cell of a square grid over the pad;
#: every pad has it with ``robot.tactile.force_field``, after the optical images, in pad order.
TACTILE_FORCE_SUFFIX = "/force"
#: ``/tactile/<pad>/markers``: an optical pad's marker flow (FORMAT.md), a ``foxglove.PointCloud``
#: of one :data:`MARKER_POINT_DTYPE` per printed marker, in the rest grid's order; each optical pad
#: whose sensor has markers has it with ``robot.tactile.force_field``, after the force fields, in
#: pad order.
TACTILE_MARKERS_SUFFIX = "/markers"
#: Suffix -> (schema name, message encoding, RawImage encoding or ``None`` for a point cloud) of the
#: ``/tactile/<pad><suffix>`` topics.
PAD_TOPIC_SCHEMAS: Dict[str, Tuple[str, str, Optional[str]]] = {
    TACTILE_DEPTH_SUFFIX: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF, "32FC1"),
    TACTILE_IMAGE_SUFFIX: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF, "rgb8"),
    TACTILE_REFERENCE_SUFFIX: (SCHEMA_RAW_IMAGE, MESSAGE_ENCODING_PROTOBUF, "rgb8"),
    TACTILE_FORCE_SUFFIX: (SCHEMA_POINT_CLOUD, MESSAGE_ENCODING_PROTOBUF, None),
    TACTILE_MARKERS_SUFFIX: (SCHEMA_POINT_CLOUD, MESSAGE_ENCODING_PROTOBUF, None),
}
#: The RawImage encoding of the pads' depth images.
TACTILE_DEPTH_ENCODING = PAD_TOPIC_SCHEMAS[TACTILE_DEPTH_SUFFIX][2]
#: The RawImage encoding of the optical pads' images and reference images.
TACTILE_IMAGE_ENCODING = PAD_TOPIC_SCHEMAS[TACTILE_IMAGE_SUFFIX][2]


def tactile_topic(pad: str, suffix: str) -> str:
    """``/tactile/<pad><suffix>``, the topic of one of :data:`PAD_TOPIC_SCHEMAS`' streams of a pad."""
    return f"{TACTILE_DEPTH_PREFIX}{pad}{suffix}"


def tactile_depth_topic(pad: str) -> str:
    """``/tactile/<pad>/depth``."""
    return tactile_topic(pad, TACTILE_DEPTH_SUFFIX)


def tactile_image_topic(pad: str) -> str:
    """``/tactile/<pad>/image``."""
    return tactile_topic(pad, TACTILE_IMAGE_SUFFIX)


def tactile_reference_topic(pad: str) -> str:
    """``/tactile/<pad>/reference``."""
    return tactile_topic(pad, TACTILE_REFERENCE_SUFFIX)


def tactile_force_topic(pad: str) -> str:
    """``/tactile/<pad>/force``."""
    return tactile_topic(pad, TACTILE_FORCE_SUFFIX)


def tactile_markers_topic(pad: str) -> str:
    """``/tactile/<pad>/markers``."""
    return tactile_topic(pad, TACTILE_MARKERS_SUFFIX)


def pad_of(topic: str, suffix: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad><suffix>`` topic, else ``None``."""
    if topic.startswith(TACTILE_DEPTH_PREFIX) and topic.endswith(suffix):
        name = topic[len(TACTILE_DEPTH_PREFIX) : -len(suffix)]
        if name and "/" not in name:
            return name
    return None


def pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/depth`` topic, else ``None``."""
    return pad_of(topic, TACTILE_DEPTH_SUFFIX)


def optical_pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/image`` topic (an optical sensor's image), else ``None``."""
    return pad_of(topic, TACTILE_IMAGE_SUFFIX)


def force_pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/force`` topic (a pad's force field), else ``None``."""
    return pad_of(topic, TACTILE_FORCE_SUFFIX)


def markers_pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/markers`` topic (an optical pad's marker flow), else
    ``None``."""
    return pad_of(topic, TACTILE_MARKERS_SUFFIX)


# --- images and points ------------------------------------------------------------------------

#: RawImage encoding -> (numpy dtype of one channel as stored, channels, dtype returned).
IMAGE_ENCODINGS: Dict[str, Tuple[str, int, Any]] = {
    "rgb8": ("u1", 3, np.uint8),
    "mono8": ("u1", 1, np.uint8),
    "mono16": ("<u2", 1, np.uint16),
    "32FC1": ("<f4", 1, np.float32),
}

#: The ``/tactile/points`` field holding each point's pad index (the ``/tactile/<pad>/depth``
#: channel order); the reader hands it to users as ``tactile["pad"]``.
TACTILE_POINT_PAD_FIELD = "phalanx"  # the wire name of format version 1
#: The ``/tactile/points`` PointCloud fields: (name, byte offset, ``PackedElementField`` type).
TACTILE_POINT_FIELDS: Tuple[Tuple[str, int, str], ...] = (
    ("x", 0, "FLOAT32"),
    ("y", 4, "FLOAT32"),
    ("z", 8, "FLOAT32"),
    ("distance", 12, "FLOAT32"),
    (TACTILE_POINT_PAD_FIELD, 16, "UINT32"),
)
#: Bytes per tactile point (the PointCloud's ``point_stride``).
TACTILE_POINT_STRIDE = 20
#: ``PackedElementField`` type -> the numpy dtype of the stored value (little-endian).
PACKED_ELEMENT_DTYPES: Dict[str, str] = {"FLOAT32": "<f4", "UINT32": "<u4"}
#: One tactile point as stored.
TACTILE_POINT_DTYPE = np.dtype(
    {
        "names": [name for name, _, _ in TACTILE_POINT_FIELDS],
        "formats": [PACKED_ELEMENT_DTYPES[kind] for _, _, kind in TACTILE_POINT_FIELDS],
        "offsets": [offset for _, offset, _ in TACTILE_POINT_FIELDS],
        "itemsize": TACTILE_POINT_STRIDE,
    }
)

#: The ``/tactile/<pad>/force`` PointCloud fields (FORMAT.md, "Force fields"): the cell's centre
#: in the pad frame (m; ``z`` = 0), the normal ``pressure`` the object puts on it (Pa, >= 0), the
#: shear traction along the pad's x and y (Pa) and ``slip`` (1 where the traction is at the friction
#: limit, else 0). (name, byte offset, ``PackedElementField`` type).
FORCE_CELL_FIELDS: Tuple[Tuple[str, int, str], ...] = (
    ("x", 0, "FLOAT32"),
    ("y", 4, "FLOAT32"),
    ("z", 8, "FLOAT32"),
    ("pressure", 12, "FLOAT32"),
    ("shear_x", 16, "FLOAT32"),
    ("shear_y", 20, "FLOAT32"),
    ("slip", 24, "UINT32"),
)
#: Bytes per force cell (the PointCloud's ``point_stride``).
FORCE_CELL_STRIDE = 28
#: One force cell as stored.
FORCE_CELL_DTYPE = np.dtype(
    {
        "names": [name for name, _, _ in FORCE_CELL_FIELDS],
        "formats": [PACKED_ELEMENT_DTYPES[kind] for _, _, kind in FORCE_CELL_FIELDS],
        "offsets": [offset for _, offset, _ in FORCE_CELL_FIELDS],
        "itemsize": FORCE_CELL_STRIDE,
    }
)

#: The ``/tactile/<pad>/markers`` PointCloud fields (FORMAT.md): where the marker is in the pad
#: plane (m; ``z`` = 0), then its rest position (``rest_x``, ``rest_y``); ``x - rest_x``, ``y -
#: rest_y`` is how far the gel moved it. (name, byte offset, ``PackedElementField`` type).
MARKER_POINT_FIELDS: Tuple[Tuple[str, int, str], ...] = (
    ("x", 0, "FLOAT32"),
    ("y", 4, "FLOAT32"),
    ("z", 8, "FLOAT32"),
    ("rest_x", 12, "FLOAT32"),
    ("rest_y", 16, "FLOAT32"),
)
#: Bytes per marker (the PointCloud's ``point_stride``).
MARKER_POINT_STRIDE = 20
#: One marker as stored.
MARKER_POINT_DTYPE = np.dtype(
    {
        "names": [name for name, _, _ in MARKER_POINT_FIELDS],
        "formats": [PACKED_ELEMENT_DTYPES[kind] for _, _, kind in MARKER_POINT_FIELDS],
        "offsets": [offset for _, offset, _ in MARKER_POINT_FIELDS],
        "itemsize": MARKER_POINT_STRIDE,
    }
)

# --- frames and mask ids (FORMAT.md, "Conventions" and "Instance mask ids") -------------------

FRAME_WORLD = "world"
FRAME_CAMERA = "camera"
FRAME_OBJECT = "object"

MASK_BACKGROUND = 0
#: The object whose pose is the ground truth.
MASK_TARGET_OBJECT = 1
#: Inclusive id ranges: the k-th distractor, arm link and hand link is ``first + k``.
MASK_DISTRACTORS = (2, 9)
MASK_ARM_LINKS = (10, 15)
#: The link moved by a seventh arm joint.
MASK_ARM_LINK_SEVENTH = 81
#: The hand's body (palm and the links fixed between it and the flange).
MASK_PALM = 16
MASK_HAND_LINKS = (17, 80)

# --- occlusion bins (FORMAT.md, "Occlusion bins") ---------------------------------------------

#: The bins' names in the data files (the manifest's ``occlusion.bins``), in histogram order.
OCCLUSION_BIN_KEYS = ("<80%", "80-85%", ">85%")
#: The levels between the bins: below the first, up to and including the second, above it.
OCCLUSION_BIN_BOUNDS = (0.80, 0.85)

# --- JSON records (the keys of each, optional ones included) ----------------------------------

#: An episode shard's ``vtgen.shard`` ``episode`` record.
EPISODE_RECORD_KEYS = (
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
)
#: An ``/episode/state`` record (``vtgen.StateRecord``).
STATE_RECORD_KEYS = (
    "time_s",
    "joint_positions",
    "T_world_object",
    "T_camera_object",
    "T_world_palm",
    "linear_velocity",
    "angular_velocity",
    "phalanges_in_contact",  # the wire name of format version 1: the robot's touch links in contact
)
#: An episode frame's ``/sample/info`` ``episode`` object.
EPISODE_FRAME_KEYS = ("frame", "time_s", "arm_move")
#: The keys ``/sample/info`` ``tactile`` has with ``robot.tactile.force_field`` (FORMAT.md, "Force
#: fields"): per pad the forces its field was made from, and the whole hand's contact force.
TOUCH_FORCE_KEYS = ("forces", "hand_force_n")
#: A pad's ``/sample/info`` ``tactile.forces.<pad>`` entry: ``force_n`` (the force on its sensing
#: area, pad frame, N: what its field sums to), ``link_force_n`` (every contact of its link),
#: ``contacts`` and the slip rule's ``friction``.
PAD_FORCE_KEYS = ("force_n", "link_force_n", "contacts", "friction")
