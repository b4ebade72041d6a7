"""fit-skin --skeleton on generated characters with known skeletons, against their truth (issue 65).

For each character (``skinsynth example humanoid`` / ``quadruped``: :mod:`skinsynth.pipeline.inputs.characters`)
at each limb length and fit seed, it runs as a user would ``skinsynth fit-skin INPUT --bones B
--skeleton --json`` with B the character's true bone count, and compares the tree found with the
true one. Each fitted bone stands for the true bone it shares most skin with (Σ_v w_fit · w_true);
the true tree is rooted at the true bone the fit's root stands for (its joints staying on their
pairs), and a true bone that no fitted bone stands for (the fit merged it into a neighbour: a neck
into the head) is skipped over, so a fitted bone's right parent is the one standing for its true bone's nearest
represented ancestor, or for its own true bone (a true bone the fit split in two). It prints one
JSON line per fit:

- ``root``: the true bone the root stands for, ``root_right`` whether it is the body's centre (the
  humanoid's pelvis; either of the quadruped's trunk bones);
- ``parents_right``: the share of the non-root bones whose parent is right (above), ``wrong``: the
  others as ``true bone<-parent's true bone``;
- ``joints_within_3pc``: the share of the joints between two represented true bones that lie within
  3 % of the height of the true joint (in the fit's rest frame), ``joint_p95`` the 95th percentile of
  their distance over the height;
- ``names_right``: the share of the bones whose chain (``leg_l``, ``arm_r``, ``neck``, ``tail``,
  ``leg_front_l``…; ``body`` and ``spine`` one trunk) is that of their true bone, ``named`` whether
  any chain was named; ``rmse_over_free``, ``seconds``.

    python benchmarks/skeleton_truth.py [--only humanoid] [--seeds 0,1,2] [--limbs 0.8,1,1.3] [--work DIR]
"""

import argparse
import json
import os
import re
import tempfile

import numpy as np
from datasets import run


def chain_of(name):
    """The chain a joint name belongs to: ``leg_l_02`` → ``leg_l``; ``body`` and ``spine_*`` → ``trunk``."""
    if name == "body" or name.startswith(("spine_", "hips_")):
        return "trunk"
    return re.sub(r"_\d+$", "", name)


def against_truth(path, rig, vertices):
    """The comparison of the skin file at ``path`` with the character's ``rig`` (module notes)."""
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.influence import dense_weights
    from skinsynth.pipeline.rig.joint_tree import rooted_at

    skin = read_skin(path)
    body = rig.body
    parents = np.asarray(skin.skeleton["parents"])
    joints = np.asarray(skin.skeleton["joints"])
    stands = (dense_weights(skin.bone_indices, skin.bone_weights, skin.bones).T @ rig.weights).argmax(axis=1)
    represented = np.zeros(len(body.names), bool)
    represented[stands] = True
    frame = skin.rest_frame
    height = np.ptp(vertices[frame, :, 1])
    root = int(np.flatnonzero(parents < 0)[0])
    # the truth rooted where the fit's tree is (the quadruped's either trunk bone): its joints stay on their pairs
    true_parents, true_joints = rooted_at(body.parents, body.joints, stands[root])
    true_joints = np.einsum("bij,bj->bi", rig.rotations[frame], true_joints) + rig.translations[frame]

    def represented_above(t):
        """(nearest represented true ancestor of t, the true bone below it on t's path)."""
        below, up = t, true_parents[t]
        while up >= 0 and not represented[up]:
            below, up = up, true_parents[up]
        return up, below

    wrong, distances = [], []
    for b in np.flatnonzero(parents >= 0):
        t, parent = stands[b], stands[parents[b]]
        above, top = represented_above(t)
        if parent == t:
            continue  # a true bone split in two
        if parent != above:
            wrong.append(f"{body.names[t]}<-{body.names[parent]}")
        else:
            distances.append(np.linalg.norm(joints[b] - true_joints[top]) / height)
    names = skin.skeleton.get("names")
    named = bool(names) and any(re.match(r"(leg|arm|neck|tail)_", n) for n in names)
    right_names = [bool(names) and chain_of(names[b]) == chain_of(rig.names[stands[b]]) for b in range(skin.bones)]
    centre = {"humanoid": ("pelvis",), "quadruped": ("trunk_back", "trunk_front")}
    kind = "humanoid" if "pelvis" in body.names else "quadruped"
    return {"root": body.names[stands[root]], "root_right": body.names[stands[root]] in centre[kind],
            "parents_right": round(1.0 - len(wrong) / max(1, skin.bones - 1), 3), "wrong": wrong,
            "joints_within_3pc": round(float(np.mean(np.asarray(distances) < 0.03)), 3) if distances else None,
            "joint_p95": round(float(np.percentile(distances, 95)), 4) if distances else None,
            "names_right": round(float(np.mean(right_names)), 3), "named": named,
            "merged": [body.names[t] for t in np.flatnonzero(~represented)]}


def main():
    from skinsynth.pipeline.inputs.characters import character

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=None, help="humanoid or quadruped")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--limbs", default="0.8,1,1.3")
    parser.add_argument("--work", default=None, help="folder kept between runs")
    parser.add_argument("--fit", default="", help="more fit-skin options, e.g. '--surplus-bones 0.5'")
    options = parser.parse_args()
    work = options.work or tempfile.mkdtemp(prefix="skeleton_truth_")
    os.makedirs(work, exist_ok=True)
    for kind in ("humanoid", "quadruped"):
        if options.only and kind != options.only:
            continue
        for limbs in (float(x) for x in options.limbs.split(",")):
            source = os.path.join(work, f"{kind}_{limbs:g}.npz")
            run(["example", kind, "-o", source, "--limbs", str(limbs)], work)
            vertices, _, rig = character(kind, limbs=limbs)
            for seed in (int(s) for s in options.seeds.split(",")):
                out = os.path.join(work, f"{kind}_{limbs:g}_{seed}.skeleton.h5")
                seconds, _, _, stdout = run(["fit-skin", source, "-o", out, "--bones", str(len(rig.body.names)),
                                             "--seed", str(seed), "--skeleton", "--json", "-q", *options.fit.split()],
                                            work)
                summary = json.loads(stdout)
                line = {"character": kind, "limbs": limbs, "seed": seed, "bones": len(rig.body.names),
                        **against_truth(out, rig, vertices),
                        "rmse_over_free": summary["skeleton"]["rmse_over_free"] and round(summary["skeleton"]["rmse_over_free"], 3),
                        "rmse_over_diagonal": float(f"{summary['rmse_over_diagonal']:.3g}"), "seconds": round(seconds, 1)}
                print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
