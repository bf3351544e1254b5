"""Decoding a sample's messages into numpy arrays (FORMAT.md, "MCAP shard").

The decoders take the messages the MCAP readers decoded (Foxglove protobuf objects and JSON
values, keyed by topic) and return arrays: images, the tactile point cloud, the pads' images,
force fields and marker flow, transforms and an episode frame's faster streams. Each checks what
it reads and raises :class:`~vtdata.errors.DatasetError` naming ``where`` (the shard and sample)
when the data does not follow the format.
"""

from __future__ import annotations

import json
from typing import Any, Callable, Dict, List, Mapping, NamedTuple, Optional, Sequence, Tuple

import numpy as np
from mcap.decoder import DecoderFactory as _McapDecoderFactory
from mcap.records import Schema

from .errors import DatasetError
from .format import (
    FORCE_CELL_DTYPE,
    FRAME_CAMERA,
    FRAME_OBJECT,
    FRAME_WORLD,
    IMAGE_ENCODINGS,
    MARKER_POINT_DTYPE,
    MESSAGE_ENCODING_JSON,
    PAD_TOPIC_SCHEMAS,
    TACTILE_DEPTH_ENCODING,
    TACTILE_DEPTH_PREFIX,
    TACTILE_DEPTH_SUFFIX,
    TACTILE_FORCE_SUFFIX,
    TACTILE_IMAGE_ENCODING,
    TACTILE_IMAGE_SUFFIX,
    TACTILE_MARKERS_SUFFIX,
    TACTILE_POINT_DTYPE,
    TACTILE_POINT_PAD_FIELD,
    TACTILE_REFERENCE_SUFFIX,
    TOPIC_CALIBRATION,
    TOPIC_DEPTH,
    TOPIC_EPISODE_STATE,
    TOPIC_IMAGE_ENCODINGS,
    TOPIC_INFO,
    TOPIC_MASK,
    TOPIC_POSE,
    TOPIC_RGB,
    TOPIC_SCENE_MODELS,
    TOPIC_SCHEMAS,
    TOPIC_TACTILE_POINTS,
    TOPIC_TF,
    pad_of,
    tactile_image_topic,
    tactile_reference_topic,
    tactile_topic,
)

# --- JSON messages ----------------------------------------------------------------------------


class _JsonDecoderFactory(_McapDecoderFactory):
    """Decodes channels with message encoding ``json`` (``/sample/info``, ``/episode/state``)."""

    def decoder_for(
        self, message_encoding: str, schema: Optional[Schema]
    ) -> Optional[Callable[[bytes], Any]]:
        if message_encoding == MESSAGE_ENCODING_JSON:
            return _decode_json
        return None


def _decode_json(data: bytes) -> Any:
    return json.loads(data.decode("utf-8"))


# --- images and transforms --------------------------------------------------------------------


def decode_raw_image(image: Any, expect: Optional[str] = None, where: str = "image") -> np.ndarray:
    """Convert a ``foxglove.RawImage`` message into a C-contiguous numpy array.

    Supports ``rgb8`` (``(H, W, 3)`` uint8), ``mono8`` (``(H, W)`` uint8), ``mono16`` (``(H, W)``
    uint16, little-endian) and ``32FC1`` (``(H, W)`` float32, little-endian). Rows are read
    ``step`` bytes apart, so padded rows are handled. ``expect`` checks the encoding.
    """
    encoding = image.encoding
    if expect is not None and encoding != expect:
        raise DatasetError(f"{where}: expected encoding {expect!r}, found {encoding!r}")
    if encoding not in IMAGE_ENCODINGS:
        raise DatasetError(
            f"{where}: unsupported image encoding {encoding!r} "
            f"(supported: {', '.join(IMAGE_ENCODINGS)})"
        )
    stored, channels, out_dtype = IMAGE_ENCODINGS[encoding]
    height, width, step = int(image.height), int(image.width), int(image.step)
    row_bytes = width * channels * np.dtype(stored).itemsize
    if step < row_bytes:
        raise DatasetError(
            f"{where}: step {step} is smaller than a {width}-pixel {encoding} row "
            f"({row_bytes} bytes)"
        )
    data = np.frombuffer(image.data, dtype=np.uint8)
    needed = (height - 1) * step + row_bytes if height > 0 else 0
    if data.size < needed:
        raise DatasetError(
            f"{where}: {height}x{width} {encoding} image with step {step} needs {needed} bytes, "
            f"data has {data.size}"
        )
    rows = np.lib.stride_tricks.as_strided(data, shape=(height, row_bytes), strides=(step, 1))
    # Copy the rows into a new contiguous (writable) buffer, then reinterpret the bytes as pixels.
    pixels = rows.copy(order="C").view(stored)
    shape: Tuple[int, ...] = (height, width, channels) if channels > 1 else (height, width)
    return np.ascontiguousarray(pixels.reshape(shape), dtype=out_dtype)


