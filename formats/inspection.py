"""What ``skinsynth inspect`` says of a model file: its stage, counts, fit errors, options and
provenance, read from the file's groups and attributes (the one place outside the stage readers
that reads a model's attributes by name)."""

import numpy as np

from .model import require, text
from .scene import Scene
from .skin_file import stored_clips
from .validation import check_controls, check_graph, check_puppet, check_skin, check_synthesis


def validate_model(path, model):
    """The same checks every command makes on what it reads: a corrupt file is one error line."""
    if "skin" not in model:
        return
    require(model, path, "mesh", ("rest_vertices", "faces"))
    require(model, path, "examples", ("vertices",))
    dims = check_skin(path, model)
    if "controls" in model:
        check_controls(path, model, dims)
    if "kcca" in model and "training" in model:
        check_puppet(path, model, dims)
    if "graph" in model:
        check_graph(path, model, dims)
    if "synthesis" in model:
        check_synthesis(path, model, dims)


def clip_table(examples, frames):
    """The clips of a read ``/examples`` group of ``frames`` frames, in order: [{name, frames,
    first, last}] (first and last: global frame numbers); a file without a clip table is one clip
    (:func:`.skin_file.stored_clips`)."""
    names, counts = stored_clips(examples, frames)
    ends = np.cumsum(counts)
    return [{"name": name, "frames": int(count), "first": int(end - count), "last": int(end - 1)}
            for name, count, end in zip(names, counts, ends)]


def describe_skeleton(skeleton):
    """What ``inspect`` says of a read /skin/skeleton: {root, joints (bones jointed to their parent),
    sliding (ids: bones sliding on their joint), free_bones (ids), parents, tree}: the tree nested
    as ``root(child(...) child ...)``, children in ascending id, a sliding bone marked ``=``, a free
    one ``~``; names: the bones' (``@names``: its chains named) or None."""
    parents = [int(p) for p in np.asarray(skeleton["parents"])]
    jointed = np.asarray(skeleton["jointed"]).astype(bool)
    sliding = np.asarray(skeleton.get("sliding", np.zeros_like(jointed))).astype(bool)
    root = parents.index(-1)
    names = skeleton.get("names", skeleton.get("@names"))  # read_skin's, or the file's attribute
    names = None if names is None else [text(n) for n in np.atleast_1d(names)]
    children = {bone: [c for c, p in enumerate(parents) if p == bone] for bone in range(len(parents))}

    def nested(bone):
        mark = "=" if sliding[bone] else "~" if not jointed[bone] and bone != root else ""
        return mark + str(bone) + (f"({' '.join(nested(c) for c in children[bone])})" if children[bone] else "")

    return {"root": root, "joints": int(jointed.sum()), "sliding": [int(b) for b in np.flatnonzero(sliding)],
            "free_bones": [b for b in range(len(parents)) if b != root and not jointed[b] and not sliding[b]],
            "parents": parents, "tree": nested(root), "names": names}


