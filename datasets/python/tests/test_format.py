"""``vtdata.format`` against ``datasets/format.json``, the format as the Rust crate writes it.

``format.json`` is written by a test of the ``vt-dataset`` crate from the crate's own constants and
types, and checked in; every constant of :mod:`vtdata.format` that it describes must equal it, so
the two readers cannot drift apart. :data:`DESCRIBED` names which constant is checked against
which part of the file; a constant added to :mod:`vtdata.format` must be listed there or in
:data:`NOT_DESCRIBED` (``test_every_constant_is_classified``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import vtdata.episodes
import vtdata.reader
from vtdata import format as fmt

# tests/ -> python/ -> datasets/
FORMAT_JSON = Path(__file__).resolve().parents[2] / "format.json"

#: The topic names of vtdata.format (its ``TOPIC_*`` strings).
TOPIC_CONSTANTS = [
    name for name in dir(fmt) if name.startswith("TOPIC_") and isinstance(getattr(fmt, name), str)
]
#: Constant of vtdata.format -> the part of format.json it is checked against.
DESCRIBED = {
    "MANIFEST_FORMAT": "format",
    "FORMAT_VERSION": "format_version",
    "SAMPLE_PERIOD_NS": "sample_period_ns",
    "MANIFEST_FILE": "files.manifest",
    "SOURCES_FILE": "files.sources",
    "ROBOT_DIR": "files.robot_dir",
    "MODELS_DIR": "files.models_dir",
    "MODELS_INFO_FILE": "files.models_info",
    "SHARD_FILE": "files.shard",
    "PARTIAL_SUFFIX": "files.partial_suffix",
    "SHARD_METADATA": "shard_metadata.name",
    "SHARD_METADATA_KEYS": "shard_metadata.keys",
    "SHARD_METADATA_OPTIONAL_KEYS": "shard_metadata.optional_keys",
    "EPISODE_METADATA_KEY": "shard_metadata.optional_keys",
    **{name: "topics[].topic" for name in TOPIC_CONSTANTS},
    "REQUIRED_TOPICS": "topics[].required",
    "TOPIC_SCHEMAS": "topics[].schema, message_encoding",
    "TOPIC_IMAGE_ENCODINGS": "topics[].image_encoding",
    **{name: "topics[].schema" for name in dir(fmt) if name.startswith("SCHEMA_")},
    "MESSAGE_ENCODING_PROTOBUF": "topics[].message_encoding",
    "MESSAGE_ENCODING_JSON": "topics[].message_encoding",
    "TACTILE_DEPTH_PREFIX": "pad_topics[].topic",
    "TACTILE_DEPTH_SUFFIX": "pad_topics[].topic",
    "TACTILE_IMAGE_SUFFIX": "pad_topics[].topic",
    "TACTILE_REFERENCE_SUFFIX": "pad_topics[].topic",
    "TACTILE_FORCE_SUFFIX": "pad_topics[].topic",
    "TACTILE_MARKERS_SUFFIX": "pad_topics[].topic",
    "PAD_TOPIC_SCHEMAS": "pad_topics[]",
    "TACTILE_DEPTH_ENCODING": "pad_topics[].image_encoding",
    "TACTILE_IMAGE_ENCODING": "pad_topics[].image_encoding",
    "IMAGE_ENCODINGS": "image_encodings",
    "TACTILE_POINT_FIELDS": "tactile_points.fields",
    "TACTILE_POINT_PAD_FIELD": "tactile_points.fields",
    "TACTILE_POINT_STRIDE": "tactile_points.point_stride",
    "TACTILE_POINT_DTYPE": "tactile_points",
    "PACKED_ELEMENT_DTYPES": "tactile_points, force_cells, marker_points: fields[].type",
    "FORCE_CELL_FIELDS": "force_cells.fields",
    "FORCE_CELL_STRIDE": "force_cells.point_stride",
    "FORCE_CELL_DTYPE": "force_cells",
    "MARKER_POINT_FIELDS": "marker_points.fields",
    "MARKER_POINT_STRIDE": "marker_points.point_stride",
    "MARKER_POINT_DTYPE": "marker_points",
    "FRAME_WORLD": "frames.world",
    "FRAME_CAMERA": "frames.camera",
    "FRAME_OBJECT": "frames.object",
    "MASK_BACKGROUND": "mask_ids.background",
    "MASK_TARGET_OBJECT": "mask_ids.target_object",
    "MASK_DISTRACTORS": "mask_ids.distractors",
    "MASK_ARM_LINKS": "mask_ids.arm_links",
    "MASK_ARM_LINK_SEVENTH": "mask_ids.arm_link_seventh",
    "MASK_PALM": "mask_ids.palm",
    "MASK_HAND_LINKS": "mask_ids.hand_links",
    "OCCLUSION_BIN_KEYS": "occlusion_bins.keys",
    "OCCLUSION_BIN_BOUNDS": "occlusion_bins.bounds",
    "EPISODE_RECORD_KEYS": "records.episode",
    "STATE_RECORD_KEYS": "records.state",
    "EPISODE_FRAME_KEYS": "records.episode_frame",
    "TOUCH_FORCE_KEYS": "records.touch_info",
    "PAD_FORCE_KEYS": "records.pad_force",
}
#: Constants of vtdata.format that format.json does not describe (none: a robot's pad names are
#: data, read from the shard, not format).
NOT_DESCRIBED: Dict[str, str] = {}


@pytest.fixture(scope="module")
def spec() -> Dict[str, Any]:
    # Checked in beside FORMAT.md and written by the vt-dataset crate's tests: missing is a failure.
    assert FORMAT_JSON.is_file(), f"{FORMAT_JSON} is missing (the vt-dataset crate's tests write it)"
    return json.loads(FORMAT_JSON.read_text(encoding="utf-8"))


def _all_topics(spec: Dict[str, Any]) -> List[Dict[str, Any]]:
    return list(spec["topics"]) + list(spec["pad_topics"])


def test_every_constant_is_classified() -> None:
    constants = {name for name in dir(fmt) if name.isupper() and not name.startswith("_")}
    assert not set(DESCRIBED) & set(NOT_DESCRIBED)
    unclassified = constants - set(DESCRIBED) - set(NOT_DESCRIBED)
    assert not unclassified, (
        f"list these vtdata.format constants in DESCRIBED or NOT_DESCRIBED: {sorted(unclassified)}"
    )
    gone = (set(DESCRIBED) | set(NOT_DESCRIBED)) - constants
    assert not gone, f"no longer in vtdata.format: {sorted(gone)}"


def test_format_identity(spec: Dict[str, Any]) -> None:
    assert fmt.MANIFEST_FORMAT == spec["format"]
    assert fmt.FORMAT_VERSION == spec["format_version"]
    assert fmt.SAMPLE_PERIOD_NS == spec["sample_period_ns"]


def test_files(spec: Dict[str, Any]) -> None:
    files = spec["files"]
    assert fmt.MANIFEST_FILE == files["manifest"]
    assert fmt.SOURCES_FILE == files["sources"]
    assert fmt.ROBOT_DIR == files["robot_dir"]
    assert fmt.MODELS_DIR == files["models_dir"]
    assert fmt.MODELS_INFO_FILE == files["models_info"]
    assert fmt.MODELS_INFO_FILE.startswith(fmt.MODELS_DIR + "/")
    assert fmt.PARTIAL_SUFFIX == files["partial_suffix"]
    # Rust's `{index:05}` and Python's str.format read the pattern alike.
    assert fmt.SHARD_FILE == files["shard"]
    assert fmt.shard_file("train", 7) == "train/shard-00007.mcap"


def test_shard_metadata(spec: Dict[str, Any]) -> None:
    meta = spec["shard_metadata"]
    assert fmt.SHARD_METADATA == meta["name"]
    assert list(fmt.SHARD_METADATA_KEYS) == list(meta["keys"])
    assert set(fmt.SHARD_METADATA_OPTIONAL_KEYS) == set(meta["optional_keys"])
    assert fmt.EPISODE_METADATA_KEY in meta["optional_keys"]


def test_topics(spec: Dict[str, Any]) -> None:
    topics = spec["topics"]
    names = [t["topic"] for t in topics]
    assert len(set(names)) == len(names)
    constants = {name: getattr(fmt, name) for name in TOPIC_CONSTANTS}
    assert sorted(constants.values()) == sorted(names), constants
    assert fmt.TOPIC_SCHEMAS == {t["topic"]: (t["schema"], t["message_encoding"]) for t in topics}
    assert fmt.TOPIC_IMAGE_ENCODINGS == {
        t["topic"]: t["image_encoding"] for t in topics if "image_encoding" in t
    }
    assert list(fmt.REQUIRED_TOPICS) == [t["topic"] for t in topics if t.get("required")]


def test_pad_topics(spec: Dict[str, Any]) -> None:
    pads: Dict[str, Dict[str, Any]] = {}
    for entry in spec["pad_topics"]:
        prefix, suffix = entry["topic"].split("{pad}")
        assert prefix == fmt.TACTILE_DEPTH_PREFIX, entry
        pads[suffix] = entry
    assert set(pads) == {
        fmt.TACTILE_DEPTH_SUFFIX,
        fmt.TACTILE_IMAGE_SUFFIX,
        fmt.TACTILE_REFERENCE_SUFFIX,
        fmt.TACTILE_FORCE_SUFFIX,
        fmt.TACTILE_MARKERS_SUFFIX,
    }
    assert fmt.PAD_TOPIC_SCHEMAS == {
        suffix: (e["schema"], e["message_encoding"], e.get("image_encoding"))
        for suffix, e in pads.items()
    }
    # The force field is a point cloud (no image encoding), written with robot.tactile.force_field.
    force = pads[fmt.TACTILE_FORCE_SUFFIX]
    assert (force["schema"], force["when"]) == (fmt.SCHEMA_POINT_CLOUD, "force_field")
    assert "image_encoding" not in force
    # So is the marker flow, with the force fields (the gel's shear moves the markers).
    markers = pads[fmt.TACTILE_MARKERS_SUFFIX]
    assert (markers["schema"], markers["when"]) == (fmt.SCHEMA_POINT_CLOUD, "force_field")
    assert "image_encoding" not in markers
    assert fmt.TACTILE_DEPTH_ENCODING == pads[fmt.TACTILE_DEPTH_SUFFIX]["image_encoding"]
    assert fmt.TACTILE_IMAGE_ENCODING == pads[fmt.TACTILE_IMAGE_SUFFIX]["image_encoding"]
    assert fmt.TACTILE_IMAGE_ENCODING == pads[fmt.TACTILE_REFERENCE_SUFFIX]["image_encoding"]
    # The topic builders and parsers follow the same patterns.
    for build, suffix in (
        (fmt.tactile_depth_topic, fmt.TACTILE_DEPTH_SUFFIX),
        (fmt.tactile_image_topic, fmt.TACTILE_IMAGE_SUFFIX),
        (fmt.tactile_reference_topic, fmt.TACTILE_REFERENCE_SUFFIX),
        (fmt.tactile_force_topic, fmt.TACTILE_FORCE_SUFFIX),
        (fmt.tactile_markers_topic, fmt.TACTILE_MARKERS_SUFFIX),
    ):
        assert build("{pad}") == pads[suffix]["topic"]
        topic = pads[suffix]["topic"].replace("{pad}", "th_distal")
        assert fmt.pad_of(topic, suffix) == "th_distal"
    assert fmt.pad_of_topic(fmt.tactile_depth_topic("left_pad")) == "left_pad"
    assert fmt.optical_pad_of_topic(fmt.tactile_image_topic("left_pad")) == "left_pad"
    assert fmt.force_pad_of_topic(fmt.tactile_force_topic("left_pad")) == "left_pad"
    assert fmt.force_pad_of_topic(fmt.tactile_depth_topic("left_pad")) is None
    assert fmt.markers_pad_of_topic(fmt.tactile_markers_topic("left_pad")) == "left_pad"
    assert fmt.markers_pad_of_topic(fmt.tactile_force_topic("left_pad")) is None


def test_schemas_and_message_encodings(spec: Dict[str, Any]) -> None:
    schemas = {name: getattr(fmt, name) for name in dir(fmt) if name.startswith("SCHEMA_")}
    assert set(schemas.values()) == {t["schema"] for t in _all_topics(spec)}, schemas
    assert {fmt.MESSAGE_ENCODING_PROTOBUF, fmt.MESSAGE_ENCODING_JSON} == {
        t["message_encoding"] for t in _all_topics(spec)
    }


def test_image_encodings(spec: Dict[str, Any]) -> None:
    # Every encoding the format writes decodes with its size; the reader may decode more.
    encodings = spec["image_encodings"]
    assert set(encodings) <= set(fmt.IMAGE_ENCODINGS), set(encodings) - set(fmt.IMAGE_ENCODINGS)
    for name, want in encodings.items():
        stored, channels, returned = fmt.IMAGE_ENCODINGS[name]
        assert channels == want["channels"], name
        assert np.dtype(stored).itemsize == want["bytes_per_channel"], name
        assert np.dtype(returned).itemsize == want["bytes_per_channel"], name
    # Every image topic's encoding is one the reader decodes.
    used = {t["image_encoding"] for t in _all_topics(spec) if "image_encoding" in t}
    assert used <= set(fmt.IMAGE_ENCODINGS)


NUMPY_OF = {"FLOAT32": np.dtype("<f4"), "UINT32": np.dtype("<u4")}


def _check_packed_layout(layout: Dict[str, Any], fields: Any, stride: int, dtype: np.dtype) -> None:
    """A packed point layout of vtdata.format (fields, stride, numpy dtype) against format.json's."""
    want = [(f["name"], f["offset"], f["type"]) for f in layout["fields"]]
    assert list(fields) == want
    assert stride == layout["point_stride"]
    assert dtype.itemsize == layout["point_stride"]
    assert list(dtype.names) == [name for name, _, _ in want]
    for name, offset, kind in want:
        field_dtype, field_offset = dtype.fields[name][:2]
        assert (field_dtype, field_offset) == (NUMPY_OF[kind], offset), name


