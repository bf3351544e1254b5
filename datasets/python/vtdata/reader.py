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
from pathlib import Path
from typing import (
    IO,
    Any,
    Dict,
    Iterator,
    List,
    Optional,
    Sequence,
    Tuple,
    Union,
)

from mcap.reader import McapReader, make_reader
from mcap_protobuf.decoder import DecoderFactory as _ProtobufDecoderFactory

# The decoders, the index builder and the format constants moved to their own modules; their
# names stay importable from here (``from vtdata.reader import TOPIC_RGB`` keeps working).
from .decoders import (  # noqa: F401
    _JsonDecoderFactory,
    _McapDecoderFactory,
    _add_message,
    _camera_fields,
    _decode_json,
    _episode_streams,
    _forces,
    _frame_transforms,
    _intrinsics,
    _markers,
    _optical,
    _tactile,
    decode_raw_image,
    force_array,
    marker_arrays,
    pose_matrix,
    quaternion_matrix,
)
from .errors import DatasetError, DatasetNotFoundError
from .format import (  # noqa: F401
    EPISODE_METADATA_KEY,
    FORMAT_VERSION,
    MANIFEST_FILE,
    MANIFEST_FORMAT,
    MODELS_DIR,
    MODELS_INFO_FILE,
    REQUIRED_TOPICS,
    SAMPLE_PERIOD_NS,
    TACTILE_DEPTH_PREFIX,
    TACTILE_DEPTH_SUFFIX,
    TACTILE_IMAGE_SUFFIX,
    TACTILE_REFERENCE_SUFFIX,
    TOPIC_CALIBRATION,
    TOPIC_DEPTH,
    TOPIC_DEPTH_NOISY,
    TOPIC_EPISODE_STATE,
    TOPIC_INFO,
    TOPIC_MASK,
    TOPIC_POSE,
    TOPIC_RGB,
    TOPIC_SCENE_MODELS,
    TOPIC_TACTILE_POINTS,
    TOPIC_TF,
    optical_pad_of_topic,
    pad_of_topic,
    tactile_reference_topic,
)
from .format import IMAGE_ENCODINGS as _IMAGE_ENCODINGS  # noqa: F401
from .format import TACTILE_POINT_DTYPE as _TACTILE_DTYPE  # noqa: F401
# Private: this module's TOPIC_* names are the topics (callers list them with vars()).
from .format import TOPIC_IMAGE_ENCODINGS as _TOPIC_IMAGE_ENCODINGS
from .format import pad_of as _pad_of
from .index import (  # noqa: F401
    _build_index,
    _check_shard_belongs,
    _describe_range,
    _episode_record,
    _read_manifest,
)
from .ply import load_ply

PathLike = Union[str, "os.PathLike[str]"]

