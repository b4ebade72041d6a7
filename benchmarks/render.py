"""Headless rendering speed (groundwork for ``skinsynth preview``, issue 16): frames per second.

For every capture in ../shared/data (and a bending bar when it is absent): the whole animation
at 640 × 480 from the three-quarter camera framing all of it, ground plane on, flat and smooth
shading, one JSON line each. The rasteriser is compiled once before timing. Goal: ≥ 10 frames/s
for a 7,000-vertex mesh on this 2-core machine.

    python benchmarks/render.py [--size 640x480] [--png DIR]
"""

import argparse
import json
import os
import tempfile
import time

import numpy as np
from datasets import captures


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--png", default=None, help="also write each capture's middle frame here")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    from skinsynth.formats.meshseq import read_mesh_sequence
    from skinsynth.pipeline.view import frame_bounds, ground_layer, render

    work = tempfile.mkdtemp(prefix="skinsynth-render-")
    for name, path in captures(work):
        sequence = read_mesh_sequence(path)
        vertices, faces = sequence.vertices, sequence.faces
        lower, upper = vertices.reshape(-1, 3).min(axis=0), vertices.reshape(-1, 3).max(axis=0)
        camera = frame_bounds(lower, upper, "three-quarter", up_axis=1, aspect=width / height)
        # the ground under a fixed camera is the same every frame: made once, as preview does
        ground = ground_layer(camera, width, height, float(lower[1]), 1, float(np.max(upper - lower)))
        render(vertices[0], faces, camera, width, height, ground=ground)  # compile / load once
        line = {"capture": name, "vertices": int(vertices.shape[1]), "faces": int(len(faces)),
                "size": [width, height]}
        for smooth in (False, True):
            started = time.perf_counter()
            for frame in vertices:
                image = render(frame, faces, camera, width, height, smooth=smooth, ground=ground)
            seconds = time.perf_counter() - started
            line["smooth" if smooth else "flat"] = {"frames_per_second": round(len(vertices) / seconds, 1)}
        if args.png:
            import matplotlib.image

            os.makedirs(args.png, exist_ok=True)
            matplotlib.image.imsave(os.path.join(args.png, f"{name}.png"),
                                    render(vertices[len(vertices) // 2], faces, camera, width, height, smooth=True,
                                           ground=ground))
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
