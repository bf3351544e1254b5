"""Run the BOP toolkit's scripts on a ``vtgen export bop`` directory.

The BOP toolkit (https://github.com/thodan/bop_toolkit, not on PyPI) knows its datasets by name:
``bop_toolkit_lib.dataset_params`` holds a fixed list of object ids and split parameters. This
module adds an exported dataset to that list under a name of your choosing, so the toolkit's own
scripts run on it unchanged::

    vtgen export bop out/paper $BOP_PATH/vtgen          # the export, in the toolkit's datasets folder
    export BOP_PATH=...                                 # the toolkit's datasets folder (its config.py)
    python -m vtdata.bop --name vtgen /path/to/bop_toolkit/scripts/calc_gt_distribution.py \\
        --dataset vtgen --dataset_split test

``python -m vtdata.bop [--name NAME] SCRIPT [ARGS...]`` registers ``NAME`` (default ``vtgen``) and
runs ``SCRIPT`` with ``ARGS`` as ``__main__``. Scripts that start other toolkit scripts in new
Python processes (``eval_bop19_pose.py`` runs ``eval_calc_errors.py``) get the registration too:
the launcher puts a ``sitecustomize`` on their ``PYTHONPATH`` that registers the same name.

From Python, ``vtdata.bop.register("vtgen")`` does the same for the current process.

What the toolkit gets for the registered name: ``obj_ids`` and ``symmetric_obj_ids`` (objects with
``symmetries_discrete`` or ``symmetries_continuous``) from ``models/models_info.json``; per split,
the scene ids (the exported shards), the image size from ``camera.json``, the classic BOP path
templates, RGB and depth as PNG. ``get_camera_params`` needs nothing: it reads ``camera.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import runpy
import sys
from os.path import join
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional

#: The environment variable the subprocess hook reads (the registered name).
ENV_NAME = "VTDATA_BOP_DATASET"

#: Pose error functions that need nothing but the models (VSD also needs per-dataset tolerances).
SUPPORTED_ERRORS = ["ad", "add", "adi", "mssd", "mspd", "cus", "proj"]


def model_params(datasets_path: str, name: str) -> Dict[str, Any]:
    """``dataset_params.get_model_params`` for an exported dataset."""
    models_path = join(datasets_path, name, "models")
    info_path = join(models_path, "models_info.json")
    with open(info_path, "r", encoding="utf-8") as f:
        info = json.load(f)
    obj_ids = sorted(int(k) for k in info)
    symmetric = [
        i
        for i in obj_ids
        if info[str(i)].get("symmetries_discrete") or info[str(i)].get("symmetries_continuous")
    ]
    return {
        "obj_ids": obj_ids,
        "symmetric_obj_ids": symmetric,
        "model_tpath": join(models_path, "obj_{obj_id:06d}.ply"),
        "models_info_path": info_path,
    }


def split_params(datasets_path: str, name: str, split: str) -> Dict[str, Any]:
    """``dataset_params.get_split_params`` for an exported dataset (classic BOP layout)."""
    base_path = join(datasets_path, name)
    split_path = join(base_path, split)
    with open(join(base_path, "camera.json"), "r", encoding="utf-8") as f:
        camera = json.load(f)
    scenes: List[int] = (
        sorted(int(d.name) for d in Path(split_path).iterdir() if d.is_dir() and d.name.isdigit())
        if os.path.isdir(split_path)
        else []
    )
    scene = join(split_path, "{scene_id:06d}")
    return {
        "name": name,
        "split": split,
        "split_type": None,
        "base_path": base_path,
        "depth_range": None,
        "azimuth_range": None,
        "elev_range": None,
        "im_modalities": ["rgb", "depth"],
        "eval_sensor": None,
        "eval_modality": None,
        "scene_ids": scenes,
        "im_size": (int(camera["width"]), int(camera["height"])),
        "split_path": split_path,
        "supported_error_types": list(SUPPORTED_ERRORS),
        "gray_tpath": join(scene, "gray", "{im_id:06d}.png"),
        "rgb_tpath": join(scene, "rgb", "{im_id:06d}.png"),
        "depth_tpath": join(scene, "depth", "{im_id:06d}.png"),
        "scene_camera_tpath": join(scene, "scene_camera.json"),
        "scene_gt_tpath": join(scene, "scene_gt.json"),
        "scene_gt_info_tpath": join(scene, "scene_gt_info.json"),
        "scene_gt_coco_tpath": join(scene, "scene_gt_coco.json"),
        "mask_tpath": join(scene, "mask", "{im_id:06d}_{gt_id:06d}.png"),
        "mask_visib_tpath": join(scene, "mask_visib", "{im_id:06d}_{gt_id:06d}.png"),
    }


def register(name: str = "vtgen") -> None:
    """Make ``bop_toolkit_lib.dataset_params`` answer for ``name`` (other names are unchanged)."""
    from bop_toolkit_lib import dataset_params  # the toolkit, installed or on PYTHONPATH

    original_model: Callable[..., Dict[str, Any]] = dataset_params.get_model_params
    original_split: Callable[..., Dict[str, Any]] = dataset_params.get_split_params
    if getattr(original_model, "_vtdata_name", None) == name:
        return

    def get_model_params(datasets_path: str, dataset_name: str, model_type: Optional[str] = None):
        if dataset_name == name:
            return model_params(datasets_path, name)
        return original_model(datasets_path, dataset_name, model_type)

    def get_split_params(datasets_path: str, dataset_name: str, split: str, split_type: Optional[str] = None):
        if dataset_name == name:
            return split_params(datasets_path, name, split)
        return original_split(datasets_path, dataset_name, split, split_type)

    get_model_params._vtdata_name = name  # type: ignore[attr-defined]
    dataset_params.get_model_params = get_model_params
    dataset_params.get_split_params = get_split_params


def main(argv: Optional[List[str]] = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m vtdata.bop",
        description="Run a BOP toolkit script with a vtgen BOP export registered as a dataset.",
    )
    parser.add_argument("--name", default="vtgen", help="the dataset name (its folder under BOP_PATH)")
    parser.add_argument("script", help="a bop_toolkit script, e.g. scripts/calc_gt_distribution.py")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the script's own arguments")
    a = parser.parse_args(argv)
    register(a.name)
    # Toolkit scripts that start other scripts in new processes register the name there too.
    hook = str(Path(__file__).resolve().parent / "_bop_site")
    os.environ[ENV_NAME] = a.name
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [hook, os.environ.get("PYTHONPATH")]))
    script = str(Path(a.script).resolve())
    sys.argv = [script, *a.args]
    sys.path.insert(0, str(Path(script).parent))
    runpy.run_path(script, run_name="__main__")


if __name__ == "__main__":
    main()
