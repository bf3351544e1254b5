"""Random-access reader for vtgen datasets (see ``datasets/FORMAT.md``).

A dataset is a folder with ``manifest.json``, ``models/`` and one folder of MCAP shards per split.
Every sample is one zstd chunk of one shard; all of its messages share ``log_time = index * 1e8``
ns. :class:`Dataset` builds its sample index from the chunk indexes in each shard's summary section
(no scan of the data), then reads a sample by decompressing only its chunk.

An **episode** shard (FORMAT.md, "Episodes": its ``vtgen.shard`` metadata has an ``episode`` key)
is one recorded trajectory: chunk ``k`` (by start time) is camera frame ``k``, the sample
``first_sample + k``. Its messages at the chunk's first log time are the frame's sample; the later
ones are the touch (``/tactile/*``) and state (``/episode/state``) streams up to the next frame.
"""

from __future__ import annotations

import collections
import hashlib
import inspect
import json
import os
import warnings
from pathlib import Path
from typing import (
    IO,
    Any,
    Callable,
    Dict,
    Iterator,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
)

import numpy as np
from mcap.decoder import DecoderFactory as _McapDecoderFactory
from mcap.reader import McapReader, make_reader
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory as _ProtobufDecoderFactory

from .ply import load_ply

PathLike = Union[str, "os.PathLike[str]"]

#: Nanoseconds between two consecutive samples on the dataset timeline (10 Hz).
SAMPLE_PERIOD_NS = 100_000_000
#: The ``format`` value of a vtgen ``manifest.json``.
MANIFEST_FORMAT = "vtgen-dataset"
#: The newest ``format_version`` this reader was written for.
FORMAT_VERSION = 1

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
#: The UR5e + Allegro's 12 pads in tactile index order (FORMAT.md): the names a dataset of that
#: robot holds. Other robots name their own pads (a parallel gripper: 2, e.g. ``left``,
#: ``right``), so the reader never assumes these: a sample's ``tactile["phalanges"]`` lists the
#: pads its shard has, in the order of the ``phalanx`` index.
ALLEGRO_PHALANGES = tuple(
    f"{f}_{p}" for f in ("ff", "mf", "rf", "th") for p in ("proximal", "medial", "distal")
)
#: Same as :data:`ALLEGRO_PHALANGES` (the name earlier versions used; not the pads of every robot).
PHALANGES = ALLEGRO_PHALANGES
#: ``/tactile/<pad>/depth``: the depth image of one pad; the pad's name is the middle part.
TACTILE_DEPTH_PREFIX, TACTILE_DEPTH_SUFFIX = "/tactile/", "/depth"
#: ``/tactile/<pad>/image``: the RGB image (``rgb8``) of a pad with an optical (GelSight/DIGIT-style)
#: sensor; only such pads have it.
TACTILE_IMAGE_SUFFIX = "/image"
#: ``/tactile/<pad>/reference``: that sensor's no-contact image without noise (``rgb8``, the size of
#: its image), written with every sample beside the image (in an episode: once, with its frame 0).
TACTILE_REFERENCE_SUFFIX = "/reference"
#: Episode shards: the state stream (JSON ``vtgen.StateRecord``) at the state rate.
TOPIC_EPISODE_STATE = "/episode/state"
#: The ``vtgen.shard`` metadata key whose presence makes a shard an episode (JSON value).
EPISODE_METADATA_KEY = "episode"
_TACTILE_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("distance", "<f4"), ("phalanx", "<u4")])
#: Topics every sample must have; other topics (later format versions) are ignored.
REQUIRED_TOPICS = (
    TOPIC_RGB,
    TOPIC_DEPTH,
    TOPIC_MASK,
    TOPIC_CALIBRATION,
    TOPIC_POSE,
    TOPIC_TF,
    TOPIC_INFO,
)

# RawImage encoding -> (numpy dtype of one channel as stored, channels, dtype returned).
_IMAGE_ENCODINGS: Dict[str, Tuple[str, int, Any]] = {
    "rgb8": ("u1", 3, np.uint8),
    "mono8": ("u1", 1, np.uint8),
    "mono16": ("<u2", 1, np.uint16),
    "32FC1": ("<f4", 1, np.float32),
}

# mcap >= 1.6 renamed the time bounds of iter_messages (start_time/end_time are deprecated there).
_HAS_NEW_TIME_BOUNDS = (
    "starting_at" in inspect.signature(McapReader.iter_decoded_messages).parameters
)


class DatasetError(RuntimeError):
    """A dataset does not follow the vtgen format (missing or inconsistent files or messages).

    The one exception type the reader raises for a damaged, incomplete or foreign dataset: a
    truncated shard, a damaged chunk, a shard from another dataset, a checksum that does not match
    the manifest. Its message names the file and, when reading a sample, the sample.
    """


class DatasetNotFoundError(DatasetError, FileNotFoundError):
    """A file the dataset needs is missing: the folder, ``manifest.json``, a shard or a model.

    Both a :class:`DatasetError` and a :class:`FileNotFoundError`.
    """


