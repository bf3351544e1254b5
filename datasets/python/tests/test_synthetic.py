"""Reader tests on datasets written in Python (no Rust binary needed)."""

from __future__ import annotations

import json
import multiprocessing
import pickle
import shutil
import struct
import subprocess
import sys
from pathlib import Path
from typing import Dict, List

import numpy as np
import pytest
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.reader import make_reader

import vtdata
from vtdata import Dataset, DatasetError, PlyError, load_ply

from synthetic import (
    ALLEGRO_PADS,
    OBJECT_ID,
    OPTICAL_SIZE,
    ROBOTS,
    SAMPLE_PERIOD_NS,
    TACTILE_RESOLUTION,
    SyntheticSample,
    cube_mesh,
    write_dataset,
    write_shard,
)

COUNTS = {"train": 5, "test": 3}
SAMPLES_PER_SHARD = 2


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("synthetic") / "ds"
    samples = write_dataset(root, COUNTS, SAMPLES_PER_SHARD)
    return root, samples


def fresh_copy(dataset, tmp_path: Path) -> Path:
    """A copy of the module dataset that a test may modify."""
    root = tmp_path / "ds"
    shutil.copytree(dataset[0], root)
    return root


def reference_rotation(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion (x, y, z, w), written independently of vtdata."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def reference_transform(pose) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = reference_rotation(pose[1])
    T[:3, 3] = pose[0]
    return T


def assert_bit_exact(actual: np.ndarray, expected: np.ndarray, name: str) -> None:
    assert isinstance(actual, np.ndarray), name
    assert actual.dtype == expected.dtype, f"{name}: dtype {actual.dtype} != {expected.dtype}"
    assert actual.shape == expected.shape, f"{name}: shape {actual.shape} != {expected.shape}"
    assert actual.flags.c_contiguous, f"{name} is not C-contiguous"
    assert actual.flags.writeable, f"{name} is read-only"
    assert actual.tobytes() == expected.tobytes(), f"{name}: values differ"


def check_sample(sample: vtdata.Sample, expected: SyntheticSample) -> None:
    assert_bit_exact(sample["rgb"], expected.rgb, "rgb")
    assert_bit_exact(sample["depth"], expected.depth, "depth")
    assert_bit_exact(sample["mask"], expected.mask, "mask")
    assert_bit_exact(sample["K"], expected.K, "K")
    for key, pose in (
        ("T_camera_object", expected.camera_object),
        ("T_world_camera", expected.world_camera),
        ("T_world_object", expected.world_object),
    ):
        T = sample[key]
        assert T.dtype == np.float64 and T.shape == (4, 4), key
        np.testing.assert_allclose(T, reference_transform(pose), rtol=0, atol=1e-12, err_msg=key)
        assert T[:3, 3].tolist() == list(pose[0]), f"{key}: translation not exact"
        assert T[3].tolist() == [0.0, 0.0, 0.0, 1.0], key
    assert sample["info"] == expected.info
    assert sample["index"] == expected.index
    assert sample["split"] == expected.split
    assert sample.rgb is sample["rgb"]  # attribute access


def test_len_and_manifest(dataset):
    root, samples = dataset
    for split, n in COUNTS.items():
        ds = Dataset(root, split)
        assert len(ds) == n
        assert ds.split == split
        assert ds.manifest == json.loads((root / "manifest.json").read_text())
        assert len(ds.shards) == -(-n // SAMPLES_PER_SHARD)
    assert len(vtdata.open_dataset(root)) == COUNTS["train"]


def test_fixture_has_one_chunk_per_sample(dataset):
    root, _ = dataset
    for path in sorted(root.glob("*/shard-*.mcap")):
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
        starts = [c.message_start_time for c in summary.chunk_indexes]
        assert all(c.compression == "zstd" for c in summary.chunk_indexes)
        assert len(starts) == len(set(starts)) == summary.statistics.message_count // 7


def test_samples_are_bit_exact_in_any_order(dataset):
    root, samples = dataset
    rng = np.random.default_rng(1)
    for split in COUNTS:
        ds = Dataset(root, split)
        for i in rng.permutation(len(ds)):
            check_sample(ds[int(i)], samples[split][int(i)])
        for i in rng.permutation(len(ds)):  # again, with every shard already open
            check_sample(ds[np.int64(i)], samples[split][int(i)])


def test_index_comes_from_chunk_indexes(dataset):
    root, _ = dataset
    ds = Dataset(root, "train")
    for i in range(len(ds)):
        shard, log_time = ds.location(i)
        assert Path(shard) == root / "train" / f"shard-{i // SAMPLES_PER_SHARD:05d}.mcap"
        assert log_time == i * SAMPLE_PERIOD_NS


def test_negative_indices_and_index_error(dataset):
    root, samples = dataset
    ds = Dataset(root, "test")
    n = len(ds)
    check_sample(ds[-1], samples["test"][n - 1])
    check_sample(ds[-n], samples["test"][0])
    for bad in (n, n + 10, -n - 1):
        with pytest.raises(IndexError):
            ds[bad]
    with pytest.raises(TypeError):
        ds[1.5]
    with pytest.raises(TypeError):
        ds[0:2]


def test_iteration(dataset):
    root, samples = dataset
    ds = Dataset(root, "train")
    got = list(ds)
    assert [s["index"] for s in got] == list(range(COUNTS["train"]))
    for sample, expected in zip(got, samples["train"]):
        check_sample(sample, expected)


def test_unknown_split(dataset):
    with pytest.raises(KeyError, match="validation"):
        Dataset(dataset[0], "validation")


def test_missing_manifest(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        Dataset(tmp_path / "nowhere")
    with pytest.raises(FileNotFoundError, match="manifest.json"):
        Dataset(tmp_path)


def test_missing_shard_names_the_file(dataset, tmp_path):
    root = fresh_copy(dataset, tmp_path)
    missing = root / "train" / "shard-00001.mcap"
    missing.unlink()
    with pytest.raises(FileNotFoundError) as err:
        Dataset(root, "train")
    assert str(missing) in str(err.value)
    assert len(Dataset(root, "test")) == COUNTS["test"]  # the other split is unaffected


def test_unwritten_shards(dataset, tmp_path):
    root = fresh_copy(dataset, tmp_path)
    manifest_path = root / "manifest.json"
    manifest = json.loads(manifest_path.read_text())
    shards = manifest["splits"]["train"]["shards"]

    # A shard in the middle not generated yet: the indices are not contiguous.
    middle = dict(shards[1])
    shards[1]["sha256"] = shards[1]["bytes"] = None
    manifest["complete"] = False
    manifest_path.write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="not contiguous.*sample 2 is missing"):
        Dataset(root, "train")

    # Only the last shard missing: the split is the samples before it.
    shards[1] = middle
    shards[-1]["sha256"] = shards[-1]["bytes"] = None
    manifest_path.write_text(json.dumps(manifest))
    (root / shards[-1]["file"]).unlink()
    ds = Dataset(root, "train")
    assert len(ds) == 4
    check_sample(ds[3], dataset[1]["train"][3])
    with pytest.raises(IndexError):
        ds[4]


def test_manifest_shard_mismatch(dataset, tmp_path):
    root = fresh_copy(dataset, tmp_path)
    manifest_path = root / "manifest.json"
    manifest = json.loads(manifest_path.read_text())
    manifest["splits"]["train"]["shards"][0]["samples"] = 3
    manifest_path.write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="shard-00000.mcap"):
        Dataset(root, "train")


def test_wrong_manifest_format(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"format": "something-else"}))
    with pytest.raises(DatasetError, match="vtgen-dataset"):
        Dataset(tmp_path)


