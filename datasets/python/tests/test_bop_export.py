"""``vtgen export bop``, read back with standard tools: the models load in ``plyfile`` (in mm), and
the exported ground truth (``scene_gt.json`` with ``scene_camera.json``) re-projects onto the exported
16-bit depth and visible masks, the same check the generator makes on its own shards."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from plyfile import PlyData

from vtgen_cli import run


@pytest.fixture(scope="module")
def bop(vtgen_bin: str, rust_hand_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bop") / "export"
    run([vtgen_bin, "export", "bop", str(rust_hand_dataset), str(out), "--quiet"], 600)
    return out


def _models(bop: Path):
    info = json.loads((bop / "models" / "models_info.json").read_text())
    models = {}
    for obj_id in info:
        ply = PlyData.read(str(bop / "models" / f"obj_{int(obj_id):06d}.ply"))
        v = ply["vertex"]
        pts = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
        nrm = np.stack([v["nx"], v["ny"], v["nz"]], axis=1).astype(np.float64)
        faces = np.stack(ply["face"]["vertex_indices"]).astype(np.int64)
        models[int(obj_id)] = (pts, nrm, faces)
    return info, models


def _surface_points(pts: np.ndarray, faces: np.ndarray, n: int = 3000):
    """Points spread over the surface by area, with their face normals (seeded: reproducible)."""
    a, b, c = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    rng = np.random.default_rng(0)
    tri = rng.choice(len(faces), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    p = (1 - s)[:, None] * a[tri] + (s * (1 - r2))[:, None] * b[tri] + (s * r2)[:, None] * c[tri]
    return p, cross[tri] / area[tri, None]


def test_models_load_in_plyfile_in_millimetres(bop: Path, rust_hand_dataset: Path) -> None:
    info, models = _models(bop)
    ours = json.loads((rust_hand_dataset / "models" / "models_info.json").read_text())["objects"]
    ids = json.loads((bop / "vtgen_objects.json").read_text())["obj_id_to_object_id"]
    assert len(models) == len(ours) >= 2
    for o in ours:
        obj_id = o["object_index"] + 1
        assert ids[str(obj_id)] == o["id"]
        pts, nrm, _ = models[obj_id]
        size = pts.max(axis=0) - pts.min(axis=0)
        np.testing.assert_allclose(size, np.array(o["extents"]) * 1000.0, atol=0.01)
        entry = info[str(obj_id)]
        np.testing.assert_allclose([entry["size_x"], entry["size_y"], entry["size_z"]], size, atol=1e-3)
        assert entry["diameter"] == pytest.approx(o["diameter"] * 1000.0)
        np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-3)


def test_ground_truth_reprojects_onto_exported_depth_and_masks(bop: Path, rust_hand_dataset: Path) -> None:
    _, models = _models(bop)
    checked = 0
    for split in ("train", "test"):
        for scene in sorted((bop / split).iterdir()):
            cams = json.loads((scene / "scene_camera.json").read_text())
            gts = json.loads((scene / "scene_gt.json").read_text())
            infos = json.loads((scene / "scene_gt_info.json").read_text())
            assert cams.keys() == gts.keys() == infos.keys()
            for im_id, gt_list in gts.items():
                (gt,) = gt_list
                cam = cams[im_id]
                K = np.array(cam["cam_K"]).reshape(3, 3)
                R = np.array(gt["cam_R_m2c"]).reshape(3, 3)
                t = np.array(gt["cam_t_m2c"])
                depth = np.asarray(Image.open(scene / "depth" / f"{int(im_id):06d}.png")).astype(np.float64) * cam["depth_scale"]
                visib = np.asarray(Image.open(scene / "mask_visib" / f"{int(im_id):06d}_000000.png")) > 0
                full = np.asarray(Image.open(scene / "mask" / f"{int(im_id):06d}_000000.png")) > 0
                info = infos[im_id][0]
                assert info["px_count_visib"] == visib.sum() and info["px_count_all"] == full.sum()
                # The visible part lies inside the full silhouette (edge pixels aside).
                assert (visib & ~full).sum() <= 0.02 * max(1, visib.sum())
                pts, nrm = _surface_points(*models[gt["obj_id"]][::2])
                pc = pts @ R.T + t
                nc = nrm @ R.T
                facing = np.einsum("ij,ij->i", nc, -pc / np.linalg.norm(pc, axis=1, keepdims=True)) > 0.3
                u = np.rint(K[0, 0] * pc[:, 0] / pc[:, 2] + K[0, 2]).astype(int)
                v = np.rint(K[1, 1] * pc[:, 1] / pc[:, 2] + K[1, 2]).astype(int)
                h, w = depth.shape
                inside = facing & (u >= 1) & (v >= 1) & (u < w - 1) & (v < h - 1)
                u, v, z = u[inside], v[inside], pc[inside, 2]
                d = depth[v, u]
                visible = (d == 0) | (d >= z - 2.0)  # nothing drawn more than 2 mm in front
                if visible.sum() < 30:
                    continue  # hidden by the hand
                u, v, z = u[visible], v[visible], z[visible]
                agree = np.zeros(len(z), dtype=bool)
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        agree |= visib[v + dy, u + dx] & (np.abs(depth[v + dy, u + dx] - z) <= 2.0)
                assert agree.mean() >= 0.99, f"{scene.name}/{im_id}: {agree.mean():.3f} of {len(z)} agree"
                checked += 1
    assert checked >= 10


def test_the_bop_toolkit_reads_the_export(bop: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With ``bop_toolkit_lib`` importable (it is not on PyPI: put a checkout of
    github.com/thodan/bop_toolkit on ``PYTHONPATH``), the toolkit's own code reads the export once
    ``vtdata.bop`` registered it: ``dataset_params``, ``inout.load_scene_gt``, its test targets
    (``inout.get_im_targets``) and its boxes (``misc.calc_2d_bbox`` over the exported masks, as
    ``calc_gt_info.py`` computes them)."""
    pytest.importorskip("bop_toolkit_lib", reason="bop_toolkit_lib is not installed (not on PyPI)")
    from bop_toolkit_lib import dataset_params, inout, misc

    import vtdata.bop

    datasets = tmp_path / "bop"
    datasets.mkdir()
    (datasets / "vtgen").symlink_to(bop)
    vtdata.bop.register("vtgen")
    models = dataset_params.get_model_params(str(datasets), "vtgen")
    info = inout.load_json(models["models_info_path"], keys_to_int=True)
    assert models["obj_ids"] == sorted(info)
    for obj_id in models["obj_ids"]:
        assert Path(models["model_tpath"].format(obj_id=obj_id)).is_file()
    targets = inout.load_json(str(datasets / "vtgen" / "test_targets_bop19.json"))
    split = dataset_params.get_split_params(str(datasets), "vtgen", "test")
    assert split["scene_ids"] and split["im_size"] == tuple(json.loads((bop / "camera.json").read_text())[k] for k in ("width", "height"))
    expected = []
    for scene_id in split["scene_ids"]:
        scene_gt = inout.load_scene_gt(split["scene_gt_tpath"].format(scene_id=scene_id))
        scene_gt_info = inout.load_json(split["scene_gt_info_tpath"].format(scene_id=scene_id), keys_to_int=True)
        for im_id, gts in scene_gt.items():
            im_targets = inout.get_im_targets(gts, scene_gt_info[im_id], 0.0, "localization")
            expected += [
                {"im_id": im_id, "inst_count": t["inst_count"], "obj_id": obj_id, "scene_id": scene_id}
                for obj_id, t in im_targets.items()
                if scene_gt_info[im_id][0]["px_count_visib"] > 0
            ]
            for gt_id, gt_info in enumerate(scene_gt_info[im_id]):
                for key, tpath in (("bbox_obj", "mask_tpath"), ("bbox_visib", "mask_visib_tpath")):
                    mask = np.asarray(Image.open(split[tpath].format(scene_id=scene_id, im_id=im_id, gt_id=gt_id)))
                    ys, xs = mask.nonzero()
                    box = [-1, -1, -1, -1] if len(xs) == 0 else [int(v) for v in misc.calc_2d_bbox(xs, ys)]
                    assert gt_info[key] == box, (scene_id, im_id, key)
    order = lambda t: (t["scene_id"], t["im_id"])  # noqa: E731
    assert sorted(targets, key=order) == sorted(expected, key=order)