def describe_model(path, model):
    """What ``inspect`` reports of a model file (``model``: :func:`.model.read_model`'s dict),
    after the checks every reader makes (:func:`validate_model`): {name: plain value}."""
    validate_model(path, model)
    out = {"file": str(path), "stage": model["stage"], "format_version": model["format_version"]}
    if "mesh" in model:
        mesh = require(model, path, "mesh", ("rest_vertices", "faces"))
        out["vertices"] = int(mesh["rest_vertices"].shape[0])
        out["faces"] = int(mesh["faces"].shape[0])
    if "examples" in model:
        examples = require(model, path, "examples", ("vertices",))
        out["frames"] = int(examples["vertices"].shape[0])
        out["fps"] = float(examples.get("@fps", 0.0))
        out["source"] = str(examples.get("@source", ""))
        out["clips"] = clip_table(examples, out["frames"])
        scene = Scene.from_attributes(examples)
        out.update(meters_per_unit=scene.meters_per_unit, up_axis=scene.up_axis, start_frame=scene.start_frame,
                   prim_path=scene.prim_path)
    if "skin" in model:
        skin = require(model, path, "skin", ("rotations", "bone_indices", "bone_weights"))
        out["bones"] = int(skin["rotations"].shape[1])
        out["max_influences"] = int(skin["bone_indices"].shape[1])
        weights = np.asarray(skin["bone_weights"])  # values of a large one read again (a DatasetSummary)
        out["mean_influences"] = float(np.mean(np.sum(weights > 0.0, axis=1)))
        for key in ("rmse", "rmse_over_diagonal", "iterations", "converged", "bones_without_weight"):
            if f"@{key}" in skin:
                value = skin[f"@{key}"]
                out[key] = bool(value) if key == "converged" else (int(value) if key in ("iterations", "bones_without_weight") else float(value))
        if "skeleton" in skin:
            out["skeleton"] = describe_skeleton(skin["skeleton"])
    if "controls" in model:
        controls = model["controls"]
        out["control_vertex_indices"] = [int(v) for v in np.asarray(controls.get("vertex_indices", []))]
        out["control_reasons"] = [r.decode() if isinstance(r, bytes) else str(r) for r in controls.get("reasons", [])]
    if "kcca" in model and "training" in model:
        kcca, training = model["kcca"], model["training"]
        out["kernel"] = str(kcca.get("@kernel", ""))
        out["kernel_scale"] = float(kcca.get("@scale", 0.0))
        out["kernel_width_reason"] = str(kcca.get("@width_reason", ""))
        out["bases"] = int(kcca.get("@bases", 0))
        out["regularization_per_bone"] = [float(k) for k in np.asarray(kcca.get("regularization", []))]
        out["global_motion"] = str(training.get("@global_motion", ""))
        out["global_motion_reason"] = str(training.get("@global_motion_reason", ""))
        out["train_frames"] = int(len(training.get("train_frames", [])))
        out["test_frames"] = int(len(training.get("test_frames", [])))
        out["translation_solver"] = "poisson" in model
        if "poisson" in model:
            out["translation_prior"] = float(model["poisson"].get("@prior", np.nan))
            out["translation_prior_reason"] = str(model["poisson"].get("@prior_reason", ""))
        out["correctives"] = "correctives" in model
        out["correctives_reason"] = str(training.get("@correctives_reason", ""))
    if "graph" in model:
        graph = model["graph"]
        out["components"] = int(graph.get("@components", 0))
        out["transitions"] = int(graph.get("@transitions", 0))
        out["cut_nodes"] = [int(b) for b in np.asarray(graph.get("cut_nodes", []))]
        names = [k for k in sorted(graph) if k.startswith("component_") and "transitions" in graph[k]]
        out["transitions_per_component"] = [int(len(graph[k]["transitions"])) for k in names]
        if all("@recurrent_share" in graph[k] for k in names):
            out["recurrent_share_per_component"] = [round(float(graph[k]["@recurrent_share"]), 4) for k in names]
            out["admitted_per_component"] = [int(graph[k]["@admitted"]) for k in names]
        if "@min_segment" in graph:
            out["min_segment"] = int(graph["@min_segment"])
            out["up_axis"] = str(graph.get("@up_axis", "Y"))
    if "synthesis" in model:
        synthesis = model["synthesis"]
        for key in ("count", "frames", "seed", "distinct", "transitions_used", "rejected_collisions",
                    "rejected_too_similar", "rejected_merges"):
            if f"@{key}" in synthesis:
                name = {"count": "animations", "frames": "animation_frames"}.get(key, key)
                out[name] = int(synthesis[f"@{key}"])
        for key in ("coverage", "mean_segment_frames", "shortest_segment"):
            if key in synthesis:
                values = np.asarray(synthesis[key]).tolist()
                out[f"{key}_per_component"] = [round(v, 4) if isinstance(v, float) else v for v in values]
        for key in ("min_segment", "window", "blend", "alignment"):
            if f"@{key}" in synthesis:
                value = synthesis[f"@{key}"]
                out[key] = value if isinstance(value, str) else int(value)
    out["provenance"] = [{k: r.get(k) for k in ("stage", "command", "tool_version", "seed", "date", "parameters",
                                                 "inputs")}
                         for r in model["provenance"]]
    return out


def description_lines(description):
    """``inspect``'s text of :func:`describe_model`'s dict: one ``key: value`` line each (floats to
    six digits), the digests as sha256sum prints them (diff two files' lists), a line per
    provenance record and per clip, and the skeleton's tree on one line."""
    lines = []
    for key, value in description.items():
        if key == "digests":  # as sha256sum prints them: diff two files' lists
            lines += [f"{digest}  {name}" for name, digest in value.items()]
        elif key == "provenance":
            lines += [f"provenance: {record['stage']} by skinsynth {record['tool_version']} on {record['date']}"
                      f" (seed {record['seed']}): {record['command']}" for record in value]
        elif key == "clips":  # one line each: name, frames, global first–last
            lines.append(f"clips: {len(value)}")
            lines += [f"  {clip['name']}: {clip['frames']} frames ({clip['first']}–{clip['last']})" for clip in value]
        elif key == "skeleton":  # one line: the joint tree (fit-skin --skeleton)
            free = ", ".join(str(b) for b in value["free_bones"]) or "none"
            sliding = ", ".join(str(b) for b in value["sliding"]) or "none"
            lines.append(f"skeleton: root bone {value['root']}, {value['joints']} joints, sliding bones: {sliding}, "
                         f"free bones: {free}; tree {value['tree']} (= sliding, ~ free); parents {value['parents']}"
                         + (f"; names {value['names']}" if value.get("names") else "; no chains named"))
        elif isinstance(value, float):
            lines.append(f"{key}: {value:.6g}")
        else:
            lines.append(f"{key}: {value}")
    return lines
