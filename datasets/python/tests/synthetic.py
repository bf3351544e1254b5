"""Write small vtgen-format datasets in pure Python, following ``datasets/FORMAT.md``.

Used by ``test_synthetic.py`` so the reader is tested without the Rust generator. Its topics,
schemas, encodings, file names, metadata and record keys are :mod:`vtdata.format`'s (which
``test_format.py`` checks against ``datasets/format.json``, the Rust crate's). The writer uses
``mcap.writer.Writer`` (zstd, one chunk per sample via ``Writer.flush``, mcap >= 1.5) and the
Foxglove protobuf classes of the ``foxglove-schemas-protobuf`` package. ``write_episode_dataset``
writes episode datasets (FORMAT.md, "Episodes": one shard per episode, one chunk per camera frame
holding the frame and the later touch and state messages up to the next frame). With
``force_resolution`` every touch reading also carries each pad's ``/tactile/<pad>/force`` grid
(FORMAT.md, "Force fields") and ``/sample/info`` its ``tactile.forces`` and ``hand_force_n``; with
``marker_count`` too, each optical pad's ``/tactile/<pad>/markers`` (its marker flow).
"""

from __future__ import annotations

import hashlib
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import build_file_descriptor_set

from vtdata.format import (
    EPISODE_FRAME_KEYS,
    EPISODE_METADATA_KEY,
    EPISODE_RECORD_KEYS,
    FORCE_CELL_DTYPE,
    FORCE_CELL_FIELDS,
    FORCE_CELL_STRIDE,
    FORMAT_VERSION,
    FRAME_CAMERA,
    FRAME_OBJECT,
    FRAME_WORLD,
    MANIFEST_FILE,
    MANIFEST_FORMAT,
    MASK_BACKGROUND,
    MASK_TARGET_OBJECT,
    MARKER_POINT_DTYPE,
    MARKER_POINT_FIELDS,
    MARKER_POINT_STRIDE,
    MESSAGE_ENCODING_PROTOBUF,
    MODELS_DIR,
    MODELS_INFO_FILE,
    PAD_FORCE_KEYS,
    PAD_TOPIC_SCHEMAS,
    SAMPLE_PERIOD_NS,
    SHARD_METADATA,
    SHARD_METADATA_KEYS,
    SHARD_METADATA_OPTIONAL_KEYS,
    STATE_RECORD_KEYS,
    TACTILE_DEPTH_ENCODING,
    TACTILE_DEPTH_SUFFIX,
    TACTILE_FORCE_SUFFIX,
    TACTILE_IMAGE_ENCODING,
    TACTILE_IMAGE_SUFFIX,
    TACTILE_MARKERS_SUFFIX,
    TACTILE_POINT_DTYPE,
    TACTILE_POINT_FIELDS,
    TACTILE_POINT_PAD_FIELD,
    TACTILE_POINT_STRIDE,
    TACTILE_REFERENCE_SUFFIX,
    TOPIC_CALIBRATION,
    TOPIC_DEPTH,
    TOPIC_EPISODE_STATE,
    TOPIC_IMAGE_ENCODINGS,
    TOPIC_INFO,
    TOPIC_MASK,
    TOPIC_POSE,
    TOPIC_RGB,
    TOPIC_SCHEMAS,
    TOPIC_TACTILE_POINTS,
    TOPIC_TF,
    TOUCH_FORCE_KEYS,
    shard_file,
    tactile_depth_topic,
    tactile_force_topic,
    tactile_image_topic,
    tactile_markers_topic,
    tactile_reference_topic,
)

