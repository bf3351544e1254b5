"""Force fields (FORMAT.md, ``/tactile/<pad>/force`` and "Force fields"): each pad's R x R grid of
pressure, shear and slip, read into a sample's ``tactile["forces"]``, an episode's touch readings,
``EpisodeDataset``'s touch streams and ``TorchDataset``'s ``forces`` tensor.

Synthetic datasets (``synthetic.write_dataset(..., force_resolution=R)``) test the round trip and
the errors; ``test_real_force_fields_balance`` reads datasets the Rust generator wrote on the
MuJoCo backend (``conftest.rust_force_datasets``: ``VTGEN_MUJOCO_BIN`` or ``VTGEN_FORCE_DATASETS``,
skipped without them) and holds every pad's cells to the force ``/sample/info`` gives it.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

import vtdata
from vtdata import Dataset, DatasetError, EpisodeDataset

from synthetic import PAD_SIZE, ROBOTS, write_dataset, write_episode_dataset, write_shard

R = 4


def cell_centres(length: float, width: float, r: int) -> np.ndarray:
    """``(r, r, 2)``: FORMAT.md's cell centres ``x = ((2u + 1)/R - 1) L/2``, ``y`` likewise, row
    ``v`` and column ``u`` (written independently of the synthetic writer)."""
    x = np.array([((2 * u + 1) / r - 1) * length / 2 for u in range(r)])
    y = np.array([((2 * v + 1) / r - 1) * width / 2 for v in range(r)])
    return np.stack([np.broadcast_to(x[None, :], (r, r)), np.broadcast_to(y[:, None], (r, r))], axis=-1)


def cell_sum(field: Dict[str, np.ndarray], length: float, width: float) -> np.ndarray:
    """The force a field's cells add up to (N, pad frame): (shear_x, shear_y, -pressure) times the
    cell area L W / R^2 (FORMAT.md, "Sums")."""
    r = field["pressure"].shape[0]
    area = length * width / (r * r)
    shear = field["shear"].astype(np.float64).sum(axis=(0, 1))
    return np.array([shear[0], shear[1], -field["pressure"].astype(np.float64).sum()]) * area


def assert_field_equal(actual: Dict[str, np.ndarray], expected: Dict[str, np.ndarray], what: str) -> None:
    assert set(actual) == {"position", "pressure", "shear", "slip"}, what
    r = expected["pressure"].shape[0]
    for key, shape, dtype in (
        ("position", (r, r, 2), np.float32),
        ("pressure", (r, r), np.float32),
        ("shear", (r, r, 2), np.float32),
        ("slip", (r, r), np.bool_),
    ):
        a = actual[key]
        assert a.shape == shape and a.dtype == dtype, f"{what} {key}: {a.shape} {a.dtype}"
        assert a.flags.c_contiguous, f"{what} {key} is not C-contiguous"
        assert a.tobytes() == np.asarray(expected[key], dtype=dtype).tobytes(), f"{what} {key} differs"


# --- the round trip -----------------------------------------------------------------------------


@pytest.mark.parametrize("reverse", [False, True], ids=["writer-order", "reversed-messages"])
@pytest.mark.parametrize(
    "robot, optical",
    [("robotiq_2f85", ("left_pad",)), ("ur5e_allegro", ()), ("three_finger", ("a_distal",))],
)
def test_force_fields_round_trip(tmp_path: Path, robot: str, optical: tuple, reverse: bool) -> None:
    """Every pad's field comes back bit for bit, in pad order (not name order), beside the optical
    images; the cells sit at FORMAT.md's centres and add up to ``tactile.forces.<pad>.force_n``."""
    root = tmp_path / "ds"
    samples = write_dataset(
        root, {"train": 3}, 2, robot=robot, optical=optical, force_resolution=R, reverse_messages=reverse
    )
    pads = list(ROBOTS[robot]["pads"])
    ds = Dataset(root, "train")
    pressed = 0
    for i, expected in enumerate(samples["train"]):
        sample = ds[i]
        forces = sample["tactile"]["forces"]
        assert list(forces) == sample["tactile"]["pads"] == pads
        assert list(sample.get("tactile_images", {})) == list(optical)
        info = sample["info"]["tactile"]
        assert sorted(info["forces"]) == sorted(pads) and len(info["hand_force_n"]) == 3
        for pad in pads:
            field = forces[pad]
            assert_field_equal(field, expected.tactile["forces"][pad], f"sample {i} {pad}")
            np.testing.assert_allclose(field["position"], cell_centres(*PAD_SIZE, R), rtol=0, atol=1e-9)
            np.testing.assert_allclose(
                cell_sum(field, *info["pads"][pad]), info["forces"][pad]["force_n"], rtol=1e-12, atol=1e-12
            )
            pressed += int((field["pressure"] > 0).sum())
        stacked = vtdata.force_array(forces)
        assert stacked.shape == (len(pads), R, R, 4) and stacked.dtype == np.float32
        for k, pad in enumerate(pads):
            field = expected.tactile["forces"][pad]
            assert stacked[k, ..., 0].tobytes() == field["pressure"].tobytes()
            assert stacked[k, ..., 1:3].tobytes() == field["shear"].tobytes()
            assert np.array_equal(stacked[k, ..., 3], field["slip"].astype(np.float32))
    assert pressed > 0, "the synthetic fields press no cell: the test would compare zeros"


