"""A DenseFusion-ready view of a vtgen dataset: fixed-size point sets and an RGB crop per sample.

DenseFusion (Wang et al., CVPR 2019) and the visuotactile network built on it take, per sample,
``n`` points of the object's depth cloud, the RGB crop by the object's bounding box with the
indices (``choose``) of those points' pixels in it, and, for the loss, model points in the object
frame and the same points moved by the ground-truth pose. :class:`DenseFusionView` maps every raw
sample of a split to these arrays (plus ``n_t`` tactile points), in numpy; ``vtdata.torch.
DenseFusionDataset`` wraps it for a ``DataLoader``.

>>> view = DenseFusionView("out/tiny", "train", seed=0)
>>> item = view[3]
>>> item["cloud"].shape, item["choose"].shape, item["img"].shape
((1000, 3), (1, 1000), (3, 128, 128))

Sampling is deterministic: sample ``i`` of split ``s`` draws from a generator seeded with
``(seed, s, i)`` only, so the arrays do not depend on the order of access, on ``DataLoader``
workers, or on other samples. See ``datasets/python/README.md`` for the table of keys.
"""

from __future__ import annotations

import hashlib
import math
import numbers
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from .format import MASK_TARGET_OBJECT
from .reader import Dataset, PathLike, Sample

__all__ = [
    "DenseFusionView",
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "N_MODEL_POINTS",
    "N_POINTS",
    "N_TACTILE",
    "N_TACTILE_RANGE",
    "densefusion_sample",
    "sample_surface",
]

#: Default number of depth points per sample (DenseFusion's ``num_points``).
N_POINTS = 1000
#: Default number of tactile points per sample.
N_TACTILE = 1000
#: Allowed numbers of tactile points (inclusive).
N_TACTILE_RANGE = (4, 1000)
#: Default number of model points for the loss (DenseFusion's ``num_pt_mesh_small``).
N_MODEL_POINTS = 500
#: Default side of the square RGB crop, in pixels.
CROP_SIZE = 128
#: Per-channel mean and standard deviation the crop is normalised with (``normalize=True``), as
#: torchvision's ImageNet models expect (applied to colours scaled to [0, 1]).
IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], dtype=np.float32)

# Mask id of the target object when /sample/info does not say (FORMAT.md, "Instance mask ids").
_TARGET_MASK_ID = MASK_TARGET_OBJECT


def _draw(rng: np.random.Generator, count: int, n: int) -> np.ndarray:
    """``n`` indices into ``range(count)`` (``count >= 1``), in random order.

    With ``count >= n`` no index repeats; with fewer, every index appears once and the other
    ``n - count`` are drawn with replacement (so no available point is left out).
    """
    if count >= n:
        return rng.choice(count, size=n, replace=False)
    extra = rng.integers(0, count, size=n - count)
    return rng.permutation(np.concatenate([np.arange(count), extra]))


