"""fit-skin --skeleton on every capture: the joints and the tree found, and what holding them costs.

For each capture in ../shared/data (and the built-in walker) it runs, as a user would,
``skinsynth fit-skin INPUT --bones B --skeleton --json`` and prints one JSON line: the jointed
rig's RMSE over the free fit's at the same bones (``rmse_over_free``), the joints (how many, how
many inside the mesh by winding number, the largest drift over the rest diagonal), the sliding
bones (each with its parent and its travel over the diagonal), the free bones hanging from the
root, where the root bone's skin is centred (a share of the height: ``root_height``) and the tree's
depth, the share of non-root bones on fixed joints, the feet (leaf bones whose rest centroid lies
in the lowest 15 % of the height) with the fixed and sliding joints on each one's path to the
root, the seconds and the peak memory, and the free fit of the same bones run as its own command
(``free_seconds``, ``seconds_over_free``: the whole commands'). With ``--surplus S`` the skeleton
is grown from (1 + S) times the bones and pruned (``--surplus-bones``), its error over that free
fit's.

    python benchmarks/skeleton.py [--only NAME] [--work DIR] [--surplus S]
"""

import argparse
import json
import os
import pathlib
import tempfile

import numpy as np
from datasets import BONES, captures, run


def feet_paths(path, summary):
    """[(bone, fixed joints, sliding joints on its path to the root)] for the leaf bones low in the rest pose."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.influence import bone_centroids

    skin = read_skin(path)
    parents = np.asarray(summary["parents"])
    jointed = np.asarray(skin.skeleton["jointed"])
    sliding = skin.skeleton["sliding"]
    up = 1 if skin.scene.up_axis == "Y" else 2
    centres = bone_centroids(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.bones)
    low = skin.rest_vertices[:, up].min() + 0.15 * np.ptp(skin.rest_vertices[:, up])
    leaves = [b for b in range(skin.bones) if b not in parents and centres[b, up] < low]
    paths = []
    for bone in leaves:
        fixed, slid, node = 0, 0, bone
        while parents[node] >= 0:
            fixed, slid = fixed + int(jointed[node]), slid + int(sliding[node])
            node = parents[node]
        paths.append((int(bone), fixed, slid))
    return paths


def root_place(path, summary):
    """(height, depth): where the root bone's skin is centred along the up axis, as a share of the
    height above the lowest point (a human's pelvis: about 0.5), and the tree's depth (bones on the
    longest path from the root, the root's excluded)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.influence import dense_weights

    skin = read_skin(path)
    parents = np.asarray(summary["parents"])
    up = 1 if skin.scene.up_axis == "Y" else 2
    height = skin.rest_vertices[:, up]
    weights = dense_weights(skin.bone_indices, skin.bone_weights, skin.bones)[:, summary["root"]]
    centre = float(weights @ height / weights.sum())
    depth = 0
    for bone in range(parents.size):
        steps, node = 0, bone
        while parents[node] >= 0:
            steps, node = steps + 1, parents[node]
        depth = max(depth, steps)
    return round((centre - height.min()) / np.ptp(height), 3), depth


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=None)
    parser.add_argument("--work", default=None, help="folder kept between runs")
    parser.add_argument("--surplus", type=float, default=0.0, help="fit-skin --surplus-bones")
    options = parser.parse_args()
    work = options.work or tempfile.mkdtemp(prefix="skeleton_bench_")
    os.makedirs(work, exist_ok=True)
    walker = os.path.join(work, "walker.npz")
    run(["example", "walker", "-o", walker], work)
    for name, source in [*captures(work), ("walker", walker)]:
        if options.only and name != options.only:
            continue
        out = os.path.join(work, f"{name}.skeleton.h5")
        bones = BONES.get(name, 20)
        grown = ["--surplus-bones", str(options.surplus)] if options.surplus else []
        seconds, peak, _, stdout = run(["fit-skin", source, "-o", out, "--bones", str(bones), "--skeleton", "--json",
                                        "-q", *grown], work)
        summary = json.loads(stdout)
        skeleton = summary["skeleton"]
        # the free fit of the same bones, as its own command: the time the skeleton is measured against
        free_seconds, _, _, free_out = run(["fit-skin", source, "-o", os.path.join(work, f"{name}.free.h5"),
                                            "--bones", str(bones), "--json", "-q"], work)
        extra = {"free_seconds": round(free_seconds, 1), "seconds_over_free": round(seconds / free_seconds, 2)}
        if options.surplus:  # no free fit of these bones inside the command: the one above
            skeleton["free_rmse"] = json.loads(free_out)["rmse"]
            skeleton["rmse_over_free"] = summary["rmse"] / skeleton["free_rmse"]
            extra["surplus"] = options.surplus
        line = {"capture": name, "input": pathlib.Path(source).name, "bones": bones,
                "rmse_over_free": round(skeleton["rmse_over_free"], 3),
                "free_rmse_over_diagonal": skeleton["free_rmse"] / summary["rmse"] * summary["rmse_over_diagonal"],
                "rmse_over_diagonal": summary["rmse_over_diagonal"], "joints": skeleton["joints"],
                "joints_inside": skeleton["joints_inside"], "largest_drift": round(skeleton["largest_drift"], 4),
                "sliding": [[s["bone"], s["parent"], round(s["travel_over_diagonal"], 4)] for s in skeleton["sliding"]],
                "free_bones": skeleton["free_bones"], "root": skeleton["root"],
                "fixed_share": round(skeleton["joints"] / max(1, bones - 1), 3),
                "feet_joints_to_root": feet_paths(out, skeleton), "seconds": round(seconds, 1),
                "peak_mib": round(peak), "chains": skeleton.get("chains"),
                **dict(zip(("root_height", "depth"), root_place(out, skeleton))), **extra}
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