#: Episodes: the state stream (JSON, schema ``vtgen.StateRecord``).
STATE_TOPIC = TOPIC_EPISODE_STATE
OBJECT_ID = "test_cube"
#: The ``generator`` of the manifest and the shards' metadata (and the MCAP ``library``).
GENERATOR = "vtgen 0.1.0"
CONFIG_SHA256 = "0" * 64
HEIGHT, WIDTH = 6, 8
#: Pixels per side of a pad's depth image in the synthetic robot datasets.
TACTILE_RESOLUTION = 4
#: (width, height) of the optical pads' RGB images (``/tactile/<pad>/image`` and ``reference``);
#: not square, so a reader that swaps the axes is caught.
OPTICAL_SIZE = (5, 3)
#: Every synthetic pad's sensing area (length along its x, width along its y; m): ``/sample/info``
#: ``tactile.pads``, and the extent of its force grid.
PAD_SIZE = (0.02, 0.015)
#: The UR5e + Allegro's 12 pads in pad index order, the names its datasets hold (the reader
#: knows no robot's pads: it reads them from the shard).
ALLEGRO_PADS = tuple(f"{f}_{p}" for f in ("ff", "mf", "rf", "th") for p in ("proximal", "medial", "distal"))
#: The robots the synthetic writer can put in a sample: their pads in index order (the order of
#: the points' pad index and of the ``/tactile/<pad>/depth`` channels) and their joints.
ROBOTS: Dict[str, Dict[str, Any]] = {
    "ur5e_allegro": {
        "pads": ALLEGRO_PADS,
        "joints": [f"{j}_joint" for j in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")]
        + [f"{f}_joint_{k}" for f in ("ff", "mf", "rf", "th") for k in range(4)],
    },
    # Not in name order, so a reader that sorts the names gets the pad index wrong.
    "robotiq_2f85": {
        "pads": ("right_pad", "left_pad"),
        "joints": [f"joint_{k}" for k in range(1, 8)] + ["finger_joint", "right_outer_knuckle_joint"],
    },
    "three_finger": {
        "pads": ("c_proximal", "c_distal", "a_proximal", "a_distal", "b_proximal", "b_distal"),
        "joints": [f"arm_{k}" for k in range(6)] + [f"{f}_{k}" for f in "abc" for k in range(2)],
    },
}

Pose = Tuple[Tuple[float, float, float], Tuple[float, float, float, float]]
#: Markers per optical pad: one count for every pad, or ``{pad: count}`` (each sensor its own grid).
MarkerCount = Union[int, Mapping[str, int]]


@dataclass
class SyntheticSample:
    split: str
    index: int
    rgb: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    K: np.ndarray
    camera_object: Pose
    world_camera: Pose
    world_object: Pose
    info: Dict[str, Any] = field(default_factory=dict)
    #: With a robot: ``pads`` (names in index order), ``points`` (N, 3) float32, ``distance`` (N,)
    #: float32, ``pad`` (N,) uint32 pad index, ``depth`` (P, R, R) float32; with optical pads also
    #: ``images`` and ``references``, ``{pad: (H, W, 3) uint8}`` in pad order; ``forces``, with
    #: force fields ``{pad: {"position", "pressure", "shear", "slip"}}`` in pad order (the arrays
    #: vtdata returns), else empty; ``markers``, with marker flow ``{pad: {"position", "rest"}}``
    #: for the optical pads in pad order, else empty.
    tactile: Optional[Dict[str, Any]] = None
    #: An episode frame's time since the episode's start (ns); a snapshot's log time is
    #: ``index * SAMPLE_PERIOD_NS``.
    time_ns: Optional[int] = None

    @property
    def log_time(self) -> int:
        return self.index * SAMPLE_PERIOD_NS if self.time_ns is None else self.time_ns


def random_pose(rng: np.random.Generator) -> Pose:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    t = rng.uniform(-1.0, 1.0, size=3)
    return (tuple(float(v) for v in t), tuple(float(v) for v in q))  # type: ignore[return-value]


def make_force_field(r: int, pressed: bool, rng: np.random.Generator) -> Dict[str, np.ndarray]:
    """A random ``r x r`` force field over a :data:`PAD_SIZE` pad, as vtdata returns one: cell
    centres (FORMAT.md's ``x = ((2u + 1)/R - 1) L/2``, rows along y), and on a ``pressed`` pad some
    cells with pressure, shear and slip (zeros elsewhere and on a pad without contact)."""
    length, width = PAD_SIZE
    u = ((2 * np.arange(r) + 1) / r - 1) * length / 2
    v = ((2 * np.arange(r) + 1) / r - 1) * width / 2
    position = np.stack(np.meshgrid(u, v, indexing="xy"), axis=-1).astype(np.float32)
    contact = rng.random((r, r)) < 0.6 if pressed else np.zeros((r, r), dtype=bool)
    pressure = np.where(contact, rng.uniform(10.0, 5000.0, size=(r, r)), 0.0).astype(np.float32)
    shear = np.where(contact[..., None], rng.uniform(-800.0, 800.0, size=(r, r, 2)), 0.0).astype(np.float32)
    slip = contact & (rng.random((r, r)) < 0.3)
    return {"position": position, "pressure": pressure, "shear": shear, "slip": slip}


def force_info(field: Dict[str, np.ndarray], contacts: int) -> Dict[str, Any]:
    """A pad's ``/sample/info`` ``tactile.forces.<pad>`` entry for ``field``: ``force_n`` is what
    its cells sum to (FORMAT.md, "Sums": pressure and shear times the cell area L*W/R^2)."""
    r = field["pressure"].shape[0]
    area = PAD_SIZE[0] * PAD_SIZE[1] / (r * r)
    shear = field["shear"].astype(np.float64).sum(axis=(0, 1)) * area
    force = [float(shear[0]), float(shear[1]), -float(field["pressure"].astype(np.float64).sum()) * area]
    entry = {"force_n": force, "link_force_n": list(force), "contacts": contacts, "friction": 1.0}
    assert tuple(entry) == PAD_FORCE_KEYS, (tuple(entry), PAD_FORCE_KEYS)
    return entry


def make_marker_flow(n: int, pressed: bool, rng: np.random.Generator) -> Dict[str, np.ndarray]:
    """``n`` random markers of a :data:`PAD_SIZE` pad, as vtdata returns them: at rest on a grid
    (rows along y, each row along x; the last row may be short), and on a ``pressed`` pad moved up
    to 0.5 mm (at rest elsewhere and on a pad without contact)."""
    length, width = PAD_SIZE
    cols = max(1, int(np.ceil(np.sqrt(n))))
    rows = max(1, -(-n // cols))
    u, v = np.arange(n) % cols, np.arange(n) // cols
    rest = np.stack([((u + 0.5) / cols - 0.5) * length, ((v + 0.5) / rows - 0.5) * width], axis=-1)
    moved = rng.uniform(-5e-4, 5e-4, size=(n, 2)) if pressed else np.zeros((n, 2))
    return {"position": (rest + moved).astype(np.float32), "rest": rest.astype(np.float32)}


def make_tactile(
    pads: Sequence[str],
    rng: np.random.Generator,
    optical: Sequence[str] = (),
    force_resolution: Optional[int] = None,
    marker_count: Optional[MarkerCount] = None,
) -> Dict[str, Any]:
    """Random tactile data of a robot with ``pads``: points on some pads, one depth image each, an
    RGB image and reference image for each pad of ``optical`` (kept in the pads' order) and, with
    ``force_resolution``, every pad's force field (pressed on the touching pads) and, with
    ``marker_count`` too, each optical pad's marker flow of that many markers (moved on the
    touching pads)."""
    unknown = [p for p in optical if p not in pads]
    assert not unknown, f"optical pads {unknown} are not pads of the robot {list(pads)}"
    # As the generator: markers are written with force fields (their gel's shear moves them).
    assert marker_count is None or force_resolution is not None, "marker flow needs force fields"
    n_pads = len(pads)
    touching = sorted(rng.choice(n_pads, size=min(2, n_pads), replace=False).tolist())
    counts = [int(rng.integers(1, 5)) if k in touching else 0 for k in range(n_pads)]
    pad = np.repeat(np.arange(n_pads, dtype=np.uint32), counts)
    n = len(pad)
    depth = rng.uniform(0.0, 0.01, size=(n_pads, TACTILE_RESOLUTION, TACTILE_RESOLUTION))
    depth[:, 0, 0] = np.inf
    w, h = OPTICAL_SIZE
    optical_pads = [p for p in pads if p in optical]
    tactile = {
        "pads": list(pads),
        "points": rng.uniform(-0.5, 0.5, size=(n, 3)).astype(np.float32),
        "distance": rng.uniform(-0.001, 0.002, size=n).astype(np.float32),
        "pad": pad,
        "depth": depth.astype(np.float32),
        "counts": counts,
        "touching": [pads[k] for k in touching],
        "images": {p: rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8) for p in optical_pads},
        "references": {p: rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8) for p in optical_pads},
        "forces": {},
        "markers": {},
    }
    if force_resolution is not None:
        tactile["forces"] = {
            p: make_force_field(force_resolution, k in touching, rng) for k, p in enumerate(pads)
        }
    if marker_count is not None:
        per_pad = marker_count if isinstance(marker_count, Mapping) else {p: marker_count for p in optical_pads}
        tactile["markers"] = {
            p: make_marker_flow(per_pad[p], pads.index(p) in touching, rng) for p in optical_pads
        }
    return tactile


def sensors_info(pads: Sequence[str], optical: Sequence[str] = ()) -> Dict[str, Any]:
    """``/sample/info`` ``tactile.sensors``: one entry per pad, its sensor model (the per-pad shape;
    datasets of earlier generators have one entry per finger segment instead). The optical pads'
    are ``optical``, the others' ``depth_camera``, but for a ``taxel_array`` on a pad of a robot
    with more than two, so every model's entry shape is written."""
    out: Dict[str, Any] = {}
    for k, pad in enumerate(pads):
        if pad in optical:
            out[pad] = {"model": "optical"}
        elif k == 0 and len(pads) > 2:
            out[pad] = {"model": "taxel_array", "rows": 4, "cols": 4}
        else:
            out[pad] = {"model": "depth_camera"}
    return out


def optical_info(rng: np.random.Generator) -> Dict[str, Any]:
    """One optical sensor's ``/sample/info`` ``tactile.optical.<pad>`` entry (FORMAT.md)."""
    lights = [
        {"direction": [0.0, 0.82, -0.57], "color": [1.0, 0.1, 0.1], "falloff": 0.25},
        {"direction": [-0.71, -0.41, -0.57], "color": [0.1, 0.8, 0.2], "falloff": 0.25},
        {"direction": [0.71, -0.41, -0.57], "color": [0.1, 0.2, 0.9], "falloff": 0.25},
    ]
    return {
        "image_size": list(OPTICAL_SIZE),
        "sensing_area_mm": [18.6, 14.3],
        "gel_thickness_mm": float(rng.uniform(1.0, 2.0)),
        "elastic_spread_mm": 0.5,
        "lights": lights,
        "ambient": 0.15,
        "background": [0.8, 0.7, 0.75],
        "vignetting": 0.3,
        "markers": {"pitch_mm": 2.0, "radius_mm": 0.3, "shift": 0.5, "opacity": 0.85},
        "noise_std": 1.0,
    }


def make_sample(
    split: str,
    index: int,
    rng: np.random.Generator,
    robot: Optional[str] = None,
    optical: Sequence[str] = (),
    force_resolution: Optional[int] = None,
    marker_count: Optional[MarkerCount] = None,
) -> SyntheticSample:
    rgb = rng.integers(0, 256, size=(HEIGHT, WIDTH, 3), dtype=np.uint8)
    depth = rng.uniform(0.2, 1.5, size=(HEIGHT, WIDTH)).astype(np.float32)
    mask = np.zeros((HEIGHT, WIDTH), dtype=np.uint8)
    mask[1:4, 2:6] = MASK_TARGET_OBJECT
    background = mask == MASK_BACKGROUND
    depth[background] = np.where(rng.random(int(background.sum())) < 0.5, 0.0, 2.0)
    fx, fy = 500.0 + index, 510.0 + index
    K = np.array([[fx, 0.0, (WIDTH - 1) / 2], [0.0, fy, (HEIGHT - 1) / 2], [0.0, 0.0, 1.0]])
    camera_object, world_camera, world_object = (random_pose(rng) for _ in range(3))
    info = {
        "split": split,
        "index": index,
        "object_id": OBJECT_ID,
        "object_index": 0,
        "mask_id": MASK_TARGET_OBJECT,
        "trajectory": index // 2,
        "instance": index % 2,
        "randomized": bool(index % 2),
        "visible_pixels": int((mask == MASK_TARGET_OBJECT).sum()),
        "T_world_camera": {"position": list(world_camera[0]), "orientation": list(world_camera[1])},
        "T_camera_object": {
            "position": list(camera_object[0]),
            "orientation": list(camera_object[1]),
        },
    }
    tactile = None
    if robot is not None:
        spec = ROBOTS[robot]
        tactile = make_tactile(spec["pads"], rng, optical, force_resolution, marker_count)
        info.update(
            {
                "physics_backend": "rapier",
                "phalanges_in_contact": tactile["touching"],
                "slip_mm": 0.0,
                "slip_deg": 0.0,
                "penetration_mm": 0.0,
                "grasp_attempts": 1,
                "joint_positions": {j: float(rng.uniform(-1, 1)) for j in spec["joints"]},
                "T_world_palm": {"position": [0.0, 0.0, 0.3], "orientation": [0.0, 0.0, 0.0, 1.0]},
                "tactile": {
                    "contact_threshold_mm": 2.0,
                    "near_mm": 0.0,
                    "far_mm": 20.0,
                    "sensors": sensors_info(spec["pads"], optical),
                    "pads": {p: list(PAD_SIZE) for p in spec["pads"]},
                    "points": dict(zip(spec["pads"], tactile["counts"])),
                },
            }
        )
        if tactile["images"]:
            info["tactile"]["optical"] = {p: optical_info(rng) for p in tactile["images"]}
        if tactile["forces"]:
            forces = {
                p: force_info(field, 2 if p in tactile["touching"] else 0)
                for p, field in tactile["forces"].items()
            }
            hand = np.sum([f["force_n"] for f in forces.values()], axis=0)
            touch_forces = {"forces": forces, "hand_force_n": [float(c) for c in hand]}
            assert tuple(touch_forces) == TOUCH_FORCE_KEYS
            info["tactile"].update(touch_forces)
    return SyntheticSample(
        split, index, rgb, depth, mask, K, camera_object, world_camera, world_object, info, tactile
    )


def _stamp(msg: Any, log_time: int) -> None:
    msg.timestamp.seconds = log_time // 1_000_000_000
    msg.timestamp.nanos = log_time % 1_000_000_000


def _raw_image(array: np.ndarray, encoding: str, log_time: int) -> RawImage:
    msg = RawImage(
        frame_id=FRAME_CAMERA,
        width=array.shape[1],
        height=array.shape[0],
        encoding=encoding,
        step=array.shape[1] * (array.shape[2] if array.ndim == 3 else 1) * array.dtype.itemsize,
        data=np.ascontiguousarray(array).astype(array.dtype.newbyteorder("<")).tobytes(),
    )
    _stamp(msg, log_time)
    return msg


def _set_pose(position: Any, orientation: Any, pose: Pose) -> None:
    (position.x, position.y, position.z) = pose[0]
    (orientation.x, orientation.y, orientation.z, orientation.w) = pose[1]


def _tactile_points(tac: Dict[str, Any]) -> bytes:
    """The ``/tactile/points`` data: one :data:`~vtdata.format.TACTILE_POINT_DTYPE` per point."""
    points = np.zeros(len(tac["pad"]), dtype=TACTILE_POINT_DTYPE)
    for axis, name in enumerate("xyz"):
        points[name] = tac["points"][:, axis]
    points["distance"], points[TACTILE_POINT_PAD_FIELD] = tac["distance"], tac["pad"]
    return points.tobytes()


def _force_cells(field: Dict[str, np.ndarray]) -> bytes:
    """A ``/tactile/<pad>/force`` cloud's data: one :data:`~vtdata.format.FORCE_CELL_DTYPE` per
    cell, row-major (whatever the arrays' shape: a test may write a grid that is not square)."""
    pressure = np.asarray(field["pressure"]).reshape(-1)
    cells = np.zeros(pressure.size, dtype=FORCE_CELL_DTYPE)
    position = np.asarray(field["position"]).reshape(-1, 2)
    shear = np.asarray(field["shear"]).reshape(-1, 2)
    cells["x"], cells["y"] = position[:, 0], position[:, 1]
    cells["pressure"] = pressure
    cells["shear_x"], cells["shear_y"] = shear[:, 0], shear[:, 1]
    cells["slip"] = np.asarray(field["slip"]).reshape(-1)
    return cells.tobytes()


def _marker_points(flow: Dict[str, np.ndarray]) -> bytes:
    """A ``/tactile/<pad>/markers`` cloud's data: one :data:`~vtdata.format.MARKER_POINT_DTYPE` per
    marker (``z`` = 0), in the flow's order."""
    position = np.asarray(flow["position"]).reshape(-1, 2)
    rest = np.asarray(flow["rest"]).reshape(-1, 2)
    markers = np.zeros(len(position), dtype=MARKER_POINT_DTYPE)
    markers["x"], markers["y"] = position[:, 0], position[:, 1]
    markers["rest_x"], markers["rest_y"] = rest[:, 0], rest[:, 1]
    return markers.tobytes()


def _tactile_messages(
    tac: Dict[str, Any],
    t: int,
    optical_encoding: str = TACTILE_IMAGE_ENCODING,
    references: bool = True,
) -> List[Tuple[str, bytes]]:
    cloud = PointCloud(
        frame_id=FRAME_CAMERA, point_stride=TACTILE_POINT_STRIDE, data=_tactile_points(tac)
    )
    _stamp(cloud, t)
    cloud.pose.orientation.w = 1.0
    for name, offset, kind in TACTILE_POINT_FIELDS:
        cloud.fields.add(name=name, offset=offset, type=PackedElementField.NumericType.Value(kind))
    out = [(TOPIC_TACTILE_POINTS, cloud.SerializeToString())]
    for pad, image in zip(tac["pads"], tac["depth"]):
        msg = _raw_image(image, TACTILE_DEPTH_ENCODING, t)
        msg.frame_id = f"{pad}_pad"
        out.append((tactile_depth_topic(pad), msg.SerializeToString()))
    # As the Rust writer: after the depth images, each optical pad's image, then its reference.
    for pad, image in tac["images"].items():
        for topic, array in [(tactile_image_topic(pad), image)] + (
            [(tactile_reference_topic(pad), tac["references"][pad])] if references else []
        ):
            msg = _raw_image(array, optical_encoding, t)
            msg.frame_id = f"{pad}_pad"
            out.append((topic, msg.SerializeToString()))
    # Then every pad's force field, in pad order, in the pad frame (identity pose).
    for pad, field in tac["forces"].items():
        forces = PointCloud(frame_id=f"{pad}_pad", point_stride=FORCE_CELL_STRIDE, data=_force_cells(field))
        _stamp(forces, t)
        forces.pose.orientation.w = 1.0
        for name, offset, kind in FORCE_CELL_FIELDS:
            forces.fields.add(name=name, offset=offset, type=PackedElementField.NumericType.Value(kind))
        out.append((tactile_force_topic(pad), forces.SerializeToString()))
    # Then each optical pad's marker flow, in pad order, in the pad frame.
    for pad, flow in tac.get("markers", {}).items():
        markers = PointCloud(frame_id=f"{pad}_pad", point_stride=MARKER_POINT_STRIDE, data=_marker_points(flow))
        _stamp(markers, t)
        markers.pose.orientation.w = 1.0
        for name, offset, kind in MARKER_POINT_FIELDS:
            markers.fields.add(name=name, offset=offset, type=PackedElementField.NumericType.Value(kind))
        out.append((tactile_markers_topic(pad), markers.SerializeToString()))
    return out


def sample_messages(
    s: SyntheticSample, optical_encoding: str = TACTILE_IMAGE_ENCODING, references: bool = True
) -> List[Tuple[str, bytes]]:
    """The (topic, payload) pairs of one sample, as FORMAT.md lists them.

    ``optical_encoding`` is the encoding the optical pads' images claim (to test error reporting);
    ``references=False`` leaves the optical reference images out (an episode's frames after 0).
    """
    t = s.log_time
    calibration = CameraCalibration(
        frame_id=FRAME_CAMERA,
        width=WIDTH,
        height=HEIGHT,
        distortion_model="plumb_bob",
        D=[0.0] * 5,
        K=s.K.reshape(-1).tolist(),
        R=np.eye(3).reshape(-1).tolist(),
        P=np.hstack([s.K, np.zeros((3, 1))]).reshape(-1).tolist(),
    )
    _stamp(calibration, t)
    pose = PoseInFrame(frame_id=FRAME_CAMERA)
    _stamp(pose, t)
    _set_pose(pose.pose.position, pose.pose.orientation, s.camera_object)
    tf = FrameTransforms()
    for child, value in ((FRAME_CAMERA, s.world_camera), (FRAME_OBJECT, s.world_object)):
        transform = tf.transforms.add(parent_frame_id=FRAME_WORLD, child_frame_id=child)
        _stamp(transform, t)
        _set_pose(transform.translation, transform.rotation, value)
    images = [
        (topic, _raw_image(array, TOPIC_IMAGE_ENCODINGS[topic], t).SerializeToString())
        for topic, array in ((TOPIC_RGB, s.rgb), (TOPIC_DEPTH, s.depth), (TOPIC_MASK, s.mask))
    ]
    return images + [
        (TOPIC_CALIBRATION, calibration.SerializeToString()),
        (TOPIC_POSE, pose.SerializeToString()),
        (TOPIC_TF, tf.SerializeToString()),
        (TOPIC_INFO, json.dumps(s.info, separators=(",", ":")).encode("utf-8")),
    ] + (
        _tactile_messages(s.tactile, t, optical_encoding, references)
        if s.tactile is not None
        else []
    )


_PROTOBUF_TOPICS = {
    TOPIC_RGB: RawImage,
    TOPIC_DEPTH: RawImage,
    TOPIC_MASK: RawImage,
    TOPIC_CALIBRATION: CameraCalibration,
    TOPIC_POSE: PoseInFrame,
    TOPIC_TF: FrameTransforms,
}


def _register_channels(
    writer: McapWriter, robot: Optional[Dict[str, Any]], episode: bool = False
) -> Dict[str, int]:
    """The channels of a shard, as the Rust writer adds them: the camera topics, ``/sample/info``,
    with a robot (``robot``: a sample's tactile dict) the points, one depth channel per pad in the
    pads' index order, then each optical pad's image and reference, then each pad's force field,
    then each optical pad's markers; in an episode ``/episode/state`` last. Topic -> channel id."""
    schema_ids: Dict[str, int] = {}
    channels: Dict[str, int] = {}

    def register(topic: str, spec: Tuple[str, ...], cls: Any = None) -> None:
        """A channel for `topic` with the format's schema name and message encoding (`spec`), its
        schema registered once: protobuf class `cls`'s, or a JSON schema."""
        name, encoding = spec[:2]
        if name not in schema_ids:
            if encoding == MESSAGE_ENCODING_PROTOBUF:
                assert cls.DESCRIPTOR.full_name == name, (topic, cls.DESCRIPTOR.full_name, name)
                kind, data = "protobuf", build_file_descriptor_set(cls).SerializeToString()
            else:
                kind, data = "jsonschema", json.dumps({"type": "object"}).encode("utf-8")
            schema_ids[name] = writer.register_schema(name=name, encoding=kind, data=data)
        channels[topic] = writer.register_channel(
            topic=topic, message_encoding=encoding, schema_id=schema_ids[name]
        )

    for topic, cls in _PROTOBUF_TOPICS.items():
        register(topic, TOPIC_SCHEMAS[topic], cls)
    register(TOPIC_INFO, TOPIC_SCHEMAS[TOPIC_INFO])
    if robot is not None:
        register(TOPIC_TACTILE_POINTS, TOPIC_SCHEMAS[TOPIC_TACTILE_POINTS], PointCloud)
        for p in robot["pads"]:
            register(tactile_depth_topic(p), PAD_TOPIC_SCHEMAS[TACTILE_DEPTH_SUFFIX], RawImage)
        for p in robot["images"]:
            register(tactile_image_topic(p), PAD_TOPIC_SCHEMAS[TACTILE_IMAGE_SUFFIX], RawImage)
            register(
                tactile_reference_topic(p), PAD_TOPIC_SCHEMAS[TACTILE_REFERENCE_SUFFIX], RawImage
            )
        for p in robot["forces"]:
            register(tactile_force_topic(p), PAD_TOPIC_SCHEMAS[TACTILE_FORCE_SUFFIX], PointCloud)
        for p in robot.get("markers", {}):
            register(tactile_markers_topic(p), PAD_TOPIC_SCHEMAS[TACTILE_MARKERS_SUFFIX], PointCloud)
    if episode:
        register(STATE_TOPIC, TOPIC_SCHEMAS[STATE_TOPIC])
    return channels


def write_shard(
    path: Path,
    split: str,
    shard_index: int,
    samples: Sequence[SyntheticSample],
    omit: Optional[Tuple[int, str]] = None,
    reverse_messages: bool = False,
    optical_encoding: str = TACTILE_IMAGE_ENCODING,
    repeat: Optional[Tuple[int, str]] = None,
) -> None:
    """Write one shard: zstd, one chunk per sample, the ``vtgen.shard`` metadata record.

    ``omit=(index, topic)`` leaves that message out, ``repeat=(index, topic)`` writes it twice (to
    test error reporting). With a robot the
    tactile channels are added as the Rust writer adds them: the points, then one depth channel per
    pad in the pads' index order, then for each optical pad (in that order) its image and its
    reference channel, then each pad's force channel, then each optical pad's markers channel.
    ``reverse_messages`` writes each sample's messages in reverse order (the reader must not depend
    on the order of messages in a chunk).
    ``optical_encoding`` is the encoding the optical images are written with (``rgb8``; another to
    test error reporting).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        writer = McapWriter(f, chunk_size=1 << 40, compression=CompressionType.ZSTD)
        writer.start(profile="", library=GENERATOR)
        robot = next((s.tactile for s in samples if s.tactile is not None), None)
        channels = _register_channels(writer, robot)
        for s in samples:
            messages = sample_messages(s, optical_encoding)
            if reverse_messages:
                messages.reverse()
            for topic, payload in messages:
                if omit == (s.index, topic):
                    continue
                for _ in range(2 if repeat == (s.index, topic) else 1):
                    writer.add_message(
                        channel_id=channels[topic],
                        log_time=s.log_time,
                        publish_time=s.log_time,
                        data=payload,
                    )
            writer.flush()  # close the chunk: exactly one chunk per sample
        writer.add_metadata(
            SHARD_METADATA,
            _shard_metadata(split, shard_index, samples[0].index if samples else 0, len(samples)),
        )
        writer.finish()


def _shard_metadata(
    split: str, shard_index: int, first_sample: int, sample_count: int, **optional: str
) -> Dict[str, str]:
    """A shard's ``vtgen.shard`` metadata record: the keys every shard has, in the format's
    order, then ``optional`` (keys only some shards have, e.g. ``episode``)."""
    record = {
        "format_version": str(FORMAT_VERSION),
        "generator": GENERATOR,
        "seed": "7",
        "config_sha256": CONFIG_SHA256,
        "split": split,
        "shard_index": str(shard_index),
        "first_sample": str(first_sample),
        "sample_count": str(sample_count),
    }
    assert tuple(record) == SHARD_METADATA_KEYS, (tuple(record), SHARD_METADATA_KEYS)
    assert set(optional) <= set(SHARD_METADATA_OPTIONAL_KEYS), optional
    return {**record, **optional}


def cube_mesh() -> Dict[str, np.ndarray]:
    """A 10 cm cube centred on the origin: 24 vertices (4 per face, face normals), 12 triangles."""
    vertices: List[Tuple[float, float, float]] = []
    normals: List[Tuple[float, float, float]] = []
    faces: List[Tuple[int, int, int]] = []
    h = 0.05
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = [0.0, 0.0, 0.0]
            n[axis] = sign
            u, v = [(axis + 1) % 3, (axis + 2) % 3]
            base = len(vertices)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis], p[u], p[v] = sign * h, a * h, b * h
                vertices.append((p[0], p[1], p[2]))
                normals.append((n[0], n[1], n[2]))
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return {
        "vertices": np.array(vertices, dtype=np.float32),
        "normals": np.array(normals, dtype=np.float32),
        "faces": np.array(faces, dtype=np.int32),
    }


def write_ply(path: Path, vertices: np.ndarray, normals: np.ndarray, faces: np.ndarray) -> None:
    """Write a mesh exactly as FORMAT.md describes it (binary little-endian PLY)."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment vtgen test mesh\n"
        f"element vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = bytearray()
    for p, n in zip(vertices, normals):
        body += struct.pack("<6f", *p, *n)
    for f in faces:
        body += struct.pack("<B3i", 3, *f)
    path.write_bytes(header.encode("ascii") + bytes(body))


def _write_manifest_and_models(
    root: Path, splits: Dict[str, Any], seed: int, robot: Optional[str]
) -> None:
    manifest = {
        "format": MANIFEST_FORMAT,
        "format_version": FORMAT_VERSION,
        "generator": GENERATOR,
        "seed": seed,
        "config_sha256": CONFIG_SHA256,
        "complete": True,
        "splits": splits,
    }
    (root / MANIFEST_FILE).write_text(json.dumps(manifest, indent=2))
    (root / "config.json").write_text(json.dumps({"robot": {"model": robot}} if robot else {}))
    models = root / MODELS_DIR
    models.mkdir(exist_ok=True)
    mesh = cube_mesh()
    write_ply(models / f"{OBJECT_ID}.ply", mesh["vertices"], mesh["normals"], mesh["faces"])
    (root / MODELS_INFO_FILE).write_text(
        json.dumps(
            {
                "objects": [
                    {
                        "id": OBJECT_ID,
                        "object_index": 0,
                        "mask_id": MASK_TARGET_OBJECT,
                        "symmetry": "discrete",
                        "mass": 0.1,
                        "extents": [0.1, 0.1, 0.1],
                        "diameter": float(np.sqrt(3) * 0.1),
                        "source": "procedural",
                        "file": f"{OBJECT_ID}.ply",
                    }
                ]
            }
        )
    )


def _shard_entry(root: Path, rel: str, shard_index: int, first: int, count: int) -> Dict[str, Any]:
    data = (root / rel).read_bytes()
    return {
        "file": rel,
        "shard_index": shard_index,
        "first_sample": first,
        "samples": count,
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
    }


def write_dataset(
    root: Path,
    counts: Dict[str, int],
    samples_per_shard: int,
    seed: int = 0,
    omit: Optional[Tuple[str, int, str]] = None,
    robot: Optional[str] = None,
    reverse_messages: bool = False,
    optical: Sequence[str] = (),
    optical_encoding: str = TACTILE_IMAGE_ENCODING,
    force_resolution: Optional[int] = None,
    marker_count: Optional[MarkerCount] = None,
) -> Dict[str, List[SyntheticSample]]:
    """Write a complete dataset (manifest, models, shards) and return its samples per split.

    ``omit=(split, index, topic)`` leaves one message out. ``robot`` (a key of :data:`ROBOTS`)
    adds the robot's ``/sample/info`` keys and tactile topics to every sample. ``optical`` names
    pads of the robot with an optical sensor: their ``/tactile/<pad>/image`` and ``reference``
    images (:data:`OPTICAL_SIZE`, written with ``optical_encoding``) and ``tactile.optical`` info.
    ``force_resolution`` gives every pad a force field of that many cells a side
    (``/tactile/<pad>/force``) and the info its ``tactile.forces`` and ``hand_force_n``;
    ``marker_count`` (with ``force_resolution``) gives each optical pad that many markers (an int,
    or ``{pad: count}``) on ``/tactile/<pad>/markers``.
    """
    if optical and robot is None:
        raise ValueError("optical pads need a robot")
    if force_resolution is not None and robot is None:
        raise ValueError("force fields need a robot")
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    samples = {
        split: [make_sample(split, i, rng, robot, optical, force_resolution, marker_count) for i in range(n)]
        for split, n in counts.items()
    }
    splits: Dict[str, Any] = {}
    for split, items in samples.items():
        shards = []
        for shard_index, first in enumerate(range(0, len(items), samples_per_shard)):
            chunk = items[first : first + samples_per_shard]
            rel = shard_file(split, shard_index)
            shard_omit = None
            if omit is not None and omit[0] == split:
                shard_omit = (omit[1], omit[2])
            write_shard(
                root / rel, split, shard_index, chunk, omit=shard_omit,
                reverse_messages=reverse_messages, optical_encoding=optical_encoding,
            )
            shards.append(_shard_entry(root, rel, shard_index, first, len(chunk)))
        splits[split] = {
            "samples": len(items),
            "samples_per_shard": samples_per_shard,
            "shards": shards,
        }
    _write_manifest_and_models(root, splits, seed, robot)
    return samples


# --- episodes (FORMAT.md, "Episodes") ------------------------------------------------------------


@dataclass
class SyntheticEpisode:
    """One episode as written: its frames (``SyntheticSample`` with ``time_ns``), every state
    record and every touch reading ``(time_ns, value)`` in time order (a frame's own reading is its
    sample's ``tactile``, the same dict), the frame times and the ``vtgen.shard`` episode record."""

    split: str
    shard_index: int
    first_sample: int
    frames: List[SyntheticSample]
    states: List[Tuple[int, Dict[str, Any]]]
    touches: List[Tuple[int, Dict[str, Any]]]
    record: Dict[str, Any]
    #: The optical pads' reference images (written once, with frame 0).
    references: Dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def times(self) -> List[int]:
        return [f.log_time for f in self.frames]


def _pose_json(pose: Pose) -> Dict[str, List[float]]:
    return {"position": list(pose[0]), "orientation": list(pose[1])}


def make_episode(
    split: str,
    shard_index: int,
    frames: int,
    rng: np.random.Generator,
    *,
    robot: str = "ur5e_allegro",
    optical: Sequence[str] = (),
    force_resolution: Optional[int] = None,
    marker_count: Optional[MarkerCount] = None,
    camera_period: int = 4,
    tactile_period: int = 2,
    state_period: int = 1,
    timestep_ns: int = 4_166_700,
    tail_steps: int = 0,
) -> SyntheticEpisode:
    """An episode of ``frames`` camera frames, one every ``camera_period`` steps of
    ``timestep_ns``; touch every ``tactile_period`` steps and states every ``state_period`` steps
    from step 0 to the episode's end, ``tail_steps`` after the last frame. FORMAT.md wants the
    periods to divide the camera's; others test the readers' alignment rule."""
    spec = ROBOTS[robot]
    first = shard_index * frames
    steps = (frames - 1) * camera_period + tail_steps
    samples: List[SyntheticSample] = []
    for k in range(frames):
        sample = make_sample(split, first + k, rng, robot, optical, force_resolution, marker_count)
        sample.time_ns = k * camera_period * timestep_ns
        sample.info.update(
            {
                "trajectory": shard_index,
                "instance": k,
                "randomized": True,
                "episode": {
                    "frame": k,
                    "time_s": sample.time_ns / 1e9,
                    "arm_move": (2 * k) // frames,
                },
            }
        )
        assert tuple(sample.info["episode"]) == EPISODE_FRAME_KEYS
        samples.append(sample)
    references = dict(samples[0].tactile["references"]) if samples[0].tactile else {}
    for sample in samples[1:]:  # every image of the episode has frame 0's reference
        if sample.tactile is not None:
            sample.tactile["references"] = references
    states: List[Tuple[int, Dict[str, Any]]] = []
    touches: List[Tuple[int, Dict[str, Any]]] = []
    for step in range(steps + 1):
        t = step * timestep_ns
        frame = samples[step // camera_period] if step % camera_period == 0 else None
        if step % state_period == 0:
            if frame is not None:  # the state of a frame's instant is the frame's
                info = frame.info
                record = {
                    "time_s": t / 1e9,
                    "joint_positions": dict(info["joint_positions"]),
                    "T_world_object": _pose_json(frame.world_object),
                    "T_camera_object": _pose_json(frame.camera_object),
                    "T_world_palm": info["T_world_palm"],
                    "phalanges_in_contact": list(info["phalanges_in_contact"]),
                }
            else:
                record = {
                    "time_s": t / 1e9,
                    "joint_positions": {j: float(rng.uniform(-1, 1)) for j in spec["joints"]},
                    "T_world_object": _pose_json(random_pose(rng)),
                    "T_camera_object": _pose_json(random_pose(rng)),
                    "T_world_palm": _pose_json(random_pose(rng)),
                    "phalanges_in_contact": list(spec["pads"][:2]),
                }
            twist = [0.0] * 6 if step == 0 else rng.uniform(-0.5, 0.5, size=6).tolist()
            record["linear_velocity"], record["angular_velocity"] = twist[:3], twist[3:]
            assert set(record) == set(STATE_RECORD_KEYS), set(record) ^ set(STATE_RECORD_KEYS)
            states.append((t, record))
        if frame is not None:
            touches.append((t, frame.tactile))
        elif step % tactile_period == 0:
            touches.append((t, make_tactile(spec["pads"], rng, optical, force_resolution, marker_count)))
    physics_hz = 1e9 / timestep_ns
    record = {
        "object_id": OBJECT_ID,
        "trajectory": shard_index,
        "frames": frames,
        "duration_s": steps * timestep_ns / 1e9,
        "physics_hz": physics_hz,
        "camera_hz": physics_hz / camera_period,
        "tactile_hz": physics_hz / tactile_period,
        "state_hz": physics_hz / state_period,
        "camera_period_steps": camera_period,
        "tactile_period_steps": tactile_period,
        "state_period_steps": state_period,
    }
    assert tuple(record) == EPISODE_RECORD_KEYS, (tuple(record), EPISODE_RECORD_KEYS)
    return SyntheticEpisode(split, shard_index, first, samples, states, touches, record, references)


def write_episode_shard(
    path: Path,
    episode: SyntheticEpisode,
    *,
    reverse_messages: bool = False,
    record: Optional[Dict[str, Any]] = None,
    omit: Optional[Tuple[int, str]] = None,
) -> None:
    """Write an episode shard as FORMAT.md's "Episodes" describes it: one zstd chunk per frame,
    the frame's messages at its instant (the optical references only in frame 0; its state last),
    then the later states and touch readings up to the next frame, in time order (a state before a
    touch reading of the same time). ``reverse_messages`` writes each chunk's messages in reverse
    order; ``record`` replaces the ``episode`` metadata record; ``omit=(frame, topic)`` leaves that
    message of the frame's instant out."""
    path.parent.mkdir(parents=True, exist_ok=True)
    times = episode.times
    with open(path, "wb") as f:
        writer = McapWriter(f, chunk_size=1 << 40, compression=CompressionType.ZSTD)
        writer.start(profile="", library=GENERATOR)
        channels = _register_channels(writer, episode.frames[0].tactile, episode=True)
        states = dict(episode.states)
        touches = dict(episode.touches)
        later_times = sorted(set(states) | set(touches))
        for k, frame in enumerate(episode.frames):
            t0 = times[k]
            end = times[k + 1] if k + 1 < len(times) else None
            messages: List[Tuple[int, str, bytes]] = [
                (t0, topic, payload)
                for topic, payload in sample_messages(frame, references=(k == 0))
                if omit != (k, topic)
            ]
            if t0 in states and omit != (k, STATE_TOPIC):
                messages.append((t0, STATE_TOPIC, json.dumps(states[t0]).encode("utf-8")))
            for t in later_times:
                if t <= t0 or (end is not None and t >= end):
                    continue
                if t in states:
                    messages.append((t, STATE_TOPIC, json.dumps(states[t]).encode("utf-8")))
                if t in touches:
                    messages += [
                        (t, topic, payload)
                        for topic, payload in _tactile_messages(touches[t], t, references=False)
                    ]
            if reverse_messages:
                messages.reverse()
            for t, topic, payload in messages:
                writer.add_message(channel_id=channels[topic], log_time=t, publish_time=t, data=payload)
            writer.flush()  # one chunk per frame
        episode_record = json.dumps(episode.record if record is None else record)
        writer.add_metadata(
            SHARD_METADATA,
            _shard_metadata(
                episode.split,
                episode.shard_index,
                episode.first_sample,
                len(episode.frames),
                **{EPISODE_METADATA_KEY: episode_record},
            ),
        )
        writer.finish()


def write_episode_dataset(
    root: Path,
    episodes: Dict[str, int],
    frames: int,
    seed: int = 0,
    *,
    robot: str = "ur5e_allegro",
    optical: Sequence[str] = (),
    force_resolution: Optional[int] = None,
    marker_count: Optional[MarkerCount] = None,
    reverse_messages: bool = False,
    **timing: int,
) -> Dict[str, List[SyntheticEpisode]]:
    """Write a complete episode dataset: ``episodes[split]`` episodes of ``frames`` frames each,
    one shard per episode (``samples_per_shard`` = ``frames``); ``force_resolution`` gives every
    touch reading force fields and ``marker_count`` the optical pads' markers
    (:func:`write_dataset`). ``timing``: :func:`make_episode`'s ``camera_period``,
    ``tactile_period``, ``state_period``, ``timestep_ns``, ``tail_steps``."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    out: Dict[str, List[SyntheticEpisode]] = {}
    splits: Dict[str, Any] = {}
    for split, n in episodes.items():
        out[split] = []
        shards = []
        for j in range(n):
            episode = make_episode(
                split,
                j,
                frames,
                rng,
                robot=robot,
                optical=optical,
                force_resolution=force_resolution,
                marker_count=marker_count,
                **timing,
            )
            rel = shard_file(split, j)
            write_episode_shard(root / rel, episode, reverse_messages=reverse_messages)
            shards.append(_shard_entry(root, rel, j, episode.first_sample, frames))
            out[split].append(episode)
        splits[split] = {"samples": n * frames, "samples_per_shard": frames, "shards": shards}
    _write_manifest_and_models(root, splits, seed, robot)
    return out