def quaternion_matrix(q: Sequence[float]) -> np.ndarray:
    """The 3x3 float64 rotation matrix of the unit quaternion ``q = (x, y, z, w)``.

    Uses exactly the arithmetic of glam's ``DMat3::from_quat`` and
    ``DMat4::from_rotation_translation`` (same operations in the same order, IEEE double), so
    matrices built here and by the Rust tools from the same stored quaternion are bit-identical.
    The quaternion is not renormalised.
    """
    x, y, z, w = (float(c) for c in q)
    x2, y2, z2 = x + x, y + y, z + z
    xx, xy, xz = x * x2, x * y2, x * z2
    yy, yz, zz = y * y2, y * z2, z * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    return np.array(
        [
            [1.0 - (yy + zz), xy - wz, xz + wy],
            [xy + wz, 1.0 - (xx + zz), yz - wx],
            [xz - wy, yz + wx, 1.0 - (xx + yy)],
        ],
        dtype=np.float64,
    )


def pose_matrix(position: Sequence[float], orientation: Sequence[float]) -> np.ndarray:
    """The 4x4 float64 homogeneous transform of a translation and an ``(x, y, z, w)`` quaternion."""
    T = np.eye(4, dtype=np.float64)
    T[:3, :3] = quaternion_matrix(orientation)
    T[:3, 3] = [float(c) for c in position]
    return T


def _intrinsics(calibration: Any, where: str) -> np.ndarray:
    K = np.array(list(calibration.K), dtype=np.float64)
    if K.size != 9:
        raise DatasetError(f"{where} {TOPIC_CALIBRATION}: K has {K.size} values, expected 9")
    return K.reshape(3, 3)


def _frame_transforms(message: Any, where: str) -> Dict[Tuple[str, str], np.ndarray]:
    out: Dict[Tuple[str, str], np.ndarray] = {}
    for tf in message.transforms:
        t, r = tf.translation, tf.rotation
        out[(tf.parent_frame_id, tf.child_frame_id)] = pose_matrix(
            (t.x, t.y, t.z), (r.x, r.y, r.z, r.w)
        )
    for key in ((FRAME_WORLD, FRAME_CAMERA), (FRAME_WORLD, FRAME_OBJECT)):
        if key not in out:
            raise DatasetError(
                f"{where} {TOPIC_TF}: no {key[0]} -> {key[1]} transform "
                f"(found {sorted(out) or 'none'})"
            )
    return out


