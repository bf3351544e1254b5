"""Windows of consecutive camera frames of an episode dataset (FORMAT.md, "Episodes").

>>> import vtdata
>>> ds = vtdata.EpisodeDataset("out/tiny-episode", "train", window=4, stride=2)
>>> item = ds[0]
>>> item["rgb"].shape                      # (4, H, W, 3) uint8: 4 consecutive camera frames
>>> item["time_ns"]                        # (4,) int64: their times since the episode's start
>>> item["state"]["T_world_object"].shape  # (4, 4, 4): the state at each frame's time
>>> item["state_seq"]["time_ns"]           # every state from the first frame to the last one

A window never crosses episodes. Each stream is aligned to the camera frames by FORMAT.md's rule:
its value at a frame's time is its latest message at or before that time (for the frame instants:
the message at that time itself). Every array has the same shape in every window of a dataset, so
``torch.utils.data.DataLoader``'s default collate batches the items (except for the opt-in
``tactile_points`` and ``info`` streams, which are lists: batch them with
:func:`vtdata.torch.collate`; and for the touch streams' ``markers``, whose count per pad is an
episode's own where ``randomization.tactile_sensors`` varies the marker pitch: that collate keeps
those of different counts as lists). :class:`vtdata.torch.EpisodeTorchDataset` gives tensors.
"""

from __future__ import annotations

import bisect
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from .decoders import force_array, marker_arrays
from .format import EPISODE_METADATA_KEY, SHARD_METADATA, TOPIC_EPISODE_STATE
from .reader import (
    Dataset,
    DatasetError,
    PathLike,
    Sample,
    _check_index,
    pose_matrix,
)

#: Every stream :class:`EpisodeDataset` can return.
STREAMS = (
    "rgb",
    "depth",
    "depth_noisy",
    "mask",
    "pose",
    "tactile",
    "tactile_points",
    "tactile_images",
    "tactile_seq",
    "state",
    "state_seq",
    "info",
)
#: The streams returned when none are named.
DEFAULT_STREAMS = ("rgb", "depth", "mask", "pose", "tactile", "state")
#: The poses of an ``/episode/state`` record, returned as ``(4, 4)`` float64 matrices.
STATE_POSES = ("T_world_object", "T_camera_object", "T_world_palm")
#: Its object twist: ``(3,)`` float64 vectors (m/s; rad/s as a rotation vector's rate).
STATE_VECTORS = ("linear_velocity", "angular_velocity")