def test_missing_message_names_shard_and_sample(tmp_path):
    root = tmp_path / "ds"
    write_dataset(root, {"train": 4}, 2, omit=("train", 3, "/camera/mask"))
    ds = Dataset(root, "train")
    ds[2]  # the other sample of that shard is fine
    with pytest.raises(DatasetError) as err:
        ds[3]
    message = str(err.value)
    assert str(root / "train" / "shard-00001.mcap") in message
    assert "sample 3" in message and "/camera/mask" in message


def test_pickle_carries_no_file_handles(dataset):
    root, samples = dataset
    ds = Dataset(root, "train")
    check_sample(ds[0], samples["train"][0])  # opens a shard
    assert ds._open  # the handle is cached ...
    clone = pickle.loads(pickle.dumps(ds))
    assert not clone._open  # ... but not pickled
    check_sample(clone[4], samples["train"][4])
    check_sample(ds[4], samples["train"][4])


_FORKED: Dict[str, Dataset] = {}


def _read_in_child(index: int) -> bytes:
    sample = _FORKED["ds"][index]
    return sample["rgb"].tobytes() + sample["depth"].tobytes()


@pytest.mark.skipif(
    "fork" not in multiprocessing.get_all_start_methods(), reason="needs the fork start method"
)
def test_fork_reopens_files(dataset):
    root, samples = dataset
    ds = Dataset(root, "train")
    for i in range(len(ds)):
        ds[i]  # every shard open in the parent before forking
    _FORKED["ds"] = ds
    try:
        with multiprocessing.get_context("fork").Pool(2) as pool:
            order = [4, 0, 3, 1, 2, 4, 0]
            results = pool.map(_read_in_child, order)
    finally:
        _FORKED.clear()
    for i, data in zip(order, results):
        s = samples["train"][i]
        assert data == s.rgb.tobytes() + s.depth.tobytes()
    check_sample(ds[2], samples["train"][2])  # the parent's handles still work