def _camera_fields(decoded: Mapping[str, Any], where: str) -> Dict[str, Any]:
    """A sample's camera images, intrinsics and ground-truth transforms (its first keys)."""
    transforms = _frame_transforms(decoded[TOPIC_TF], where)
    pose = decoded[TOPIC_POSE].pose
    images = {
        key: decode_raw_image(
            decoded[topic], expect=TOPIC_IMAGE_ENCODINGS[topic], where=where + f" {topic}"
        )
        for key, topic in (("rgb", TOPIC_RGB), ("depth", TOPIC_DEPTH), ("mask", TOPIC_MASK))
    }
    return {
        **images,
        "K": _intrinsics(decoded[TOPIC_CALIBRATION], where),
        "T_camera_object": pose_matrix(
            (pose.position.x, pose.position.y, pose.position.z),
            (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w),
        ),
        "T_world_camera": transforms[(FRAME_WORLD, FRAME_CAMERA)],
        "T_world_object": transforms[(FRAME_WORLD, FRAME_OBJECT)],
    }


# --- pads: one reader for every /tactile/<pad>/... stream -------------------------------------


class _PadStream(NamedTuple):
    """One kind of per-pad stream, ``/tactile/<pad><suffix>``: what :func:`_pad_stream` needs to
    read it. Everything else (the pads in channel order, the ``/sample/info`` list, the pads being
    the sample's, decoding with errors that name the topic, one size for all) is the same for every
    kind and done there once."""

    #: The topic's end (``/depth``, ``/image``, ``/reference``, ``/force``, ``/markers``).
    suffix: str
    #: What the messages are, in errors ("force fields of a, b ...").
    what: str
    #: One pad's message -> its value; ``where`` names the shard, the sample and the topic.
    decode: Callable[[Any, str], Any]
    #: The ``/sample/info`` ``tactile`` key that lists exactly the pads with this stream (``{pad:
    #: ...}``, checked when the info has it) and what those pads are called in errors; ``None``.
    listed: Optional[Tuple[str, str]] = None
    #: Another stream every pad of this one must have (markers and references: the pad's optical
    #: image) and what such pads are called in errors; ``None`` for none besides the depth image.
    needs: Optional[Tuple[str, str]] = None
    #: What must be the same for every pad's value ("size", "resolution") and how a value's is
    #: written ("4x4"); ``None`` when each pad may have its own.
    same: Optional[Tuple[str, Callable[[Any], str]]] = None


def _pads_in_channel_order(
    decoded: Mapping[str, Any], channel_ids: Mapping[str, int], suffix: str
) -> List[str]:
    """The pads of the ``/tactile/<pad><suffix>`` topics in ``decoded``, in the order of their
    channels: the writer adds a robot's pad channels in its pads' order, the order of the points'
    pad index (names would sort otherwise, e.g. ``right`` before ``left``)."""
    return [
        name
        for _, name in sorted(
            (channel_ids.get(t, 0), name) for t in decoded for name in [pad_of(t, suffix)] if name
        )
    ]


def _listed_pads(
    decoded: Mapping[str, Any], pads: Sequence[str], stream: _PadStream, where: str
) -> Optional[Dict[str, Any]]:
    """The ``/sample/info`` list of the pads with ``stream`` (``tactile.pads`` for the depth
    images, ``tactile.optical`` for the optical images, ``tactile.forces`` for the force fields),
    checked against ``pads``, the sample's; ``None`` when the info has no such list."""
    if stream.listed is None:
        return None
    key, pads_are = stream.listed
    info = decoded.get(TOPIC_INFO)
    touch = info.get("tactile") if isinstance(info, dict) else None
    listed = touch.get(key) if isinstance(touch, dict) else None
    if not isinstance(listed, dict):
        return None
    if set(listed) != set(pads):
        raise DatasetError(
            f"{where}: /sample/info tactile.{key} lists the {pads_are} {sorted(listed)}, the "
            f"sample has {stream.what} of {sorted(pads)} ({TACTILE_DEPTH_PREFIX}<pad>{stream.suffix})"
        )
    return listed


