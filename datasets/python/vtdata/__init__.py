"""Python reader for vtgen synthetic visuotactile datasets.

>>> import vtdata
>>> ds = vtdata.Dataset("out/tiny", split="train")
>>> sample = ds[0]
>>> sample["rgb"].shape, sample["K"], sample["T_camera_object"]

``vtdata.DenseFusionView`` maps each sample to DenseFusion's inputs (depth points, RGB crop,
tactile points, model points; numpy). ``vtdata.EpisodeDataset`` windows the camera frames of an
episode dataset, every stream aligned to them. ``vtdata.TorchDataset``,
``vtdata.DenseFusionDataset`` and ``vtdata.EpisodeTorchDataset`` (and the ``vtdata.torch`` module)
wrap a split for PyTorch; they are imported on first use, so ``import vtdata`` never imports torch.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .densefusion import DenseFusionView, densefusion_sample
from .episodes import EpisodeDataset
from .ply import PlyError, load_ply
from .reader import (
    Dataset,
    DatasetError,
    DatasetNotFoundError,
    Sample,
    decode_raw_image,
    force_array,
    load_models,
    marker_arrays,
    open_dataset,
    pose_matrix,
    quaternion_matrix,
)

if TYPE_CHECKING:
    from . import torch  # noqa: F401  (vtdata.torch, imported lazily at run time)
    from .torch import DenseFusionDataset, EpisodeTorchDataset, TorchDataset

__version__ = "0.1.0"

__all__ = [
    "Dataset",
    "DatasetError",
    "DatasetNotFoundError",
    "DenseFusionDataset",
    "DenseFusionView",
    "EpisodeDataset",
    "EpisodeTorchDataset",
    "PlyError",
    "Sample",
    "TorchDataset",
    "decode_raw_image",
    "densefusion_sample",
    "force_array",
    "load_models",
    "load_ply",
    "marker_arrays",
    "open_dataset",
    "pose_matrix",
    "quaternion_matrix",
]


def __getattr__(name: str) -> Any:
    # PEP 562: import the torch wrapper (and torch itself) only when it is asked for.
    if name in ("TorchDataset", "DenseFusionDataset", "EpisodeTorchDataset"):
        return getattr(importlib.import_module(".torch", __name__), name)
    if name == "torch":
        return importlib.import_module(".torch", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