def test_no_forces_without_force_topics(tmp_path: Path) -> None:
    """Without force topics ``tactile`` has no ``forces`` key (as ``depth_noisy`` is absent)."""
    root = tmp_path / "ds"
    write_dataset(root, {"train": 2}, 2, robot="robotiq_2f85", optical=("left_pad",))
    sample = Dataset(root, "train")[0]
    assert "forces" not in sample["tactile"] and "forces" not in sample["info"]["tactile"]


# --- errors: a DatasetError naming the shard, the sample and the topic --------------------------


def _rewrite(root: Path, samples: List[Any]) -> str:
    shard = root / "train" / "shard-00000.mcap"
    write_shard(shard, "train", 0, samples)
    return str(shard)


def test_a_malformed_grid_is_a_clear_error(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    samples = write_dataset(root, {"train": 3}, 3, robot="robotiq_2f85", force_resolution=R)["train"]
    # Sample 1: left_pad's cloud has 3 rows of 4 cells: 12 cells, no square grid.
    samples[1].tactile["forces"]["left_pad"] = {k: v[:3] for k, v in samples[1].tactile["forces"]["left_pad"].items()}
    # Sample 2: square grids, but of two resolutions.
    samples[2].tactile["forces"]["left_pad"] = {k: v[:2, :2] for k, v in samples[2].tactile["forces"]["left_pad"].items()}
    shard = _rewrite(root, samples)
    ds = Dataset(root, "train")
    assert list(ds[0]["tactile"]["forces"]) == ["right_pad", "left_pad"]
    with pytest.raises(DatasetError) as err:
        ds[1]
    assert str(err.value) == (
        f"{shard}: sample 1 of split 'train' /tactile/left_pad/force: 12 force cells, not a square R x R grid (R >= 1)"
    )
    with pytest.raises(DatasetError, match=r"sample 2 of split 'train': the pads' force fields differ in resolution: right_pad 4x4, left_pad 2x2"):
        ds[2]


def test_force_fields_must_match_the_info_and_the_tactile_data(tmp_path: Path) -> None:
    kw = dict(robot="robotiq_2f85", force_resolution=R)
    # /sample/info lists a pad whose field is missing.
    root = tmp_path / "missing"
    write_dataset(root, {"train": 2}, 2, omit=("train", 1, "/tactile/left_pad/force"), **kw)
    ds = Dataset(root, "train")
    assert list(ds[0]["tactile"]["forces"]) == ["right_pad", "left_pad"]
    with pytest.raises(
        DatasetError,
        match=r"sample 1 .*tactile\.forces lists the pads \['left_pad', 'right_pad'\], the sample has force fields of \['right_pad'\]",
    ):
        ds[1]
    # Force fields without the tactile point cloud: no pads to be fields of.
    root = tmp_path / "no-points"
    write_dataset(root, {"train": 1}, 1, omit=("train", 0, "/tactile/points"), **kw)
    with pytest.raises(DatasetError, match=r"sample 0 .*: force fields of right_pad, left_pad but no /tactile/points"):
        Dataset(root, "train")[0]


def _cloud(cells: int, stride: int = 28) -> PointCloud:
    return PointCloud(point_stride=stride, data=bytes(cells * stride))


def test_force_decoder_checks() -> None:
    """The decoder alone: a pad that is not a pad of the tactile data, a wrong stride, an empty
    cloud, a field of one cell, and the fields' order (their channels')."""
    from vtdata.decoders import _forces

    pads = ["b", "a"]
    decoded = {"/tactile/a/force": _cloud(4), "/tactile/b/force": _cloud(4)}
    ids = {"/tactile/b/force": 20, "/tactile/a/force": 21}
    assert list(_forces(decoded, ids, "here", pads)) == ["b", "a"]
    assert _forces({}, ids, "here", pads) is None
    with pytest.raises(DatasetError, match=r"^here: force fields of a, which are not pads of the sample \(no /tactile/<pad>/depth; pads: b\)$"):
        _forces(decoded, ids, "here", ["b"])
    with pytest.raises(DatasetError, match="force fields of b, a but no /tactile/points"):
        _forces(decoded, ids, "here", None)
    with pytest.raises(DatasetError, match=r"^here /tactile/a/force: expected 28-byte force cells, got point stride 20 and 80 bytes of data$"):
        _forces({"/tactile/a/force": _cloud(4, stride=20)}, {}, "here", pads)
    with pytest.raises(DatasetError, match=r"here /tactile/a/force: 0 force cells, not a square"):
        _forces({"/tactile/a/force": _cloud(0)}, {}, "here", pads)
    truncated = PointCloud(point_stride=28, data=bytes(4 * 28 - 1))
    with pytest.raises(DatasetError, match="expected 28-byte force cells, got point stride 28 and 111 bytes"):
        _forces({"/tactile/a/force": truncated}, {}, "here", pads)
    one = PointCloud(point_stride=28, data=struct.pack("<6fI", 0.0, 0.0, 0.0, 12.5, -1.0, 2.0, 1))
    field = _forces({"/tactile/a/force": one}, {}, "here", pads)["a"]
    assert field["pressure"].tolist() == [[12.5]] and field["shear"].tolist() == [[[-1.0, 2.0]]]
    assert field["slip"].tolist() == [[True]]


def test_force_fields_come_with_the_sample_tactile() -> None:
    """``_tactile`` reads the fields with the points and depth images, and only with force topics."""
    from vtdata.decoders import _tactile

    image = RawImage(width=2, height=2, encoding="32FC1", step=8, data=bytes(16))
    points = PointCloud(point_stride=20, data=b"")
    decoded = {"/tactile/points": points, "/tactile/a/depth": image, "/tactile/a/force": _cloud(9)}
    tactile = _tactile(decoded, {}, "here")
    assert tactile["forces"]["a"]["pressure"].shape == (3, 3)
    del decoded["/tactile/a/force"]
    assert "forces" not in _tactile(decoded, {}, "here")


# --- episodes and torch -------------------------------------------------------------------------


def test_episode_touch_readings_carry_their_forces(tmp_path: Path) -> None:
    """Every touch reading of an episode (the frame's own and those up to the next frame) has its
    instant's fields; ``EpisodeDataset``'s touch streams stack them as ``(K, P, R, R, 4)``."""
    root = tmp_path / "ep"
    timing = dict(camera_period=4, tactile_period=2, state_period=1)
    written = write_episode_dataset(
        root, {"train": 2}, 4, seed=5, optical=("ff_distal",), force_resolution=3, **timing
    )
    pads = list(ROBOTS["ur5e_allegro"]["pads"])
    ds = Dataset(root, "train")
    readings = 0
    for episode in written["train"]:
        touches = dict(episode.touches)
        for k, frame in enumerate(episode.frames):
            sample = ds[episode.first_sample + k]
            assert list(sample["tactile"]["forces"]) == pads
            for pad in pads:
                assert_field_equal(sample["tactile"]["forces"][pad], frame.tactile["forces"][pad], f"frame {k} {pad}")
            for t, reading in sample["episode"]["tactile"]:
                assert list(reading["forces"]) == pads, f"reading at {t} ns"
                for pad in pads:
                    assert_field_equal(reading["forces"][pad], touches[t]["forces"][pad], f"reading at {t} ns {pad}")
                readings += 1
    assert readings > 0, "no touch reading between frames"

    windows = EpisodeDataset(root, "train", window=2, stride=1, streams=("tactile", "tactile_seq", "tactile_points"))
    item = windows[1]
    tactile, seq = item["tactile"], item["tactile_seq"]
    assert tactile["forces"].shape == (2, len(pads), 3, 3, 4) and tactile["forces"].dtype == np.float32
    assert seq["forces"].shape == (len(seq["time_ns"]), len(pads), 3, 3, 4)
    touches = dict(written["train"][0].touches)
    for j, t in enumerate(tactile["time_ns"].tolist()):
        np.testing.assert_array_equal(tactile["forces"][j], vtdata.force_array(touches[t]["forces"]))
        assert list(item["tactile_points"][j]["forces"]) == pads
    for j, t in enumerate(seq["time_ns"].tolist()):
        np.testing.assert_array_equal(seq["forces"][j], vtdata.force_array(touches[t]["forces"]))


def test_torch_gives_a_forces_tensor(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import FORCE_CHANNELS, TorchDataset, collate

    assert FORCE_CHANNELS == ("pressure", "shear_x", "shear_y", "slip")
    root = tmp_path / "ds"
    samples = write_dataset(root, {"train": 3}, 2, robot="robotiq_2f85", optical=("left_pad",), force_resolution=R)
    pads = ["right_pad", "left_pad"]
    item = TorchDataset(root, "train")[0]
    forces = item["forces"]
    assert isinstance(forces, torch.Tensor) and forces.dtype == torch.float32
    assert forces.shape == (2, R, R, 4)
    for k, pad in enumerate(pads):
        field = samples["train"][0].tactile["forces"][pad]
        assert forces[k, ..., 0].numpy().tobytes() == field["pressure"].tobytes()
        assert forces[k, ..., 1].numpy().tobytes() == np.ascontiguousarray(field["shear"][..., 0]).tobytes()
        assert forces[k, ..., 2].numpy().tobytes() == np.ascontiguousarray(field["shear"][..., 1]).tobytes()
        assert torch.equal(forces[k, ..., 3], torch.from_numpy(field["slip"].astype(np.float32)))
    seen = 0
    for batch in DataLoader(TorchDataset(root, "train"), batch_size=2, collate_fn=collate):
        b = len(batch["index"])
        assert batch["forces"].shape == (b, 2, R, R, 4)
        assert list(batch["tactile_images"]) == ["left_pad"]
        for j, index in enumerate(batch["index"].tolist()):
            want = vtdata.force_array(samples["train"][index].tactile["forces"])
            assert batch["forces"][j].numpy().tobytes() == want.tobytes()
        seen += b
    assert seen == 3
    plain = tmp_path / "plain"
    write_dataset(plain, {"train": 1}, 1, robot="robotiq_2f85")
    assert "forces" not in TorchDataset(plain, "train")[0]


# --- data the Rust generator wrote (MuJoCo backend) ---------------------------------------------


def test_real_force_fields_balance(rust_force_datasets: List[Path]) -> None:
    """For every pad of every sample, the cells' (shear_x, shear_y, -pressure) times the cell area
    (L W / R^2, L and W from ``tactile.pads``) add up to ``tactile.forces.<pad>.force_n`` within 5 %
    + 1e-4 N; the grid is the config's resolution, its cells at FORMAT.md's centres, the pressure
    >= 0, shear and slip only where the object presses. An episode's touch readings between frames
    have every pad's field too."""
    checked = pressing = between = 0
    for root in rust_force_datasets:
        config = json.loads((root / "config.json").read_text(encoding="utf-8"))
        r = config["robot"]["tactile"]["force_field"]["resolution"]
        manifest = json.loads((root / "manifest.json").read_text(encoding="utf-8"))
        for split in manifest["splits"]:
            ds = Dataset(root, split)
            for i in range(len(ds)):
                sample = ds[i]
                where = f"{root.name} {split}[{i}]"
                tactile, info = sample["tactile"], sample["info"]["tactile"]
                pads = tactile["pads"]
                assert list(tactile["forces"]) == pads, where
                assert sorted(info["forces"]) == sorted(pads), where
                assert len(info["hand_force_n"]) == 3, where
                for pad in pads:
                    field = tactile["forces"][pad]
                    length, width = info["pads"][pad]
                    assert field["pressure"].shape == (r, r), f"{where} {pad}"
                    np.testing.assert_allclose(
                        field["position"], cell_centres(length, width, r), rtol=0, atol=1e-6, err_msg=f"{where} {pad}"
                    )
                    pressed = field["pressure"] > 0
                    assert (field["pressure"] >= 0).all(), f"{where} {pad}: negative pressure"
                    assert not (field["slip"] & ~pressed).any(), f"{where} {pad}: a cell slips with no pressure"
                    assert not (np.abs(field["shear"]).sum(axis=-1)[~pressed] > 0).any(), f"{where} {pad}: shear without pressure"
                    want = np.array(info["forces"][pad]["force_n"], dtype=np.float64)
                    got = cell_sum(field, length, width)
                    tolerance = 0.05 * np.linalg.norm(want) + 1e-4
                    assert np.linalg.norm(got - want) <= tolerance, (
                        f"{where} {pad}: the cells sum to {got.tolist()} N, /sample/info tactile.forces gives "
                        f"force_n {want.tolist()} N (tolerance {tolerance:.3g} N)"
                    )
                    checked += 1
                    pressing += int(np.linalg.norm(want) > 1e-3)
                for t, reading in sample.get("episode", {}).get("tactile", []):
                    assert list(reading["forces"]) == pads, f"{where} touch at {t} ns"
                    assert {f["pressure"].shape for f in reading["forces"].values()} == {(r, r)}
                    between += 1
    assert checked > 0, f"no pad to check in {[str(r) for r in rust_force_datasets]}"
    assert pressing > 0, "no pad with a contact force: the sums compare zeros with zeros"
    print(f"force fields: {checked} pads checked ({pressing} pressed), {between} episode touch readings")