def _pad_stream(
    decoded: Mapping[str, Any],
    channel_ids: Mapping[str, int],
    where: str,
    stream: _PadStream,
    pads: Optional[Sequence[str]],
) -> Tuple[Dict[str, Any], Optional[Dict[str, Any]]]:
    """Read one kind of per-pad stream of a sample (or of an episode's touch reading): ``({pad:
    value}, listed)`` with the pads in the order of their channels (the writer adds them in the
    robot's pad order), empty without such topics, and the ``/sample/info`` list of those pads
    (``None`` without one).

    Checked, with a :class:`DatasetError` naming ``where`` (the shard and sample) and the topic:
    the pads are the ones ``/sample/info`` lists for the stream (when it lists them); they are
    pads of the sample (``pads``: its ``/tactile/<pad>/depth`` pads; ``None`` when it has no
    tactile data, which no per-pad stream may come without); each has the stream ``needs``; each
    message decodes; the values agree in ``same``. A topic with more than one message at one
    instant never gets here: :func:`_add_message` refuses it.
    """
    names = _pads_in_channel_order(decoded, channel_ids, stream.suffix)
    listed = _listed_pads(decoded, names, stream, where)
    if not names:
        return {}, listed
    if pads is None:
        raise DatasetError(
            f"{where}: {stream.what} of {', '.join(names)} but no {TOPIC_TACTILE_POINTS} "
            f"(every {TACTILE_DEPTH_PREFIX}<pad>/... stream is of a pad of the robot's tactile data)"
        )
    unknown = [p for p in names if p not in pads]
    if unknown:
        raise DatasetError(
            f"{where}: {stream.what} of {', '.join(unknown)}, which are not pads of the sample "
            f"(no {TACTILE_DEPTH_PREFIX}<pad>{TACTILE_DEPTH_SUFFIX}; pads: {', '.join(pads)})"
        )
    if stream.needs is not None:
        suffix, pads_are = stream.needs
        without = [p for p in names if tactile_topic(p, suffix) not in decoded]
        if without:
            raise DatasetError(
                f"{where}: {stream.what} of {', '.join(without)}, which are not {pads_are} of the "
                f"sample (no {TACTILE_DEPTH_PREFIX}<pad>{suffix})"
            )
    values: Dict[str, Any] = {}
    for pad in names:
        topic = tactile_topic(pad, stream.suffix)
        values[pad] = stream.decode(decoded[topic], f"{where} {topic}")
    if stream.same is not None:
        aspect, describe = stream.same
        if len({describe(v) for v in values.values()}) > 1:
            raise DatasetError(
                f"{where}: the pads' {stream.what} differ in {aspect}: "
                + ", ".join(f"{p} {describe(v)}" for p, v in values.items())
            )
    return values, listed


def _read_once(topic: str) -> bool:
    """Whether the reader decodes ``topic``, so that a sample (or a touch reading) must have at
    most one message on it: the fixed topics and every ``/tactile/<pad>/...`` stream it knows.
    Other topics (later format versions, ``/scene/models``) are not its business."""
    if topic in TOPIC_SCHEMAS:
        return topic != TOPIC_SCENE_MODELS
    return any(pad_of(topic, suffix) for suffix in PAD_TOPIC_SCHEMAS)


def _add_message(group: Dict[str, Any], topic: str, value: Any, where: str) -> None:
    """Put a message of one instant into ``group`` (topic -> message), refusing a second one on a
    topic the reader decodes (:func:`_read_once`); ``where`` names the shard, sample and instant."""
    if topic in group and _read_once(topic):
        raise DatasetError(f"{where}: more than one {topic} message")
    group[topic] = value


def _image_decoder(encoding: str) -> Callable[[Any, str], np.ndarray]:
    def decode(message: Any, where: str) -> np.ndarray:
        return decode_raw_image(message, expect=encoding, where=where)

    return decode


def _image_size(image: np.ndarray) -> str:
    return f"{image.shape[1]}x{image.shape[0]}"


# --- tactile points and the pads' depth images ------------------------------------------------

#: ``/tactile/<pad>/depth``: every pad has one, all the same size; ``/sample/info``
#: ``tactile.pads`` lists the pads. The sample's pads are the pads of these topics.
PAD_DEPTH = _PadStream(
    TACTILE_DEPTH_SUFFIX,
    "depth images",
    _image_decoder(TACTILE_DEPTH_ENCODING),
    listed=("pads", "pads"),
    same=("size", _image_size),
)