def test_models(dataset):
    root, _ = dataset
    models = Dataset(root, "train").models()
    assert list(models) == [OBJECT_ID]
    model = models[OBJECT_ID]
    mesh = cube_mesh()
    info = json.loads((root / "models" / "models_info.json").read_text())["objects"][0]
    assert model["info"] == info
    for key in ("vertices", "normals", "faces"):
        assert_bit_exact(model[key], mesh[key], key)


def test_load_ply(dataset):
    root, _ = dataset
    mesh = load_ply(root / "models" / f"{OBJECT_ID}.ply")
    expected = cube_mesh()
    for key in ("vertices", "normals", "faces"):
        assert_bit_exact(mesh[key], expected[key], key)


def _ply(header_props: str, n_vertices: int, vertex_bytes: bytes, faces: bytes, n_faces: int,
         fmt: str = "binary_little_endian") -> bytes:
    header = (
        f"ply\r\nformat {fmt} 1.0\r\ncomment end_header is not the end\r\nobj_info x\r\n"
        f"element vertex {n_vertices}\r\n{header_props}"
        f"element face {n_faces}\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
    )
    return header.encode("ascii") + vertex_bytes + faces


def test_load_ply_generic_header(tmp_path):
    # Extra, interleaved vertex properties of several types; no normals; CRLF header.
    props = (
        "property double x\nproperty uchar red\nproperty float y\nproperty float z\n"
        "property ushort quality\n"
    )
    vertices = [(0.5, 7, 1.5, -2.0, 9), (1.0, 8, 2.0, 3.0, 10), (-1.0, 9, 0.0, 0.25, 11)]
    vbytes = b"".join(struct.pack("<dBffH", *v) for v in vertices)
    fbytes = struct.pack("<B3i", 3, 0, 1, 2)
    path = tmp_path / "generic.ply"
    path.write_bytes(_ply(props, 3, vbytes, fbytes, 1))
    mesh = load_ply(path)
    assert mesh["normals"] is None
    assert_bit_exact(
        mesh["vertices"],
        np.array([[0.5, 1.5, -2.0], [1.0, 2.0, 3.0], [-1.0, 0.0, 0.25]], dtype=np.float32),
        "vertices",
    )
    assert_bit_exact(mesh["faces"], np.array([[0, 1, 2]], dtype=np.int32), "faces")

    # Big endian is read too.
    props_be = "property float x\nproperty float y\nproperty float z\n"
    vbytes_be = b"".join(struct.pack(">fff", *v) for v in [(1, 2, 3), (4, 5, 6), (7, 8, 9)])
    path.write_bytes(_ply(props_be, 3, vbytes_be, struct.pack(">B3i", 3, 2, 1, 0), 1,
                          fmt="binary_big_endian"))
    mesh = load_ply(path)
    assert mesh["vertices"].tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
    assert mesh["faces"].tolist() == [[2, 1, 0]]