class Sample(Dict[str, Any]):
    """One dataset sample: a plain ``dict`` whose keys can also be read as attributes.

    Keys:

    - ``rgb``: ``(H, W, 3)`` uint8, sRGB colour.
    - ``depth``: ``(H, W)`` float32 z-depth in metres, ``0.0`` where no surface was hit.
    - ``depth_noisy`` (only when the config has a sensor noise model): ``(H, W)`` float32, the
      depth as a noisy RGB-D camera reads it (``0.0`` = no reading); ``depth`` stays exact.
    - ``mask``: ``(H, W)`` uint8 instance ids (0 background, 1 target object, see FORMAT.md).
    - ``K``: ``(3, 3)`` float64 camera intrinsics.
    - ``T_camera_object``, ``T_world_camera``, ``T_world_object``: ``(4, 4)`` float64 homogeneous
      transforms; ``T_A_B`` maps coordinates in frame B to frame A.
    - ``info``: the ``/sample/info`` JSON object.
    - ``index``: the sample's index in its split; ``split``: the split name.
    - ``tactile`` (only with a robot in the scene): a dict with ``points`` ``(N, 3)`` float32
      tactile points in the camera frame, ``distance`` ``(N,)`` float32 depth from the pad,
      ``phalanx`` ``(N,)`` uint32 pad index into ``phalanges``, ``phalanges`` (the robot's ``P``
      pad names in index order, read from the shard: the 12 ``ff_proximal`` … ``th_distal`` of
      the Allegro, 2 of a parallel gripper) and ``depth`` ``(P, R, R)`` float32 pad camera images
      (``inf`` = no surface), one per ``/tactile/<pad>/depth`` topic.
    - ``tactile_images`` and ``tactile_references`` (only when some pad has an optical
      GelSight/DIGIT-style sensor): ``{pad: (H, W, 3) uint8}`` in pad order, the sensor's RGB image
      (``/tactile/<pad>/image``, linear 8-bit levels) and its no-contact reference image without
      noise (``/tactile/<pad>/reference``, same size); the same pads in both, a subset of
      ``tactile["phalanges"]``. The sensor's parameters are ``info["tactile"]["optical"][pad]``.
      In an episode the references are written once, with frame 0; every frame gets them.
    - ``episode`` (only in an episode dataset, FORMAT.md "Episodes"): the frame's faster streams,
      ``{"frame": k, "time_ns": t, "states": [(t_ns, record), ...], "tactile": [(t_ns, touch),
      ...]}``: ``frame`` is the frame's index in its episode, ``time_ns`` its simulated time since
      the episode's start (its log time), ``states`` the ``/episode/state`` records (dicts) from
      the frame's instant (included) up to the next frame, ``tactile`` the touch readings *after*
      the frame's own (which is ``tactile``) up to the next frame, each a dict like ``tactile``
      plus, with optical pads, ``images`` ``{pad: (H, W, 3) uint8}``. Times ascend.
      ``info["episode"]`` has the frame's ``frame``, ``time_s`` and ``arm_move``.
    """

    __slots__ = ()

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


class _JsonDecoderFactory(_McapDecoderFactory):
    """Decodes channels with message encoding ``json`` (the ``/sample/info`` channel)."""

    def decoder_for(
        self, message_encoding: str, schema: Optional[Schema]
    ) -> Optional[Callable[[bytes], Any]]:
        if message_encoding == "json":
            return _decode_json
        return None


def _decode_json(data: bytes) -> Any:
    return json.loads(data.decode("utf-8"))


class _OpenShard:
    """An open shard file and the MCAP reader on it."""

    __slots__ = ("file", "reader")

    def __init__(self, path: str) -> None:
        self.file: IO[bytes] = open(path, "rb")
        try:
            # CRCs checked: a damaged chunk that still decompresses is caught by its checksum.
            self.reader: McapReader = make_reader(
                self.file,
                validate_crcs=True,
                decoder_factories=[_ProtobufDecoderFactory(), _JsonDecoderFactory()],
            )
        except Exception:
            self.file.close()
            raise

    def close(self) -> None:
        self.file.close()