def _tactile_points(cloud: Any, where: str) -> np.ndarray:
    """The ``/tactile/points`` PointCloud's points (:data:`~vtdata.format.TACTILE_POINT_DTYPE`)."""
    if cloud.point_stride != TACTILE_POINT_DTYPE.itemsize:
        raise DatasetError(
            f"{where} {TOPIC_TACTILE_POINTS}: point stride {cloud.point_stride}, expected "
            f"{TACTILE_POINT_DTYPE.itemsize}"
        )
    return np.frombuffer(bytes(cloud.data), dtype=TACTILE_POINT_DTYPE)


def _tactile(decoded: Dict[str, Any], channel_ids: Mapping[str, int], where: str) -> Dict[str, Any]:
    """The tactile point cloud, the pad depth images and (with force topics) the pads' force fields
    and the optical pads' marker flow of a sample.

    The pads are the sample's ``/tactile/<pad>/depth`` topics, whatever the robot: in the order of
    their channels (:func:`_pads_in_channel_order`), checked against ``/sample/info``
    ``tactile.pads`` when the info has it. ``forces`` is there only when the sample has
    ``/tactile/<pad>/force`` topics (:func:`_forces`), ``markers`` only when it has
    ``/tactile/<pad>/markers`` topics (:func:`_markers`).
    """
    pts = _tactile_points(decoded[TOPIC_TACTILE_POINTS], where)
    pads = _pads_in_channel_order(decoded, channel_ids, TACTILE_DEPTH_SUFFIX)
    depth, _ = _pad_stream(decoded, channel_ids, where, PAD_DEPTH, pads)
    if not pads:
        raise DatasetError(
            f"{where}: {TOPIC_TACTILE_POINTS} but no /tactile/<pad>/depth message (no pad)"
        )
    index = pts[TACTILE_POINT_PAD_FIELD]
    if len(pts) and int(index.max()) >= len(pads):
        raise DatasetError(
            f"{where} {TOPIC_TACTILE_POINTS}: pad index {int(index.max())} but the "
            f"sample has {len(pads)} pads ({', '.join(pads)})"
        )
    out = {
        "points": np.ascontiguousarray(np.stack([pts["x"], pts["y"], pts["z"]], axis=1)),
        "distance": pts["distance"].copy(),
        "pad": index.copy(),
        "pads": pads,
        "depth": np.stack(list(depth.values())),
    }
    forces = _forces(decoded, channel_ids, where, pads)
    if forces is not None:
        out["forces"] = forces
    markers = _markers(decoded, channel_ids, where, pads)
    if markers is not None:
        out["markers"] = markers
    return out


# --- force fields (FORMAT.md, "Force fields") -------------------------------------------------

#: The last axis of :func:`force_array`: a cell's normal pressure, its shear traction along the
#: pad's x and y (Pa) and its slip flag (1.0 or 0.0).
FORCE_CHANNELS = ("pressure", "shear_x", "shear_y", "slip")


