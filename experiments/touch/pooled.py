#!/usr/bin/env python3
"""Touch against the trained vision-only network, pooled over several `run.sh cpu` evaluations.

    python3 experiments/touch/pooled.py EVAL_DIR...

Each EVAL_DIR is an evaluation folder (`vtpose eval` of `tactile_channel` and `vision_only`) with
its `samples-tactile_channel.csv` and `samples-vision_only.csv`. Prints one markdown table: all
samples, each occlusion bin, each evaluation's object pair and each object, with both networks'
mean position and angle errors, their share of samples under 2 cm ADD(-S) (ADD-S for symmetric
objects), and the grasps (trajectories) on which touch gives the lower mean position error,
with a two-sided exact sign test, as the per-pair reports pair them.
"""
import collections
import csv
import math
import re
import sys

BINS = ["< 80 % occluded", "80–85 %", "> 85 %"]


def load(folder, network):
    with open(f"{folder}/samples-{network}.csv", newline="") as f:
        return {(r["object"], r["index"]): r for r in csv.DictReader(f)}


def sign_test(better, worse):
    n, k = better + worse, min(better, worse)
    return 1.0 if n == 0 else min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


def occlusion_bin(level):
    level = float(level)
    return BINS[0] if level < 0.80 else BINS[1] if level <= 0.85 else BINS[2]


def add_s_cm(row):
    return float(row["adds_cm"] if row["symmetric"] == "true" else row["add_cm"])


def readable(object_id):
    return re.sub(r"^\d+_", "", object_id).replace("_", " ")


def main(folders):
    # subset -> grasp -> [(touch position, vision position, touch angle, vision angle, touch < 2 cm, vision < 2 cm)]
    subsets = collections.defaultdict(lambda: collections.defaultdict(list))
    pairs, objects = [], []
    for folder in folders:
        touch, vision = load(folder, "tactile_channel"), load(folder, "vision_only")
        pair = " + ".join(sorted({readable(r["object"]) for r in touch.values()}))
        pairs.append(pair)
        for key, t in touch.items():
            v = vision.get(key)
            if v is None:
                continue  # skipped by one network (no visible object pixel)
            name = readable(t["object"])
            if name not in objects:
                objects.append(name)
            row = (float(t["position_cm"]), float(v["position_cm"]), float(t["angle_deg"]), float(v["angle_deg"]),
                   add_s_cm(t) < 2.0, add_s_cm(v) < 2.0)
            for subset in ["all", occlusion_bin(t["occlusion"]), pair, name]:
                subsets[subset][(folder, t["object"], t["trajectory"])].append(row)
    print("| subset | samples | position, touch / vision (cm) | grasps where touch is better / worse | p "
          "| angle, touch / vision (°) | ADD(-S) < 2 cm, touch / vision (%) |")
    print("|---|---|---|---|---|---|---|")
    for subset in ["all"] + BINS + pairs + objects:
        grasps = subsets.get(subset)
        if not grasps:
            continue
        rows = [r for g in grasps.values() for r in g]
        mean = lambda i: sum(r[i] for r in rows) / len(rows)
        means = [(sum(r[0] for r in g) / len(g), sum(r[1] for r in g) / len(g)) for g in grasps.values()]
        better = sum(t < v for t, v in means)
        worse = sum(t > v for t, v in means)
        p = sign_test(better, worse)
        print(f"| {subset} | {len(rows)} | {mean(0):.3f} / {mean(1):.3f} | {better} / {worse} | "
              f"{'< 0.001' if p < 0.001 else f'{p:.3f}'} | {mean(2):.1f} / {mean(3):.1f} | "
              f"{100 * mean(4):.1f} / {100 * mean(5):.1f} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
