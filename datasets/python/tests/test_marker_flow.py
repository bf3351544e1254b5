"""Marker flow (FORMAT.md, ``/tactile/<pad>/markers``): each optical pad's printed markers, where
the gel has moved them and their rest positions, read into a sample's ``tactile["markers"]``, an
episode's touch readings, ``EpisodeDataset``'s touch streams and ``TorchDataset``'s ``markers``.

Synthetic datasets (``synthetic.write_dataset(..., force_resolution=R, marker_count=N)``) test the
round trip and the errors; ``test_real_marker_flow`` reads the datasets the Rust generator wrote on
the MuJoCo backend (``conftest.rust_force_datasets``, as ``test_force_fields.py``; skipped without
them) and holds every optical pad's markers to its sensor's grid.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

import synthetic
import vtdata
from vtdata import Dataset, DatasetError, EpisodeDataset
from vtdata.format import TOUCH_FORCE_KEYS

from synthetic import ROBOTS, make_marker_flow, write_dataset, write_episode_dataset, write_shard

R = 3


def assert_flow_equal(actual: Dict[str, np.ndarray], expected: Dict[str, np.ndarray], what: str) -> None:
    """A pad's flow as vtdata returns it: ``position`` and ``rest`` ``(N, 2)`` float32, C-contiguous,
    equal byte for byte to what was written."""
    assert set(actual) == {"position", "rest"}, what
    n = len(expected["rest"])
    for key in ("position", "rest"):
        a = actual[key]
        assert a.shape == (n, 2) and a.dtype == np.float32, f"{what} {key}: {a.shape} {a.dtype}"
        assert a.flags.c_contiguous, f"{what} {key} is not C-contiguous"
        assert a.tobytes() == np.asarray(expected[key], dtype=np.float32).tobytes(), f"{what} {key} differs"


def moved(flow: Dict[str, np.ndarray]) -> int:
    """How many of a flow's markers are off their rest position."""
    return int((flow["position"] != flow["rest"]).any(axis=-1).sum())


# --- the round trip -----------------------------------------------------------------------------


@pytest.mark.parametrize("reverse", [False, True], ids=["writer-order", "reversed-messages"])
@pytest.mark.parametrize(
    "robot, optical, marker_count",
    [
        # Both jaws, listed in name order: the flow comes in pad order (right, then left), each
        # pad with its own count.
        ("robotiq_2f85", ("left_pad", "right_pad"), {"right_pad": 12, "left_pad": 7}),
        ("ur5e_allegro", ("ff_distal", "th_distal"), 9),
        ("three_finger", ("a_distal",), 5),
    ],
)
def test_marker_flow_round_trip(tmp_path: Path, robot: str, optical: tuple, marker_count: Any, reverse: bool) -> None:
    """Every optical pad's markers come back bit for bit, in pad order (not name order), beside the
    force fields and images; :func:`vtdata.marker_arrays` lays each pad's out as x, y, rest_x,
    rest_y."""
    root = tmp_path / "ds"
    samples = write_dataset(
        root,
        {"train": 3},
        2,
        robot=robot,
        optical=optical,
        force_resolution=R,
        marker_count=marker_count,
        reverse_messages=reverse,
    )
    pads = [p for p in ROBOTS[robot]["pads"] if p in optical]
    ds = Dataset(root, "train")
    displaced = 0
    for i, expected in enumerate(samples["train"]):
        sample = ds[i]
        markers = sample["tactile"]["markers"]
        assert list(markers) == pads == list(sample["tactile_images"])
        assert list(sample["tactile"]["forces"]) == list(ROBOTS[robot]["pads"])
        for pad in pads:
            want = expected.tactile["markers"][pad]
            n = marker_count[pad] if isinstance(marker_count, dict) else marker_count
            assert len(want["rest"]) == n
            assert_flow_equal(markers[pad], want, f"sample {i} {pad}")
            displaced += moved(markers[pad])
        arrays = vtdata.marker_arrays(markers)
        assert list(arrays) == pads
        for pad in pads:
            a, want = arrays[pad], expected.tactile["markers"][pad]
            assert a.shape == (len(want["rest"]), 4) and a.dtype == np.float32
            assert np.ascontiguousarray(a[:, :2]).tobytes() == want["position"].tobytes()
            assert np.ascontiguousarray(a[:, 2:]).tobytes() == want["rest"].tobytes()
    assert displaced > 0, "no marker moved: the test would compare the rest grid with itself"