def _force_field(cloud: Any, where: str) -> Dict[str, np.ndarray]:
    """One pad's ``/tactile/<pad>/force`` PointCloud as ``R x R`` arrays (row ``v``, column ``u``:
    cell ``(u, v)`` is point ``v * R + u``, rows along the pad's y as its depth image's):
    ``position`` ``(R, R, 2)`` float32 (the cell's centre, pad frame, m), ``pressure`` ``(R, R)``
    float32 (Pa), ``shear`` ``(R, R, 2)`` float32 (Pa, along the pad's x and y), ``slip`` ``(R, R)``
    bool. The cloud must be a square grid of at least one cell of
    :data:`~vtdata.format.FORCE_CELL_DTYPE`."""
    stride = FORCE_CELL_DTYPE.itemsize
    data = bytes(cloud.data)
    n = len(data) // stride
    r = int(round(np.sqrt(n)))
    if cloud.point_stride != stride or len(data) % stride != 0:
        raise DatasetError(
            f"{where}: expected {stride}-byte force cells, got point stride {cloud.point_stride} "
            f"and {len(data)} bytes of data"
        )
    if n == 0 or r * r != n:
        raise DatasetError(f"{where}: {n} force cells, not a square R x R grid (R >= 1)")
    cells = np.frombuffer(data, dtype=FORCE_CELL_DTYPE).reshape(r, r)
    return {
        "position": np.ascontiguousarray(np.stack([cells["x"], cells["y"]], axis=-1)),
        "pressure": np.ascontiguousarray(cells["pressure"]),
        "shear": np.ascontiguousarray(np.stack([cells["shear_x"], cells["shear_y"]], axis=-1)),
        "slip": cells["slip"] != 0,
    }


#: ``/tactile/<pad>/force``: a square grid per pad, every pad's the same resolution;
#: ``/sample/info`` ``tactile.forces`` lists the pads.
PAD_FORCE = _PadStream(
    TACTILE_FORCE_SUFFIX,
    "force fields",
    _force_field,
    listed=("forces", "pads"),
    same=("resolution", lambda f: "{}x{}".format(*f["pressure"].shape)),
)


def _forces(
    decoded: Dict[str, Any],
    channel_ids: Mapping[str, int],
    where: str,
    pads: Optional[Sequence[str]],
) -> Optional[Dict[str, Dict[str, np.ndarray]]]:
    """The pads' force fields ``{pad: field}`` (:func:`_force_field`, read by :func:`_pad_stream`),
    ``None`` when the sample has no ``/tactile/<pad>/force`` topic. ``pads``: the sample's pads,
    ``None`` when it has no tactile data (then a force field is an error)."""
    fields, _ = _pad_stream(decoded, channel_ids, where, PAD_FORCE, pads)
    return fields or None


def force_array(forces: Mapping[str, Mapping[str, np.ndarray]]) -> np.ndarray:
    """The force fields of a touch reading (a sample's ``tactile["forces"]``) as one ``(P, R, R,
    4)`` float32 array: for each pad in the dict's (pad) order, per cell :data:`FORCE_CHANNELS`
    (pressure, shear_x, shear_y in Pa, slip as 1.0 or 0.0)."""
    return np.stack(
        [
            np.concatenate(
                [f["pressure"][..., None], f["shear"], f["slip"][..., None].astype(np.float32)],
                axis=-1,
            )
            for f in forces.values()
        ]
    ).astype(np.float32, copy=False)


# --- marker flow (FORMAT.md, ``/tactile/<pad>/markers``) ------------------------------------------

#: The last axis of :func:`marker_arrays`: where a marker is in the pad plane, then its rest
#: position (m, pad frame).
MARKER_CHANNELS = ("x", "y", "rest_x", "rest_y")


def _marker_flow(cloud: Any, where: str) -> Dict[str, np.ndarray]:
    """One optical pad's ``/tactile/<pad>/markers`` PointCloud, one row per printed marker in the
    rest grid's order (rows along the pad's y, each row along x): ``position`` ``(N, 2)`` float32
    (where the marker is, pad frame, m) and ``rest`` ``(N, 2)`` float32 (its rest position). The
    cloud must be packed :data:`~vtdata.format.MARKER_POINT_DTYPE` points; it may be empty (a sensor
    whose marker pitch leaves no dot inside its sensing area)."""
    stride = MARKER_POINT_DTYPE.itemsize
    data = bytes(cloud.data)
    if cloud.point_stride != stride or len(data) % stride != 0:
        raise DatasetError(
            f"{where}: expected {stride}-byte markers, got point stride {cloud.point_stride} "
            f"and {len(data)} bytes of data"
        )
    markers = np.frombuffer(data, dtype=MARKER_POINT_DTYPE)
    return {
        "position": np.ascontiguousarray(np.stack([markers["x"], markers["y"]], axis=-1)),
        "rest": np.ascontiguousarray(np.stack([markers["rest_x"], markers["rest_y"]], axis=-1)),
    }


