"""PyTorch wrapper for vtgen datasets (requires ``pip install vtdata[torch]``).

>>> from torch.utils.data import DataLoader
>>> from vtdata.torch import TorchDataset, collate
>>> loader = DataLoader(TorchDataset(root, "train"), batch_size=8, num_workers=4,
...                     shuffle=True, collate_fn=collate)
>>> batch = next(iter(loader))
>>> batch["rgb"].shape          # (8, H, W, 3) uint8
>>> batch["info"][0]["object_id"]
>>> batch["tactile_images"]["left"].shape   # (8, H, W, 3) uint8, with optical tactile sensors
>>> batch["forces"].shape       # (8, P, R, R, 4) float32, with force fields (pressure, shear, slip)
>>> batch["markers"]["left"].shape  # (8, N, 4) float32, with marker flow (x, y, rest_x, rest_y)

``TorchDataset`` is safe with ``num_workers > 0`` under both ``fork`` and ``spawn``: the wrapped
:class:`vtdata.Dataset` pickles without file handles and opens shard files lazily in each worker.

``EpisodeTorchDataset`` is :class:`vtdata.EpisodeDataset` (windows of consecutive camera frames of an
episode dataset) as tensors; the default collate batches its default streams, and so does
:func:`collate`:

>>> loader = DataLoader(EpisodeTorchDataset(root, "train", window=4, stride=2), batch_size=8)
>>> batch = next(iter(loader))
>>> batch["rgb"].shape, batch["state"]["T_world_object"].shape
(torch.Size([8, 4, H, W, 3]), torch.Size([8, 4, 4, 4]))

``DenseFusionDataset`` is the DenseFusion-ready view (:class:`vtdata.densefusion.DenseFusionView`)
as tensors; its samples all have the same shapes, so the default collate batches them:

>>> loader = DataLoader(DenseFusionDataset(root, "train", seed=0), batch_size=8, num_workers=2)
>>> batch = next(iter(loader))
>>> batch["cloud"].shape, batch["choose"].shape, batch["img"].shape
(torch.Size([8, 1000, 3]), torch.Size([8, 1, 1000]), torch.Size([8, 3, 128, 128]))
"""

from __future__ import annotations

import os
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np
import torch
from torch.utils.data import Dataset as _TorchDataset

from .densefusion import DenseFusionView
from .decoders import FORCE_CHANNELS, MARKER_CHANNELS, force_array, marker_arrays
from .episodes import DEFAULT_STREAMS, EpisodeDataset
from .reader import Dataset

__all__ = [
    "DenseFusionDataset",
    "EpisodeTorchDataset",
    "FORCE_CHANNELS",
    "MARKER_CHANNELS",
    "PAD_IMAGE_KEYS",
    "TorchDataset",
    "collate",
    "to_tensors",
]

TensorSample = Dict[str, Any]

#: The sample keys whose value is a ``{pad: (H, W, 3) uint8 array}`` dict (optical tactile images);
#: :func:`to_tensors` converts the arrays inside them too.
PAD_IMAGE_KEYS = ("tactile_images", "tactile_references")


