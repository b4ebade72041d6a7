"""USD caches: point caches round-trip, and UsdSkel's own skinning replays skinsynth's LBS."""

import os

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel

from skinsynth.formats.errors import FormatError
from skinsynth.formats.usd import read_points_cache, read_skel_points, write_points_cache, write_skel_cache


def random_rotations(rng, count):
    """(count, 3, 3) uniformly random rotation matrices, from unit quaternions."""
    w, x, y, z = rng.normal(size=(count, 4)).T
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def lbs(rest, indices, weights, rotations, translations):
    """skinsynth's convention: v_i(t) = sum_k w_ik (R_b(t) rest_i + t_b(t)); vertices (F, V, 3)."""
    rotated = np.einsum("fvkij,vj->fvki", rotations[:, indices], rest)
    return np.einsum("vk,fvki->fvi", weights, rotated + translations[:, indices])


@pytest.fixture
def rig():
    rng = np.random.default_rng(7)
    frames, count, bones, influences = 6, 200, 5, 4
    rest = rng.uniform(-1, 1, size=(count, 3)) * [1.0, 2.0, 0.5] + [3.0, 0.0, -1.0]
    faces = rng.integers(0, count, size=(300, 3))
    indices = np.stack([rng.permutation(bones)[:influences] for _ in range(count)])
    weights = rng.random((count, influences)) * (rng.random((count, influences)) < 0.6)  # sparse
    weights[:, 0] += 0.05
    weights /= weights.sum(axis=1, keepdims=True)
    rotations = random_rotations(rng, frames * bones).reshape(frames, bones, 3, 3)
    translations = rng.normal(scale=2.0, size=(frames, bones, 3))
    centers = rest[rng.choice(count, bones, replace=False)]
    return dict(rest=rest, faces=faces, indices=indices, weights=weights, rotations=rotations,
                translations=translations, centers=centers)


def write_rig(path, rig, **kwargs):
    write_skel_cache(path, rig["rest"], rig["faces"], rig["indices"], rig["weights"], rig["rotations"],
                     rig["translations"], rig["centers"], kwargs.pop("fps", 30.0), **kwargs)


# ---------------------------------------------------------------- point caches


@pytest.mark.parametrize("ext", ["usda", "usdc", "usd"])
def test_points_cache_round_trip(tmp_path, ext, rig):
    vertices = lbs(rig["rest"], rig["indices"], rig["weights"], rig["rotations"], rig["translations"])
    path = tmp_path / f"anim.{ext}"

    write_points_cache(path, vertices, rig["faces"], 29.97, prim_name="horse", up_axis="Z")
    got_vertices, got_faces, fps = read_points_cache(path)

    np.testing.assert_allclose(got_vertices, vertices, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(got_faces, rig["faces"])
    assert fps == pytest.approx(29.97)
    assert os.listdir(tmp_path) == [f"anim.{ext}"]

    stage = Usd.Stage.Open(str(path))
    assert stage.GetDefaultPrim().GetPath() == "/horse"
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, len(vertices) - 1)
    assert stage.GetFramesPerSecond() == pytest.approx(29.97)
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/horse"))
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    extent = np.array(mesh.GetExtentAttr().Get(3))
    np.testing.assert_allclose(extent, [vertices[3].min(0), vertices[3].max(0)], atol=1e-6)


def test_points_cache_overwrite_reads_new_contents(tmp_path):
    """The file is replaced by rename: readers must not be served a stale cached layer."""
    path = tmp_path / "a.usdc"
    faces = np.array([[0, 1, 2]])
    first = np.zeros((2, 3, 3))
    write_points_cache(path, first, faces, 24)
    read_points_cache(path)
    write_points_cache(path, first + 1, faces, 24)
    np.testing.assert_array_equal(read_points_cache(path)[0], first + 1)


def test_read_points_cache_picks_prim(tmp_path):
    path = tmp_path / "b.usda"
    write_points_cache(path, np.zeros((3, 3, 3)), [[0, 1, 2]], 10, prim_name="body")
    assert read_points_cache(path, prim="/body")[0].shape == (3, 3, 3)
    with pytest.raises(FormatError, match="no prim at /cloth"):
        read_points_cache(path, prim="/cloth")


# ---------------------------------------------------------------- UsdSkel


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_skel_cache_matches_numpy_lbs_through_usdskel(tmp_path, ext, rig):
    path = tmp_path / f"skel.{ext}"
    write_rig(path, rig)

    expected = lbs(rig["rest"], rig["indices"], rig["weights"], rig["rotations"], rig["translations"])
    skinned = read_skel_points(path)

    assert skinned.shape == expected.shape
    diagonal = np.linalg.norm(np.ptp(expected.reshape(-1, 3), axis=0))
    error = np.abs(skinned - expected).max() / diagonal
    assert error < 1e-5, error
    assert os.listdir(tmp_path) == [f"skel.{ext}"]