#: ``/tactile/<pad>/markers``: only an optical pad has them (only an optical sensor prints
#: markers); the counts may differ from pad to pad (each pad's sensor has its own grid, and
#: ``randomization.tactile_sensors`` varies its pitch per sample and pad).
PAD_MARKERS = _PadStream(
    TACTILE_MARKERS_SUFFIX,
    "markers",
    _marker_flow,
    needs=(TACTILE_IMAGE_SUFFIX, "optical pads"),
)


def _markers(
    decoded: Dict[str, Any],
    channel_ids: Mapping[str, int],
    where: str,
    pads: Optional[Sequence[str]],
) -> Optional[Dict[str, Dict[str, np.ndarray]]]:
    """The optical pads' marker flow ``{pad: flow}`` (:func:`_marker_flow`, read by
    :func:`_pad_stream`), ``None`` when the sample has no ``/tactile/<pad>/markers`` topic.
    ``pads`` as for :func:`_forces`. Besides, a pad that ``/sample/info`` ``tactile.optical``
    lists with ``markers`` null has none."""
    flows, _ = _pad_stream(decoded, channel_ids, where, PAD_MARKERS, pads)
    info = decoded.get(TOPIC_INFO)
    touch = info.get("tactile") if isinstance(info, dict) else None
    optical = touch.get("optical") if isinstance(touch, dict) else None
    if isinstance(optical, dict):
        unprinted = [
            p for p in flows
            if isinstance(optical.get(p), dict) and "markers" in optical[p] and optical[p]["markers"] is None
        ]
        if unprinted:
            raise DatasetError(
                f"{where}: markers of {', '.join(unprinted)}, whose sensors have none "
                f"(/sample/info tactile.optical.<pad>.markers is null)"
            )
    return flows or None


def marker_arrays(markers: Mapping[str, Mapping[str, np.ndarray]]) -> Dict[str, np.ndarray]:
    """The marker flow of a touch reading (a sample's ``tactile["markers"]``) as one ``(N, 4)``
    float32 array per pad, in the dict's (pad) order: per marker :data:`MARKER_CHANNELS` (x, y,
    rest_x, rest_y; m). One array per pad, not one ``(P, N, 4)`` stack: each pad's sensor has its
    own marker grid, so the counts ``N`` may differ from pad to pad."""
    return {
        pad: np.concatenate([flow["position"], flow["rest"]], axis=-1).astype(np.float32, copy=False)
        for pad, flow in markers.items()
    }


# --- optical images (FORMAT.md, ``/tactile/<pad>/image`` and ``/tactile/<pad>/reference``) ----


def _optical_image(message: Any, where: str) -> np.ndarray:
    image = decode_raw_image(message, expect=TACTILE_IMAGE_ENCODING, where=where)
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise DatasetError(f"{where}: empty {_image_size(image)} image")
    return image


#: ``/tactile/<pad>/image``: an optical pad's RGB image (``rgb8``, not empty; each sensor its own
#: size); ``/sample/info`` ``tactile.optical`` lists the optical pads.
PAD_IMAGE = _PadStream(
    TACTILE_IMAGE_SUFFIX, "optical images", _optical_image, listed=("optical", "optical pads")
)
#: ``/tactile/<pad>/reference``: an optical pad's no-contact image, beside its image.
PAD_REFERENCE = _PadStream(
    TACTILE_REFERENCE_SUFFIX,
    "reference images",
    _optical_image,
    needs=(TACTILE_IMAGE_SUFFIX, "optical pads"),
)