class EpisodeDataset:
    """Windows of ``window`` consecutive camera frames of the episodes of one split.

    ``EpisodeDataset(root, split, window=K, stride=S, streams=...)``: window starts ``0, S, 2S,
    ...`` in every episode, as long as the window fits (``start + K <= frames``); an episode shorter
    than ``K`` frames gives none. ``root`` may also be an open :class:`vtdata.Dataset` (then
    ``split`` is ignored). Raises :class:`vtdata.DatasetError` on a split without episodes (a
    snapshot dataset). ``ds[i]`` is a dict (all arrays numpy, a leading ``K`` axis per frame):

    - always: ``episode`` (int, the episode's position in ``ds.dataset.episodes``), ``start``
      (int, the window's first frame), ``object_id`` (str), ``trajectory`` (int), ``frame``
      ``(K,)`` int64 frame indices in the episode, ``index`` ``(K,)`` int64 sample indices in the
      split (``vtdata.Dataset`` indices), ``time_ns`` ``(K,)`` int64 and ``time_s`` ``(K,)``
      float64 the frames' simulated times since the episode's start.
    - ``rgb`` ``(K, H, W, 3)`` uint8; ``depth`` ``(K, H, W)`` float32; ``depth_noisy`` ``(K, H,
      W)`` float32 (a dataset without a depth noise model raises :class:`vtdata.DatasetError`);
      ``mask`` ``(K, H, W)`` uint8.
    - ``pose``: ``K`` ``(K, 3, 3)`` float64 intrinsics and ``T_camera_object``,
      ``T_world_camera``, ``T_world_object`` ``(K, 4, 4)`` float64, of each frame.
    - ``tactile``: ``{"time_ns": (K,) int64, "depth": (K, P, R, R) float32, "counts": (K, P)
      int64}``: the touch reading aligned to each frame (its pads' depth images and points per
      pad, pads in ``ds.pads`` order) and its time; with force fields also ``"forces": (K, P, F,
      F, 4) float32`` (each pad's ``F x F`` grid of pressure, shear_x, shear_y, slip:
      :func:`vtdata.reader.force_array`) and, with marker flow, ``"markers": {pad: (K, N, 4)
      float32}`` (each optical pad's markers: x, y, rest_x, rest_y; :func:`vtdata.marker_arrays`;
      ``N`` is the pad's own, the same in every reading of an episode).
    - ``tactile_points``: a list of ``K`` dicts (``points`` ``(N, 3)``, ``distance``, ``pad``,
      ``pads``, ``depth``, with force fields ``forces`` and ``markers``: a sample's
      ``tactile``), the aligned readings' point clouds.
    - ``tactile_images``: ``{pad: (K, H, W, 3) uint8}`` the optical pads' aligned images, and
      ``tactile_references`` ``{pad: (H, W, 3) uint8}`` (one per episode).
    - ``tactile_seq``: every touch reading from the first frame's time to the last one's
      (inclusive, ``M = (K - 1) * camera_period / tactile_period + 1`` of them): ``{"time_ns":
      (M,), "depth": (M, P, R, R), "counts": (M, P)}``, with force fields ``"forces": (M, P, F, F,
      4)``, with marker flow ``"markers": {pad: (M, N, 4)}`` and, with optical pads, ``"images":
      {pad: (M, H, W, 3)}``.
    - ``state``: the ``/episode/state`` record aligned to each frame: ``{"time_ns": (K,),
      "T_world_object", "T_camera_object", "T_world_palm": (K, 4, 4) float64, "linear_velocity",
      "angular_velocity": (K, 3) float64, "joint_positions": (K, J) float64}`` (joints in
      ``ds.joint_names`` order).
    - ``state_seq``: the same for every state record from the first frame's time to the last
      one's (inclusive; at the state rate, e.g. every physics step): ``(M, ...)`` arrays.
    - ``info``: a list of the ``K`` frames' ``/sample/info`` dicts.

    The raw records (each state's touch links in contact, ...) are in the frames' samples:
    ``ds.dataset[i]["episode"]``. Like :class:`vtdata.Dataset`, an ``EpisodeDataset`` pickles
    without file handles, so ``DataLoader`` workers may share it.
    """

    def __init__(
        self,
        root: Union[PathLike, Dataset],
        split: str = "train",
        *,
        window: int = 2,
        stride: int = 1,
        streams: Sequence[str] = DEFAULT_STREAMS,
        max_open_files: int = 32,
        verify: bool = False,
    ) -> None:
        if isinstance(streams, str):
            streams = (streams,)
        unknown = [s for s in streams if s not in STREAMS]
        if unknown:
            raise ValueError(f"unknown stream(s) {unknown}; the streams are {list(STREAMS)}")
        if int(window) != window or window < 1:
            raise ValueError(f"window must be an integer >= 1, got {window!r}")
        if int(stride) != stride or stride < 1:
            raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
        if isinstance(root, Dataset):
            self.dataset = root
        else:
            self.dataset = Dataset(root, split, max_open_files=max_open_files, verify=verify)
        if not self.dataset.is_episodic:
            raise DatasetError(
                f"split {self.dataset.split!r} of {self.dataset.root} has no episode shards (no "
                f"'{EPISODE_METADATA_KEY}' in their {SHARD_METADATA} metadata): read a snapshot dataset with "
                f"vtdata.Dataset"
            )
        self.window = int(window)
        self.stride = int(stride)
        self.streams = tuple(dict.fromkeys(streams))
        #: ``(episode, start frame)`` of every window, in order.
        self.windows: List[Tuple[int, int]] = [
            (e, start)
            for e, episode in enumerate(self.dataset.episodes)
            for start in range(0, episode["frames"] - self.window + 1, self.stride)
        ]
        self._joint_names: Optional[List[str]] = None
        self._pads: Optional[List[str]] = None

    # --- sequence protocol -------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, index: int) -> Dict[str, Any]:
        if isinstance(index, slice):
            raise TypeError("EpisodeDataset indices must be integers, not slices")
        e, start = self.windows[_check_index(index, len(self.windows))]
        return self._read_window(e, start)

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(root={str(self.dataset.root)!r}, split={self.dataset.split!r}, "
            f"window={self.window}, stride={self.stride}, windows={len(self)}, "
            f"episodes={len(self.dataset.episodes)}, streams={list(self.streams)})"
        )

    # --- names -------------------------------------------------------------------------------

    @property
    def joint_names(self) -> List[str]:
        """The columns of ``state["joint_positions"]``: the joints of the first episode's first
        state record, in the record's order (its keys are written sorted)."""
        if self._joint_names is None:
            self._joint_names = list(self._first_state()["joint_positions"])
        return self._joint_names

    @property
    def pads(self) -> List[str]:
        """The pads of ``tactile["depth"]``'s second axis (the robot's pad order)."""
        if self._pads is None:
            first = self.dataset[self.dataset.episodes[0]["first_sample"]]
            if "tactile" not in first:
                raise DatasetError(f"{self.dataset.root}: the episodes have no touch (no robot)")
            self._pads = list(first["tactile"]["pads"])
        return self._pads

    def _first_state(self) -> Dict[str, Any]:
        first = self.dataset[self.dataset.episodes[0]["first_sample"]]
        states = first["episode"]["states"]
        if not states:
            raise DatasetError(
                f"{self.dataset.root}: frame 0 of the first episode has no /episode/state record"
            )
        return states[0][1]

    # --- reading -----------------------------------------------------------------------------

    def _read_window(self, e: int, start: int) -> Dict[str, Any]:
        episode = self.dataset.episodes[e]
        first = episode["first_sample"]
        indices = list(range(first + start, first + start + self.window))
        samples = [self.dataset[i] for i in indices]
        times = np.array([s["episode"]["time_ns"] for s in samples], dtype=np.int64)
        where = f"{episode['shard']}: window of frames {start}..{start + self.window - 1}"
        if np.any(np.diff(times) <= 0):
            raise DatasetError(f"{where}: frame times {times.tolist()} do not ascend")
        item: Dict[str, Any] = {
            "episode": e,
            "start": start,
            "object_id": str(episode.get("object_id", samples[0]["info"].get("object_id"))),
            "trajectory": int(episode.get("trajectory", samples[0]["info"].get("trajectory", -1))),
            "frame": np.arange(start, start + self.window, dtype=np.int64),
            "index": np.array(indices, dtype=np.int64),
            "time_ns": times,
            "time_s": times.astype(np.float64) / 1e9,
        }
        streams = self.streams
        for key in ("rgb", "depth", "mask", "depth_noisy"):
            if key in streams:
                if any(key not in s for s in samples):
                    raise DatasetError(f"{where}: stream {key!r}: the dataset's frames have no {key}")
                item[key] = np.stack([s[key] for s in samples])
        if "pose" in streams:
            for key in ("K", "T_camera_object", "T_world_camera", "T_world_object"):
                item[key] = np.stack([s[key] for s in samples])
        if "info" in streams:
            item["info"] = [s["info"] for s in samples]
        touch_streams = {"tactile", "tactile_points", "tactile_images", "tactile_seq"}
        if touch_streams & set(streams):
            self._touch(item, samples, e, start, times, where)
        if "state" in streams or "state_seq" in streams:
            self._state(item, samples, e, start, times, where)
        return item

    def _lookback(self, e: int, start: int, stream: Callable[[Sample], List[Tuple[int, Any]]]) -> Optional[Tuple[int, Any]]:
        """The latest message of ``stream`` before the window's first frame (in earlier frames)."""
        first = self.dataset.episodes[e]["first_sample"]
        for frame in range(start - 1, -1, -1):
            entries = stream(self.dataset[first + frame])
            if entries:
                return entries[-1]
        return None

    def _aligned(
        self,
        entries: List[Tuple[int, Any]],
        times: np.ndarray,
        e: int,
        start: int,
        stream: Callable[[Sample], List[Tuple[int, Any]]],
        what: str,
        where: str,
    ) -> List[Tuple[int, Any]]:
        """For each frame time, the latest entry at or before it (FORMAT.md's alignment rule)."""
        stamps = [t for t, _ in entries]
        out: List[Tuple[int, Any]] = []
        earlier: Optional[Tuple[int, Any]] = None
        for t in times.tolist():
            k = bisect.bisect_right(stamps, t) - 1
            if k >= 0:
                out.append(entries[k])
                continue
            if earlier is None:
                earlier = self._lookback(e, start, stream)
            if earlier is None:
                raise DatasetError(f"{where}: no {what} at or before {t} ns")
            out.append(earlier)
        return out

    def _touch(
        self, item: Dict[str, Any], samples: List[Sample], e: int, start: int, times: np.ndarray, where: str
    ) -> None:
        streams = self.streams

        def readings(sample: Sample) -> List[Tuple[int, Dict[str, Any]]]:
            out: List[Tuple[int, Dict[str, Any]]] = []
            if "tactile" in sample:
                own = dict(sample["tactile"])
                if "tactile_images" in sample:
                    own["images"] = sample["tactile_images"]
                out.append((sample["episode"]["time_ns"], own))
            out += sample["episode"]["tactile"]
            return out

        entries = [r for s in samples for r in readings(s)]
        if not entries and all("tactile" not in s for s in samples):
            raise DatasetError(f"{where}: touch streams asked for, but the frames have no touch (no robot)")
        aligned = self._aligned(entries, times, e, start, readings, "touch reading", where)
        if "tactile" in streams:
            item["tactile"] = _touch_arrays(aligned, where)
        if "tactile_points" in streams:
            item["tactile_points"] = [
                {k: v for k, v in reading.items() if k != "images"} for _, reading in aligned
            ]
        if "tactile_images" in streams:
            pads = list(aligned[0][1].get("images", {}))
            if not pads:
                raise DatasetError(f"{where}: stream 'tactile_images': the dataset has no optical pads")
            item["tactile_images"] = {
                pad: np.stack([_image(reading, pad, t, where) for t, reading in aligned]) for pad in pads
            }
            item["tactile_references"] = dict(samples[0]["tactile_references"])
        if "tactile_seq" in streams:
            inside = [(t, r) for t, r in entries if times[0] <= t <= times[-1]]
            seq = _touch_arrays(inside, where)
            pads = list(inside[0][1].get("images", {})) if inside else []
            if pads:
                seq["images"] = {
                    pad: np.stack([_image(reading, pad, t, where) for t, reading in inside]) for pad in pads
                }
            item["tactile_seq"] = seq

    def _state(
        self, item: Dict[str, Any], samples: List[Sample], e: int, start: int, times: np.ndarray, where: str
    ) -> None:
        def states(sample: Sample) -> List[Tuple[int, Dict[str, Any]]]:
            return list(sample["episode"]["states"])

        entries = [r for s in samples for r in states(s)]
        joints = self.joint_names
        if "state" in self.streams:
            aligned = self._aligned(entries, times, e, start, states, f"{TOPIC_EPISODE_STATE} record", where)
            item["state"] = _state_arrays(aligned, joints, where)
        if "state_seq" in self.streams:
            inside = [(t, r) for t, r in entries if times[0] <= t <= times[-1]]
            item["state_seq"] = _state_arrays(inside, joints, where)