def test_no_markers_without_marker_topics(tmp_path: Path) -> None:
    """Without marker topics ``tactile`` has no ``markers`` key (as without force topics no
    ``forces``), force fields or not."""
    root = tmp_path / "ds"
    write_dataset(root, {"train": 1}, 1, robot="robotiq_2f85", optical=("left_pad",), force_resolution=R)
    sample = Dataset(root, "train")[0]
    assert "forces" in sample["tactile"] and "markers" not in sample["tactile"]


def test_an_empty_marker_grid_reads_as_no_markers_of_that_pad(tmp_path: Path) -> None:
    """A sensor whose pitch leaves no dot inside its area writes an empty cloud: ``(0, 2)`` arrays."""
    root = tmp_path / "ds"
    write_dataset(
        root, {"train": 1}, 1, robot="robotiq_2f85", optical=("right_pad", "left_pad"), force_resolution=R,
        marker_count={"right_pad": 0, "left_pad": 4},
    )
    markers = Dataset(root, "train")[0]["tactile"]["markers"]
    assert [(pad, flow["position"].shape, flow["rest"].shape) for pad, flow in markers.items()] == [
        ("right_pad", (0, 2), (0, 2)),
        ("left_pad", (4, 2), (4, 2)),
    ]
    assert markers["right_pad"]["position"].dtype == np.float32
    assert vtdata.marker_arrays(markers)["right_pad"].shape == (0, 4)


# --- errors: a DatasetError naming the shard, the sample and the topic --------------------------


def _gripper(tmp_path: Path, n: int = 3) -> List[Any]:
    kw = dict(robot="robotiq_2f85", optical=("right_pad", "left_pad"), force_resolution=R, marker_count=6)
    return write_dataset(tmp_path / "ds", {"train": n}, n, **kw)["train"]


def _shard(tmp_path: Path) -> str:
    return str(tmp_path / "ds" / "train" / "shard-00000.mcap")


def test_a_wrong_stride_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(synthetic, "MARKER_POINT_STRIDE", 24)
    _gripper(tmp_path, 1)
    with pytest.raises(DatasetError) as err:
        Dataset(tmp_path / "ds", "train")[0]
    assert str(err.value) == (
        f"{_shard(tmp_path)}: sample 0 of split 'train' /tactile/right_pad/markers: expected 20-byte markers, "
        "got point stride 24 and 120 bytes of data"
    )


