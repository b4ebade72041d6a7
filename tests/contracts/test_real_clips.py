"""Slow tests on the shared clip folders (several clips of one mesh): one rig for several clips,
and a take solved on an existing rig. Skipped, with the reason, when the folders are absent."""

import json

import numpy as np
import pytest

from cli_helpers import assert_ok, assert_user_error, cli
from skinsynth.formats.skin_file import read_skin

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def horse(horse_clips):
    folder, skin, joint = horse_clips
    return folder, skin.parent, joint


def test_gallop_and_collapse_get_one_rig_with_their_clip_table(horse):
    folder, work, joint = horse
    skin = read_skin(str(work / "skin.h5"))
    assert skin.clip_names == ("gallop", "collapse") and skin.clip_frames == (48, 53)
    assert [c["name"] for c in joint["clips"]] == ["gallop", "collapse"]
    per_clip = np.array([c["rmse"] for c in joint["clips"]])
    # the whole file's RMSE is the frame-weighted mean of the clips' squared errors
    assert np.isclose(np.sqrt(np.sum(per_clip ** 2 * [48, 53]) / 101), joint["rmse"])
    assert all(c["rmse_over_diagonal"] < 0.01 for c in joint["clips"])


def test_solving_a_clip_again_on_its_own_rig_is_no_worse_than_its_fit(horse, tmp_path):
    """The fit ends on a weight update; the bones re-solved for those weights can only gain."""
    folder, work, joint = horse
    out = json.loads(assert_ok(cli("fit-skin", f"collapse={folder / 'horse_collapse.npz'}", "--rig",
                                   work / "skin.h5", "-o", tmp_path / "collapse.h5", "--json")).stdout)
    assert out["rmse"] <= joint["clips"][1]["rmse"] * (1 + 1e-6)
    rig, take = read_skin(str(work / "skin.h5")), read_skin(str(tmp_path / "collapse.h5"))
    assert np.array_equal(rig.bone_weights, take.bone_weights) and np.array_equal(rig.rest_vertices,
                                                                                 take.rest_vertices)


def test_a_rig_of_another_mesh_is_refused(horse, shared_data, tmp_path):
    folder, work, _ = horse
    elephant = shared_data / "elephant_clips" / "elephant_poses.npz"
    if not elephant.exists():
        pytest.skip(f"{elephant} is absent")
    assert_user_error(cli("fit-skin", elephant, "--rig", work / "skin.h5", "-o", tmp_path / "x.h5"),
                      "skin.h5", "42321", folder=tmp_path)
    assert_user_error(cli("fit-skin", folder / "horse_gallop.npz", elephant, "-o", tmp_path / "x.h5", "--bones", 4),
                      "elephant_poses.npz", "42321 vertices", folder=tmp_path)