def test_tactile_points(spec: Dict[str, Any]) -> None:
    points = spec["tactile_points"]
    _check_packed_layout(points, fmt.TACTILE_POINT_FIELDS, fmt.TACTILE_POINT_STRIDE, fmt.TACTILE_POINT_DTYPE)
    # The pad index: the last field, a uint32 (its wire name is the format's; the reader hands it
    # out as tactile["pad"]).
    last = points["fields"][-1]
    assert last["name"] == fmt.TACTILE_POINT_PAD_FIELD and last["type"] == "UINT32"
    layouts = ("tactile_points", "force_cells", "marker_points")
    kinds = {f["type"] for layout in layouts for f in spec[layout]["fields"]}
    assert {k: np.dtype(v) for k, v in fmt.PACKED_ELEMENT_DTYPES.items()} == {
        kind: NUMPY_OF[kind] for kind in kinds
    }


def test_force_cells(spec: Dict[str, Any]) -> None:
    """``/tactile/<pad>/force``'s cell layout: x, y, z, pressure, shear_x, shear_y (float32) and
    slip (uint32), 28 bytes a cell."""
    cells = spec["force_cells"]
    _check_packed_layout(cells, fmt.FORCE_CELL_FIELDS, fmt.FORCE_CELL_STRIDE, fmt.FORCE_CELL_DTYPE)
    assert fmt.FORCE_CELL_STRIDE == 28


