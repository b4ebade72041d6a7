"""formats.gltf lays a joint tree out as nested nodes: the walker's true rig (an exact jointed LBS)
written through pipeline.skeleton's tree rig, read back and skinned as a glTF engine does
(tests/glb_reading.py), is the LBS; joint parents that are no tree are refused."""

import dataclasses

import numpy as np
import pytest

from skinsynth.formats.gltf import Clip, SkinnedScene, write_skinned_glb
from skinsynth.pipeline.inputs.examples import walker
from skinsynth.pipeline.rig.skeleton import gltf_clip, gltf_rig

from glb_reading import glb_document, glb_node_parents, glb_skinned


@pytest.fixture
def walker_scene():
    _, faces, rig = walker(frames=8, cycles=1, rings=8, segments=6, rig=True)
    indices = np.tile(np.arange(10), (len(rig.rest), 1))
    built = gltf_rig(rig.rest, faces, indices, rig.weights, rig.joints, parents=rig.parents)
    clip = Clip(**gltf_clip("walk", rig.rotations, rig.translations, rig.joints, 24.0, parents=rig.parents))
    return rig, SkinnedScene(**built, clips=[clip])


def test_the_nodes_nest_as_the_tree_and_skin_as_the_lbs(tmp_path, walker_scene):
    rig, scene = walker_scene
    write_skinned_glb(tmp_path / "walker.glb", scene)
    document, _ = glb_document(tmp_path / "walker.glb")
    joints = document["skins"][0]["joints"]
    parents = glb_node_parents(document)
    assert [joints.index(parents[node]) - 1 for node in joints[1:]] == rig.parents.tolist()
    assert joints[0] not in parents and document["nodes"][joints[1]]["name"] == "chain_00_joint_00"
    for node in joints:  # children in ascending joint order
        children = [joints.index(c) for c in document["nodes"][node].get("children", [])]
        assert children == sorted(children)
    truth = np.einsum("vk,fvki->fvi", rig.weights,
                      np.einsum("fkij,vj->fvki", rig.rotations, rig.rest) + rig.translations[:, None])
    error = np.abs(glb_skinned(tmp_path / "walker.glb") - truth).max() / np.linalg.norm(np.ptp(truth[0], axis=0))
    assert error <= 1e-6, error


def test_joint_parents_that_are_no_tree_are_refused(tmp_path, walker_scene):
    _, scene = walker_scene
    for parents in ([-1, 0, 3, 2, 1, 1, 1, 1, 1, 1, 1], [0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1], [-1, 0, 1]):
        with pytest.raises(ValueError, match="joint parents"):
            write_skinned_glb(tmp_path / "bad.glb", dataclasses.replace(scene, parents=np.array(parents)))
    assert not list(tmp_path.iterdir())
