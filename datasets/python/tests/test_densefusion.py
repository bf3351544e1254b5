"""Tests of the DenseFusion-ready view (``vtdata.densefusion``, ``vtdata.torch``).

The synthetic-data tests need no Rust. The others use the datasets ``conftest.py`` generates with
``$VTGEN_BIN`` (``scenes/tiny.yaml``, ``scenes/tiny-hand.yaml``) and follow its rule: they fail
without ``VTGEN_BIN`` unless ``VTDATA_SKIP_RUST=1``, which skips them.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Dict, List, Mapping

import numpy as np
import pytest

import vtdata
from vtdata.densefusion import DenseFusionView, densefusion_sample

from synthetic import write_dataset
from vtgen_cli import REPO_ROOT

SPLITS = ("train", "test")
N, N_T, M, S = 1000, 1000, 500, 128


def expected_shapes(n: int = N, n_t: int = N_T, m: int = M, s: int = S) -> Dict[str, Any]:
    """Key -> (shape, numpy dtype) of one item, as datasets/python/README.md documents it."""
    return {
        "cloud": ((n, 3), np.float32),
        "choose": ((1, n), np.int64),
        "img": ((3, s, s), np.float32),
        "bbox": ((4,), np.int64),
        "cloud_count": ((), np.int64),
        "tactile": ((n_t, 3), np.float32),
        "tactile_count": ((), np.int64),
        "model_points": ((m, 3), np.float32),
        "target": ((m, 3), np.float32),
        "R": ((3, 3), np.float32),
        "t": ((3,), np.float32),
        "object_index": ((), np.int64),
        "symmetric": ((), np.bool_),
        "occlusion": ((), np.float32),
    }


def check_item(item: Mapping[str, Any], sample: vtdata.Sample, crop_size: Any = S) -> None:
    """Every point of ``item`` lies in the object mask of ``sample``, on its depth, and
    ``choose``/``bbox``/``target`` are consistent with it (OpenCV projection, FORMAT.md)."""
    where = f"{sample['split']}[{sample['index']}]"
    mask, depth, K = sample["mask"], sample["depth"], sample["K"]
    height, width = mask.shape
    cloud = item["cloud"].astype(np.float64)
    x, y, z = cloud.T
    assert int(item["cloud_count"]) == int(((mask == 1) & (depth > 0)).sum()) > 0, where
    assert np.all(z > 0), where
    u = np.rint(K[0, 0] * x / z + K[0, 2]).astype(np.int64)
    v = np.rint(K[1, 1] * y / z + K[1, 2]).astype(np.int64)
    assert u.min() >= 0 and u.max() < width and v.min() >= 0 and v.max() < height, where
    assert np.all(mask[v, u] == 1), f"{where}: cloud points outside the object mask"
    np.testing.assert_array_equal(item["cloud"][:, 2], depth[v, u], err_msg=where)
    # Without replacement when the mask has enough pixels, else every pixel at least once.
    distinct = np.unique(v * width + u).size
    assert distinct == min(len(u), int(item["cloud_count"])), where

    rows, cols = np.nonzero(mask == 1)
    rmin, rmax, cmin, cmax = item["bbox"].tolist()
    assert (rmin, rmax, cmin, cmax) == (rows.min(), rows.max() + 1, cols.min(), cols.max() + 1)
    h, w = rmax - rmin, cmax - cmin
    if crop_size is None:
        row, col, stride = v - rmin, u - cmin, w
    else:  # the resized pixel that contains the chosen pixel's centre
        row = np.floor((v - rmin + 0.5) * crop_size / h).astype(np.int64)
        col = np.floor((u - cmin + 0.5) * crop_size / w).astype(np.int64)
        stride = crop_size
    np.testing.assert_array_equal(item["choose"][0], row * stride + col, err_msg=where)

    T = sample["T_camera_object"]
    np.testing.assert_allclose(item["R"], T[:3, :3], atol=1e-6)
    np.testing.assert_allclose(item["t"], T[:3, 3], atol=1e-6)
    posed = item["model_points"].astype(np.float64) @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(item["target"], posed, atol=1e-5, err_msg=where)
    assert int(item["object_index"]) == sample["info"]["object_index"]
    assert item["object_id"] == sample["info"]["object_id"] and item["index"] == sample["index"]


def assert_items_equal(a: Mapping[str, Any], b: Mapping[str, Any]) -> None:
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        else:
            assert a[key] == b[key], key


# --- synthetic datasets (no Rust) -------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("densefusion") / "ds"
    write_dataset(root, {"train": 4, "test": 2}, samples_per_shard=2)
    return root


@pytest.mark.parametrize("crop_size", [S, None])
def test_synthetic_items(synthetic: Path, crop_size: Any) -> None:
    view = DenseFusionView(synthetic, "train", crop_size=crop_size, normalize=False, seed=3)
    ds = vtdata.Dataset(synthetic, "train")
    for i in range(len(view)):
        item, sample = view[i], ds[i]
        shapes = expected_shapes()
        if crop_size is None:
            rmin, rmax, cmin, cmax = item["bbox"].tolist()
            shapes["img"] = ((3, rmax - rmin, cmax - cmin), np.float32)
        for key, (shape, dtype) in shapes.items():
            assert item[key].shape == shape and item[key].dtype == dtype, key
        check_item(item, sample, crop_size)
        # 12 mask pixels for 1000 points: every pixel is used.
        assert int(item["cloud_count"]) == 12
        # No robot: zero tactile points, flagged by tactile_count.
        assert int(item["tactile_count"]) == 0 and not item["tactile"].any()
        assert math.isnan(float(item["occlusion"])) and bool(item["symmetric"])  # cube: discrete
        # Model points lie on the 10 cm cube's surface, all six faces.
        p = np.abs(item["model_points"])
        assert p.max() <= 0.05 + 1e-6 and np.all(np.isclose(p.max(axis=1), 0.05, atol=1e-6))
        axis = np.argmax(p, axis=1)
        sign = np.sign(item["model_points"][np.arange(M), axis])
        assert len(set(zip(axis.tolist(), sign.tolist()))) == 6
        if crop_size is None:
            # The exact crop: the crop pixel each point chooses has that point's colour.
            rows, cols = np.divmod(item["choose"][0], item["img"].shape[2])
            rmin, _, cmin, _ = item["bbox"].tolist()
            colours = np.rint(item["img"][:, rows, cols].T * 255.0)
            np.testing.assert_array_equal(colours, sample["rgb"][rows + rmin, cols + cmin])


@pytest.mark.parametrize("crop_size", [S, None])
def test_invisible_object_gives_zeros(synthetic: Path, crop_size: Any) -> None:
    view = DenseFusionView(synthetic, "train", crop_size=crop_size)
    sample = view.dataset[1]
    sample["mask"] = np.zeros_like(sample["mask"])
    item = view.convert(sample)
    assert int(item["cloud_count"]) == 0
    assert item["img"].shape == ((3, S, S) if crop_size else (3, 1, 1))
    for key in ("cloud", "choose", "img", "bbox"):
        assert not item[key].any(), key
    assert item["cloud"].shape == (N, 3) and item["choose"].shape == (1, N)
    # The pose and the model points do not depend on the image.
    np.testing.assert_array_equal(item["target"], view[1]["target"])


def test_normalisation(synthetic: Path) -> None:
    raw = DenseFusionView(synthetic, "train", normalize=False)[0]["img"]
    norm = DenseFusionView(synthetic, "train", normalize=True)[0]["img"]
    assert raw.min() >= 0.0 and raw.max() <= 1.0
    mean, std = vtdata.densefusion.IMAGENET_MEAN, vtdata.densefusion.IMAGENET_STD
    np.testing.assert_allclose(norm, (raw - mean[:, None, None]) / std[:, None, None], atol=1e-6)


@pytest.mark.parametrize("n_tactile", [0, 3, 1001, -5, 10.0, "8", True])
def test_n_tactile_out_of_range(synthetic: Path, n_tactile: Any) -> None:
    with pytest.raises(ValueError, match=r"n_tactile must be an integer in 4\.\.=1000"):
        DenseFusionView(synthetic, "train", n_tactile=n_tactile)


def test_other_options_are_validated(synthetic: Path) -> None:
    for kwargs in ({"n_points": 0}, {"n_model_points": -1}, {"crop_size": 0}, {"seed": -1}):
        with pytest.raises(ValueError, match=next(iter(kwargs))):
            DenseFusionView(synthetic, "train", **kwargs)
    for n_tactile in (4, 1000, np.int64(16)):
        item = DenseFusionView(synthetic, "train", n_tactile=n_tactile, n_points=7)[0]
        assert item["tactile"].shape == (n_tactile, 3) and item["cloud"].shape == (7, 3)


def test_deterministic_under_seed(synthetic: Path) -> None:
    a = DenseFusionView(synthetic, "train", seed=11)
    b = DenseFusionView(vtdata.Dataset(synthetic, "train"), seed=11)  # a view on an open Dataset
    order = list(range(len(a)))
    first = [a[i] for i in order]
    for i in reversed(order):  # other order, other object: same arrays
        assert_items_equal(b[i], first[i])
    assert_items_equal(a[-1], first[-1])
    # The same sample index in another split draws other points.
    other_split = DenseFusionView(synthetic, "test", seed=11)[0]
    assert not np.array_equal(other_split["model_points"], first[0]["model_points"])
    # Another seed draws other points; n_tactile does not change the depth or model points.
    other = DenseFusionView(synthetic, "train", seed=12)[0]
    assert not np.array_equal(other["model_points"], first[0]["model_points"])
    fewer = DenseFusionView(synthetic, "train", seed=11, n_tactile=4)[0]
    np.testing.assert_array_equal(fewer["cloud"], first[0]["cloud"])
    np.testing.assert_array_equal(fewer["model_points"], first[0]["model_points"])
    # The function behind the view, given the view's seed.
    sample = a.dataset[2]
    model = a.dataset.models()[sample["info"]["object_id"]]
    assert_items_equal(densefusion_sample(sample, model, a.seed_of(2)), first[2])


def test_torch_dataset_default_collate(synthetic: Path) -> None:
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import DenseFusionDataset, collate

    assert vtdata.DenseFusionDataset is DenseFusionDataset
    ds = DenseFusionDataset(synthetic, "train", n_points=64, n_tactile=4, seed=5)
    view = DenseFusionView(synthetic, "train", n_points=64, n_tactile=4, seed=5)
    for collate_fn in (None, collate):
        kwargs = {} if collate_fn is None else {"collate_fn": collate_fn}
        batch = next(iter(DataLoader(ds, batch_size=3, **kwargs)))
        for key, (shape, dtype) in expected_shapes(64, 4).items():
            assert tuple(batch[key].shape) == (3, *shape), key
            assert batch[key].dtype == torch.from_numpy(np.zeros(0, dtype)).dtype, key
            np.testing.assert_array_equal(batch[key][1].numpy(), view[1][key], err_msg=key)
        assert batch["index"].tolist() == [0, 1, 2] and len(batch["object_id"]) == 3
    flipped = DenseFusionDataset(synthetic, "train", transform=lambda s: s["cloud"].flip(0))
    cloud = torch.from_numpy(DenseFusionView(synthetic, "train")[0]["cloud"])
    assert torch.equal(flipped[0], cloud.flip(0))


# --- datasets generated by vtgen ----------------------------------------------------------------


@pytest.mark.parametrize("split", SPLITS)
def test_tiny_split_through_dataloader(rust_dataset: Path, split: str) -> None:
    """Documented shapes for every sample, with num_workers=2, and the points lie in the mask."""
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import DenseFusionDataset

    ds = vtdata.Dataset(rust_dataset, split)
    loader = DataLoader(
        DenseFusionDataset(rust_dataset, split, seed=0), batch_size=4, num_workers=2, shuffle=True,
        generator=torch.Generator().manual_seed(0),
    )
    expected = expected_shapes()
    seen: List[int] = []
    for batch in loader:
        b = len(batch["index"])
        for key, (shape, dtype) in expected.items():
            assert tuple(batch[key].shape) == (b, *shape), key
            assert batch[key].dtype == torch.from_numpy(np.zeros(0, dtype)).dtype, key
        for j, index in enumerate(batch["index"].tolist()):
            item = {k: v[j] for k, v in batch.items()}
            item = {k: v.numpy() if isinstance(v, torch.Tensor) else v for k, v in item.items()}
            item["index"] = index
            sample = ds[index]
            check_item(item, sample)
            # tiny.yaml has no robot: zero tactile points.
            assert int(item["tactile_count"]) == 0 and not item["tactile"].any()
            assert 0.0 <= float(item["occlusion"]) <= 1.0
            symmetry = ds.models()[item["object_id"]]["info"]["symmetry"]
            assert bool(item["symmetric"]) == (symmetry != "none")
        seen += batch["index"].tolist()
    assert sorted(seen) == list(range(len(ds)))


def test_tiny_same_arrays_with_workers(rust_dataset: Path) -> None:
    """The seed alone fixes the arrays: 2 shuffled workers give what the main process computes."""
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import DenseFusionDataset

    view = DenseFusionView(rust_dataset, "test", seed=42)
    loader = DataLoader(
        DenseFusionDataset(rust_dataset, "test", seed=42), batch_size=3, num_workers=2,
        shuffle=True, generator=torch.Generator().manual_seed(1),
    )
    for batch in loader:
        for j, index in enumerate(batch["index"].tolist()):
            expected = view[index]
            for key in ("cloud", "choose", "img", "model_points", "target"):
                np.testing.assert_array_equal(batch[key][j].numpy(), expected[key], err_msg=key)


def test_tiny_hand_tactile_points_come_from_the_tactile_topic(rust_hand_dataset: Path) -> None:
    ds = vtdata.Dataset(rust_hand_dataset, "train")
    view_all = DenseFusionView(ds, n_tactile=1000, seed=0)
    view_few = DenseFusionView(ds, n_tactile=4, seed=0)
    touched = 0
    for i in range(len(ds)):
        sample = ds[i]
        raw = sample["tactile"]["points"]
        item = view_all[i]
        check_item(item, sample)  # the hand occludes the object: still only mask-1 pixels
        assert int(item["tactile_count"]) == len(raw)
        if len(raw) == 0:
            assert not item["tactile"].any()
            continue
        touched += 1
        # Every resampled point is one of /tactile/points (bit for bit) ...
        rows = {p.tobytes() for p in raw}
        assert all(p.tobytes() in rows for p in item["tactile"])
        # ... and with at most 1000 of them, every one of them is used.
        if len(raw) <= 1000:
            assert {p.tobytes() for p in item["tactile"]} == rows
        few = view_few[i]["tactile"]
        assert few.shape == (4, 3) and all(p.tobytes() in rows for p in few)
        assert len({p.tobytes() for p in few}) == min(4, len(rows))  # no repeats when enough
    assert touched > 0, "no tiny-hand sample has tactile points"


DOC_WITH_TRAINING_LOOP = REPO_ROOT / "docs" / "data.md"


def readme_training_snippet() -> str:
    """The Python block of docs/data.md that trains on the DenseFusion view."""
    text = DOC_WITH_TRAINING_LOOP.read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    blocks = [b for b in blocks if "DenseFusionDataset(" in b]
    assert len(blocks) == 1, "docs/data.md must have exactly one python block using DenseFusionDataset"
    return blocks[0]


def test_readme_training_loop_runs_on_tiny(rust_dataset: Path) -> None:
    pytest.importorskip("torch")
    code = readme_training_snippet()
    assert '"out/tiny"' in code
    code = code.replace('"out/tiny"', repr(str(rust_dataset)))
    namespace: Dict[str, Any] = {"__name__": "readme_snippet"}
    exec(compile(code, str(DOC_WITH_TRAINING_LOOP), "exec"), namespace)
    assert math.isfinite(namespace["loss"].item())