def test_a_ragged_cloud_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Data that is not a whole number of markers (a truncated cloud)."""
    whole = synthetic._marker_points
    monkeypatch.setattr(synthetic, "_marker_points", lambda flow: whole(flow)[:-3])
    _gripper(tmp_path, 1)
    with pytest.raises(DatasetError) as err:
        Dataset(tmp_path / "ds", "train")[0]
    assert str(err.value) == (
        f"{_shard(tmp_path)}: sample 0 of split 'train' /tactile/right_pad/markers: expected 20-byte markers, "
        "got point stride 20 and 117 bytes of data"
    )


def test_markers_must_be_of_the_samples_optical_pads(tmp_path: Path) -> None:
    samples = _gripper(tmp_path)
    shard = _shard(tmp_path)
    # Sample 1: right_pad's sensor is not optical here (no image), yet it has markers.
    del samples[1].tactile["images"]["right_pad"]
    del samples[1].info["tactile"]["optical"]["right_pad"]
    # Sample 2: /sample/info gives left_pad's sensor no markers, yet the sample has them.
    samples[2].info["tactile"]["optical"]["left_pad"]["markers"] = None
    write_shard(Path(shard), "train", 0, samples)
    ds = Dataset(tmp_path / "ds", "train")
    assert list(ds[0]["tactile"]["markers"]) == ["right_pad", "left_pad"]
    with pytest.raises(DatasetError) as err:
        ds[1]
    assert str(err.value) == (
        f"{shard}: sample 1 of split 'train': markers of right_pad, which are not optical pads of the "
        "sample (no /tactile/<pad>/image)"
    )
    with pytest.raises(DatasetError) as err:
        ds[2]
    assert str(err.value) == (
        f"{shard}: sample 2 of split 'train': markers of left_pad, whose sensors have none "
        "(/sample/info tactile.optical.<pad>.markers is null)"
    )


def test_markers_without_tactile_data_are_an_error(tmp_path: Path) -> None:
    """Markers in a sample without ``/tactile/points``: no pads for them to be of."""
    samples = _gripper(tmp_path, 1)
    # No force fields either, so the markers are what the reader finds without tactile data.
    samples[0].tactile["forces"] = {}
    for key in TOUCH_FORCE_KEYS:
        del samples[0].info["tactile"][key]
    write_shard(Path(_shard(tmp_path)), "train", 0, samples, omit=(0, "/tactile/points"))
    with pytest.raises(DatasetError) as err:
        Dataset(tmp_path / "ds", "train")[0]
    assert str(err.value) == (
        f"{_shard(tmp_path)}: sample 0 of split 'train': markers of right_pad, left_pad but no /tactile/points "
        "(every /tactile/<pad>/... stream is of a pad of the robot's tactile data)"
    )


def _cloud(markers: int, stride: int = 20) -> PointCloud:
    return PointCloud(point_stride=stride, data=bytes(markers * stride))


def test_marker_decoder_checks() -> None:
    """The decoder alone: the pads' order (their channels'), a pad that is not a pad of the tactile
    data, one without an optical image, a wrong stride, a ragged cloud, one marker's values."""
    from vtdata.decoders import _markers

    image = RawImage(width=1, height=1, encoding="rgb8", step=3, data=bytes(3))
    decoded: Dict[str, Any] = {
        "/tactile/a/markers": _cloud(4),
        "/tactile/b/markers": _cloud(2),
        "/tactile/a/image": image,
        "/tactile/b/image": image,
    }
    ids = {"/tactile/b/markers": 30, "/tactile/a/markers": 31}
    pads = ["b", "a"]
    flows = _markers(decoded, ids, "here", pads)
    assert [(p, f["rest"].shape) for p, f in flows.items()] == [("b", (2, 2)), ("a", (4, 2))]
    assert _markers({"/tactile/a/image": image}, ids, "here", pads) is None
    with pytest.raises(DatasetError, match=r"^here: markers of a, which are not pads of the sample \(no /tactile/<pad>/depth; pads: b\)$"):
        _markers(decoded, ids, "here", ["b"])
    with pytest.raises(DatasetError, match=r"^here: markers of b, a but no /tactile/points"):
        _markers(decoded, ids, "here", None)
    plain = {k: v for k, v in decoded.items() if k != "/tactile/b/image"}
    with pytest.raises(DatasetError, match=r"^here: markers of b, which are not optical pads of the sample"):
        _markers(plain, ids, "here", pads)
    wide = {"/tactile/a/markers": _cloud(4, stride=28), "/tactile/a/image": image}
    with pytest.raises(DatasetError, match=r"^here /tactile/a/markers: expected 20-byte markers, got point stride 28 and 112 bytes of data$"):
        _markers(wide, {}, "here", pads)
    ragged = {"/tactile/a/markers": PointCloud(point_stride=20, data=bytes(41)), "/tactile/a/image": image}
    with pytest.raises(DatasetError, match=r"^here /tactile/a/markers: expected 20-byte markers, got point stride 20 and 41 bytes of data$"):
        _markers(ragged, {}, "here", pads)
    one = PointCloud(point_stride=20, data=struct.pack("<5f", 0.0015, -0.25, 0.0, 0.001, -0.5))
    flow = _markers({"/tactile/a/markers": one, "/tactile/a/image": image}, {}, "here", pads)["a"]
    assert flow["position"].tolist() == [[np.float32(0.0015), -0.25]]
    assert flow["rest"].tolist() == [[np.float32(0.001), -0.5]]


def test_markers_come_with_the_sample_tactile() -> None:
    """``_tactile`` reads the markers with the points and depth images, and only with marker topics."""
    from vtdata.decoders import _tactile

    depth = RawImage(width=2, height=2, encoding="32FC1", step=8, data=bytes(16))
    image = RawImage(width=1, height=1, encoding="rgb8", step=3, data=bytes(3))
    points = PointCloud(point_stride=20, data=b"")
    decoded = {"/tactile/points": points, "/tactile/a/depth": depth, "/tactile/a/image": image, "/tactile/a/markers": _cloud(5)}
    tactile = _tactile(decoded, {}, "here")
    assert tactile["markers"]["a"]["position"].shape == (5, 2)
    del decoded["/tactile/a/markers"]
    assert "markers" not in _tactile(decoded, {}, "here")


# --- episodes and torch -------------------------------------------------------------------------