def test_marker_points(spec: Dict[str, Any]) -> None:
    """``/tactile/<pad>/markers``' point layout: x, y, z (where the marker is) and rest_x, rest_y
    (its rest position), float32, 20 bytes a marker."""
    markers = spec["marker_points"]
    _check_packed_layout(markers, fmt.MARKER_POINT_FIELDS, fmt.MARKER_POINT_STRIDE, fmt.MARKER_POINT_DTYPE)
    assert fmt.MARKER_POINT_STRIDE == 20


def test_frames(spec: Dict[str, Any]) -> None:
    frames = spec["frames"]
    assert (fmt.FRAME_WORLD, fmt.FRAME_CAMERA, fmt.FRAME_OBJECT) == (
        frames["world"],
        frames["camera"],
        frames["object"],
    )


def test_mask_ids(spec: Dict[str, Any]) -> None:
    ids = spec["mask_ids"]
    assert fmt.MASK_BACKGROUND == ids["background"]
    assert fmt.MASK_TARGET_OBJECT == ids["target_object"]
    assert list(fmt.MASK_DISTRACTORS) == list(ids["distractors"])
    assert list(fmt.MASK_ARM_LINKS) == list(ids["arm_links"])
    assert fmt.MASK_ARM_LINK_SEVENTH == ids["arm_link_seventh"]
    assert fmt.MASK_PALM == ids["palm"]
    assert list(fmt.MASK_HAND_LINKS) == list(ids["hand_links"])