def test_load_ply_errors(tmp_path):
    path = tmp_path / "bad.ply"
    props = "property float x\nproperty float y\nproperty float z\n"
    vbytes = struct.pack("<9f", *range(9))
    path.write_bytes(_ply(props, 3, vbytes, struct.pack("<B4i", 4, 0, 1, 2, 0), 1))
    with pytest.raises(PlyError, match="only triangles"):
        load_ply(path)
    path.write_bytes(_ply(props, 3, vbytes, struct.pack("<B3i", 3, 0, 1, 3), 1))
    with pytest.raises(PlyError, match="out of range"):
        load_ply(path)
    path.write_bytes(_ply(props, 3, vbytes[:-4], b"", 0))
    with pytest.raises(PlyError, match="too short"):
        load_ply(path)
    path.write_bytes(b"ply\nformat ascii 1.0\nend_header\n")
    with pytest.raises(PlyError, match="ascii"):
        load_ply(path)


def _raw(array: np.ndarray, encoding: str, pad: int) -> RawImage:
    h, w = array.shape[:2]
    row = array.reshape(h, -1).view(np.uint8).reshape(h, -1)
    padded = np.full((h, row.shape[1] + pad), 0xAB, dtype=np.uint8)
    padded[:, : row.shape[1]] = row
    data = padded.tobytes()[:-pad] if pad else padded.tobytes()  # last row may be unpadded
    return RawImage(width=w, height=h, encoding=encoding, step=row.shape[1] + pad, data=data)


@pytest.mark.parametrize("pad", [0, 5])
def test_decode_raw_image_honours_step(pad):
    rng = np.random.default_rng(2)
    cases = [
        ("rgb8", rng.integers(0, 256, (4, 5, 3), dtype=np.uint8)),
        ("mono8", rng.integers(0, 256, (4, 5), dtype=np.uint8)),
        ("mono16", rng.integers(0, 65536, (4, 5), dtype=np.uint16)),
        ("32FC1", rng.normal(size=(4, 5)).astype(np.float32)),
    ]
    for encoding, array in cases:
        decoded = vtdata.decode_raw_image(_raw(array.astype(array.dtype.newbyteorder("<")),
                                               encoding, pad))
        assert_bit_exact(decoded, array, encoding)


def test_decode_raw_image_errors():
    image = RawImage(width=4, height=2, encoding="rgb8", step=12, data=bytes(23))
    with pytest.raises(DatasetError, match="needs 24 bytes"):
        vtdata.decode_raw_image(image)
    with pytest.raises(DatasetError, match="expected encoding 'mono8'"):
        vtdata.decode_raw_image(image, expect="mono8")
    with pytest.raises(DatasetError, match="step 11"):
        vtdata.decode_raw_image(
            RawImage(width=4, height=2, encoding="rgb8", step=11, data=bytes(24))
        )
    with pytest.raises(DatasetError, match="unsupported image encoding 'bgr8'"):
        vtdata.decode_raw_image(RawImage(width=1, height=1, encoding="bgr8", step=3, data=bytes(3)))


def test_quaternion_matrix():
    rng = np.random.default_rng(3)
    assert np.array_equal(vtdata.quaternion_matrix((0, 0, 0, 1)), np.eye(3))
    for _ in range(100):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        R = vtdata.quaternion_matrix(q)
        np.testing.assert_allclose(R, reference_rotation(q), rtol=0, atol=1e-15)
        np.testing.assert_allclose(R @ R.T, np.eye(3), rtol=0, atol=1e-14)
        # q and -q are the same rotation
        np.testing.assert_allclose(vtdata.quaternion_matrix(-q), R, rtol=0, atol=1e-15)


# --- robots: the pads, joints and their counts come from the data --------------------------------


