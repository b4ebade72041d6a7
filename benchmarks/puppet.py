"""Puppet benchmark: training time and held-out errors of kernel CCA against Feng's baselines.

One JSON line per dataset: every sequence under ../shared/data (when present) and built-in
procedural ones. Protocol (issue 3): fit-skin, 8 control points chosen by select-controls' rule,
train on every 4th frame, test on the rest; errors are RMS vertex distances with the largest
rest bounding-box side scaled to 1 (Feng §7). Plus one line timing the training of a
face-sized model (23,728 vertices, 260 bones, 38 examples, synthetic LBS).

    python benchmarks/puppet.py [--only NAME] [--bones 16]
"""

import argparse
import json
import time

import numpy as np
from datasets import shared_sequences


def _datasets():
    from skinsynth.pipeline.alignment import apply_frames
    from skinsynth.pipeline.examples import articulated_tube, bending_bar
    from skinsynth.pipeline.rotations import rotation_exp

    yield from shared_sequences()
    yield ("bending_bar", *bending_bar(frames=80))
    vertices, faces = articulated_tube()
    yield "articulated_tube", vertices, faces
    # The same motion carried across the scene and turned: the control-frame mode must cope.
    frames = vertices.shape[0]
    turn = rotation_exp(np.linspace(0.0, 1.5, frames)[:, None] * np.array([0.2, 1.0, 0.1]))
    travel = np.linspace(0.0, 12.0, frames)[:, None] * np.array([1.0, 0.1, 0.3])
    yield "articulated_tube_travelling", apply_frames(turn, travel, vertices), faces


def _evaluate(name, vertices, faces, bones):
    from skinsynth.pipeline.controls import select_controls
    from skinsynth.pipeline.evaluation import evaluate_puppet
    from skinsynth.pipeline.puppet import parse_frame_spec, train_puppet
    from skinsynth.pipeline.skin_fit import fit_skin

    started = time.perf_counter()
    fit = fit_skin(vertices, bones, iterations=30)
    fit_seconds = time.perf_counter() - started
    controls = select_controls(vertices, fit.rest_vertices, count=8).indices
    train = parse_frame_spec("every:4", vertices.shape[0])
    test = np.setdiff1d(np.arange(vertices.shape[0]), train)
    line = {"dataset": name, "frames": int(vertices.shape[0]), "vertices": int(vertices.shape[1]), "bones": bones,
            "controls": [int(c) for c in controls], "train_frames": int(train.size), "test_frames": int(test.size),
            "fit_skin_seconds": round(fit_seconds, 2)}
    for mode in ("auto", "control-frame", "world"):
        for kernel in ("gaussian", "polynomial"):
            started = time.perf_counter()
            puppet = train_puppet(vertices, fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights,
                                  fit.rotations, fit.translations, controls, train, kernel=kernel, global_motion=mode)
            seconds = time.perf_counter() - started
            result = evaluate_puppet(puppet, vertices, test)
            key = f"{mode}/{kernel}"
            line[key] = {"train_seconds": round(seconds, 3), **{k: round(v, 6) for k, v in result.overall.items()},
                         "pca_components": result.notes["pca_components"]}
            line[key]["kcca_over_pca"] = round(result.overall["kcca"] / result.overall["pca_blendshape"], 3)
            line[key]["lowest"] = min(result.overall, key=result.overall.get)
            line[key]["translation_prior"] = puppet.translation_prior
            if mode == "auto":
                line[key]["chosen"] = puppet.global_motion
    return line


def _face_sized_training():
    from skinsynth.pipeline.examples import synthetic_lbs
    from skinsynth.pipeline.puppet import train_puppet

    data = synthetic_lbs(bones=260, frames=38, rings=1483, segments=16, seed=0, angle=0.3, width=0.5)
    controls = np.linspace(0, data["vertices"].shape[1] - 3, 8).astype(int)
    started = time.perf_counter()
    train_puppet(data["vertices"], data["rest"], data["faces"], data["bone_indices"], data["bone_weights"],
                 data["rotations"], data["translations"], controls, np.arange(38))
    return {"dataset": "synthetic_face_sized", "vertices": int(data["vertices"].shape[1]), "bones": 260,
            "examples": 38, "controls": 8, "train_seconds": round(time.perf_counter() - started, 2),
            "regularization": "auto", "translation_solver": True}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run only this dataset name")
    parser.add_argument("--bones", type=int, default=16)
    args = parser.parse_args()
    for name, vertices, faces in _datasets():
        if not args.only or args.only == name:
            print(json.dumps(_evaluate(name, vertices, faces, args.bones)), flush=True)
    if not args.only or args.only == "synthetic_face_sized":
        print(json.dumps(_face_sized_training()), flush=True)


if __name__ == "__main__":
    main()