def _optical(
    decoded: Dict[str, Any],
    channel_ids: Mapping[str, int],
    where: str,
    pads: Optional[Sequence[str]],
) -> Optional[Tuple[Dict[str, np.ndarray], Dict[str, np.ndarray]]]:
    """The optical pads' images and reference images (both read by :func:`_pad_stream`), ``None``
    when the sample has none. ``pads`` as for :func:`_forces`. Besides, each image needs its
    reference, of its size, and is the ``image_size`` ``/sample/info`` ``tactile.optical`` gives
    its sensor (when it gives one)."""
    images, listed = _pad_stream(decoded, channel_ids, where, PAD_IMAGE, pads)
    references, _ = _pad_stream(decoded, channel_ids, where, PAD_REFERENCE, pads)
    if not images:
        return None
    for pad, image in images.items():
        image_topic, reference_topic = tactile_image_topic(pad), tactile_reference_topic(pad)
        reference = references.get(pad)
        if reference is None:
            raise DatasetError(f"{where}: {image_topic} without its {reference_topic}")
        if reference.shape != image.shape:
            raise DatasetError(
                f"{where}: {reference_topic} is {_image_size(reference)}, its image {_image_size(image)}"
            )
        sensor = listed.get(pad) if listed is not None else None
        size = sensor.get("image_size") if isinstance(sensor, dict) else None
        if size is not None and size != [image.shape[1], image.shape[0]]:
            raise DatasetError(
                f"{where}: {image_topic} is {_image_size(image)}, but /sample/info "
                f"tactile.optical.{pad}.image_size is {size} ([width, height])"
            )
    # The references in the images' (pad) order.
    return images, {pad: references[pad] for pad in images}


# --- episodes ---------------------------------------------------------------------------------


def _touch_reading(
    group: Dict[str, Any], channel_ids: Mapping[str, int], where: str
) -> Dict[str, Any]:
    """One touch reading of an episode (its ``/tactile/*`` messages of one time) like a sample's
    ``tactile`` (with force fields, their ``forces`` and ``markers``), plus, with optical pads,
    ``images`` ``{pad: (H, W, 3) uint8}``."""
    if TOPIC_TACTILE_POINTS not in group:
        raise DatasetError(f"{where}: /tactile/<pad> messages without {TOPIC_TACTILE_POINTS}")
    reading = _tactile(group, channel_ids, where)
    images, _ = _pad_stream(group, channel_ids, where, PAD_IMAGE, reading["pads"])
    if images:
        reading["images"] = images
    return reading


def _episode_streams(
    frame: int,
    time_ns: int,
    decoded: Mapping[str, Any],
    later: Sequence[Tuple[int, str, int, Any]],
    channel_ids: Dict[str, int],
    where: str,
) -> Dict[str, Any]:
    """An episode frame's ``sample["episode"]``: the states from its instant on and the touch
    readings after its own, up to the next frame (the rest of its chunk), in time order."""
    states: List[Tuple[int, Any]] = []
    if TOPIC_EPISODE_STATE in decoded:
        states.append((time_ns, decoded[TOPIC_EPISODE_STATE]))
    touch: Dict[int, Dict[str, Any]] = {}
    for t, topic, channel_id, value in later:
        if topic == TOPIC_EPISODE_STATE:
            if any(s == t for s, _ in states):
                raise DatasetError(f"{where}: more than one {TOPIC_EPISODE_STATE} message at {t} ns")
            states.append((t, value))
        elif topic.startswith(TACTILE_DEPTH_PREFIX) and not topic.endswith(TACTILE_REFERENCE_SUFFIX):
            _add_message(touch.setdefault(t, {}), topic, value, f"{where} (touch at {t} ns)")
            channel_ids.setdefault(topic, channel_id)
    tactile = [
        (t, _touch_reading(touch[t], channel_ids, f"{where} (touch at {t} ns)"))
        for t in sorted(touch)
    ]
    states.sort(key=lambda item: item[0])
    return {"frame": frame, "time_ns": time_ns, "states": states, "tactile": tactile}