@pytest.mark.parametrize("reverse", [False, True], ids=["writer-order", "reversed-messages"])
@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_tactile_of_any_robot(tmp_path, robot, reverse):
    """The Allegro's 12 pads, a parallel gripper's 2 (not in name order), a 3-finger gripper's 6:
    the pads are the shard's ``/tactile/<pad>/depth`` topics in their channels' order (the order of
    the points' pad index), whatever order the messages of a chunk come in."""
    root = tmp_path / "ds"
    samples = write_dataset(root, {"train": 3}, 2, robot=robot, reverse_messages=reverse)
    pads = list(ROBOTS[robot]["pads"])
    if robot == "ur5e_allegro":
        assert pads == list(ALLEGRO_PADS) and len(pads) == 12
    ds = Dataset(root, "train")
    for i, expected in enumerate(samples["train"]):
        sample = ds[i]
        check_sample(sample, expected)
        t, want = sample["tactile"], expected.tactile
        assert t["pads"] == pads
        assert "phalanx" not in t and "phalanges" not in t, "the reader says pad, not the wire name"
        r = TACTILE_RESOLUTION
        assert t["depth"].shape == (len(pads), r, r)
        assert_bit_exact(t["depth"], want["depth"], "tactile depth")
        assert_bit_exact(t["points"], want["points"], "tactile points")
        assert_bit_exact(t["distance"], want["distance"], "tactile distance")
        assert_bit_exact(t["pad"], want["pad"], "tactile pad index")
        counts = sample["info"]["tactile"]["points"]
        assert sum(counts.values()) == len(t["points"]) > 0
        for k, name in enumerate(t["pads"]):
            assert int((t["pad"] == k).sum()) == counts[name], name
        touched = {t["pads"][k] for k in np.unique(t["pad"]).tolist()}
        assert touched <= set(sample["info"]["phalanges_in_contact"])
        assert len(sample["info"]["joint_positions"]) == len(ROBOTS[robot]["joints"])


def test_tactile_pads_must_match_the_info(tmp_path):
    """A pad ``/sample/info`` lists without its depth image is a damaged sample, named."""
    root = tmp_path / "ds"
    write_dataset(root, {"train": 2}, 2, robot="robotiq_2f85", omit=("train", 1, "/tactile/left_pad/depth"))
    ds = Dataset(root, "train")
    assert ds[0]["tactile"]["pads"] == ["right_pad", "left_pad"]
    with pytest.raises(DatasetError, match=r"sample 1 .*tactile\.pads lists the pads \['left_pad', 'right_pad'\]"):
        ds[1]


def test_tactile_pad_index_beyond_the_pads():
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

    from vtdata.reader import _tactile

    image = RawImage(width=2, height=2, encoding="32FC1", step=8, data=bytes(16))
    cloud = PointCloud(point_stride=20, data=struct.pack("<4fI", 0, 0, 0, 0, 2))
    decoded = {"/tactile/points": cloud, "/tactile/a/depth": image, "/tactile/b/depth": image}
    ids = {"/tactile/points": 9, "/tactile/b/depth": 10, "/tactile/a/depth": 11}
    with pytest.raises(DatasetError, match="pad index 2 but the sample has 2 pads"):
        _tactile(decoded, ids, "here")
    cloud.data = struct.pack("<4fI", 0, 0, 0, 0, 1)
    assert _tactile(decoded, ids, "here")["pads"] == ["b", "a"]
    with pytest.raises(DatasetError, match="no /tactile/<pad>/depth"):
        _tactile({"/tactile/points": cloud}, ids, "here")


def test_densefusion_and_torch_of_a_gripper(tmp_path):
    """The DenseFusion view and the torch wrapper take a 2-pad gripper's tactile points as they
    take the Allegro's."""
    root = tmp_path / "ds"
    samples = write_dataset(root, {"train": 3}, 2, robot="robotiq_2f85")
    view = vtdata.DenseFusionView(root, "train", n_tactile=8, n_points=4, crop_size=None)
    for i, expected in enumerate(samples["train"]):
        item = view[i]
        assert int(item["tactile_count"]) == len(expected.tactile["points"])
        rows = {p.tobytes() for p in expected.tactile["points"]}
        assert item["tactile"].shape == (8, 3) and all(p.tobytes() in rows for p in item["tactile"])
    pytest.importorskip("torch")
    from vtdata.torch import TorchDataset, collate

    batch = collate([TorchDataset(root, "train")[i] for i in range(2)])
    assert [t["pads"] for t in batch["tactile"]] == [["right_pad", "left_pad"]] * 2