def sample_surface(
    vertices: np.ndarray, faces: np.ndarray, n: int, rng: np.random.Generator
) -> np.ndarray:
    """``n`` points uniformly distributed over a triangle mesh's surface, ``(n, 3)`` float64.

    Triangles are chosen with probability proportional to their area, points uniformly inside them.
    Vertices alone would not do: a procedural box has 8 corners, so 500 "model points" drawn from
    its vertices would be 8 points repeated. A mesh without (non-degenerate) faces falls back to its
    vertices.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = float(areas.sum())
    if f.shape[0] == 0 or not total > 0.0:
        return v[_draw(rng, v.shape[0], n)]
    tri = rng.choice(f.shape[0], size=n, p=areas / total)
    # Uniform barycentric coordinates: fold the unit square onto the triangle (r1 + r2 <= 1).
    r1, r2 = rng.random(n), rng.random(n)
    fold = r1 + r2 > 1.0
    r1[fold], r2[fold] = 1.0 - r1[fold], 1.0 - r2[fold]
    return a[tri] + r1[:, None] * (b[tri] - a[tri]) + r2[:, None] * (c[tri] - a[tri])


def _streams(
    seed: Union[int, Sequence[int], np.random.SeedSequence], n: int
) -> List[np.random.Generator]:
    """``n`` independent generators derived from ``seed``.

    The children are built like ``SeedSequence.spawn`` does, but without spawning from (and so
    mutating) a ``SeedSequence`` passed in: the same ``seed`` always gives the same streams.
    """
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return [
        np.random.default_rng(
            np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, k), pool_size=ss.pool_size)
        )
        for k in range(n)
    ]


def _resize_bilinear(image: np.ndarray, size: int) -> np.ndarray:
    """Resize ``(h, w, C)`` to ``(size, size, C)`` float32, bilinear with half-pixel centres.

    The convention of ``torch.nn.functional.interpolate(..., align_corners=False)``: output pixel
    ``r`` samples the input at ``(r + 0.5) · h / size − 0.5``, clamped to the image.
    """
    h, w = image.shape[:2]

    def axis(n_in: int) -> Any:
        x = np.clip((np.arange(size) + 0.5) * n_in / size - 0.5, 0.0, n_in - 1)
        i0 = np.floor(x).astype(np.int64)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, (x - i0).astype(np.float32)

    y0, y1, wy = axis(h)
    x0, x1, wx = axis(w)
    src = image.astype(np.float32)
    wx = wx[None, :, None]
    top = src[y0][:, x0] * (1.0 - wx) + src[y0][:, x1] * wx
    bottom = src[y1][:, x0] * (1.0 - wx) + src[y1][:, x1] * wx
    return top * (1.0 - wy[:, None, None]) + bottom * wy[:, None, None]


def densefusion_sample(
    sample: Mapping[str, Any],
    model: Mapping[str, Any],
    seed: Union[int, Sequence[int], np.random.SeedSequence],
    *,
    n_points: int = N_POINTS,
    n_tactile: int = N_TACTILE,
    n_model_points: int = N_MODEL_POINTS,
    crop_size: Optional[int] = CROP_SIZE,
    normalize: bool = True,
) -> Dict[str, Any]:
    """Map one raw sample to DenseFusion's inputs (see :class:`DenseFusionView` for the keys).

    ``sample`` is a :class:`vtdata.Sample` (``rgb``, ``depth``, ``mask``, ``K``,
    ``T_camera_object``, ``info``, ``index`` and, with a robot, ``tactile``), ``model`` the
    sample's object from :meth:`vtdata.Dataset.models`. ``seed`` (anything
    ``numpy.random.SeedSequence`` takes) fixes every random choice; the depth points, the tactile
    points and the model points draw from independent streams of it, so changing e.g.
    ``n_tactile`` does not change the depth points.
    """
    rng_cloud, rng_tactile, rng_model = _streams(seed, 3)
    info = sample["info"]
    target_mask = sample["mask"] == info.get("mask_id", _TARGET_MASK_ID)
    depth_view = _depth_view(
        sample["rgb"], sample["depth"], target_mask, sample["K"], rng_cloud,
        n_points=n_points, crop_size=crop_size, normalize=normalize,
    )

    # --- tactile points (camera frame), resampled to n_tactile ----------------------------------
    touch = sample.get("tactile")
    touch_points = touch["points"] if touch is not None else np.zeros((0, 3), np.float32)
    if len(touch_points) > 0:
        tactile = touch_points[_draw(rng_tactile, len(touch_points), n_tactile)]
    else:
        tactile = np.zeros((n_tactile, 3), dtype=np.float32)
    tactile = np.ascontiguousarray(tactile, dtype=np.float32)

    # --- model points (object frame) and the same points under the ground-truth pose -----------
    T = np.asarray(sample["T_camera_object"], dtype=np.float64)
    points = sample_surface(model["vertices"], model["faces"], n_model_points, rng_model)
    target = points @ T[:3, :3].T + T[:3, 3]

    occlusion = info.get("occlusion", {}).get("level", math.nan)
    return {
        **depth_view,
        "tactile": tactile,
        "tactile_count": np.asarray(len(touch_points), dtype=np.int64),
        "model_points": points.astype(np.float32),
        "target": target.astype(np.float32),
        "R": T[:3, :3].astype(np.float32),
        "t": T[:3, 3].astype(np.float32),
        "object_index": np.asarray(info["object_index"], dtype=np.int64),
        "symmetric": np.asarray(model["info"].get("symmetry", "none") != "none"),
        "occlusion": np.asarray(occlusion, dtype=np.float32),
        "object_id": info["object_id"],
        "index": int(sample["index"]),
    }


def _depth_view(
    rgb: np.ndarray,
    depth: np.ndarray,
    target_mask: np.ndarray,
    K: np.ndarray,
    rng: np.random.Generator,
    *,
    n_points: int,
    crop_size: Optional[int],
    normalize: bool,
) -> Dict[str, np.ndarray]:
    """:func:`densefusion_sample`'s ``cloud``, ``choose``, ``img``, ``bbox`` and ``cloud_count``:
    ``n_points`` random object pixels with a depth, back-projected (OpenCV pinhole), and the RGB
    crop of the object's bounding box they index; zeros when the object is not visible."""
    valid = np.flatnonzero(target_mask & (depth > 0.0))  # row-major flat pixel indices
    width = target_mask.shape[1]
    out_size = (crop_size, crop_size) if crop_size is not None else None
    if valid.size > 0:
        rows, cols = np.nonzero(target_mask)
        rmin, rmax, cmin, cmax = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        pixels = valid[_draw(rng, valid.size, n_points)]
        v, u = np.divmod(pixels, width)
        z = depth.reshape(-1)[pixels].astype(np.float64)
        x = (u - K[0, 2]) * z / K[0, 0]
        y = (v - K[1, 2]) * z / K[1, 1]
        cloud = np.stack([x, y, z], axis=1).astype(np.float32)
        crop = rgb[rmin:rmax, cmin:cmax]
        h, w = crop.shape[:2]
        if out_size is None:
            out_size = (h, w)
            crop = crop.astype(np.float32)
            row, col = v - rmin, u - cmin
        else:
            crop = _resize_bilinear(crop, crop_size)  # type: ignore[arg-type]
            # The resized pixel whose area contains the chosen pixel's centre.
            row = np.minimum((2 * (v - rmin) + 1) * crop_size // (2 * h), crop_size - 1)
            col = np.minimum((2 * (u - cmin) + 1) * crop_size // (2 * w), crop_size - 1)
        choose = (row * out_size[1] + col).astype(np.int64)[None, :]
        bbox = np.array([rmin, rmax, cmin, cmax], dtype=np.int64)
        img = crop / np.float32(255.0)
        if normalize:
            img = (img - IMAGENET_MEAN) / IMAGENET_STD
        img = np.ascontiguousarray(img.transpose(2, 0, 1), dtype=np.float32)
    else:
        # The object is not visible: zeros (cloud_count = 0 tells a training loop to skip it).
        cloud = np.zeros((n_points, 3), dtype=np.float32)
        choose = np.zeros((1, n_points), dtype=np.int64)
        img = np.zeros((3, *(out_size or (1, 1))), dtype=np.float32)
        bbox = np.zeros(4, dtype=np.int64)
    return {
        "cloud": cloud,
        "choose": choose,
        "img": img,
        "bbox": bbox,
        "cloud_count": np.asarray(valid.size, dtype=np.int64),
    }


def _integer(name: str, value: Any, lo: int, hi: Optional[int] = None) -> int:
    """``value`` as an ``int`` in ``lo..=hi``, else a ``ValueError`` naming the option."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not (ok and lo <= value and (hi is None or value <= hi)):
        allowed = f"in {lo}..={hi}" if hi is not None else f">= {lo}"
        raise ValueError(f"{name} must be an integer {allowed}, got {value!r}")
    return int(value)


def _split_key(split: str) -> int:
    # A stable integer for the split name (Python's hash() of a str changes between processes).
    return int.from_bytes(hashlib.sha256(split.encode("utf-8")).digest()[:8], "little")


class DenseFusionView(Sequence[Dict[str, Any]]):
    """One split of a vtgen dataset as DenseFusion inputs; ``view[i]`` is a dict of numpy arrays.

    ``root`` is a dataset folder or an open :class:`vtdata.Dataset` (then ``split`` is ignored).
    Keys of ``view[i]`` (``n = n_points``, ``n_t = n_tactile``, ``M = n_model_points``,
    ``S = crop_size``):

    - ``cloud`` ``(n, 3)`` float32: camera-frame points back-projected from the depth at ``n``
      random pixels of the object mask (id 1) with depth > 0; without replacement when the mask has
      ``n`` such pixels, else every pixel once and the rest drawn with replacement.
    - ``choose`` ``(1, n)`` int64: each point's pixel as an index into the flattened crop
      (``row * S + col``), for gathering per-pixel CNN features as DenseFusion does.
    - ``img`` ``(3, S, S)`` float32: the RGB crop by the mask's bounding box, resized (bilinear) to
      ``S × S``, scaled to [0, 1] and, with ``normalize``, normalised by :data:`IMAGENET_MEAN` /
      :data:`IMAGENET_STD`. ``crop_size=None`` keeps the exact crop ``(3, h, w)`` (then ``choose``
      indexes ``row * w + col`` and batches need ``batch_size=1`` or padding).
    - ``bbox`` ``(4,)`` int64: the crop in the full image, ``[row_min, row_max, col_min, col_max)``.
    - ``cloud_count`` int64: object pixels with depth the points were drawn from; ``0`` when the
      object is not visible, and then ``cloud``, ``choose``, ``img`` and ``bbox`` are zeros.
    - ``tactile`` ``(n_t, 3)`` float32: camera-frame tactile points from ``/tactile/points``,
      resampled like ``cloud``; zeros when the sample has none (no robot, or no touch).
    - ``tactile_count`` int64: the sample's tactile points (``0``: ``tactile`` is zeros).
    - ``model_points`` ``(M, 3)`` float32: points spread uniformly over the model surface (area
      weighted, object frame, metres); ``target`` ``(M, 3)`` float32: the same points moved by
      the ground-truth pose, ``R @ p + t``.
    - ``R`` ``(3, 3)`` and ``t`` ``(3,)`` float32: ``T_camera_object``.
    - ``object_index`` int64, ``symmetric`` bool (``symmetry`` in ``models_info.json`` is not
      ``none``), ``occlusion`` float32 (the paper's occlusion level, NaN if the dataset has none).
    - ``object_id`` str and ``index`` int.

    Scalars are 0-d numpy arrays so that both ``torch``'s default collate and
    ``vtdata.torch.collate`` batch them into tensors. The generator of sample ``i`` is seeded with
    ``(seed, split, i)``: identical arrays for the same seed, whatever the access order or worker.
    For fresh points every epoch, set ``view.seed`` (e.g. ``base + epoch``) before iterating.
    """

    def __init__(
        self,
        root: Union[PathLike, Dataset],
        split: str = "train",
        *,
        n_points: int = N_POINTS,
        n_tactile: int = N_TACTILE,
        n_model_points: int = N_MODEL_POINTS,
        crop_size: Optional[int] = CROP_SIZE,
        normalize: bool = True,
        seed: int = 0,
    ) -> None:
        lo, hi = N_TACTILE_RANGE
        self.n_tactile = _integer("n_tactile", n_tactile, lo, hi)
        self.n_points = _integer("n_points", n_points, 1)
        self.n_model_points = _integer("n_model_points", n_model_points, 1)
        self.crop_size = None if crop_size is None else _integer("crop_size", crop_size, 1)
        self.normalize = bool(normalize)
        self.seed = _integer("seed", seed, 0)
        self.dataset = root if isinstance(root, Dataset) else Dataset(root, split)

    @property
    def split(self) -> str:
        return self.dataset.split

    def __len__(self) -> int:
        return len(self.dataset)

    def seed_of(self, index: int) -> np.random.SeedSequence:
        """The seed of sample ``index``'s random choices (a function of seed, split, index only)."""
        index = range(len(self))[index]  # normalises negative indices, IndexError past the end
        return np.random.SeedSequence([self.seed, _split_key(self.split), index])

    def __getitem__(self, index: int) -> Dict[str, Any]:  # type: ignore[override]
        if isinstance(index, slice):
            raise TypeError("DenseFusionView indices must be integers, not slices")
        return self.convert(self.dataset[index])

    def convert(self, sample: Sample) -> Dict[str, Any]:
        """The DenseFusion arrays of a raw sample of this view's split."""
        model = self.dataset.models()[sample["info"]["object_id"]]
        return densefusion_sample(
            sample,
            model,
            self.seed_of(sample["index"]),
            n_points=self.n_points,
            n_tactile=self.n_tactile,
            n_model_points=self.n_model_points,
            crop_size=self.crop_size,
            normalize=self.normalize,
        )

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}({self.dataset!r}, n_points={self.n_points}, "
            f"n_tactile={self.n_tactile}, n_model_points={self.n_model_points}, "
            f"crop_size={self.crop_size}, normalize={self.normalize}, seed={self.seed})"
        )