# mcap >= 1.6 renamed the time bounds of iter_messages (start_time/end_time are deprecated there).
_HAS_NEW_TIME_BOUNDS = (
    "starting_at" in inspect.signature(McapReader.iter_decoded_messages).parameters
)


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
      ``pad`` ``(N,)`` uint32 pad index into ``pads``, ``pads`` (the robot's ``P`` pad names in
      index order, read from the shard: 12 on the Allegro hand, 2 on a parallel gripper) and
      ``depth`` ``(P, R, R)`` float32 pad camera images
      (``inf`` = no surface), one per ``/tactile/<pad>/depth`` topic. With force fields
      (``robot.tactile.force_field``, FORMAT.md "Force fields") also ``forces``: ``{pad: {"position":
      (R, R, 2) float32, "pressure": (R, R) float32, "shear": (R, R, 2) float32, "slip": (R, R)
      bool}}`` in pad order, each pad's ``/tactile/<pad>/force`` grid (row ``v``, column ``u``: the
      cell centred at ``position`` in the pad frame, m; the normal pressure the object puts on it
      and its shear traction along the pad's x and y, Pa; whether the cell slips); absent without
      force topics. :func:`vtdata.reader.force_array` stacks them as ``(P, R, R, 4)``. The forces
      they were made from are ``info["tactile"]["forces"][pad]`` (``force_n``, pad frame, N).
      With force fields each optical pad whose sensor has markers also has its **marker flow** in
      ``markers``: ``{pad: {"position": (N, 2) float32, "rest": (N, 2) float32}}`` in pad order,
      the pad's ``/tactile/<pad>/markers`` points (one per printed marker, in the rest grid's
      order, rows along the pad's y: where the gel has moved it and its rest position, pad frame,
      m; ``position - rest`` is its displacement); absent without marker topics. ``N`` is the
      pad's own (each sensor has its grid); :func:`vtdata.reader.marker_arrays` gives ``{pad: (N,
      4)}`` (x, y, rest_x, rest_y).
    - ``tactile_images`` and ``tactile_references`` (only when some pad has an optical
      GelSight/DIGIT-style sensor): ``{pad: (H, W, 3) uint8}`` in pad order, the sensor's RGB image
      (``/tactile/<pad>/image``, linear 8-bit levels) and its no-contact reference image without
      noise (``/tactile/<pad>/reference``, same size); the same pads in both, a subset of
      ``tactile["pads"]``. The sensor's parameters are ``info["tactile"]["optical"][pad]``.
      In an episode the references are written once, with frame 0; every frame gets them.
    - ``episode`` (only in an episode dataset, FORMAT.md "Episodes"): the frame's faster streams,
      ``{"frame": k, "time_ns": t, "states": [(t_ns, record), ...], "tactile": [(t_ns, touch),
      ...]}``: ``frame`` is the frame's index in its episode, ``time_ns`` its simulated time since
      the episode's start (its log time), ``states`` the ``/episode/state`` records (dicts) from
      the frame's instant (included) up to the next frame, ``tactile`` the touch readings *after*
      the frame's own (which is ``tactile``) up to the next frame, each a dict like ``tactile``
      plus, with optical pads, ``images`` ``{pad: (H, W, 3) uint8}`` (a reading's ``forces`` and
      ``markers`` are the force fields and marker flow of its instant). Times ascend.
      ``info["episode"]`` has the frame's ``frame``, ``time_s`` and ``arm_move``.
    """

    __slots__ = ()

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None



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
                f"split {split!r} is not in {self.root / MANIFEST_FILE} (splits: {available})"
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

    # --- sequence protocol --------------------------------------------------------------------

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

    # --- public helpers -----------------------------------------------------------------------

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

    # --- reading ------------------------------------------------------------------------------

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

    def _sample_messages(
        self, shard: str, log_time: int, end: int, index: int
    ) -> Tuple[Dict[str, Any], Dict[str, int], List[Tuple[int, str, int, Any]]]:
        """Read sample ``index``'s chunk: its messages at ``log_time`` by topic (each topic the
        reader decodes once, :func:`~vtdata.decoders._add_message`), their channel ids and (an episode frame's) the later messages up to ``end``
        as ``(log_time, topic, channel id, message)``."""
        messages = self._messages(shard, log_time, end)
        decoded: Dict[str, Any] = {}
        # Topic -> channel id: the writer adds a robot's pad channels in its pads' index order.
        channel_ids: Dict[str, int] = {}
        later: List[Tuple[int, str, int, Any]] = []
        try:
            for _schema, channel, message, value in messages:
                if message.log_time != log_time:
                    later.append((message.log_time, channel.topic, channel.id, value))
                    continue
                _add_message(decoded, channel.topic, value, f"{shard}: sample {index} of split {self.split!r}")
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
        return decoded, channel_ids, later

    def _add_first_frame_references(
        self, shard: str, decoded: Dict[str, Any], channel_ids: Dict[str, int], where: str
    ) -> None:
        """Give a later episode frame's optical images the reference images of its frame 0
        (FORMAT.md: an episode's reference images come once, with its frame 0)."""
        references = self._first_frame_references(shard, where)
        for topic in list(decoded):
            pad = optical_pad_of_topic(topic)
            if pad is None:
                continue
            reference = tactile_reference_topic(pad)
            if reference not in decoded and reference in references:
                channel_ids[reference], decoded[reference] = references[reference]

    def _read_sample(self, shard: str, log_time: int, index: int) -> Sample:
        episode = self._episode_of_shard.get(shard)
        # A snapshot's chunk is its sample; an episode frame's chunk runs on to the frame's later
        # touch and state messages (FORMAT.md, "Episodes": the sample is the first log time's).
        end = self._ends[index] if episode is not None else log_time
        decoded, channel_ids, later = self._sample_messages(shard, log_time, end, index)
        where = f"{shard}: sample {index} of split {self.split!r}"
        sample = Sample(
            **_camera_fields(decoded, where),
            info=decoded[TOPIC_INFO],
            index=index,
            split=self.split,
        )
        if TOPIC_DEPTH_NOISY in decoded:
            sample["depth_noisy"] = decode_raw_image(
                decoded[TOPIC_DEPTH_NOISY],
                expect=_TOPIC_IMAGE_ENCODINGS[TOPIC_DEPTH_NOISY],
                where=where + f" {TOPIC_DEPTH_NOISY}",
            )
        pads = None
        if TOPIC_TACTILE_POINTS in decoded:
            sample["tactile"] = _tactile(decoded, channel_ids, where)
            pads = sample["tactile"]["pads"]
        else:
            # Force fields or markers without tactile data: an error.
            _forces(decoded, channel_ids, where, None)
            _markers(decoded, channel_ids, where, None)
        frame = index - episode["first_sample"] if episode is not None else 0
        if frame > 0:
            self._add_first_frame_references(shard, decoded, channel_ids, where)
        optical = _optical(decoded, channel_ids, where, pads)
        if optical is not None:
            sample["tactile_images"], sample["tactile_references"] = optical
        if episode is not None:
            sample["episode"] = _episode_streams(frame, log_time, decoded, later, channel_ids, where)
        return sample


def open_dataset(root: PathLike, split: str = "train") -> Dataset:
    """Open one split of the vtgen dataset at ``root`` (same as ``Dataset(root, split)``)."""
    return Dataset(root, split)


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
    models_dir = Path(root) / MODELS_DIR
    info_path = Path(root) / MODELS_INFO_FILE
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