def test_episode_touch_readings_carry_their_markers(tmp_path: Path) -> None:
    """Every touch reading of an episode (the frame's own and those up to the next frame) has its
    instant's markers; ``EpisodeDataset``'s touch streams stack each pad's as ``(K, N, 4)``."""
    root = tmp_path / "ep"
    timing = dict(camera_period=4, tactile_period=2, state_period=1)
    counts = {"ff_distal": 6, "th_distal": 9}
    written = write_episode_dataset(
        root, {"train": 2}, 4, seed=5, optical=("th_distal", "ff_distal"), force_resolution=3, marker_count=counts, **timing
    )
    pads = ["ff_distal", "th_distal"]  # pad order
    ds = Dataset(root, "train")
    readings = displaced = 0
    for episode in written["train"]:
        touches = dict(episode.touches)
        for k, frame in enumerate(episode.frames):
            sample = ds[episode.first_sample + k]
            assert list(sample["tactile"]["markers"]) == pads
            for pad in pads:
                assert_flow_equal(sample["tactile"]["markers"][pad], frame.tactile["markers"][pad], f"frame {k} {pad}")
            for t, reading in sample["episode"]["tactile"]:
                assert list(reading["markers"]) == pads, f"reading at {t} ns"
                for pad in pads:
                    assert_flow_equal(reading["markers"][pad], touches[t]["markers"][pad], f"reading at {t} ns {pad}")
                    displaced += moved(reading["markers"][pad])
                readings += 1
    assert readings > 0, "no touch reading between frames"
    assert displaced > 0, "no marker moved between frames"

    windows = EpisodeDataset(root, "train", window=2, stride=1, streams=("tactile", "tactile_seq", "tactile_points"))
    item = windows[1]
    tactile, seq = item["tactile"], item["tactile_seq"]
    touches = dict(written["train"][0].touches)
    for stream, m in ((tactile, 2), (seq, len(seq["time_ns"]))):
        assert list(stream["markers"]) == pads
        for pad in pads:
            got = stream["markers"][pad]
            assert got.shape == (m, counts[pad], 4) and got.dtype == np.float32
            for j, t in enumerate(stream["time_ns"].tolist()):
                np.testing.assert_array_equal(got[j], vtdata.marker_arrays(touches[t]["markers"])[pad])
    for j in range(2):
        assert list(item["tactile_points"][j]["markers"]) == pads


def test_episode_touch_streams_check_the_markers_of_each_reading() -> None:
    """The readings of one window must have the same pads with markers, each with one count."""
    from vtdata.episodes import _touch_arrays

    rng = np.random.default_rng(3)

    def reading(**counts: int) -> Dict[str, Any]:
        markers = {pad: make_marker_flow(n, True, rng) for pad, n in counts.items()}
        return {"pads": ["a", "b"], "depth": np.zeros((2, 1, 1), np.float32), "pad": np.zeros(0, np.uint32), "markers": markers}

    out = _touch_arrays([(0, reading(a=3, b=4)), (5, reading(a=3, b=4))], "here")
    assert {pad: m.shape for pad, m in out["markers"].items()} == {"a": (2, 3, 4), "b": (2, 4, 4)}
    with pytest.raises(DatasetError, match=r"^here: the touch readings' markers of b differ in count: 0 ns 4, 5 ns 5$"):
        _touch_arrays([(0, reading(a=3, b=4)), (5, reading(a=3, b=5))], "here")
    with pytest.raises(DatasetError, match=r"^here: the touch reading at 5 ns has markers of \['a'\], the one at 0 ns of \['a', 'b'\]$"):
        _touch_arrays([(0, reading(a=3, b=4)), (5, reading(a=3))], "here")