def _image(reading: Dict[str, Any], pad: str, t: int, where: str) -> np.ndarray:
    images = reading.get("images", {})
    if pad not in images:
        raise DatasetError(f"{where}: the touch reading at {t} ns has no optical image of {pad}")
    return images[pad]


def _touch_arrays(readings: List[Tuple[int, Dict[str, Any]]], where: str) -> Dict[str, Any]:
    """``time_ns``, ``depth`` (pad depth images), ``counts`` (points per pad) and, when the readings
    have force fields, ``forces`` (:func:`~vtdata.reader.force_array` of each) and, when they have
    marker flow, ``markers`` (``{pad: (M, N, 4)}``, :func:`~vtdata.reader.marker_arrays` of each)
    of touch readings."""
    if not readings:
        return {
            "time_ns": np.zeros(0, dtype=np.int64),
            "depth": np.zeros((0, 0, 0, 0), dtype=np.float32),
            "counts": np.zeros((0, 0), dtype=np.int64),
        }
    pads = readings[0][1]["pads"]
    for t, reading in readings:
        if reading["pads"] != pads:
            raise DatasetError(f"{where}: the touch reading at {t} ns has pads {reading['pads']}, not {pads}")
    out: Dict[str, Any] = {
        "time_ns": np.array([t for t, _ in readings], dtype=np.int64),
        "depth": np.stack([reading["depth"] for _, reading in readings]),
        "counts": np.stack(
            [np.bincount(reading["pad"], minlength=len(pads)).astype(np.int64) for _, reading in readings]
        ),
    }
    force_pads = [list(reading.get("forces", {})) for _, reading in readings]
    if any(force_pads):
        for (t, _), have in zip(readings, force_pads):
            if have != force_pads[0]:
                raise DatasetError(
                    f"{where}: the touch reading at {t} ns has force fields of {have}, the one at "
                    f"{readings[0][0]} ns of {force_pads[0]}"
                )
        fields = [force_array(reading["forces"]) for _, reading in readings]
        if len({f.shape for f in fields}) != 1:
            raise DatasetError(
                f"{where}: the touch readings' force fields differ in resolution: "
                + ", ".join(f"{t} ns {f.shape[1]}x{f.shape[2]}" for (t, _), f in zip(readings, fields))
            )
        out["forces"] = np.stack(fields)
    marker_pads = [list(reading.get("markers", {})) for _, reading in readings]
    if any(marker_pads):
        for (t, _), have in zip(readings, marker_pads):
            if have != marker_pads[0]:
                raise DatasetError(
                    f"{where}: the touch reading at {t} ns has markers of {have}, the one at "
                    f"{readings[0][0]} ns of {marker_pads[0]}"
                )
        flows = [marker_arrays(reading["markers"]) for _, reading in readings]
        out["markers"] = {}
        for pad in marker_pads[0]:
            # A pad's sensor (its one reference image) and so its marker grid are the episode's.
            counts = [len(flow[pad]) for flow in flows]
            if len(set(counts)) != 1:
                raise DatasetError(
                    f"{where}: the touch readings' markers of {pad} differ in count: "
                    + ", ".join(f"{t} ns {n}" for (t, _), n in zip(readings, counts))
                )
            out["markers"][pad] = np.stack([flow[pad] for flow in flows])
    return out