def to_tensors(sample: Mapping[str, Any]) -> TensorSample:
    """Convert every numpy array of a sample into a ``torch.Tensor`` (same dtype, same shape).

    ``rgb`` stays ``(H, W, 3)`` uint8 (no channel reordering, no scaling), ``depth`` ``(H, W)``
    float32, ``mask`` ``(H, W)`` uint8, ``K`` and the ``T_*`` poses float64. The optical tactile
    images (``tactile_images``, ``tactile_references``, when the dataset has them) stay
    ``{pad: tensor}`` dicts, each tensor ``(H, W, 3)`` uint8 like ``rgb``. With force fields (a
    ``tactile`` dict with ``forces``) the sample gains ``forces``: ``(P, R, R, 4)`` float32, each
    pad's grid (pads in ``tactile["forces"]`` order, the pad order: every pad of
    ``tactile["pads"]`` as vtgen writes them) with :data:`FORCE_CHANNELS` per cell (pressure,
    shear_x, shear_y in Pa; slip 1.0 or 0.0). With marker flow (a ``tactile`` dict with
    ``markers``) it gains ``markers``: ``{pad: (N, 4) float32}`` in pad order, each optical pad's
    markers with :data:`MARKER_CHANNELS` (x, y, rest_x, rest_y; m, pad frame): a dict, not one
    ``(P, N, 4)`` tensor, as each pad's sensor has its own marker grid (``N`` may differ from pad
    to pad, and from sample to sample with randomized sensors). Other values (``info``, ``index``,
    ``split``, the ``tactile`` dict) pass through unchanged.
    """
    out: TensorSample = {}
    for key, value in sample.items():
        if isinstance(value, np.ndarray):
            out[key] = torch.from_numpy(value)
        elif key in PAD_IMAGE_KEYS and isinstance(value, Mapping):
            out[key] = {
                pad: torch.from_numpy(image) if isinstance(image, np.ndarray) else image
                for pad, image in value.items()
            }
        else:
            out[key] = value
    tactile = sample.get("tactile")
    if isinstance(tactile, Mapping) and tactile.get("forces"):
        out["forces"] = torch.from_numpy(force_array(tactile["forces"]))
    if isinstance(tactile, Mapping) and tactile.get("markers"):
        out["markers"] = {pad: torch.from_numpy(a) for pad, a in marker_arrays(tactile["markers"]).items()}
    return out


class TorchDataset(_TorchDataset):
    """A ``torch.utils.data.Dataset`` over one split of a vtgen dataset.

    ``ds[i]`` is a dict with the keys of :class:`vtdata.Sample`, arrays converted to tensors by
    :func:`to_tensors` (with force fields, plus ``forces`` ``(P, R, R, 4)`` and, with marker
    flow, ``markers`` ``{pad: (N, 4)}``); ``transform``, if
    given, is applied to that dict and its result returned.
    Batch with :func:`collate` (``DataLoader(..., collate_fn=vtdata.torch.collate)``): the default
    collate cannot batch ``info``, whose nested dicts hold strings and may differ between samples.
    """

    def __init__(
        self,
        root: Union[str, "os.PathLike[str]"],
        split: str = "train",
        transform: Optional[Callable[[TensorSample], Any]] = None,
    ) -> None:
        self.dataset = Dataset(root, split)
        self.transform = transform

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, index: int) -> Any:
        sample = to_tensors(self.dataset[index])
        if self.transform is not None:
            return self.transform(sample)
        return sample

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.dataset!r}, transform={self.transform!r})"


class DenseFusionDataset(_TorchDataset):
    """The DenseFusion-ready view of one split as a ``torch.utils.data.Dataset``.

    ``options`` are those of :class:`vtdata.densefusion.DenseFusionView` (``n_points=1000``,
    ``n_tactile=1000``, ``n_model_points=500``, ``crop_size=128``, ``normalize=True``,
    ``seed=0``); ``ds[i]`` is that view's dict with every array converted by :func:`to_tensors`
    (same shapes and dtypes), then passed through ``transform`` if given. Every sample has the same
    shapes (unless ``crop_size=None``), so ``DataLoader``'s default collate works, and so does
    :func:`collate`.
    """

    def __init__(
        self,
        root: Union[str, "os.PathLike[str]", Dataset],
        split: str = "train",
        transform: Optional[Callable[[TensorSample], Any]] = None,
        **options: Any,
    ) -> None:
        self.view = DenseFusionView(root, split, **options)
        self.transform = transform

    def __len__(self) -> int:
        return len(self.view)

    def __getitem__(self, index: int) -> Any:
        sample = to_tensors(self.view[index])
        if self.transform is not None:
            return self.transform(sample)
        return sample

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.view!r}, transform={self.transform!r})"


def _nested_tensors(value: Any) -> Any:
    """Every numpy array inside dicts and lists as a tensor (same dtype and shape)."""
    if isinstance(value, np.ndarray):
        return torch.from_numpy(value)
    if isinstance(value, Mapping):
        return {key: _nested_tensors(v) for key, v in value.items()}
    if isinstance(value, list):
        return [_nested_tensors(v) for v in value]
    return value