class Dataset(Sequence[Sample]):
    """Random access to the samples of one split of a vtgen dataset.

    ``Dataset(root, split)`` reads ``manifest.json`` and the summary section of every shard of the
    split that the manifest lists as written (non-null ``sha256``); ``ds[i]`` then reads sample
    ``i`` from its chunk. Shard files are opened lazily and cached per process (at most
    ``max_open_files`` at a time); after a ``fork`` the child opens its own handles, and pickling a
    ``Dataset`` carries no file handles, so it is safe to use in ``DataLoader`` workers. A
    ``Dataset`` is not safe to share between threads of one process.

    In an episode dataset (FORMAT.md, "Episodes") a sample is a camera frame: ``ds[i]`` is the
    frame's sample plus its faster streams (``sample["episode"]``, see :class:`Sample`), and
    :attr:`episodes` lists the split's episodes (:class:`EpisodeDataset` windows them).
    """

    def __init__(
        self,
        root: PathLike,
        split: str = "train",
        *,
        max_open_files: int = 32,
        verify: bool = False,
    ) -> None:
        if max_open_files < 1:
            raise ValueError(f"max_open_files must be >= 1, got {max_open_files}")
        self.root = Path(root)
        self.split = split
        self.max_open_files = max_open_files
        self.manifest: Dict[str, Any] = _read_manifest(self.root)
        splits = self.manifest.get("splits")
        if not isinstance(splits, dict) or split not in splits:
            available = sorted(splits) if isinstance(splits, dict) else []
            raise KeyError(
                f"split {split!r} is not in {self.root / 'manifest.json'} (splits: {available})"
            )
        #: Paths of the split's shard files that the index was built from, in manifest order.
        self.shards: List[str] = []
        #: The split's episodes, in manifest (split) order; empty in a snapshot dataset. Each is the
        #: shard's ``vtgen.shard`` ``episode`` record (``object_id``, ``trajectory``, ``frames``,
        #: ``duration_s``, the rates and periods) plus ``shard`` (its path) and ``first_sample``
        #: (the split index of its frame 0); ``frames`` is its number of chunks (camera frames).
        self.episodes: List[Dict[str, Any]] = []
        # _samples[i] = (shard path, chunk message_start_time) of sample i; _ends[i] = the chunk's
        # message_end_time (an episode frame's chunk also holds its later streams).
        index = _build_index(self.root, split, splits[split], self.shards, self.manifest, self.episodes)
        self._samples: List[Tuple[str, int]] = [(shard, start) for shard, start, _ in index]
        self._ends: List[int] = [end for _, _, end in index]
        self._episode_of_shard: Dict[str, Dict[str, Any]] = {e["shard"]: e for e in self.episodes}
        self._episode_position: Dict[str, int] = {e["shard"]: k for k, e in enumerate(self.episodes)}
        # Episode shard -> its frame 0's /tactile/<pad>/reference messages (topic -> (channel id,
        # message)), read on first use: later frames share them.
        self._references: Dict[str, Dict[str, Tuple[int, Any]]] = {}
        self._models: Optional[Dict[str, Dict[str, Any]]] = None
        self._open: "collections.OrderedDict[str, _OpenShard]" = collections.OrderedDict()
        self._open_pid = os.getpid()
        if verify:
            self.verify_checksums()

    # --- sequence protocol -------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self._samples)

    def __getitem__(self, index: int) -> Sample:  # type: ignore[override]
        if isinstance(index, slice):
            raise TypeError("Dataset indices must be integers, not slices")
        index = _check_index(index, len(self._samples))
        shard, log_time = self._samples[index]
        return self._read_sample(shard, log_time, index)

    def __iter__(self) -> Iterator[Sample]:
        for i in range(len(self)):
            yield self[i]

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(root={str(self.root)!r}, split={self.split!r}, "
            f"samples={len(self)}, shards={len(self.shards)})"
        )

    # --- public helpers ----------------------------------------------------------------------

    def location(self, index: int) -> Tuple[str, int]:
        """The shard path and ``log_time`` (ns) of sample ``index`` (an episode frame: its time)."""
        return self._samples[_check_index(index, len(self._samples))]

    @property
    def is_episodic(self) -> bool:
        """Whether the split's shards are episodes (FORMAT.md, "Episodes")."""
        return bool(self.episodes)

    def episode_of(self, index: int) -> Optional[Tuple[int, int]]:
        """``(episode, frame)`` of sample ``index``: its episode's position in :attr:`episodes` and
        its frame in that episode; ``None`` for a snapshot sample."""
        i = _check_index(index, len(self._samples))
        episode = self._episode_of_shard.get(self._samples[i][0])
        if episode is None:
            return None
        return self._episode_position[episode["shard"]], i - episode["first_sample"]

    def models(self) -> Dict[str, Dict[str, Any]]:
        """The dataset's object models, keyed by object id.

        Each value is ``{"info": <models_info.json entry>, "vertices": (N, 3) float32,
        "normals": (N, 3) float32, "faces": (M, 3) int32}``, in the model frame, metres. Loaded on
        the first call and cached.
        """
        if self._models is None:
            self._models = load_models(self.root)
        return self._models

    def verify_checksums(self) -> None:
        """Recompute the SHA-256 of every shard of the split and compare it with the manifest.

        Raises :class:`DatasetError` naming the first shard whose checksum differs.
        """
        for entry in self.manifest["splits"][self.split].get("shards", []):
            expected = entry.get("sha256")
            if expected is None:
                continue
            path = self.root / entry["file"]
            if not path.is_file():
                raise DatasetNotFoundError(f"shard {path} is listed in the manifest but missing on disk")
            digest = hashlib.sha256()
            with open(path, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    digest.update(block)
            if digest.hexdigest() != expected:
                raise DatasetError(
                    f"{path}: SHA-256 {digest.hexdigest()} does not match the manifest ({expected})"
                )

    def close(self) -> None:
        """Close the shard files this process opened (they are reopened on the next access)."""
        if self._open_pid == os.getpid():
            for shard in self._open.values():
                shard.close()
        self._open.clear()
        self._open_pid = os.getpid()

    def __enter__(self) -> "Dataset":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        # Interpreter shutdown may already have torn down os/attributes: best effort only.
        try:
            self.close()
        except Exception:
            pass

    def __getstate__(self) -> Dict[str, Any]:
        state = self.__dict__.copy()
        state["_open"] = collections.OrderedDict()
        state["_open_pid"] = None
        state["_references"] = {}
        return state

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._open_pid = os.getpid()

    # --- reading -----------------------------------------------------------------------------

    def _reader(self, shard: str) -> McapReader:
        pid = os.getpid()
        if self._open_pid != pid:
            # Forked child: the inherited descriptors share their file offsets with the parent, so
            # never use them. Closing our copies does not affect the parent.
            for inherited in self._open.values():
                try:
                    inherited.close()
                except OSError:
                    pass
            self._open = collections.OrderedDict()
            self._open_pid = pid
        handle = self._open.get(shard)
        if handle is None:
            while len(self._open) >= self.max_open_files:
                self._open.popitem(last=False)[1].close()
            handle = _OpenShard(shard)
            self._open[shard] = handle
        else:
            self._open.move_to_end(shard)
        return handle.reader

    def _messages(
        self, shard: str, start: int, end: int, topics: Optional[List[str]] = None
    ) -> Iterator[Any]:
        """The decoded messages of ``shard`` with ``start <= log_time <= end``, in file order."""
        reader = self._reader(shard)
        if _HAS_NEW_TIME_BOUNDS:
            return reader.iter_decoded_messages(
                topics=topics, starting_at=start, ending_before=end + 1, log_time_order=False
            )
        return reader.iter_decoded_messages(
            topics=topics, start_time=start, end_time=end + 1, log_time_order=False
        )

    def _first_frame_references(self, shard: str, where: str) -> Dict[str, Tuple[int, Any]]:
        """An episode's ``/tactile/<pad>/reference`` messages: written once, with its frame 0."""
        cached = self._references.get(shard)
        if cached is not None:
            return cached
        episode = self._episode_of_shard[shard]
        first_shard, start = self._samples[episode["first_sample"]]
        assert first_shard == shard
        summary = self._reader(shard).get_summary()
        topics = sorted(
            c.topic
            for c in (summary.channels.values() if summary is not None else [])
            if _pad_of(c.topic, TACTILE_REFERENCE_SUFFIX)
        )
        found: Dict[str, Tuple[int, Any]] = {}
        if topics:
            try:
                for _schema, channel, _message, value in self._messages(shard, start, start, topics):
                    found[channel.topic] = (channel.id, value)
            except Exception as e:
                raise DatasetError(
                    f"{where}: the episode's frame 0 (sample {episode['first_sample']}), which holds "
                    f"its optical reference images, is damaged ({type(e).__name__}: {e})"
                ) from e
        self._references[shard] = found
        return found

    def _read_sample(self, shard: str, log_time: int, index: int) -> Sample:
        episode = self._episode_of_shard.get(shard)
        # A snapshot's chunk is its sample; an episode frame's chunk runs on to the frame's later
        # touch and state messages (FORMAT.md, "Episodes": the sample is the first log time's).
        end = self._ends[index] if episode is not None else log_time
        messages = self._messages(shard, log_time, end)
        decoded: Dict[str, Any] = {}
        # Topic -> channel id: the writer adds a robot's pad channels in its pads' index order.
        channel_ids: Dict[str, int] = {}
        # An episode frame's messages after its instant: (log_time, topic, channel id, message).
        later: List[Tuple[int, str, int, Any]] = []
        try:
            for _schema, channel, message, value in messages:
                if message.log_time != log_time:
                    later.append((message.log_time, channel.topic, channel.id, value))
                    continue
                if channel.topic in decoded and (
                    channel.topic in REQUIRED_TOPICS or channel.topic == TOPIC_EPISODE_STATE
                ):
                    raise DatasetError(
                        f"{shard}: sample {index} of split {self.split!r} has more than one "
                        f"{channel.topic} message"
                    )
                decoded[channel.topic] = value
                channel_ids[channel.topic] = channel.id
        except DatasetError:
            raise
        except Exception as e:  # zstd, CRC, record and protobuf errors of a damaged chunk
            raise DatasetError(
                f"{shard}: sample {index} of split {self.split!r} is damaged "
                f"({type(e).__name__}: {e})"
            ) from e
        missing = [t for t in REQUIRED_TOPICS if t not in decoded]
        if missing:
            raise DatasetError(
                f"{shard}: sample {index} of split {self.split!r} (log_time {log_time}) has no "
                f"message on {', '.join(missing)}"
            )
        where = f"{shard}: sample {index} of split {self.split!r}"
        transforms = _frame_transforms(decoded[TOPIC_TF], where)
        pose = decoded[TOPIC_POSE].pose
        sample = Sample(
            rgb=decode_raw_image(decoded[TOPIC_RGB], expect="rgb8", where=where + f" {TOPIC_RGB}"),
            depth=decode_raw_image(
                decoded[TOPIC_DEPTH], expect="32FC1", where=where + f" {TOPIC_DEPTH}"
            ),
            mask=decode_raw_image(
                decoded[TOPIC_MASK], expect="mono8", where=where + f" {TOPIC_MASK}"
            ),
            K=_intrinsics(decoded[TOPIC_CALIBRATION], where),
            T_camera_object=pose_matrix(
                (pose.position.x, pose.position.y, pose.position.z),
                (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w),
            ),
            T_world_camera=transforms[("world", "camera")],
            T_world_object=transforms[("world", "object")],
            info=decoded[TOPIC_INFO],
            index=index,
            split=self.split,
        )
        if TOPIC_DEPTH_NOISY in decoded:
            sample["depth_noisy"] = decode_raw_image(
                decoded[TOPIC_DEPTH_NOISY], expect="32FC1", where=where + f" {TOPIC_DEPTH_NOISY}"
            )
        if TOPIC_TACTILE_POINTS in decoded:
            sample["tactile"] = _tactile(decoded, channel_ids, where)
        frame = index - episode["first_sample"] if episode is not None else 0
        if frame > 0:
            # FORMAT.md: an episode's reference images come once, with its frame 0.
            references = self._first_frame_references(shard, where)
            for topic in list(decoded):
                pad = optical_pad_of_topic(topic)
                reference = f"{TACTILE_DEPTH_PREFIX}{pad}{TACTILE_REFERENCE_SUFFIX}"
                if pad is not None and reference not in decoded and reference in references:
                    channel_ids[reference], decoded[reference] = references[reference]
        optical = _optical(decoded, channel_ids, where, sample.get("tactile"))
        if optical is not None:
            sample["tactile_images"], sample["tactile_references"] = optical
        if episode is not None:
            sample["episode"] = _episode_streams(frame, log_time, decoded, later, channel_ids, where)
        return sample


def open_dataset(root: PathLike, split: str = "train") -> Dataset:
    """Open one split of the vtgen dataset at ``root`` (same as ``Dataset(root, split)``)."""
    return Dataset(root, split)


# --- decoding helpers ------------------------------------------------------------------------


def decode_raw_image(image: Any, expect: Optional[str] = None, where: str = "image") -> np.ndarray:
    """Convert a ``foxglove.RawImage`` message into a C-contiguous numpy array.

    Supports ``rgb8`` (``(H, W, 3)`` uint8), ``mono8`` (``(H, W)`` uint8), ``mono16`` (``(H, W)``
    uint16, little-endian) and ``32FC1`` (``(H, W)`` float32, little-endian). Rows are read
    ``step`` bytes apart, so padded rows are handled. ``expect`` checks the encoding.
    """
    encoding = image.encoding
    if expect is not None and encoding != expect:
        raise DatasetError(f"{where}: expected encoding {expect!r}, found {encoding!r}")
    if encoding not in _IMAGE_ENCODINGS:
        raise DatasetError(
            f"{where}: unsupported image encoding {encoding!r} "
            f"(supported: {', '.join(_IMAGE_ENCODINGS)})"
        )
    stored, channels, out_dtype = _IMAGE_ENCODINGS[encoding]
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


def _pad_of(topic: str, suffix: str) -> Optional[str]:
    if topic.startswith(TACTILE_DEPTH_PREFIX) and topic.endswith(suffix):
        name = topic[len(TACTILE_DEPTH_PREFIX) : -len(suffix)]
        if name and "/" not in name:
            return name
    return None


def pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/depth`` topic, else ``None``."""
    return _pad_of(topic, TACTILE_DEPTH_SUFFIX)


def optical_pad_of_topic(topic: str) -> Optional[str]:
    """The pad name of a ``/tactile/<pad>/image`` topic (an optical sensor's image), else ``None``."""
    return _pad_of(topic, TACTILE_IMAGE_SUFFIX)


def _optical(
    decoded: Dict[str, Any],
    channel_ids: Mapping[str, int],
    where: str,
    tactile: Optional[Dict[str, Any]],
) -> Optional[Tuple[Dict[str, np.ndarray], Dict[str, np.ndarray]]]:
    """The optical pads' images and reference images, ``None`` when the sample has none.

    The pads are the sample's ``/tactile/<pad>/image`` topics in the order of their channels (the
    writer adds them in the robot's pad order). Each needs its ``/tactile/<pad>/reference`` of the
    same size, both ``rgb8``; the pads must be pads of the tactile data and, when ``/sample/info``
    has ``tactile.optical``, the pads it lists, at its ``image_size``.
    """
    found = sorted(
        (channel_ids.get(t, 0), name)
        for t in decoded
        for name in [optical_pad_of_topic(t)]
        if name
    )
    pads = [name for _, name in found]
    orphans = sorted(
        name
        for t in decoded
        for name in [_pad_of(t, TACTILE_REFERENCE_SUFFIX)]
        if name and name not in pads
    )
    if orphans:
        raise DatasetError(
            f"{where}: {', '.join(f'/tactile/{p}/reference' for p in orphans)} without its "
            f"/tactile/<pad>/image"
        )
    info = decoded.get(TOPIC_INFO)
    touch = info.get("tactile") if isinstance(info, dict) else None
    listed = touch.get("optical") if isinstance(touch, dict) else None
    if isinstance(listed, dict) and set(listed) != set(pads):
        raise DatasetError(
            f"{where}: /sample/info tactile.optical lists the optical pads {sorted(listed)}, the "
            f"sample has images of {sorted(pads)} (/tactile/<pad>/image)"
        )
    if not pads:
        return None
    if tactile is None:
        raise DatasetError(
            f"{where}: optical images of {', '.join(pads)} but no {TOPIC_TACTILE_POINTS} "
            "(optical pads are pads of the robot's tactile data)"
        )
    unknown = [p for p in pads if p not in tactile["phalanges"]]
    if unknown:
        raise DatasetError(
            f"{where}: optical images of {', '.join(unknown)}, which are not pads of the sample "
            f"(no /tactile/<pad>/depth; pads: {', '.join(tactile['phalanges'])})"
        )
    images: Dict[str, np.ndarray] = {}
    references: Dict[str, np.ndarray] = {}
    for pad in pads:
        image_topic = f"{TACTILE_DEPTH_PREFIX}{pad}{TACTILE_IMAGE_SUFFIX}"
        reference_topic = f"{TACTILE_DEPTH_PREFIX}{pad}{TACTILE_REFERENCE_SUFFIX}"
        if reference_topic not in decoded:
            raise DatasetError(f"{where}: {image_topic} without its {reference_topic}")
        image = decode_raw_image(decoded[image_topic], expect="rgb8", where=f"{where} {image_topic}")
        reference = decode_raw_image(
            decoded[reference_topic], expect="rgb8", where=f"{where} {reference_topic}"
        )
        h, w = image.shape[:2]
        if reference.shape != image.shape:
            raise DatasetError(
                f"{where}: {reference_topic} is {reference.shape[1]}x{reference.shape[0]}, its "
                f"image {w}x{h}"
            )
        if h == 0 or w == 0:
            raise DatasetError(f"{where} {image_topic}: empty {w}x{h} image")
        sensor = listed.get(pad) if isinstance(listed, dict) else None
        size = sensor.get("image_size") if isinstance(sensor, dict) else None
        if size is not None and size != [w, h]:
            raise DatasetError(
                f"{where}: {image_topic} is {w}x{h}, but /sample/info "
                f"tactile.optical.{pad}.image_size is {size} ([width, height])"
            )
        images[pad] = image
        references[pad] = reference
    return images, references


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
                raise DatasetError(f"{where}: two {TOPIC_EPISODE_STATE} messages at {t} ns")
            states.append((t, value))
        elif topic.startswith(TACTILE_DEPTH_PREFIX) and not topic.endswith(TACTILE_REFERENCE_SUFFIX):
            group = touch.setdefault(t, {})
            if topic in group:
                raise DatasetError(f"{where}: two {topic} messages at {t} ns")
            group[topic] = value
            channel_ids.setdefault(topic, channel_id)
    tactile: List[Tuple[int, Dict[str, Any]]] = []
    for t in sorted(touch):
        group = touch[t]
        at = f"{where} (touch at {t} ns)"
        if TOPIC_TACTILE_POINTS not in group:
            raise DatasetError(f"{at}: /tactile/<pad> messages without {TOPIC_TACTILE_POINTS}")
        reading = _tactile(group, channel_ids, at)
        pads = sorted(
            (channel_ids.get(topic, 0), pad, topic)
            for topic in group
            for pad in [optical_pad_of_topic(topic)]
            if pad
        )
        if pads:
            reading["images"] = {
                pad: decode_raw_image(group[topic], expect="rgb8", where=f"{at} {topic}")
                for _, pad, topic in pads
            }
        tactile.append((t, reading))
    states.sort(key=lambda item: item[0])
    return {"frame": frame, "time_ns": time_ns, "states": states, "tactile": tactile}


def _tactile(decoded: Dict[str, Any], channel_ids: Mapping[str, int], where: str) -> Dict[str, Any]:
    """The tactile point cloud and the pad depth images of a sample.

    The pads are the sample's ``/tactile/<pad>/depth`` topics, whatever the robot: in the order of
    their channels (the writer adds them in the robot's pad order, the order of the points'
    ``phalanx`` index; names sort otherwise, e.g. ``right`` before ``left``), checked
    against ``/sample/info`` ``tactile.pads`` when the info has it.
    """
    cloud = decoded[TOPIC_TACTILE_POINTS]
    if cloud.point_stride != _TACTILE_DTYPE.itemsize:
        raise DatasetError(f"{where} {TOPIC_TACTILE_POINTS}: point stride {cloud.point_stride}, expected 20")
    pts = np.frombuffer(bytes(cloud.data), dtype=_TACTILE_DTYPE)
    pads = sorted(
        ((channel_ids.get(t, 0), t, name) for t in decoded for name in [pad_of_topic(t)] if name),
    )
    topics = [t for _, t, _ in pads]
    names = [name for _, _, name in pads]
    info = decoded.get(TOPIC_INFO)
    touch = info.get("tactile") if isinstance(info, dict) else None
    listed = touch.get("pads") if isinstance(touch, dict) else None
    if isinstance(listed, dict) and set(listed) != set(names):
        raise DatasetError(
            f"{where}: /sample/info tactile.pads lists the pads {sorted(listed)}, the sample has "
            f"depth images of {sorted(names)} (/tactile/<pad>/depth)"
        )
    if not names:
        raise DatasetError(
            f"{where}: {TOPIC_TACTILE_POINTS} but no /tactile/<pad>/depth message (no pad)"
        )
    depth = [
        decode_raw_image(decoded[t], expect="32FC1", where=f"{where} {t}") for t in topics
    ]
    shapes = {d.shape for d in depth}
    if len(shapes) != 1:
        raise DatasetError(
            f"{where}: the pad depth images differ in size: "
            + ", ".join(f"{n} {d.shape[1]}x{d.shape[0]}" for n, d in zip(names, depth))
        )
    if len(pts) and int(pts["phalanx"].max()) >= len(names):
        raise DatasetError(
            f"{where} {TOPIC_TACTILE_POINTS}: phalanx index {int(pts['phalanx'].max())} but the "
            f"sample has {len(names)} pads ({', '.join(names)})"
        )
    return {
        "points": np.ascontiguousarray(np.stack([pts["x"], pts["y"], pts["z"]], axis=1)),
        "distance": pts["distance"].copy(),
        "phalanx": pts["phalanx"].copy(),
        "phalanges": names,
        "depth": np.stack(depth),
    }


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
    for key in (("world", "camera"), ("world", "object")):
        if key not in out:
            raise DatasetError(
                f"{where} {TOPIC_TF}: no {key[0]} -> {key[1]} transform "
                f"(found {sorted(out) or 'none'})"
            )
    return out


# --- manifest, index and models --------------------------------------------------------------


def _read_manifest(root: Path) -> Dict[str, Any]:
    path = root / "manifest.json"
    if not path.is_file():
        if not root.is_dir():
            raise DatasetNotFoundError(f"dataset folder {root} does not exist")
        raise DatasetNotFoundError(f"{path} is missing: {root} is not a vtgen dataset")
    try:
        with open(path, "r", encoding="utf-8") as f:
            manifest = json.load(f)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path} is not valid JSON: {e}") from e
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else type(manifest).__name__
        raise DatasetError(f"{path}: format is {found!r}, expected {MANIFEST_FORMAT!r}")
    version = manifest.get("format_version")
    if not isinstance(version, int) or version < 1:
        raise DatasetError(f"{path}: invalid format_version {version!r}")
    if version > FORMAT_VERSION:
        warnings.warn(
            f"{path}: format_version {version} is newer than this reader ({FORMAT_VERSION}); "
            "unknown fields are ignored",
            stacklevel=3,
        )
    return manifest


def _check_shard_belongs(
    shard: str,
    meta: Optional[Mapping[str, str]],
    split: str,
    entry: Mapping[str, Any],
    manifest: Mapping[str, Any],
) -> None:
    """The shard's ``vtgen.shard`` metadata names this dataset (its config hash), split and shard."""
    if meta is None:
        raise DatasetError(f"{shard}: no 'vtgen.shard' metadata record: not a vtgen shard")
    theirs, ours = meta.get("config_sha256"), manifest.get("config_sha256")
    if ours is not None and theirs != ours:
        raise DatasetError(
            f"{shard}: this shard belongs to another dataset (its config_sha256 is {theirs}, "
            f"the manifest's {ours})"
        )
    where = (meta.get("split"), meta.get("shard_index"))
    want = (split, str(entry.get("shard_index")))
    if entry.get("shard_index") is not None and where != want:
        raise DatasetError(
            f"{shard}: holds shard {where[1]} of split {where[0]!r}, but the manifest lists it "
            f"as shard {want[1]} of split {want[0]!r}"
        )


def _episode_record(shard: str, meta: Mapping[str, str]) -> Optional[Dict[str, Any]]:
    """The shard's ``vtgen.shard`` ``episode`` record (JSON), ``None`` in a snapshot shard."""
    raw = meta.get(EPISODE_METADATA_KEY)
    if raw is None:
        return None
    try:
        record = json.loads(raw)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{shard}: vtgen.shard '{EPISODE_METADATA_KEY}' is not valid JSON: {e}") from e
    if not isinstance(record, dict):
        raise DatasetError(f"{shard}: vtgen.shard '{EPISODE_METADATA_KEY}' is not a JSON object")
    return record


def _build_index(
    root: Path,
    split: str,
    split_entry: Mapping[str, Any],
    shards_out: List[str],
    manifest: Mapping[str, Any],
    episodes_out: List[Dict[str, Any]],
) -> List[Tuple[str, int, int]]:
    """Map every sample of the split to (shard path, chunk start, chunk end log time) from the
    shards' chunk indexes; each episode shard's record goes to ``episodes_out``."""
    manifest_path = root / "manifest.json"
    found: Dict[int, Tuple[str, int, int]] = {}
    for entry in split_entry.get("shards", []):
        if entry.get("sha256") is None:
            continue  # listed but not generated yet (interrupted or distributed run)
        path = root / entry["file"]
        if not path.is_file():
            raise DatasetNotFoundError(
                f"shard {path} is listed in {manifest_path} but missing on disk"
            )
        shard = str(path)
        shards_out.append(shard)
        with open(path, "rb") as f:
            try:
                reader = make_reader(f)
                summary = reader.get_summary()
                metadata = {m.name: m.metadata for m in reader.iter_metadata()}
            except Exception as e:
                raise DatasetError(
                    f"{shard}: cannot read the MCAP summary (truncated or damaged file?): {e}"
                ) from e
        if summary is None:
            raise DatasetError(f"{shard}: MCAP file has no summary section")
        meta = metadata.get("vtgen.shard")
        _check_shard_belongs(shard, meta, split, entry, manifest)
        assert meta is not None
        episode = _episode_record(shard, meta)
        # (split index, chunk start, chunk end) of each chunk of the shard.
        located: List[Tuple[int, int, int]] = []
        if episode is None:
            for chunk in summary.chunk_indexes:
                start, end = chunk.message_start_time, chunk.message_end_time
                if start % SAMPLE_PERIOD_NS != 0 or end != start:
                    raise DatasetError(
                        f"{shard}: chunk at offset {chunk.chunk_start_offset} spans log times "
                        f"{start}..{end} ns; every chunk must hold exactly one sample at a multiple "
                        f"of {SAMPLE_PERIOD_NS} ns"
                    )
                located.append((start // SAMPLE_PERIOD_NS, start, end))
        else:
            # An episode: its chunks in time order are its frames, numbered from first_sample.
            # Their time spans must not overlap, so a frame's time range selects its chunk alone.
            first = meta.get("first_sample", entry.get("first_sample"))
            try:
                first = int(first)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                raise DatasetError(f"{shard}: episode shard without a valid first_sample ({first!r})") from None
            chunks = sorted(
                (c for c in summary.chunk_indexes if c.message_index_offsets),
                key=lambda c: (c.message_start_time, c.message_end_time),
            )
            for k, chunk in enumerate(chunks):
                start, end = chunk.message_start_time, chunk.message_end_time
                if k > 0 and start <= located[-1][2]:
                    raise DatasetError(
                        f"{shard}: the chunks of frames {k - 1} and {k} overlap in time "
                        f"({located[-1][1]}..{located[-1][2]} ns and {start}..{end} ns); each "
                        f"chunk of an episode is one camera frame up to the next"
                    )
                located.append((first + k, start, end))
            frames = episode.get("frames")
            if isinstance(frames, int) and frames != len(chunks):
                raise DatasetError(
                    f"{shard}: its episode record has {frames} frames, the shard {len(chunks)} chunks"
                )
            episodes_out.append({**episode, "shard": shard, "first_sample": first, "frames": len(chunks)})
        indices: List[int] = []
        for index, start, end in located:
            if index in found:
                other = found[index][0]
                raise DatasetError(
                    f"sample {index} of split {split!r} is stored twice: in {other} and {shard}"
                )
            found[index] = (shard, start, end)
            indices.append(index)
        first, count = entry.get("first_sample"), entry.get("samples")
        if isinstance(first, int) and isinstance(count, int):
            if sorted(indices) != list(range(first, first + count)):
                raise DatasetError(
                    f"{shard}: the manifest lists samples {first}..{first + count - 1} but the "
                    f"shard's chunk indexes hold {len(indices)} samples "
                    f"({_describe_range(sorted(indices))})"
                )
    n = len(found)
    if n and (min(found) != 0 or max(found) != n - 1):
        missing = next(i for i in range(max(found) + 1) if i not in found)
        raise DatasetError(
            f"split {split!r} of {root} is not contiguous: {n} samples found but sample {missing} "
            f"is missing (is a shard still unwritten? see 'complete' in {manifest_path})"
        )
    return [found[i] for i in range(n)]


def _describe_range(indices: Sequence[int]) -> str:
    if not indices:
        return "none"
    return f"{indices[0]}..{indices[-1]}"


def _check_index(index: int, length: int) -> int:
    try:
        i = int(index)
    except TypeError:
        raise TypeError(f"sample index must be an integer, not {type(index).__name__}") from None
    if i != index:
        raise TypeError(f"sample index must be an integer, not {index!r}")
    if i < 0:
        i += length
    if not 0 <= i < length:
        raise IndexError(f"sample index {index} out of range for a split of {length} samples")
    return i


def load_models(root: PathLike) -> Dict[str, Dict[str, Any]]:
    """Load ``models/models_info.json`` and every model's PLY mesh of the dataset at ``root``."""
    models_dir = Path(root) / "models"
    info_path = models_dir / "models_info.json"
    if not info_path.is_file():
        raise DatasetNotFoundError(f"{info_path} is missing")
    with open(info_path, "r", encoding="utf-8") as f:
        info = json.load(f)
    out: Dict[str, Dict[str, Any]] = {}
    for entry in info.get("objects", []):
        ply_path = models_dir / entry["file"]
        if not ply_path.is_file():
            raise DatasetNotFoundError(f"model {ply_path} listed in {info_path} is missing")
        mesh = load_ply(ply_path)
        if mesh["normals"] is None:
            raise DatasetError(f"{ply_path}: vertices have no nx ny nz normals")
        out[entry["id"]] = {
            "info": entry,
            "vertices": mesh["vertices"],
            "normals": mesh["normals"],
            "faces": mesh["faces"],
        }
    return out
