"""glTF export on the real captures (issue 23): validity, fidelity in three.js, size, time.

For each capture (its bone count from ``datasets.BONES``): fit-skin, build-graph, synthesize
``--count`` animations of ``--frames`` frames; then ``export --animation 0:K -o syn.glb`` (and
with ``--root-motion``, and the skin fit's own clip), Khronos glTF-Validator's error and warning
counts, three.js's CPU-skinned positions (GLTFLoader, AnimationMixer) against skinsynth's LBS at
the first, middle and last frame of every clip (largest error over the rest pose's diagonal), and
bytes per animation on disk against the VAT folder and the bone-texture folder of the same
animations (``export -o vat/``, ``--as bones``; float and ``--half``). One JSON line per capture.

    python benchmarks/gltf.py [--count 8] [--frames 600] [--clips 4] [--work DIR]

Needs node and tests/contracts/js/node_modules (``make setup``).
"""

import argparse
import json
import os
import subprocess
import tempfile

import h5py
import numpy as np
from datasets import BONES, captures, run

JS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "contracts", "js")


def folder_bytes(path):
    return sum(os.path.getsize(os.path.join(root, name)) for root, _, names in os.walk(path) for name in names)


def three_error(glb, motions, skin, work):
    """Largest |three.js − LBS| over the diagonal, at the first, middle and last frame of each clip."""
    from skinsynth.gpu import lbs

    frames = motions[0][0].shape[0]
    chosen = [0, frames // 2, frames - 1]
    out = os.path.join(work, "three.bin")
    done = subprocess.run(["node", os.path.join(JS, "gltf_three.mjs"), glb, out, str(skin.fps),
                           *[str(f) for f in chosen]], capture_output=True, text=True, check=True)
    count = json.loads(done.stdout)["vertices"]
    played = np.fromfile(out, dtype=np.float32).reshape(len(motions), len(chosen), count, 3).astype(np.float64)
    scale, up = skin.scene.meters_per_unit, skin.scene.up_axis
    worst = 0.0
    for clip, (rotations, translations) in enumerate(motions):
        truth = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, np.asarray(rotations, np.float64),
                    np.asarray(translations, np.float64), device="cpu")[chosen] * scale
        if up == "Z":
            truth = np.stack([truth[..., 0], truth[..., 2], -truth[..., 1]], axis=-1)
        worst = max(worst, float(np.abs(played[clip] - truth).max()))
    diagonal = float(np.linalg.norm(np.ptp(skin.rest_vertices * scale, axis=0)))
    return worst / diagonal


def validate(glb):
    done = subprocess.run(["node", os.path.join(JS, "gltf_validate.mjs"), glb], capture_output=True, text=True,
                          check=True)
    report = json.loads(done.stdout)
    return {"errors": report["errors"], "warnings": report["warnings"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=8, help="animations synthesized")
    parser.add_argument("--frames", type=int, default=600, help="frames per animation")
    parser.add_argument("--clips", type=int, default=4, help="animations exported (and checked in three.js)")
    parser.add_argument("--work", default=None)
    args = parser.parse_args()
    from skinsynth.formats.model import read_model
    from skinsynth.formats.skin_file import read_skin

    work = args.work or tempfile.mkdtemp(prefix="skinsynth-gltf-")
    os.makedirs(work, exist_ok=True)
    for name, path in captures(work):
        bones = BONES.get(name, 16)
        skin_path, graph, synth = (os.path.join(work, f"{name}.{s}.h5") for s in ("skin", "graph", "synth"))
        run(["fit-skin", path, "-o", skin_path, "--bones", str(bones), "-q"], work)
        try:
            run(["build-graph", skin_path, "-o", graph, "-q"], work)
            run(["synthesize", graph, "-o", synth, "-n", str(args.count), "-m", str(args.frames), "-q"], work)
        except RuntimeError as error:  # e.g. a clip with no transition (issue 25): the fit alone
            print(json.dumps({"capture": name, "synthesis": f"skipped: {str(error)[-200:]}"}), flush=True)
            synth = None
        skin = read_skin(skin_path, read_model(skin_path, groups=("mesh", "examples", "skin")))
        line = {"capture": name, "vertices": int(skin.rest_vertices.shape[0]), "bones": bones}
        fit_glb = os.path.join(work, f"{name}.fit.glb")
        seconds, peak, _, _ = run(["export", skin_path, "-o", fit_glb, "-q"], work)
        line["skin_fit"] = {**validate(fit_glb), "seconds": round(seconds, 2), "peak_mib": round(peak),
                            "three_error_over_diagonal": three_error(fit_glb, [(skin.rotations, skin.translations)],
                                                                     skin, work)}
        if synth:
            clips = min(args.clips, args.count)
            with h5py.File(synth) as f:
                motions = [(f["synthesis/bone_matrices"][a], f["synthesis/bone_translations"][a]) for a in range(clips)]
            for label, flag in (("synthesis", []), ("synthesis_root_motion", ["--root-motion"])):
                glb = os.path.join(work, f"{name}.{label}.glb")
                seconds, peak, _, _ = run(["export", synth, "--animation", f"0:{clips}", "-o", glb, "-q", *flag], work)
                line[label] = {**validate(glb), "seconds": round(seconds, 2), "peak_mib": round(peak),
                               "three_error_over_diagonal": three_error(glb, motions, skin, work),
                               "bytes": os.path.getsize(glb)}
            sizes = {"glb_per_animation": None, "vat_float_per_animation": None, "vat_half_per_animation": None}
            one = os.path.join(work, f"{name}.one.glb")
            run(["export", synth, "--animation", "0", "-o", one, "-q"], work)
            two = os.path.join(work, f"{name}.two.glb")
            run(["export", synth, "--animation", "0:2", "-o", two, "-q"], work)
            sizes["glb_per_animation"] = os.path.getsize(two) - os.path.getsize(one)  # the mesh counted once
            sizes["glb_mesh_and_skin"] = os.path.getsize(one) - sizes["glb_per_animation"]
            for key, extra in (("vat_float_per_animation", []), ("vat_half_per_animation", ["--half"])):
                vat_one, vat_two = (os.path.join(work, f"{name}.vat{k}{len(extra)}/") for k in (1, 2))
                run(["export", synth, "--animation", "0", "-o", vat_one, "-q", *extra], work)
                run(["export", synth, "--animation", "0:2", "-o", vat_two, "-q", *extra], work)
                sizes[key] = folder_bytes(vat_two) - folder_bytes(vat_one)
            for key, extra in (("bones_float_per_animation", []), ("bones_half_per_animation", ["--half"])):
                one_dir, two_dir = (os.path.join(work, f"{name}.bones{k}{len(extra)}/") for k in (1, 2))
                run(["export", synth, "--animation", "0", "-o", one_dir, "--as", "bones", "-q", *extra], work)
                run(["export", synth, "--animation", "0:2", "-o", two_dir, "--as", "bones", "-q", *extra], work)
                sizes[key] = folder_bytes(two_dir) - folder_bytes(one_dir)
            sizes["frames"] = args.frames
            sizes["vat_float_over_glb"] = round(sizes["vat_float_per_animation"] / sizes["glb_per_animation"], 1)
            line["sizes"] = sizes
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