class EpisodeTorchDataset(_TorchDataset):
    """Windows of consecutive camera frames of an episode dataset as a ``torch.utils.data.Dataset``.

    The arguments are :class:`vtdata.EpisodeDataset`'s (``window``, ``stride``, ``streams``);
    ``ds[i]`` is its dict with every numpy array, nested ones included (``state``, ``tactile``,
    ``tactile_images``, ...), converted to a tensor of the same dtype and shape, then passed
    through ``transform`` if given. The default streams have the same shapes in every window, so
    the default collate batches them, and so does :func:`collate` (``tactile_points`` and
    ``info``, lists of ``K`` per window, need :func:`collate`, which keeps them as lists; so do the
    ``tactile`` stream's ``markers`` of a dataset whose randomized sensors give each episode its
    own marker count).
    """

    def __init__(
        self,
        root: Union[str, "os.PathLike[str]", Dataset],
        split: str = "train",
        transform: Optional[Callable[[TensorSample], Any]] = None,
        *,
        window: int = 2,
        stride: int = 1,
        streams: Sequence[str] = DEFAULT_STREAMS,
    ) -> None:
        self.episodes = EpisodeDataset(root, split, window=window, stride=stride, streams=streams)
        self.transform = transform

    def __len__(self) -> int:
        return len(self.episodes)

    def __getitem__(self, index: int) -> Any:
        item = _nested_tensors(self.episodes[index])
        if self.transform is not None:
            return self.transform(item)
        return item

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.episodes!r}, transform={self.transform!r})"


def collate(batch: Sequence[Mapping[str, Any]]) -> Dict[str, Any]:
    """Batch a list of sample dicts.

    Tensors are stacked along a new first dimension (they must have equal shapes), integers
    (``index``) become an int64 tensor, dicts of tensors with the same keys in every sample
    (``tactile_images``, ``tactile_references``, ``markers``; an episode window's ``state``,
    ``tactile``, ..., whose values may be such dicts again) become a dict of stacked tensors
    (``{pad: (B, H, W, 3)}``), and everything else (``info``, ``split``, ``tactile``, ...) is kept
    as a list with one entry per sample. Inside such a dict, an entry whose tensors differ in shape
    is kept as a list of the samples' tensors: a pad's markers, whose count varies with randomized
    sensors.
    """
    if len(batch) == 0:
        raise ValueError("cannot collate an empty batch")
    keys = list(batch[0].keys())
    for i, sample in enumerate(batch[1:], start=1):
        if set(sample.keys()) != set(keys):
            raise ValueError(
                f"batch element {i} has keys {sorted(sample.keys())}, element 0 has {sorted(keys)}"
            )
    out: Dict[str, Any] = {}
    for key in keys:
        values: List[Any] = [sample[key] for sample in batch]
        if all(isinstance(v, torch.Tensor) for v in values):
            out[key] = torch.stack(values)
        elif all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            out[key] = torch.tensor(values, dtype=torch.int64)
        elif all(_tensor_dict(v) for v in values) and _same_structure(values):
            out[key] = _stack_dicts(values)
        else:
            out[key] = values
    return out


def _tensor_dict(value: Any) -> bool:
    """A non-empty mapping whose values are all tensors or such mappings (e.g. ``{pad: image}``)."""
    return (
        isinstance(value, Mapping)
        and len(value) > 0
        and all(isinstance(v, torch.Tensor) or _tensor_dict(v) for v in value.values())
    )


def _same_structure(values: Sequence[Mapping[str, Any]]) -> bool:
    """Tensor dicts with the same keys, nested dicts included."""
    first = values[0]
    for v in values:
        if v.keys() != first.keys():
            return False
    for name, item in first.items():
        if isinstance(item, Mapping):
            if not all(isinstance(v[name], Mapping) for v in values) or not _same_structure([v[name] for v in values]):
                return False
        elif not all(isinstance(v[name], torch.Tensor) for v in values):
            return False
    return True


def _stack_dicts(values: Sequence[Mapping[str, Any]]) -> Dict[str, Any]:
    """Tensor dicts of one structure as one dict, each entry's tensors stacked; those of different
    shapes (a pad's markers, with randomized sensors) as a list."""
    out: Dict[str, Any] = {}
    for name, item in values[0].items():
        parts = [v[name] for v in values]
        if isinstance(item, Mapping):
            out[name] = _stack_dicts(parts)
        elif all(part.shape == item.shape for part in parts):
            out[name] = torch.stack(parts)
        else:
            out[name] = parts
    return out