def test_torch_gives_each_pads_markers(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import MARKER_CHANNELS, TorchDataset, collate

    assert MARKER_CHANNELS == ("x", "y", "rest_x", "rest_y")
    root = tmp_path / "ds"
    counts = {"right_pad": 5, "left_pad": 8}
    samples = write_dataset(
        root, {"train": 3}, 2, robot="robotiq_2f85", optical=("right_pad", "left_pad"), force_resolution=R, marker_count=counts
    )
    pads = ["right_pad", "left_pad"]
    item = TorchDataset(root, "train")[0]
    assert list(item["markers"]) == pads
    for pad in pads:
        markers, flow = item["markers"][pad], samples["train"][0].tactile["markers"][pad]
        assert isinstance(markers, torch.Tensor) and markers.dtype == torch.float32
        assert markers.shape == (counts[pad], 4)
        assert np.ascontiguousarray(markers[:, :2].numpy()).tobytes() == flow["position"].tobytes()
        assert np.ascontiguousarray(markers[:, 2:].numpy()).tobytes() == flow["rest"].tobytes()
    seen = 0
    for batch in DataLoader(TorchDataset(root, "train"), batch_size=2, collate_fn=collate):
        b = len(batch["index"])
        assert batch["forces"].shape == (b, 2, R, R, 4)
        for pad in pads:
            assert batch["markers"][pad].shape == (b, counts[pad], 4)
            for j, index in enumerate(batch["index"].tolist()):
                want = vtdata.marker_arrays(samples["train"][index].tactile["markers"])[pad]
                assert batch["markers"][pad][j].numpy().tobytes() == want.tobytes()
        seen += b
    assert seen == 3
    # Randomized sensors give a pad another count in another sample: collate keeps that pad's
    # markers as a list of the samples' tensors, and still stacks the pads whose counts agree.
    a = {"markers": {"left_pad": torch.zeros(3, 4), "right_pad": torch.zeros(2, 4)}}
    b = {"markers": {"left_pad": torch.ones(5, 4), "right_pad": torch.ones(2, 4)}}
    batch = collate([a, b])
    assert [tuple(t.shape) for t in batch["markers"]["left_pad"]] == [(3, 4), (5, 4)]
    assert batch["markers"]["right_pad"].shape == (2, 2, 4)
    plain = tmp_path / "plain"
    write_dataset(plain, {"train": 1}, 1, robot="robotiq_2f85", optical=("left_pad",), force_resolution=R)
    assert "markers" not in TorchDataset(plain, "train")[0]


# --- data the Rust generator wrote (MuJoCo backend) ---------------------------------------------


def marker_grid(sensor: Dict[str, Any]) -> np.ndarray:
    """``(N, 2)``: the rest positions of an optical sensor's markers (m, pad frame) from its
    ``/sample/info`` ``tactile.optical.<pad>`` entry: a square grid of its ``pitch_mm`` centred on
    the pad, as many dots along each axis as fit whole in its ``sensing_area_mm``, rows along y,
    each row along x (written independently of the generator)."""
    markers = sensor["markers"]
    p, r = markers["pitch_mm"] * 1e-3, markers["radius_mm"] * 1e-3
    nx, ny = (max(math.floor((a * 1e-3 - 2.0 * r) / p), -1) + 1 for a in sensor["sensing_area_mm"])
    return np.array(
        [[(i - (nx - 1) / 2) * p, (j - (ny - 1) / 2) * p] for j in range(ny) for i in range(nx)], dtype=np.float64
    ).reshape(-1, 2)


def test_real_marker_flow(rust_force_datasets: List[Path]) -> None:
    """Every optical pad whose sensor has markers has its flow in every sample, in pad order: the
    markers at rest on the sensor's grid (all distinct), each moved by a finite displacement of
    less than 5 mm; an episode's touch readings between frames have the same pads' markers."""
    checked = between = displaced = 0
    for root in rust_force_datasets:
        manifest = json.loads((root / "manifest.json").read_text(encoding="utf-8"))
        for split in manifest["splits"]:
            ds = Dataset(root, split)
            for i in range(len(ds)):
                sample = ds[i]
                where = f"{root.name} {split}[{i}]"
                optical = sample["info"]["tactile"].get("optical", {})
                printed = [p for p in sample.get("tactile_images", {}) if optical[p]["markers"] is not None]
                markers = sample["tactile"].get("markers", {})
                assert list(markers) == printed, f"{where}: markers of {list(markers)}, optical pads with markers {printed}"
                for pad, flow in markers.items():
                    rest = flow["rest"].astype(np.float64)
                    assert len({tuple(r) for r in flow["rest"].tolist()}) == len(rest), f"{where} {pad}: two markers rest at one place"
                    np.testing.assert_allclose(rest, marker_grid(optical[pad]), rtol=0, atol=1e-6, err_msg=f"{where} {pad}: rest grid")
                    shift = flow["position"].astype(np.float64) - rest
                    assert np.isfinite(shift).all(), f"{where} {pad}: a marker's position is not finite"
                    worst = float(np.linalg.norm(shift, axis=-1).max(initial=0.0))
                    assert worst < 5e-3, f"{where} {pad}: a marker moved {worst * 1e3:.2f} mm"
                    displaced += int((np.linalg.norm(shift, axis=-1) > 0).sum())
                    checked += 1
                for t, reading in sample.get("episode", {}).get("tactile", []):
                    assert list(reading.get("markers", {})) == printed, f"{where} touch at {t} ns"
                    between += 1
    assert checked > 0, f"no optical pad with markers in {[str(r) for r in rust_force_datasets]}"
    assert displaced > 0, "no marker moved: the flow would be the rest grid"
    print(f"marker flow: {checked} pads checked ({displaced} markers moved), {between} episode touch readings")
