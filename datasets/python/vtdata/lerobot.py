"""Export a vtgen dataset as a LeRobotDataset v3.0 (``vtgen export lerobot``; docs/data.md, "LeRobot export").

>>> from vtdata.lerobot import export_lerobot
>>> export_lerobot("out/tiny-episode", "out/tiny-episode-lerobot", repo_id="vtgen/tiny-episode")

The dataset is written by LeRobot's own writer (``LeRobotDataset.create``, ``add_frame``,
``save_episode``, ``finalize``), so its parquet files, videos and metadata are what LeRobot
writes and reads. Every split goes into one LeRobot dataset, train episodes first; ``meta/vtgen.json``
says which episodes are in which split, and carries the streams' native rates, the alignment rule,
the camera and tactile calibrations and the units.

**Time.** A LeRobot dataset has one rate (``fps``, an integer) and ``timestamp = frame_index / fps``.
vtgen's streams run at their own rates, each a whole number of physics steps (FORMAT.md,
"Episodes"). Exported frame ``k`` of an episode is the simulated instant of physics step ``k * p``,
where ``p = physics_hz / fps`` must be a whole number of steps (the default fps, the camera's
rounded rate, gives the camera period). Each stream's value at that instant is its latest reading
at or before it (FORMAT.md's alignment rule). The exact simulated time is ``vtgen.time_s``; the
nominal ``timestamp`` differs from it by the rounding of the physics rate (30 Hz nominal for a
29.99976 Hz camera: 0.27 µs per frame). A snapshot dataset is exported as one-frame episodes, one
per sample, at a nominal :data:`SNAPSHOT_FPS` (FORMAT.md's 10 Hz sample timeline).

Run as ``python -m vtdata.lerobot DATASET --out DIR``; user errors (no dataset, an out folder that
is not empty, an fps that is not a whole number of physics steps, LeRobot not installed) exit with
status 2 and one line naming the file or option.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import shutil
import sys
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from .errors import DatasetError
from .format import MANIFEST_FILE
from .reader import Dataset, PathLike, Sample

#: The pip lines that make LeRobot importable next to a newer torch (LeRobot 0.4.4 pins
#: torch < 2.11; its dataset code runs on newer ones): vtdata's ``lerobot`` extra, then LeRobot
#: without its pins. Decoding the videos needs FFmpeg's shared libraries for torchcodec
#: (``scripts/system-deps --lerobot``).
LEROBOT_PIP = 'pip install -e "datasets/python[lerobot]" && pip install --no-deps "lerobot==0.4.4"'
#: The LeRobot version the export was written and tested with.
LEROBOT_VERSION = "0.4.4"
#: The nominal rate of a snapshot dataset's one-frame episodes: FORMAT.md's sample timeline
#: (``log_time = index * 100 ms``).
SNAPSHOT_FPS = 10
#: LeRobot's default video codec (AV1, SVT-AV1 encoder, yuv420p).
DEFAULT_VCODEC = "libsvtav1"
#: ``meta/vtgen.json``: what LeRobot's metadata has no place for.
META_FILE = "meta/vtgen.json"
#: The lossless per-pixel arrays: their LeRobot statistics are over all pixels (per pad for the
#: pads' depth), as LeRobot's per-channel image statistics, not per pixel (which would put
#: H x W numbers per statistic into meta/stats.json and every episode's metadata).
PIXEL_ARRAYS = ("observation.depth", "observation.depth_noisy", "observation.mask", "observation.tactile.depth")
POSE_NAMES = ["x", "y", "z", "qx", "qy", "qz", "qw"]


class ExportError(RuntimeError):
    """A user error: the message names the file, option or package."""


# --- LeRobot ---------------------------------------------------------------------------------


def _import_lerobot() -> Any:
    """``lerobot.datasets.lerobot_dataset``, or :class:`ExportError` with the pip line."""
    try:
        from lerobot.datasets import lerobot_dataset
    except ImportError as e:
        raise ExportError(
            f"LeRobot is not importable by {sys.executable} ({e}); install it (without its torch pin) with: "
            f"{LEROBOT_PIP}"
        ) from None
    return lerobot_dataset


def _pixel_stats(data: np.ndarray, per_first_axis: bool) -> Dict[str, np.ndarray]:
    """LeRobot's statistics keys (min, max, mean, std, count, q01…q99) of a ``(N, ...)`` array over
    its finite values: over everything (shape ``(1,) * (ndim - 1)``), or per index of its second
    axis (``per_first_axis``: a pad's depth, shape ``(P, 1, 1)``)."""
    x = np.asarray(data, dtype=np.float64)
    x = np.where(np.isfinite(x), x, np.nan)
    if per_first_axis:
        axes = (0,) + tuple(range(2, x.ndim))
        shape = (x.shape[1],) + (1,) * (x.ndim - 2)
    else:
        axes = tuple(range(x.ndim))
        shape = (1,) * (x.ndim - 1)
    flat = np.moveaxis(x, 1, 0).reshape(x.shape[1], -1) if per_first_axis else x.reshape(1, -1)
    with np.errstate(all="ignore"), _quiet_nan_warnings():
        stats = {
            "min": np.nanmin(x, axis=axes),
            "max": np.nanmax(x, axis=axes),
            "mean": np.nanmean(x, axis=axes),
            "std": np.nanstd(x, axis=axes),
        }
        for q in (1, 10, 50, 90, 99):
            stats[f"q{q:02d}"] = np.nanquantile(flat, q / 100.0, axis=1)
    # A pad that never saw a surface has no finite value: 0 keeps the JSON standard.
    out = {k: np.nan_to_num(np.asarray(v, dtype=np.float64).reshape(shape)) for k, v in stats.items()}
    out["count"] = np.array([x.shape[0]])
    return out


@contextlib.contextmanager
def _quiet_nan_warnings() -> Iterator[None]:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


@contextlib.contextmanager
def _pixel_array_stats(module: Any) -> Iterator[None]:
    """Within: LeRobot's ``save_episode`` computes the statistics of :data:`PIXEL_ARRAYS` with
    :func:`_pixel_stats`, every other feature's with its own ``compute_episode_stats``."""
    original = module.compute_episode_stats

    def compute(episode_data: Dict[str, Any], features: Dict[str, Any], *args: Any, **kwargs: Any) -> Dict[str, Any]:
        ours = {k: v for k, v in episode_data.items() if k in PIXEL_ARRAYS}
        rest = {k: v for k, v in episode_data.items() if k not in PIXEL_ARRAYS}
        stats = original(rest, features, *args, **kwargs)
        for key, data in ours.items():
            stats[key] = _pixel_stats(np.asarray(data), per_first_axis=key == "observation.tactile.depth")
        return stats

    module.compute_episode_stats = compute
    try:
        yield
    finally:
        module.compute_episode_stats = original


def _quiet_encoders() -> None:
    """SVT-AV1's and FFmpeg's info lines (a banner per video, "moving the moov atom") say
    nothing about the export: errors only. The encoder workers inherit the environment."""
    import os

    os.environ.setdefault("SVT_LOG", "1")
    try:
        import av.logging

        av.logging.set_level(av.logging.ERROR)
    except (ImportError, AttributeError):
        pass


# --- the source dataset ----------------------------------------------------------------------


def _record_pose(pose: Dict[str, Sequence[float]], where: str) -> np.ndarray:
    """A FORMAT.md pose ``{"position", "orientation"}`` as ``(x, y, z, qx, qy, qz, qw)`` float64."""
    try:
        p = [float(v) for v in pose["position"]]
        q = [float(v) for v in pose["orientation"]]
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{where}: bad pose {pose!r} ({e})") from None
    if len(p) != 3 or len(q) != 4:
        raise DatasetError(f"{where}: bad pose {pose!r}")
    return np.array(p + q, dtype=np.float64)


class _Source:
    """The splits of a vtgen dataset that have samples, in manifest order (train first)."""

    def __init__(self, root: Path) -> None:
        if not root.exists():
            raise ExportError(f"{root}: no such dataset folder")
        if not (root / MANIFEST_FILE).is_file():
            raise ExportError(f"{root}: not a vtgen dataset (no {MANIFEST_FILE})")
        self.root = root
        try:
            self.manifest = json.loads((root / MANIFEST_FILE).read_text())
        except (OSError, ValueError) as e:
            raise ExportError(f"{root / MANIFEST_FILE}: cannot read it ({e})") from None
        splits = self.manifest.get("splits")
        if not isinstance(splits, dict):
            raise ExportError(f"{root / MANIFEST_FILE}: no 'splits'")
        order = sorted(splits, key=lambda s: (s != "train", s != "test", s))
        self.splits: Dict[str, Dataset] = {}
        for split in order:
            ds = Dataset(root, split)
            if len(ds):
                self.splits[split] = ds
        if not self.splits:
            raise ExportError(f"{root}: the dataset has no written samples (see {MANIFEST_FILE})")
        kinds = {split: ds.is_episodic for split, ds in self.splits.items()}
        if len(set(kinds.values())) != 1:
            raise ExportError(f"{root}: some splits are episodes and some snapshots: {kinds}")
        self.episodic = next(iter(kinds.values()))
        try:
            self.config = json.loads((root / "config.json").read_text())
        except (OSError, ValueError):
            self.config = {}
        self.robot_type: Optional[str] = None
        robot_yaml = root / "robot" / "meshes.json"
        if robot_yaml.is_file():
            try:
                self.robot_type = str(json.loads(robot_yaml.read_text()).get("name") or "") or None
            except (OSError, ValueError):
                self.robot_type = None


# --- frames ----------------------------------------------------------------------------------


def _latest(entries: List[Tuple[int, Any]], step: int, dt_ns: float) -> Tuple[int, Any]:
    """The entry of ``entries`` (``(time_ns, value)``, ascending) at or before physics step
    ``step`` (compared in steps, so the log times' rounding cannot move a reading across it)."""
    best: Optional[Tuple[int, Any]] = None
    for t, value in entries:
        if round(t / dt_ns) <= step:
            best = (t, value)
        else:
            break
    if best is None:
        raise DatasetError(f"no reading at or before step {step}")
    return best


class _Layout:
    """The exported features, from a dataset's first sample."""

    def __init__(self, source: _Source, first: Sample, joint_names: List[str]) -> None:
        self.episodic = source.episodic
        self.height, self.width = first["rgb"].shape[:2]
        self.has_noisy = "depth_noisy" in first
        self.joint_names = joint_names
        tactile = first.get("tactile")
        self.pads: List[str] = list(tactile["pads"]) if tactile else []
        self.pad_depth_shape: Tuple[int, ...] = tuple(tactile["depth"].shape) if tactile else ()
        self.optical: Dict[str, Tuple[int, ...]] = {
            pad: tuple(img.shape) for pad, img in first.get("tactile_images", {}).items()
        }
        self.has_palm = "T_world_palm" in first["info"]
        #: The columns of ``vtgen.time_s``: the frame's simulated time and each stream's reading's.
        self.time_names = ["frame", "camera"]
        if self.episodic:
            self.time_names += (["tactile"] if self.pads else []) + ["state"]

    def features(self) -> Dict[str, Dict[str, Any]]:
        video = ["height", "width", "channels"]
        f: Dict[str, Dict[str, Any]] = {
            "observation.images.rgb": {"dtype": "video", "shape": (self.height, self.width, 3), "names": video},
            "observation.depth": {"dtype": "float32", "shape": (self.height, self.width), "names": ["height", "width"]},
            "observation.mask": {"dtype": "uint8", "shape": (self.height, self.width), "names": ["height", "width"]},
        }
        if self.has_noisy:
            f["observation.depth_noisy"] = {
                "dtype": "float32",
                "shape": (self.height, self.width),
                "names": ["height", "width"],
            }
        for pad, shape in self.optical.items():
            f[f"observation.images.tactile_{pad}"] = {"dtype": "video", "shape": shape, "names": video}
            f[f"observation.images.tactile_{pad}_reference"] = {"dtype": "video", "shape": shape, "names": video}
        if self.pads:
            f["observation.tactile.depth"] = {
                "dtype": "float32",
                "shape": self.pad_depth_shape,
                "names": ["pad", "height", "width"],
            }
        if self.joint_names:
            f["observation.state"] = {"dtype": "float32", "shape": (len(self.joint_names),), "names": self.joint_names}
            if self.episodic:
                f["action"] = {"dtype": "float32", "shape": (len(self.joint_names),), "names": self.joint_names}
        f["observation.camera.K"] = {"dtype": "float64", "shape": (3, 3), "names": ["row", "column"]}
        poses = ["T_camera_object", "T_world_object", "T_world_camera"] + (["T_world_palm"] if self.has_palm else [])
        for key in poses:
            f[f"ground_truth.{key}"] = {"dtype": "float64", "shape": (7,), "names": POSE_NAMES}
        if self.episodic:
            for key in ("linear_velocity", "angular_velocity"):
                f[f"ground_truth.{key}"] = {"dtype": "float64", "shape": (3,), "names": ["x", "y", "z"]}
        # LeRobot's one-number features (shape (1,)) do not encode on numpy >= 2.4: the times and
        # indices are vectors.
        f["vtgen.time_s"] = {"dtype": "float64", "shape": (len(self.time_names),), "names": self.time_names}
        f["vtgen.index"] = {"dtype": "int64", "shape": (2,), "names": ["camera_frame", "sample_index"]}
        return f

    def frame(
        self,
        sample: Sample,
        where: str,
        time_ns: int,
        touch: Optional[Tuple[int, Dict[str, Any]]],
        state: Optional[Tuple[int, Dict[str, Any]]],
        camera_frame: int,
    ) -> Dict[str, Any]:
        """One LeRobot frame (without ``task`` and ``action``) from a vtdata sample and the touch
        reading and state aligned to its instant (episodes), or the sample's own (snapshots)."""
        out: Dict[str, Any] = {
            "observation.images.rgb": sample["rgb"],
            "observation.depth": _check(sample["depth"], (self.height, self.width), np.float32, where, "depth"),
            "observation.mask": _check(sample["mask"], (self.height, self.width), np.uint8, where, "mask"),
            "observation.camera.K": np.asarray(sample["K"], dtype=np.float64),
            "ground_truth.T_world_camera": _record_pose(sample["info"]["T_world_camera"], where),
            "vtgen.index": np.array([camera_frame, int(sample["index"])], dtype=np.int64),
        }
        times = {"frame": time_ns, "camera": sample["episode"]["time_ns"] if "episode" in sample else 0}
        if self.has_noisy:
            out["observation.depth_noisy"] = _check(
                sample["depth_noisy"], (self.height, self.width), np.float32, where, "depth_noisy"
            )
        if self.pads:
            t_touch, reading = touch if touch is not None else (0, sample["tactile"])
            if list(reading["pads"]) != self.pads:
                raise DatasetError(f"{where}: pads {reading['pads']}, the dataset's first sample has {self.pads}")
            out["observation.tactile.depth"] = _check(
                reading["depth"], self.pad_depth_shape, np.float32, where, "tactile depth"
            )
            images = reading.get("images", sample.get("tactile_images", {})) if touch else sample.get("tactile_images", {})
            refs = sample.get("tactile_references", {})
            for pad, shape in self.optical.items():
                if pad not in images or pad not in refs:
                    raise DatasetError(f"{where}: no optical image (or reference) of pad {pad}")
                out[f"observation.images.tactile_{pad}"] = _check(images[pad], shape, np.uint8, where, f"{pad} image")
                out[f"observation.images.tactile_{pad}_reference"] = _check(
                    refs[pad], shape, np.uint8, where, f"{pad} reference"
                )
            times["tactile"] = t_touch
        info = sample["info"]
        if state is not None:
            t_state, record = state
            joints = record.get("joint_positions", {})
            for key in ("T_camera_object", "T_world_object", "T_world_palm"):
                if key == "T_world_palm" and not self.has_palm:
                    continue
                if key not in record:
                    raise DatasetError(f"{where}: the /episode/state record at {t_state} ns has no {key}")
                out[f"ground_truth.{key}"] = _record_pose(record[key], where)
            for key in ("linear_velocity", "angular_velocity"):
                out[f"ground_truth.{key}"] = np.asarray(record.get(key, [np.nan] * 3), dtype=np.float64).reshape(3)
            times["state"] = t_state
        else:
            joints = info.get("joint_positions", {})
            out["ground_truth.T_camera_object"] = _record_pose(info["T_camera_object"], where)
            out["ground_truth.T_world_object"] = _world_object(sample)
            if self.has_palm:
                out["ground_truth.T_world_palm"] = _record_pose(info["T_world_palm"], where)
        out["vtgen.time_s"] = np.array([times[name] / 1e9 for name in self.time_names], dtype=np.float64)
        if self.joint_names:
            missing = [j for j in self.joint_names if j not in joints]
            if missing:
                raise DatasetError(f"{where}: no joint_positions of {missing}")
            out["observation.state"] = np.array([joints[j] for j in self.joint_names], dtype=np.float32)
        return out


def _world_object(sample: Sample) -> np.ndarray:
    """``T_world_object`` of a snapshot sample as ``(x, y, z, qx, qy, qz, qw)``: ``/tf``'s, which
    the reader gives as a matrix; its quaternion is recovered from the matrix (Shepperd's method,
    w >= 0)."""
    T = np.asarray(sample["T_world_object"], dtype=np.float64)
    return np.concatenate([T[:3, 3], _quaternion(T[:3, :3])])


def _quaternion(R: np.ndarray) -> np.ndarray:
    """The unit quaternion ``(x, y, z, w)``, ``w >= 0``, of a rotation matrix."""
    m = R
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    v = np.array(q, dtype=np.float64)
    v /= np.linalg.norm(v)
    return -v if v[3] < 0 else v


def _check(array: Any, shape: Tuple[int, ...], dtype: Any, where: str, what: str) -> np.ndarray:
    a = np.asarray(array)
    if a.shape != tuple(shape) or a.dtype != dtype:
        raise DatasetError(
            f"{where}: {what} is {a.dtype} {a.shape}, the dataset's first sample has {np.dtype(dtype)} {tuple(shape)}"
        )
    return a


# --- the export ------------------------------------------------------------------------------


def _frame_period_steps(episode: Dict[str, Any], fps: int, where: str) -> int:
    """Physics steps per exported frame at ``fps``: a whole number, as vtgen's own rates."""
    physics_hz = float(episode["physics_hz"])
    steps = physics_hz / fps
    p = round(steps)
    if p < 1 or abs(steps - p) > 1e-3 * steps:
        raise ExportError(
            f"--fps {fps}: the physics runs at {physics_hz:.6g} Hz ({where}), so a frame would be {steps:.4g} "
            f"physics steps; choose an fps that is a whole number of steps (e.g. "
            f"{', '.join(str(round(physics_hz / k)) for k in (int(episode['camera_period_steps']), int(episode['tactile_period_steps']), 1))})"
        )
    return p


def _episode_frames(
    ds: Dataset, episode: Dict[str, Any], p: int, layout: _Layout, where: str
) -> Iterator[Dict[str, Any]]:
    """The exported frames of one episode at ``p`` physics steps per frame."""
    c = int(episode["camera_period_steps"])
    frames = int(episode["frames"])
    dt_ns = 1e9 / float(episode["physics_hz"])
    last_step = (frames - 1) * c
    cache: Dict[int, Sample] = {}
    for k in range(last_step // p + 1):
        step = k * p
        j = step // c
        if j not in cache:
            cache.clear()
            cache[j] = ds[int(episode["first_sample"]) + j]
        sample = cache[j]
        frame_where = f"{where} frame {j}"
        streams = sample["episode"]
        state = _latest(list(streams["states"]), step, dt_ns) if streams["states"] else None
        if state is None:
            raise DatasetError(f"{frame_where}: no /episode/state record at or before step {step}")
        touch = None
        if layout.pads:
            own = dict(sample["tactile"])
            own["images"] = sample.get("tactile_images", {})
            touch = _latest([(streams["time_ns"], own)] + list(streams["tactile"]), step, dt_ns)
        time_ns = round(step * dt_ns)
        yield layout.frame(sample, frame_where, time_ns, touch, state, j)


def export_lerobot(
    root: PathLike,
    out: PathLike,
    *,
    repo_id: Optional[str] = None,
    fps: Optional[int] = None,
    vcodec: str = DEFAULT_VCODEC,
    progress: Optional[Callable[[str], None]] = None,
) -> Dict[str, Any]:
    """Write the vtgen dataset at ``root`` as a LeRobotDataset v3.0 in ``out`` (new or empty).

    Returns a summary: ``episodes``, ``frames``, ``fps``, ``splits`` (``{split: [episode
    indices]}``). Raises :class:`ExportError` for a user error (the message names the file or
    option) and :class:`vtdata.DatasetError` for a damaged dataset.
    """
    module = _import_lerobot()
    LeRobotDataset = module.LeRobotDataset
    root = Path(root)
    out = Path(out)
    if out.exists():
        if not out.is_dir() or any(out.iterdir()):
            raise ExportError(f"{out} exists and is not an empty folder: choose a new folder for the export")
    source = _Source(root)
    repo_id = repo_id or f"vtgen/{root.resolve().name}"
    if repo_id.count("/") != 1 or not all(repo_id.split("/")):
        raise ExportError(f"--repo-id {repo_id!r}: LeRobot wants <owner>/<name>")
    first_split, first_ds = next(iter(source.splits.items()))
    first = first_ds[0]
    joint_names: List[str] = sorted(first["info"].get("joint_positions", {}))
    if source.episodic:
        states = first["episode"]["states"]
        if not states:
            raise DatasetError(f"{first_ds.episodes[0]['shard']}: frame 0 has no /episode/state record")
        joint_names = list(states[0][1].get("joint_positions", {}))
    layout = _Layout(source, first, joint_names)
    if source.episodic:
        episode0 = first_ds.episodes[0]
        fps = int(fps) if fps is not None else round(float(episode0["camera_hz"]))
        if fps < 1:
            raise ExportError(f"--fps {fps}: must be at least 1")
        period = _frame_period_steps(episode0, fps, episode0["shard"])
    else:
        fps = int(fps) if fps is not None else SNAPSHOT_FPS
        if fps < 1:
            raise ExportError(f"--fps {fps}: must be at least 1")
        period = 0

    if out.exists():
        out.rmdir()  # LeRobot creates the folder itself
    _quiet_encoders()
    features = layout.features()
    writer = LeRobotDataset.create(
        repo_id=repo_id,
        fps=fps,
        features=features,
        root=out,
        robot_type=source.robot_type,
        use_videos=True,
        vcodec=vcodec,
    )
    episodes_meta: List[Dict[str, Any]] = []
    splits: Dict[str, List[int]] = {}
    frames_total = 0
    with _pixel_array_stats(module):
        for split, ds in source.splits.items():
            splits[split] = []
            units = ds.episodes if source.episodic else [None] * len(ds)
            for u, episode in enumerate(units):
                index = len(episodes_meta)
                if episode is not None:
                    where = f"{episode['shard']}"
                    p = _frame_period_steps(episode, fps, where)
                    frames = list(_episode_frames(ds, episode, p, layout, where))
                    sample0 = ds[int(episode["first_sample"])]
                    object_id = str(episode["object_id"])
                    extra = {
                        "object_id": object_id,
                        "trajectory": int(episode["trajectory"]),
                        "shard": Path(episode["shard"]).relative_to(root).as_posix(),
                        "first_sample": int(episode["first_sample"]),
                        "vtgen_frames": int(episode["frames"]),
                        "duration_s": float(episode["duration_s"]),
                    }
                else:
                    sample0 = ds[u]
                    shard, _ = ds.location(u)
                    where = f"{shard} sample {u}"
                    frames = [layout.frame(sample0, where, 0, None, None, 0)]
                    object_id = str(sample0["info"].get("object_id"))
                    extra = {
                        "object_id": object_id,
                        "trajectory": int(sample0["info"].get("trajectory", -1)),
                        "instance": int(sample0["info"].get("instance", -1)),
                        "shard": Path(shard).relative_to(root).as_posix(),
                        "sample_index": u,
                    }
                task = f"hold {object_id}"
                for k, frame in enumerate(frames):
                    if "action" in features:
                        nxt = frames[min(k + 1, len(frames) - 1)]
                        frame["action"] = nxt["observation.state"]
                    frame["task"] = task
                    writer.add_frame(frame)
                writer.save_episode()
                frames_total += len(frames)
                episodes_meta.append(
                    {
                        "episode_index": index,
                        "split": split,
                        "frames": len(frames),
                        "task": task,
                        **extra,
                        "camera": _camera_meta(sample0, layout),
                        **({"tactile": _tactile_meta(sample0)} if layout.pads else {}),
                    }
                )
                splits[split].append(index)
                if progress:
                    progress(f"episode {index} ({split} {extra['shard']}): {len(frames)} frames")
    writer.finalize()
    # LeRobot leaves the empty folders of the frames it encoded.
    images = out / "images"
    if images.is_dir() and not any(p.is_file() for p in images.rglob("*")):
        shutil.rmtree(images)
    _write_meta(out, source, layout, fps, period, splits, episodes_meta, vcodec)
    return {"episodes": len(episodes_meta), "frames": frames_total, "fps": fps, "splits": splits}


def _camera_meta(sample: Sample, layout: _Layout) -> Dict[str, Any]:
    K = np.asarray(sample["K"], dtype=np.float64)
    return {
        "width": layout.width,
        "height": layout.height,
        "K": K.reshape(-1).tolist(),
        "distortion_model": "plumb_bob",
        "D": [0.0] * 5,
        "frame": "OpenCV: x right, y down, z forward",
        "T_world_camera": _record_pose(sample["info"]["T_world_camera"], "camera").tolist(),
    }


def _tactile_meta(sample: Sample) -> Dict[str, Any]:
    tactile = dict(sample["info"].get("tactile", {}))
    # Per-instant entries are the frames' (points per pad, force fields), not a calibration.
    for key in ("points", "forces", "hand_force_n"):
        tactile.pop(key, None)
    tactile["pad_order"] = list(sample["tactile"]["pads"])
    return tactile


FEATURE_DOCS = {
    "observation.images.rgb": "/camera/rgb: the main camera's sRGB colour (video)",
    "observation.depth": "/camera/depth: z-depth along the camera's z axis, metres, 0 = no surface (float32, exact)",
    "observation.depth_noisy": "/camera/depth_noisy: the depth as an RGB-D sensor reads it, metres, 0 = no reading",
    "observation.mask": "/camera/mask: instance ids (0 background, 1 the object, FORMAT.md 'Instance mask ids')",
    "observation.images.tactile_<pad>": "/tactile/<pad>/image: the optical pad's image, linear 8-bit levels (video)",
    "observation.images.tactile_<pad>_reference": "/tactile/<pad>/reference: the same sensor untouched, no noise (video)",
    "observation.tactile.depth": "/tactile/<pad>/depth of every pad, pad order: z-depth from the pad plane, metres, +inf = no surface",
    "observation.state": "joint positions (rad; m for a prismatic joint), the joints that move on their own",
    "action": "the joint positions of the next exported frame (the last frame: its own); vtgen records no commands",
    "observation.camera.K": "camera intrinsics, row-major 3x3 (OpenCV pinhole, no distortion)",
    "ground_truth.T_camera_object": "the object's pose in the camera frame (OpenCV): x, y, z (m), qx, qy, qz, qw",
    "ground_truth.T_world_object": "the object's pose in the world frame (z up)",
    "ground_truth.T_world_camera": "the camera's pose in the world frame",
    "ground_truth.T_world_palm": "the grasp frame's pose in the world frame",
    "ground_truth.linear_velocity": "the object's linear velocity, world frame, m/s, over the physics step before",
    "ground_truth.angular_velocity": "the object's angular velocity, world frame, rad/s (a rotation vector's rate)",
    "vtgen.time_s": "simulated times since the episode's start, s: the frame's exact one (timestamp = frame_index / fps "
    "is nominal), then those of the camera frame, touch reading and state record it took (0 in snapshots)",
    "vtgen.index": "the camera frame used: its index in the vtgen episode (0 for a snapshot) and its sample index "
    "in its vtgen split (vtdata.Dataset index)",
}


def _write_meta(
    out: Path,
    source: _Source,
    layout: _Layout,
    fps: int,
    period: int,
    splits: Dict[str, List[int]],
    episodes: List[Dict[str, Any]],
    vcodec: str,
) -> None:
    features = layout.features()
    docs = {}
    for key in features:
        generic = key
        for pad in layout.optical:
            generic = generic.replace(f"tactile_{pad}", "tactile_<pad>")
        docs[key] = FEATURE_DOCS.get(generic, "")
    meta: Dict[str, Any] = {
        "format": "vtgen-lerobot",
        "format_version": 1,
        "lerobot_version": LEROBOT_VERSION,
        "source": {
            "generator": source.manifest.get("generator"),
            "format_version": source.manifest.get("format_version"),
            "seed": source.manifest.get("seed"),
            "config_sha256": source.manifest.get("config_sha256"),
        },
        "kind": "episodes" if source.episodic else "snapshots",
        "fps": fps,
        "units": "metres, radians, seconds; quaternions (x, y, z, w); camera frame OpenCV; world z up",
        "vcodec": vcodec,
        "splits": splits,
        "joint_names": layout.joint_names,
        "pads": layout.pads,
        "optical_pads": list(layout.optical),
        "features": docs,
        "episodes": episodes,
    }
    if source.episodic:
        e0 = next(iter(source.splits.values())).episodes[0]
        meta["physics_hz"] = float(e0["physics_hz"])
        meta["frame_period_steps"] = period
        meta["rates"] = {
            name: {"hz": float(e0[f"{name}_hz"]), "period_steps": int(e0[f"{name}_period_steps"])}
            for name in ("camera", "tactile", "state")
        }
        meta["rates"]["export"] = {"hz": float(e0["physics_hz"]) / period, "period_steps": period}
        meta["alignment"] = (
            "exported frame k is the simulated instant of physics step k * frame_period_steps; each stream "
            "(camera, touch, state) gives its latest reading at or before that instant (FORMAT.md, Episodes); "
            "timestamp = k / fps is nominal, vtgen.time_s the exact simulated time"
        )
    else:
        meta["alignment"] = (
            f"one episode per vtgen sample (a snapshot), one frame at timestamp 0; fps {fps} is nominal "
            f"(vtgen's sample timeline)"
        )
    (out / META_FILE).write_text(json.dumps(meta, indent=2) + "\n")
    info_path = out / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    # LeRobot's own key for splits: "start:end" episode ranges (the splits are contiguous).
    info["splits"] = {s: f"{ids[0]}:{ids[-1] + 1}" for s, ids in splits.items() if ids}
    info_path.write_text(json.dumps(info, indent=4) + "\n")


# --- command line ----------------------------------------------------------------------------


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m vtdata.lerobot",
        description="Export a vtgen dataset as a LeRobotDataset v3.0 (docs/data.md, \"LeRobot export\").",
    )
    parser.add_argument("dataset", help="the vtgen dataset folder (with manifest.json)")
    parser.add_argument("--out", required=True, help="a new (or empty) folder for the LeRobot dataset")
    parser.add_argument("--repo-id", default=None, help="LeRobot repo id <owner>/<name> (default vtgen/<folder name>)")
    parser.add_argument(
        "--fps",
        type=int,
        default=None,
        help="frames per second: a whole number of physics steps (default: the camera's rate; snapshots 10)",
    )
    parser.add_argument("--vcodec", default=DEFAULT_VCODEC, help="video codec (LeRobot's: libsvtav1, h264, hevc)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    if args.quiet:
        logging.disable(logging.WARNING)
        try:
            import datasets

            datasets.disable_progress_bars()
        except ImportError:
            pass
    progress = None if args.quiet else (lambda line: print(line, file=sys.stderr))
    try:
        summary = export_lerobot(
            args.dataset, args.out, repo_id=args.repo_id, fps=args.fps, vcodec=args.vcodec, progress=progress
        )
    except (ExportError, DatasetError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    splits = ", ".join(f"{s} {len(ids)}" for s, ids in summary["splits"].items())
    print(
        f"wrote {args.out}: {summary['episodes']} episodes ({splits}), {summary['frames']} frames at "
        f"{summary['fps']} fps (LeRobotDataset v3.0)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
