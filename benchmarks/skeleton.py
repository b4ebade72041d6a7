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
(``free_seconds``, ``seconds_over_free``: the whole commands'; ``rmse_over_free_command``: the error over
that command's, where ``rmse_over_free`` is over the free fit inside ``--skeleton``, its helper bones reseeded). With ``--surplus S`` the skeleton
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


#: The chains a character of each kind has (issue 65's must-show: humans legs, arms, spine, neck/head;
#: four legs fore and hind).
EXPECTED = {"biped": ("arm_l", "arm_r", "leg_l", "leg_r", "neck", "spine"),
            "quadruped": ("leg_back_l", "leg_back_r", "leg_front_l", "leg_front_r")}
TRUNK = ("body", "spine", "hips")


def chain_checks(path):
    """What issue 65 asks of the named chains, checked on the skin at ``path`` (None where nothing is named):
    ``kind`` (biped or quadruped, by the legs named), ``missing`` (chains of :data:`EXPECTED` not named),
    ``off_trunk`` (``chain<-parent``: a limb chain whose first bone does not hang from the trunk, body, spine
    or hips), ``empty`` (named bones that dominate no vertex), ``sides`` (whether each side's chains lie on
    that side of the body's centre line: every left chain's skin on one side, every right one's on the other)
    (on four legs, left is up × forward, forward from the hind legs' tops to the front ones'; on two, the
    arms on the side of the leg of their side, from the line between the legs' tops), on two legs ``head_top``
    (the neck's last bone centred above every arm's first joint) and, on four legs,
    ``head_front`` (the neck's end nearer the front legs' tops than the hind ones') and ``tail_back``; the largest slide over the height (``slide_over_height``)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.chain_labels import chain_tops, named_chains
    from skinsynth.pipeline.rig.influence import bone_centroids, dense_weights

    skin = read_skin(path)
    names, parents = skin.skeleton.get("names"), np.asarray(skin.skeleton["parents"])
    up = 1 if skin.scene.up_axis == "Y" else 2
    height = float(np.ptp(skin.rest_vertices[:, up]))
    sliding = np.asarray(skin.skeleton["sliding"], bool)
    slide = float(np.max(np.asarray(skin.skeleton["slide_high"]) - np.asarray(skin.skeleton["slide_low"]),
                         initial=0.0, where=sliding[:, None])) / height if sliding.any() else 0.0
    checks = {"slide_over_height": round(slide, 3)}
    if not names:
        return checks
    chains, tops = named_chains(names), chain_tops(names)
    kind = "quadruped" if "leg_front_l" in chains or "leg_back_l" in chains else "biped"
    owner = dense_weights(skin.bone_indices, skin.bone_weights, skin.bones).argmax(axis=1)
    centres = bone_centroids(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.bones)
    joints = np.asarray(skin.skeleton["joints"])
    members = {c: sorted((b for b, n in enumerate(names) if n.rsplit("_", 1)[0] == c), key=lambda b: names[b])
               for c in chains}  # each chain's bones from the body outwards
    off = [f"{c}<-{names[parents[b]]}" for c, b in tops.items() if not c.startswith(TRUNK) and parents[b] >= 0
           and not names[parents[b]].startswith(TRUNK)]
    empty = [n for b, n in enumerate(names) if not n.startswith("chain_") and not (owner == b).any()]
    checks.update(kind=kind, missing=[c for c in EXPECTED[kind] if c not in chains], off_trunk=off, empty=empty)
    lefts = [c for c in chains if c.endswith("_l")]
    rights = [c for c in chains if c.endswith("_r")]
    skin_of = {c: skin.rest_vertices[np.isin(owner, members[c])].mean(axis=0) for c in lefts + rights}
    upward = np.eye(3)[up]
    if kind == "quadruped" and len(lefts) + len(rights) == 4:  # left is up × forward, forward towards the forelegs
        front = np.mean([joints[tops[c]] for c in chains if c.startswith("leg_front")], axis=0)
        back = np.mean([joints[tops[c]] for c in chains if c.startswith("leg_back")], axis=0)
        left, middle = np.cross(upward, front - back), (front + back) / 2.0
        checks["sides"] = bool(all((skin_of[c] - middle) @ left > 0 for c in lefts)
                               and all((skin_of[c] - middle) @ left < 0 for c in rights))
    elif kind == "biped" and {"leg_l", "leg_r"} <= set(chains):  # each arm on its own leg's side of the hips
        left = joints[tops["leg_l"]] - joints[tops["leg_r"]]
        left -= (left @ upward) * upward
        middle = (joints[tops["leg_l"]] + joints[tops["leg_r"]]) / 2.0
        checks["sides"] = bool(all((skin_of[c] - middle) @ left > 0 for c in lefts)
                               and all((skin_of[c] - middle) @ left < 0 for c in rights))
    # each leg goes down from its top: no bone of it centred 5 % of the height above the one before
    checks["legs_climb"] = [c for c in chains if c.startswith("leg") and
                            np.any(np.diff(centres[members[c], up]) > 0.05 * height)]
    if kind == "biped" and "neck" in chains:  # the head above the shoulders
        checks["head_top"] = bool(all(centres[members["neck"][-1]][up] > joints[tops[c]][up] for c in chains
                                      if c.startswith("arm")))
    if kind == "quadruped" and len(lefts) + len(rights) == 4:
        for chain, label, nearer, other in (("neck", "head_front", front, back), ("tail", "tail_back", back, front)):
            if chain in chains:
                end = centres[members[chain][-1]]
                checks[label] = bool(np.linalg.norm(end - nearer) < np.linalg.norm(end - other))
    return checks


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
        extra = {"free_seconds": round(free_seconds, 1), "seconds_over_free": round(seconds / free_seconds, 2),
                 "rmse_over_free_command": round(summary["rmse"] / json.loads(free_out)["rmse"], 3)}
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
                **dict(zip(("root_height", "depth"), root_place(out, skeleton))), **chain_checks(out), **extra}
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
