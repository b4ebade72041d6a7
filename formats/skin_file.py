"""The ``skin`` stage file written by ``fit-skin``: mesh, examples and the fitted LBS model.

Groups (all arrays float64 unless noted; conventions in docs/format.md):

- ``/mesh``: ``rest_vertices (V, 3)``, ``faces (T, 3)`` int64; ``@rest_frame``; and only when the
  input had material UVs, ``face_uvs (T, 3, 2)`` (each face corner's (u, v), v up).
- ``/examples``: ``vertices (F, V, 3)``; ``clip_frames (C,)`` int64, the frames of each clip
  (summing to F; the clips are the frames in order); ``@clip_names`` (C,) str; ``@fps``,
  ``@source``, and the input's scene (:mod:`.scene`): ``@meters_per_unit``, ``@up_axis``,
  ``@start_frame``, ``@prim_path``. A file from before clips were stored is one clip, named after
  its source (:func:`stored_clips`).
- ``/skin``: ``bone_indices (V, K)`` int32, ``bone_weights (V, K)`` (≥ 0, rows sum to 1, sorted
  decreasing, unused slots 0), ``rotations (F, B, 3, 3)``, ``translations (F, B, 3)``,
  ``dual_quaternions (F, B, 8)`` (real then dual part, each (w, x, y, z), hemisphere-consistent
  over time), ``bone_rest_frames (B, 4, 4)`` (world-from-bone at rest: identity rotation, origin
  at the bone's weighted vertex centroid), ``error_history (iterations,)``,
  ``frame_rmse (F,)``, ``initial_labels (V,)`` int32; attributes ``@rmse``, ``@rmse_over_diagonal``,
  ``@diagonal``, ``@bones``, ``@max_influences``, ``@iterations``, ``@converged``,
  ``@bones_without_weight``.
- ``/skin/skeleton`` (only from ``fit-skin --skeleton``): the rig's joints and hierarchy, the
  bones above already fitted so that every joint holds. ``parents (B,)`` int64 (−1: the root
  bone, exactly one), ``jointed (B,)`` bool (the bone turns about its joint with its parent;
  False for the root and for free bones, which hang from the root with translations of their
  own), ``joints (B, 3)`` (each bone's joint in the rest pose; its weighted rest centroid where
  it has none), ``drift (B,)`` (each joint's drift on the free fit it was found from, over the
  diagonal; 0 without a joint); attributes ``@root``, ``@free_rmse`` (the free fit's RMSE at
  the same bones), ``@max_drift`` (both absent for a skeleton given with ``--skeleton FILE``),
  ``@names`` (B,) the bones' names where the chains were named or a given skeleton named them.
"""

from dataclasses import dataclass, field

import numpy as np

from .errors import FormatError
from .scene import Scene
from .model import read_model, require, text
from .validation import check_skin


@dataclass
class SkinModel:
    """What a ``skin`` file holds, as plain arrays (see the module docstring for shapes)."""

    rest_vertices: np.ndarray
    faces: np.ndarray
    rest_frame: int
    examples: np.ndarray
    fps: float
    source: str
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    dual_quaternions: np.ndarray
    bone_rest_frames: np.ndarray
    rmse: float
    rmse_over_diagonal: float
    provenance: list
    scene: Scene = field(default_factory=Scene)
    face_uvs: np.ndarray | None = None
    clip_names: tuple = ("clip",)
    clip_frames: tuple = ()
    skeleton: dict | None = None  # /skin/skeleton's arrays and attributes, as read (module notes)

    @property
    def bones(self):
        return self.rotations.shape[1]


def skin_groups(sequence, rest_frame, fit, dual_quaternions, bone_rest_frames, frame_rmse, diagonal, skeleton=None):
    """The HDF5 groups of a skin file, from a MeshSequence and a pipeline SkinFit; ``skeleton``:
    /skin/skeleton's arrays and attributes (module notes), None for a free rig."""
    mesh = {"rest_vertices": fit.rest_vertices, "faces": sequence.faces.astype(np.int64)}
    if sequence.face_uvs is not None:  # only then: a file without UVs keeps its datasets
        mesh["face_uvs"] = np.asarray(sequence.face_uvs, dtype=np.float64)
    return {
        "mesh": {**mesh, "@rest_frame": int(rest_frame)},
        "examples": {"vertices": sequence.vertices, **clip_groups(sequence),
                     "@fps": float(sequence.fps), "@source": sequence.source, **sequence.scene.attributes()},
        "skin": {
            "bone_indices": fit.bone_indices.astype(np.int32),
            "bone_weights": fit.bone_weights,
            "rotations": fit.rotations,
            "translations": fit.translations,
            "dual_quaternions": dual_quaternions,
            "bone_rest_frames": bone_rest_frames,
            "error_history": np.asarray(fit.error_history),
            "frame_rmse": frame_rmse,
            "initial_labels": fit.labels.astype(np.int32),
            "@rmse": float(fit.rmse),
            "@rmse_over_diagonal": float(fit.rmse / diagonal),
            "@diagonal": float(diagonal),
            "@bones": int(fit.rotations.shape[1]),
            "@max_influences": int(fit.bone_indices.shape[1]),
            "@iterations": int(fit.iterations),
            "@converged": bool(fit.converged),
            "@bones_without_weight": int(fit.bones_without_weight),
            **({} if skeleton is None else {"skeleton": skeleton_group(**skeleton)}),
        },
    }