def test_occlusion_bins(spec: Dict[str, Any]) -> None:
    bins = spec["occlusion_bins"]
    assert list(fmt.OCCLUSION_BIN_KEYS) == list(bins["keys"])
    assert list(fmt.OCCLUSION_BIN_BOUNDS) == list(bins["bounds"])


def test_record_keys(spec: Dict[str, Any]) -> None:
    """The keys of the JSON records the reader lists; a JSON object's key order is not format."""
    records = spec["records"]
    assert set(fmt.EPISODE_RECORD_KEYS) == set(records["episode"])
    assert set(fmt.STATE_RECORD_KEYS) == set(records["state"])
    assert set(fmt.EPISODE_FRAME_KEYS) == set(records["episode_frame"])
    assert set(fmt.PAD_FORCE_KEYS) == set(records["pad_force"])
    # The touch info's force keys are among its keys (the others: pads, points, optical, ...).
    assert set(fmt.TOUCH_FORCE_KEYS) <= set(records["touch_info"])
    for keys in (fmt.EPISODE_RECORD_KEYS, fmt.STATE_RECORD_KEYS, fmt.EPISODE_FRAME_KEYS, fmt.PAD_FORCE_KEYS):
        assert len(set(keys)) == len(keys)
    # The state keys EpisodeDataset turns into arrays are state record keys.
    assert set(vtdata.episodes.STATE_POSES) <= set(records["state"])
    assert set(vtdata.episodes.STATE_VECTORS) <= set(records["state"])