# --- optical tactile sensors: /tactile/<pad>/image and /tactile/<pad>/reference -------------------


@pytest.mark.parametrize("reverse", [False, True], ids=["writer-order", "reversed-messages"])
@pytest.mark.parametrize(
    "robot, optical, order",
    [
        # Both pads of the gripper, in its pad order (not name order).
        ("robotiq_2f85", ("left_pad", "right_pad"), ["right_pad", "left_pad"]),
        # Only some pads of the hand (the distal ones of two fingers).
        ("ur5e_allegro", ("th_distal", "ff_distal"), ["ff_distal", "th_distal"]),
    ],
)
def test_optical_images_of_some_pads(tmp_path, robot, optical, order, reverse):
    """The optical pads' RGB and reference images come as ``{pad: (H, W, 3) uint8}`` in pad order,
    only for the pads that have them, next to the depth images of every pad."""
    root = tmp_path / "ds"
    samples = write_dataset(
        root, {"train": 3}, 2, robot=robot, optical=optical, reverse_messages=reverse
    )
    w, h = OPTICAL_SIZE
    ds = Dataset(root, "train")
    for i, expected in enumerate(samples["train"]):
        sample = ds[i]
        check_sample(sample, expected)
        assert sample["tactile"]["pads"] == list(ROBOTS[robot]["pads"])
        images, references = sample["tactile_images"], sample["tactile_references"]
        assert list(images) == list(references) == order
        assert sample.tactile_images is images  # attribute access
        for pad in order:
            assert images[pad].shape == references[pad].shape == (h, w, 3)
            assert_bit_exact(images[pad], expected.tactile["images"][pad], f"{pad} image")
            assert_bit_exact(references[pad], expected.tactile["references"][pad], f"{pad} reference")
            assert sample["info"]["tactile"]["optical"][pad]["image_size"] == [w, h]


def test_no_optical_images_without_optical_sensors(dataset, tmp_path):
    """Without an optical pad (with or without a robot) the keys are absent, as ``depth_noisy``."""
    root = tmp_path / "ds"
    write_dataset(root, {"train": 2}, 2, robot="robotiq_2f85")
    for ds in (Dataset(root, "train"), Dataset(dataset[0], "train")):
        sample = ds[0]
        assert "tactile_images" not in sample and "tactile_references" not in sample


def test_optical_image_errors(tmp_path):
    """A wrong encoding, a missing reference, images the info does not list, or the wrong size: a
    ``DatasetError`` naming the sample and the topic."""
    kw = dict(robot="robotiq_2f85", optical=("left_pad",))

    root = tmp_path / "bgr"
    write_dataset(root, {"train": 1}, 1, optical_encoding="bgr8", **kw)
    with pytest.raises(DatasetError, match=r"sample 0 .*/tactile/left_pad/image: expected encoding 'rgb8', found 'bgr8'"):
        Dataset(root, "train")[0]

    root = tmp_path / "no-reference"
    write_dataset(root, {"train": 2}, 2, omit=("train", 1, "/tactile/left_pad/reference"), **kw)
    ds = Dataset(root, "train")
    assert list(ds[0]["tactile_images"]) == ["left_pad"]
    with pytest.raises(DatasetError, match=r"sample 1 .*/tactile/left_pad/image without its /tactile/left_pad/reference"):
        ds[1]

    root = tmp_path / "no-image"
    write_dataset(root, {"train": 1}, 1, omit=("train", 0, "/tactile/left_pad/image"), **kw)
    with pytest.raises(DatasetError, match=r"sample 0 .*: /sample/info tactile\.optical lists the optical pads \['left_pad'\], the sample has optical images of \[\]"):
        Dataset(root, "train")[0]

    # /sample/info lists an optical pad whose images are missing, or another image size.
    root = tmp_path / "info"
    samples = write_dataset(root, {"train": 2}, 2, **kw)["train"]
    samples[0].info["tactile"]["optical"]["right_pad"] = samples[0].info["tactile"]["optical"]["left_pad"]
    samples[1].info["tactile"]["optical"]["left_pad"]["image_size"] = [4, 3]
    write_shard(root / "train" / "shard-00000.mcap", "train", 0, samples)
    ds = Dataset(root, "train")
    with pytest.raises(DatasetError, match=r"tactile\.optical lists the optical pads \['left_pad', 'right_pad'\], the sample has optical images of \['left_pad'\]"):
        ds[0]
    with pytest.raises(DatasetError, match=r"sample 1 .*/tactile/left_pad/image is 5x3, but /sample/info tactile\.optical\.left_pad\.image_size is \[4, 3\]"):
        ds[1]