def skeleton_group(parents, jointed, joints, drift, root, free_rmse, max_drift, sliding=None, slide_low=None,
                   slide_high=None, names=None):
    """/skin/skeleton (module notes) from plain arrays and numbers (the sliding bones' three
    datasets only where some bone slides; ``@names`` only where given)."""
    group = {"parents": np.asarray(parents, dtype=np.int64), "jointed": np.asarray(jointed, dtype=bool),
             "joints": np.asarray(joints, dtype=np.float64), "drift": np.asarray(drift, dtype=np.float64),
             "@root": int(root)}
    if sliding is not None and np.any(sliding):
        group.update(sliding=np.asarray(sliding, dtype=bool), slide_low=np.asarray(slide_low, dtype=np.float64),
                     slide_high=np.asarray(slide_high, dtype=np.float64))
    if names is not None:
        group["@names"] = [str(n) for n in names]
    # A skeleton the user brought (--skeleton FILE) has no free fit and no threshold: left out.
    group.update({f"@{name}": float(value) for name, value in (("free_rmse", free_rmse), ("max_drift", max_drift))
                  if np.isfinite(value)})
    return group


def clip_groups(sequence):
    """The clip table of ``/examples`` for a MeshSequence (one clip, named after its source,
    when it names none)."""
    names = sequence.clip_names or (clip_name_of(sequence.source),)
    frames = sequence.clip_frames or (len(sequence.vertices),)
    return {"clip_frames": np.asarray(frames, dtype=np.int64), "@clip_names": [str(n) for n in names]}


def clip_name_of(source):
    """The name of a one-clip file's clip: its source's name (:func:`.clip_inputs.default_name`)."""
    from .clip_inputs import default_name

    return default_name(source.split(" ")[0]) if source else "clip"


def stored_clips(examples, frames):
    """(names (C,), frames (C,)) of a read ``/examples`` group holding ``frames`` frames."""
    if "clip_frames" not in examples:
        return (clip_name_of(str(examples.get("@source", ""))),), (int(frames),)
    names = examples.get("@clip_names", ())
    return tuple(str(n) for n in np.atleast_1d(names)), tuple(int(f) for f in np.atleast_1d(examples["clip_frames"]))


_SKIN_DATASETS = ("bone_indices", "bone_weights", "rotations", "translations", "dual_quaternions",
                  "bone_rest_frames")


def read_skin(path, model=None):
    """Read the LBS model of a file that carries one (a skin file or any later stage's file)."""
    model = read_model(path) if model is None else model
    if "skin" not in model:
        raise FormatError(path, f"is a '{model['stage']}' file without a skin fit (/skin); run fit-skin first")
    mesh = require(model, path, "mesh", ("rest_vertices", "faces"))
    examples = require(model, path, "examples", ("vertices",))
    skin = require(model, path, "skin", _SKIN_DATASETS)
    check_skin(path, model)  # kinds, shapes, finite values, index ranges, unit weights
    names, frames = stored_clips(examples, len(examples["vertices"]))
    return SkinModel(
        rest_vertices=mesh["rest_vertices"], faces=mesh["faces"], rest_frame=int(mesh.get("@rest_frame", 0)),
        examples=examples["vertices"], fps=float(examples.get("@fps", 24.0)), source=str(examples.get("@source", "")),
        bone_indices=skin["bone_indices"], bone_weights=skin["bone_weights"], rotations=skin["rotations"],
        translations=skin["translations"], dual_quaternions=skin["dual_quaternions"],
        bone_rest_frames=skin["bone_rest_frames"], rmse=float(skin.get("@rmse", np.nan)),
        rmse_over_diagonal=float(skin.get("@rmse_over_diagonal", np.nan)), provenance=model["provenance"],
        scene=Scene.from_attributes(examples), face_uvs=mesh.get("face_uvs"), clip_names=names, clip_frames=frames,
        skeleton=_read_skeleton(skin.get("skeleton")))


def _read_skeleton(group):
    """/skin/skeleton as read (validated by ``check_skin``), the arrays in their kinds, or None; a
    file where no bone slides reads as ``sliding`` all False and zero bounds, so readers need no
    default of their own (and :func:`skeleton_group` writes them again only where a bone slides)."""
    if group is None:
        return None
    bones = len(group["parents"])
    return {"parents": np.asarray(group["parents"], dtype=np.int64), "jointed": np.asarray(group["jointed"]).astype(bool),
            "joints": np.asarray(group["joints"], dtype=np.float64), "drift": np.asarray(group["drift"], dtype=np.float64),
            "root": int(group.get("@root", int(np.flatnonzero(np.asarray(group["parents"]) < 0)[0]))),
            "free_rmse": float(group.get("@free_rmse", np.nan)), "max_drift": float(group.get("@max_drift", np.nan)),
            "sliding": np.asarray(group.get("sliding", np.zeros(bones))).astype(bool),
            "slide_low": np.asarray(group.get("slide_low", np.zeros((bones, 3))), dtype=np.float64),
            "slide_high": np.asarray(group.get("slide_high", np.zeros((bones, 3))), dtype=np.float64),
            "names": [text(n) for n in np.atleast_1d(group["@names"])] if "@names" in group else None}
