"""The fit a fit-skin request asks for in one call (pipeline/skin/rig_fit.py): its phases, each
announced to ``progress`` with its length, and the /skin/skeleton record of a jointed fit."""

import numpy as np

from skinsynth.pipeline.inputs.clips import Clips
from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.mesh.geometry import bounding_box_diagonal
from skinsynth.pipeline.skin import finish_fit, fit_rig, skin_summary
from skinsynth.pipeline.skin.rig_fit import JOINTED_ITERATIONS


class _Scene:
    meters_per_unit, up_axis, start_frame, prim_path = 1.0, "Y", 0.0, "/mesh"

    def describe(self, frames):
        return f"frames 0–{frames - 1}"


def _recorder():
    """``progress`` that keeps (phase, length, iterations reported)."""
    phases = []

    def progress(phase, length):
        phases.append([phase, length, 0])

        def step(iteration, rmse):
            phases[-1][2] += 1
        return step
    return phases, progress


def test_a_found_skeleton_is_a_second_phase_and_its_record_and_line_come_with_the_fit():
    vertices, faces = walker(frames=12, rings=6, segments=6)
    diagonal = bounding_box_diagonal(vertices[0])
    phases, progress = _recorder()
    fit, record = fit_rig(vertices, faces, 10, find_joints=True, iterations=3, diagonal=diagonal, progress=progress)
    assert [(p, n) for p, n, _ in phases] == [("fit", 3), ("joints", JOINTED_ITERATIONS)]
    assert phases[0][2] == 3 and 0 < phases[1][2] <= JOINTED_ITERATIONS
    assert set(record) == {"parents", "jointed", "joints", "drift", "root", "free_rmse", "max_drift", "names"}
    assert record["free_rmse"] > 0 and np.asarray(record["joints"]).shape == (10, 3)
    frame_rmse, _, _ = finish_fit(fit, vertices)
    summary, lines = skin_summary("out.h5", fit, frame_rmse, Clips.single(12), diagonal, 24.0, _Scene(), 1.0, "cpu",
                                  [], record, faces)
    assert summary["bones"] == 10 and summary["frames"] == 12 and summary["skeleton"]["joints"] >= 1
    assert lines[0].startswith("wrote out.h5: 10 bones") and lines[-1].startswith("skeleton: root bone")


def test_a_given_rig_keeps_its_weights_and_its_rest_frames():
    vertices, faces = walker(frames=12, rings=6, segments=6)
    free, _ = fit_rig(vertices, faces, 6, iterations=2)
    phases, progress = _recorder()
    fit, record = fit_rig(vertices[::2], faces, None, rig=_Rig(free), iterations=2, progress=progress)
    assert record is None and [(p, n) for p, n, _ in phases] == [("fit", 2)]
    assert np.array_equal(fit.bone_weights, free.bone_weights) and fit.rotations.shape[:2] == (6, 6)
    kept = np.arange(6 * 16, dtype=float).reshape(6, 4, 4)
    assert finish_fit(fit, vertices[::2], rest_frames=kept)[2] is kept


class _Rig:
    """A SkinModel's rig fields, from a fit."""

    def __init__(self, fit):
        self.rest_vertices, self.bone_indices, self.bone_weights = fit.rest_vertices, fit.bone_indices, fit.bone_weights
        self.bones = fit.rotations.shape[1]


def test_a_slide_past_a_tenth_of_the_height_is_named_loose_in_the_summary_and_its_line():
    """Issue 65: a sliding joint is a joint that slides a little (``SLIDE_LIMIT``, a tenth of the
    height); the summary gives each slide's travel over the height and names the bones that slide
    farther "loose", those carrying bones below them too."""
    from types import SimpleNamespace

    import trimesh

    from skinsynth.pipeline.skin.rig_fit import SLIDE_LIMIT, _skeleton_summary

    box = trimesh.creation.box(extents=(0.5, 2.0, 0.5))  # 2 tall along y, 0.5 along z
    fit = SimpleNamespace(rest_vertices=np.asarray(box.vertices), rmse=1.0)
    low = np.zeros((4, 3))
    high = np.zeros((4, 3))
    high[2, 1] = 0.5 * SLIDE_LIMIT * 2.0  # half the limit along y
    high[3, 2] = 3.0 * SLIDE_LIMIT * 2.0  # three times it along z
    record = {"parents": np.array([-1, 0, 1, 1]), "jointed": np.array([False, True, False, False]),
              "joints": np.zeros((4, 3)), "drift": np.zeros(4), "root": 0, "free_rmse": 1.0, "max_drift": 0.02,
              "sliding": np.array([False, False, True, True]), "slide_low": low, "slide_high": high}
    summary, line = _skeleton_summary(record, fit, np.asarray(box.faces), diagonal=1.0)
    assert [s["travel_over_height"] for s in summary["sliding"]] == [0.5 * SLIDE_LIMIT, 3.0 * SLIDE_LIMIT]
    assert summary["loose"] == [3] and "loose: 3 slide past 10% of the height" in line
    assert "carr" not in line
    record["parents"] = np.array([-1, 0, 3, 1])  # the loose bone carries another: said so
    assert "3 carries bones below" in _skeleton_summary(record, fit, np.asarray(box.faces), diagonal=1.0)[1]
    # Z up: the height is along z
    summary, _ = _skeleton_summary(record, fit, np.asarray(box.faces), diagonal=1.0, up_axis=2)
    assert summary["sliding"][1]["travel_over_height"] == 3.0 * SLIDE_LIMIT * 2.0 / 0.5