def _state_arrays(
    records: List[Tuple[int, Dict[str, Any]]], joints: Sequence[str], where: str
) -> Dict[str, np.ndarray]:
    """The arrays of a list of ``/episode/state`` records (see :class:`EpisodeDataset`)."""
    out: Dict[str, Any] = {"time_ns": np.array([t for t, _ in records], dtype=np.int64)}
    for key in STATE_POSES:
        out[key] = np.stack([_pose(r, key, t, where) for t, r in records]) if records else np.zeros((0, 4, 4))
    for key in STATE_VECTORS:
        out[key] = (
            np.array([_field(r, key, t, where) for t, r in records], dtype=np.float64).reshape(len(records), 3)
        )
    rows = []
    for t, record in records:
        positions = _field(record, "joint_positions", t, where)
        missing = [j for j in joints if j not in positions]
        if missing:
            raise DatasetError(f"{where}: the state at {t} ns has no joint_positions of {missing}")
        rows.append([float(positions[j]) for j in joints])
    out["joint_positions"] = np.array(rows, dtype=np.float64).reshape(len(records), len(joints))
    return out


def _field(record: Dict[str, Any], key: str, t: int, where: str) -> Any:
    if key not in record:
        raise DatasetError(f"{where}: the /episode/state record at {t} ns has no {key}")
    return record[key]


def _pose(record: Dict[str, Any], key: str, t: int, where: str) -> np.ndarray:
    pose = _field(record, key, t, where)
    try:
        return pose_matrix(pose["position"], pose["orientation"])
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{where}: the /episode/state record at {t} ns: bad {key} ({e})") from e
