"""build-graph benchmark: seconds, transitions and components as one JSON line per dataset.

Datasets: every sequence under ../shared/data (fit with the bone count of Zheng Table 1 where
known: horse 22) and a procedural stand-in for the horse gallop: a tube of 8,402 vertices,
48 frames, whose body bends at three joints through exactly two cycles of 24 frames (as the
horse gallop's two perfect cycles) while its last two joints — a tail — swing with a period
of 17 frames. Zheng report for the horse: 24 transitions, 2 components (the tail separates),
1.4 minutes of analysis.

    python benchmarks/graph.py [--only NAME]
"""

import argparse
import json
import time

import numpy as np
from datasets import BONES, shared_sequences


def _datasets():
    from skinsynth.pipeline.inputs.examples import articulated_tube

    for name, vertices, faces in shared_sequences():
        yield name, vertices, faces, BONES.get(name, 20)
    periods = np.array([[24.0, 24.0, 24.0, 17.0, 17.0], [24.0, 24.0, 24.0, 17.0, 17.0]])
    vertices, faces = articulated_tube(frames=48, rings=350, segments=24, joints=5, periods=periods, seed=3)
    yield "tube_body_and_tail", vertices, faces, 22


def main():
    from skinsynth.pipeline.synthesis import build_graph
    from skinsynth.pipeline.skin import fit_skin

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run only this dataset name")
    args = parser.parse_args()
    for name, vertices, faces, bones in _datasets():
        if args.only and args.only != name:
            continue
        started = time.perf_counter()
        fit = fit_skin(vertices, bones, iterations=30)
        fit_seconds = time.perf_counter() - started
        line = {"dataset": name, "frames": int(vertices.shape[0]), "vertices": int(vertices.shape[1]), "bones": bones,
                "fit_skin_seconds": round(fit_seconds, 2)}
        for label, single in (("multi_component", False), ("single_component", True)):
            started = time.perf_counter()
            analysis = build_graph(fit.rest_vertices, faces, fit.bone_indices, fit.bone_weights, fit.rotations,
                                   fit.translations, single_component=single)
            line[label] = {"seconds": round(time.perf_counter() - started, 3),
                           "transitions": analysis.transition_count, "components": len(analysis.components),
                           "cut_nodes": analysis.cut_nodes,
                           "component_bones": [c.bones for c in analysis.components],
                           "transitions_per_component": [len(c.transitions.pairs) for c in analysis.components]}
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