def test_optical_images_must_be_of_tactile_pads():
    from vtdata.reader import _optical

    rgb = RawImage(width=2, height=1, encoding="rgb8", step=6, data=bytes(range(6)))
    small = RawImage(width=1, height=1, encoding="rgb8", step=3, data=bytes(3))
    decoded = {"/tactile/a/image": rgb, "/tactile/a/reference": rgb}
    pads = ["b", "a"]
    images, references = _optical(decoded, {}, "here", pads)
    assert images["a"].tolist() == [[[0, 1, 2], [3, 4, 5]]] and references["a"].shape == (1, 2, 3)
    assert _optical({}, {}, "here", pads) is None
    with pytest.raises(DatasetError, match="optical images of a but no /tactile/points"):
        _optical(decoded, {}, "here", None)
    with pytest.raises(DatasetError, match="optical images of a, which are not pads of the sample"):
        _optical(decoded, {}, "here", ["b"])
    with pytest.raises(DatasetError, match=r"^here: reference images of a, which are not optical pads of the sample \(no /tactile/<pad>/image\)$"):
        _optical({"/tactile/a/reference": rgb}, {}, "here", pads)
    with pytest.raises(DatasetError, match="/tactile/a/reference is 1x1, its image 2x1"):
        _optical({**decoded, "/tactile/a/reference": small}, {}, "here", pads)


def test_every_pad_stream_is_read_by_the_shared_reader():
    """Every ``/tactile/<pad>/...`` stream of the format is one ``_PadStream`` read by
    ``_pad_stream``: the same errors, whatever the stream, for a pad the sample does not have and
    for a pad stream without tactile data."""
    from vtdata import decoders as d

    streams = [d.PAD_DEPTH, d.PAD_IMAGE, d.PAD_REFERENCE, d.PAD_FORCE, d.PAD_MARKERS]
    assert {s.suffix for s in streams} == set(vtdata.format.PAD_TOPIC_SCHEMAS)
    for stream in streams:
        decoded = {f"/tactile/a{stream.suffix}": None}  # refused before it is decoded
        with pytest.raises(DatasetError, match=rf"^here: {stream.what} of a, which are not pads of the sample \(no /tactile/<pad>/depth; pads: b\)$"):
            d._pad_stream(decoded, {}, "here", stream, ["b"])
        with pytest.raises(DatasetError, match=rf"^here: {stream.what} of a but no /tactile/points "):
            d._pad_stream(decoded, {}, "here", stream, None)
        assert d._pad_stream({}, {}, "here", stream, None) == ({}, None)


@pytest.mark.parametrize(
    "topic",
    [
        "/tactile/points",
        "/tactile/left_pad/depth",
        "/tactile/left_pad/image",
        "/tactile/left_pad/reference",
        "/tactile/left_pad/force",
        "/tactile/left_pad/markers",
        "/camera/rgb",
    ],
)
def test_a_topic_twice_in_a_sample_is_refused(tmp_path, topic):
    """Two messages of one sample on a topic the reader decodes (any pad stream among them): a
    ``DatasetError`` naming the shard, the sample and the topic, not the last one silently."""
    root = tmp_path / "ds"
    kw = dict(robot="robotiq_2f85", optical=("left_pad",), force_resolution=2, marker_count=4)
    samples = write_dataset(root, {"train": 2}, 2, **kw)["train"]
    shard = root / "train" / "shard-00000.mcap"
    write_shard(shard, "train", 0, samples, repeat=(1, topic))
    ds = Dataset(root, "train")
    assert list(ds[0]["tactile"]["forces"]) == ["right_pad", "left_pad"]
    with pytest.raises(DatasetError, match=rf"^{shard}: sample 1 of split 'train': more than one {topic} message$"):
        ds[1]