def test_reader_re_exports_the_format_constants() -> None:
    """``vtdata.reader`` still offers the constants that moved to ``vtdata.format``, as the same
    objects (one definition)."""
    moved = [
        "SAMPLE_PERIOD_NS",
        "MANIFEST_FORMAT",
        "FORMAT_VERSION",
        "REQUIRED_TOPICS",
        "EPISODE_METADATA_KEY",
        "TACTILE_DEPTH_PREFIX",
        "TACTILE_DEPTH_SUFFIX",
        "TACTILE_IMAGE_SUFFIX",
        "TACTILE_REFERENCE_SUFFIX",
        "pad_of_topic",
        "optical_pad_of_topic",
    ] + TOPIC_CONSTANTS
    for name in moved:
        assert getattr(vtdata.reader, name) is getattr(fmt, name), name
    assert vtdata.reader._IMAGE_ENCODINGS is fmt.IMAGE_ENCODINGS
    assert vtdata.reader._TACTILE_DTYPE is fmt.TACTILE_POINT_DTYPE
    assert vtdata.reader._pad_of is fmt.pad_of
    # vtdata.reader's TOPIC_* names are topics only (callers list them with vars()).
    topics = {k: v for k, v in vars(vtdata.reader).items() if k.startswith("TOPIC_")}
    assert topics == {name: getattr(fmt, name) for name in TOPIC_CONSTANTS}