def test_skel_cache_layout_for_dccs(tmp_path, rig):
    path = tmp_path / "skel.usda"
    write_rig(path, rig, fps=25.0, prim_name="horse")
    stage = Usd.Stage.Open(str(path))
    assert stage.GetDefaultPrim().IsA(UsdSkel.Root)
    assert stage.GetTimeCodesPerSecond() == 25.0 and stage.GetEndTimeCode() == 5
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/horse/Skeleton"))
    # one root joint with the bones under it (Unreal refuses several roots)
    assert list(skeleton.GetJointsAttr().Get()) == ["root"] + [f"root/bone_{b:03d}" for b in range(5)]
    topology = UsdSkel.Topology(skeleton.GetJointsAttr().Get())
    assert [topology.IsRoot(j) for j in range(6)] == [True] + [False] * 5
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/horse/Skeleton/Animation"))
    assert len(animation.GetScalesAttr().Get()) == 6  # DCCs drop animations without scales
    assert animation.GetRotationsAttr().GetNumTimeSamples() == 6
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/horse/Mesh"))
    assert binding.GetJointIndicesPrimvar().GetElementSize() == 4
    assert binding.GetJointWeightsPrimvar().GetInterpolation() == "vertex"
    assert UsdGeom.Mesh(stage.GetPrimAtPath("/horse/Mesh")).GetSubdivisionSchemeAttr().Get() == "none"


def test_skel_cache_identity_transforms_give_rest_pose(tmp_path, rig):
    rig["rotations"][:] = np.eye(3)
    rig["translations"][:] = 0
    write_rig(tmp_path / "rest.usdc", rig)
    np.testing.assert_allclose(read_skel_points(tmp_path / "rest.usdc"),
                               np.broadcast_to(rig["rest"], (6, 200, 3)), atol=1e-5)


def test_read_skel_points_needs_a_skeleton(tmp_path):
    path = tmp_path / "points.usda"
    write_points_cache(path, np.zeros((2, 3, 3)), [[0, 1, 2]], 24)
    with pytest.raises(FormatError, match="no skinned mesh"):
        read_skel_points(path)


# ---------------------------------------------------------------- failures leave nothing behind


def _bad_points(kind):
    vertices, faces = np.zeros((3, 4, 3)), np.array([[0, 1, 2]])
    if kind == "vertex shape":
        vertices = np.zeros((3, 4, 2))
    elif kind == "face index":
        faces = np.array([[0, 1, 4]])
    elif kind == "nan":
        vertices[1, 2, 0] = np.nan
    return vertices, faces


@pytest.mark.parametrize("kind", ["vertex shape", "face index", "nan"])
def test_points_writer_failure_leaves_no_file(tmp_path, kind):
    from skinsynth.formats.errors import FormatError

    vertices, faces = _bad_points(kind)
    with pytest.raises(FormatError if kind == "nan" else ValueError):  # NaN: a user error naming the file
        write_points_cache(tmp_path / "x.usdc", vertices, faces, 24)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("change", ["weights shape", "weights sum", "bone index", "not rigid", "rotation shape",
                                    "prim name"])
def test_skel_writer_failure_leaves_no_file(tmp_path, rig, change):
    kwargs = {}
    if change == "weights shape":
        rig["weights"] = rig["weights"][:, :3]
    elif change == "weights sum":
        rig["weights"] = rig["weights"] * 2
    elif change == "bone index":
        rig["indices"] = rig["indices"] + 1
    elif change == "not rigid":
        rig["rotations"] = rig["rotations"] * 1.1
    elif change == "rotation shape":
        rig["rotations"] = rig["rotations"][:, :, :2]
    elif change == "prim name":
        kwargs["prim_name"] = "not a name"
    with pytest.raises(ValueError):
        write_rig(tmp_path / "x.usda", rig, **kwargs)
    assert os.listdir(tmp_path) == []


def test_failure_while_writing_removes_the_temporary_file(tmp_path, monkeypatch):
    import skinsynth.formats.usd as usd

    calls = []

    def failing_extent(points):
        calls.append(1)
        if len(calls) == 2:  # the stage exists on disk by now
            raise RuntimeError("disk full")
        return original(points)

    original = usd._extent
    monkeypatch.setattr(usd, "_extent", failing_extent)
    with pytest.raises(RuntimeError):
        write_points_cache(tmp_path / "x.usda", np.zeros((3, 3, 3)), [[0, 1, 2]], 24)
    assert os.listdir(tmp_path) == []


def test_failed_overwrite_keeps_old_file(tmp_path):
    path = tmp_path / "keep.usdc"
    write_points_cache(path, np.ones((2, 3, 3)), [[0, 1, 2]], 24)
    with pytest.raises(ValueError):
        write_points_cache(path, np.ones((2, 3, 2)), [[0, 1, 2]], 24)
    assert os.listdir(tmp_path) == ["keep.usdc"]
    np.testing.assert_array_equal(read_points_cache(path)[0], np.ones((2, 3, 3)))


def test_writer_rejects_non_usd_extension(tmp_path):
    with pytest.raises(FormatError, match="must end in .usd"):
        write_points_cache(tmp_path / "x.abc", np.zeros((2, 3, 3)), [[0, 1, 2]], 24)
    assert os.listdir(tmp_path) == []