def test_torch_passes_optical_images_through(tmp_path):
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import TorchDataset, collate, to_tensors

    root = tmp_path / "ds"
    samples = write_dataset(root, {"train": 3}, 2, robot="robotiq_2f85", optical=("left_pad",))
    w, h = OPTICAL_SIZE
    item = TorchDataset(root, "train")[0]
    for key, want in (("tactile_images", "images"), ("tactile_references", "references")):
        assert list(item[key]) == ["left_pad"]
        image = item[key]["left_pad"]
        assert isinstance(image, torch.Tensor) and image.dtype == torch.uint8
        assert image.shape == (h, w, 3)  # as rgb: (H, W, 3), no reordering or scaling
        assert image.numpy().tobytes() == samples["train"][0].tactile[want]["left_pad"].tobytes()
    assert to_tensors({"tactile_images": {}})["tactile_images"] == {}

    loader = DataLoader(TorchDataset(root, "train"), batch_size=2, collate_fn=collate)
    seen = 0
    for batch in loader:
        b = len(batch["index"])
        for key, want in (("tactile_images", "images"), ("tactile_references", "references")):
            assert list(batch[key]) == ["left_pad"]
            stacked = batch[key]["left_pad"]
            assert stacked.shape == (b, h, w, 3) and stacked.dtype == torch.uint8
            for j, index in enumerate(batch["index"].tolist()):
                expected = samples["train"][index].tactile[want]["left_pad"]
                assert stacked[j].numpy().tobytes() == expected.tobytes()
        assert isinstance(batch["tactile"], list)  # the tactile dict stays one per sample
        seen += b
    assert seen == 3


def test_import_does_not_import_torch():
    code = "import sys, vtdata; vtdata.Dataset; assert 'torch' not in sys.modules, 'torch imported'"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_torch_dataloader(dataset):
    torch = pytest.importorskip("torch")
    from torch.utils.data import DataLoader

    from vtdata.torch import TorchDataset, collate

    root, samples = dataset
    ds = TorchDataset(root, "train")
    assert isinstance(ds, torch.utils.data.Dataset)
    assert vtdata.TorchDataset is TorchDataset
    item = ds[1]
    assert item["rgb"].dtype == torch.uint8 and item["rgb"].shape == (6, 8, 3)
    assert item["depth"].dtype == torch.float32 and item["mask"].dtype == torch.uint8
    assert item["K"].dtype == torch.float64 and item["T_camera_object"].dtype == torch.float64
    assert item["info"] == samples["train"][1].info

    loader = DataLoader(ds, batch_size=2, num_workers=2, collate_fn=collate)
    seen: List[int] = []
    for batch in loader:
        b = batch["rgb"].shape[0]
        assert batch["rgb"].shape == (b, 6, 8, 3)
        assert batch["depth"].shape == (b, 6, 8) and batch["mask"].shape == (b, 6, 8)
        assert batch["K"].shape == (b, 3, 3) and batch["T_world_object"].shape == (b, 4, 4)
        assert batch["index"].dtype == torch.int64
        assert isinstance(batch["info"], list) and len(batch["info"]) == b
        assert batch["split"] == ["train"] * b
        for j, index in enumerate(batch["index"].tolist()):
            expected = samples["train"][index]
            assert batch["rgb"][j].numpy().tobytes() == expected.rgb.tobytes()
            assert batch["depth"][j].numpy().tobytes() == expected.depth.tobytes()
            assert batch["info"][j] == expected.info
        seen += batch["index"].tolist()
    assert seen == list(range(COUNTS["train"]))

    flipped = TorchDataset(root, "train", transform=lambda s: s["rgb"].flip(0))
    assert torch.equal(flipped[0], torch.from_numpy(samples["train"][0].rgb).flip(0))