def test_a_crowd_saved_as_it_is_written_holds_what_a_crowd_saved_once_holds(tmp_path, monkeypatch):
    """Issue 25: a binary crowd's layer is saved (and lets go of its samples) every
    SAVE_EVERY_BYTES, so a crowd of any size is written in bounded memory; what the file holds is
    the same as a crowd saved once."""
    import skinsynth.formats.usd as usd
    from skinsynth.formats.usd import animated_mesh_paths, read_points_cache, write_points_characters

    rng = np.random.default_rng(3)
    crowd = rng.normal(size=(5, 7, 20, 3))
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    write_points_characters(tmp_path / "once.usdc", crowd, faces, 24.0)
    saves = []
    save = usd.Sdf.Layer.Save
    monkeypatch.setattr(usd, "SAVE_EVERY_BYTES", 7 * (20 * 12 + 48) * 2)  # every second character
    monkeypatch.setattr(usd.Sdf.Layer, "Save", lambda layer, *a: saves.append(1) or save(layer, *a))
    write_points_characters(tmp_path / "saved.usdc", crowd, faces, 24.0)
    assert len(saves) == 3  # after characters 2 and 4, and at the end
    for name in ("once.usdc", "saved.usdc"):
        paths = animated_mesh_paths(tmp_path / name)
        assert len(paths) == 5
        for c, prim in enumerate(paths):
            vertices, read_faces, fps = read_points_cache(tmp_path / name, prim)
            assert np.array_equal(vertices, crowd[c].astype(np.float32)) and fps == 24.0


# ---------------------------------------------------------------- UsdSkel of a joint tree


@pytest.fixture
def walker_tree():
    """The walker's true rig (an exact jointed LBS) and its JointTree, as pipeline.skeleton makes it."""
    from skinsynth.formats.usd import JointTree
    from skinsynth.pipeline.inputs.examples import walker
    from skinsynth.pipeline.rig.skeleton import joint_names, rest_locals, tree_local_transforms

    _, faces, rig = walker(frames=8, cycles=1, rings=8, segments=6, rig=True)
    local_r, local_t = tree_local_transforms(rig.rotations, rig.translations, rig.joints, rig.parents)
    tree = JointTree(parents=rig.parents, names=joint_names(rig.parents), rest=rest_locals(rig.joints, rig.parents),
                     rotations=local_r, translations=local_t)
    return rig, faces, tree


def test_a_joint_tree_is_the_usdskel_topology_and_usdskel_skins_it_as_the_lbs(tmp_path, walker_tree):
    rig, faces, tree = walker_tree
    indices = np.tile(np.arange(10), (len(rig.rest), 1))
    path = tmp_path / "tree.usda"
    write_skel_cache(path, rig.rest, faces, indices, rig.weights, rig.rotations, rig.translations, rig.joints, 24.0,
                     joint_tree=tree)
    expected = lbs(rig.rest, indices, rig.weights, rig.rotations, rig.translations)
    error = np.abs(read_skel_points(path) - expected).max() / np.linalg.norm(np.ptp(expected[0], axis=0))
    assert error < 1e-5, error
    stage = Usd.Stage.Open(str(path))
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/mesh/Skeleton"))
    paths = [str(p) for p in skeleton.GetJointsAttr().Get()]
    topology = UsdSkel.Topology(skeleton.GetJointsAttr().Get())
    assert topology.Validate()[0]  # parents before children
    bone = {i: tree.names.index(p.rsplit("/", 1)[-1]) for i, p in enumerate(paths) if i}
    assert sorted(bone.values()) == list(range(10)) and paths[0] == "root"
    parent_joints = topology.GetParentIndices()
    assert [-1 if parent_joints[i] == 0 else bone[parent_joints[i]] for i in range(1, 11)] == \
        [int(rig.parents[bone[i]]) for i in range(1, 11)]
    assert paths[1] == "root/chain_00_joint_00" and paths[2].startswith("root/chain_00_joint_00/")  # the pelvis
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/mesh/Mesh"))
    written = np.asarray(binding.GetJointIndicesPrimvar().Get()).reshape(-1, 10)
    np.testing.assert_array_equal([bone[j] for j in written[0]], np.arange(10))  # indices follow the joints' order


def test_a_joint_tree_that_is_no_tree_is_refused(tmp_path, walker_tree):
    import dataclasses

    rig, faces, tree = walker_tree
    indices = np.tile(np.arange(10), (len(rig.rest), 1))
    cyclic = dataclasses.replace(tree, parents=np.array([-1, 2, 1, 2, 3, 0, 5, 6, 1, 1]))
    with pytest.raises(ValueError, match="not a tree"):
        write_skel_cache(tmp_path / "bad.usda", rig.rest, faces, indices, rig.weights, rig.rotations,
                         rig.translations, rig.joints, 24.0, joint_tree=cyclic)
    assert not list(tmp_path.iterdir())
