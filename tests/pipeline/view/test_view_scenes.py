"""What ``skinsynth view`` shows (pipeline/view/scenes.py), each function against a brute-force
loop or a case worked by hand."""

import numpy as np
import pytest

from skinsynth.pipeline.view import scenes


def random_mesh(rng, vertices=40, faces=70):
    return rng.normal(size=(vertices, 3)), rng.integers(0, vertices, size=(faces, 3))


def test_split_by_key_gives_back_every_face_in_its_part():
    rng = np.random.default_rng(0)
    _, faces = random_mesh(rng)
    keys = rng.integers(0, 4, size=len(faces))
    keys[keys == 2] = 3  # a key with no face has no part
    parts = scenes.split_by_key(faces, keys)
    assert [k for k, _, _ in parts] == [0, 1, 3]
    for key, ids, local in parts:
        assert np.array_equal(ids[local], faces[keys == key])  # the same faces, in order
        assert np.array_equal(ids, np.unique(faces[keys == key]))  # only the vertices they use
        assert local.dtype == np.uint32


def test_error_levels_quantise_the_mean_corner_error_brute_force():
    rng = np.random.default_rng(1)
    _, faces = random_mesh(rng)
    errors = rng.uniform(0.0, 0.3, size=40)
    levels = scenes.error_levels(errors, faces, scale=0.2, steps=5)
    for t, (a, b, c) in enumerate(faces):
        mean = (errors[a] + errors[b] + errors[c]) / 3
        assert levels[t] == round(min(mean / 0.2, 1.0) * 4)
    with pytest.raises(ValueError):
        scenes.error_levels(errors, faces, 0.2, 1)


def test_level_colors_run_from_preview_grey_to_preview_red():
    from skinsynth.pipeline.view.preview import ERROR_HIGH, ERROR_LOW

    colors = scenes.level_colors(6)
    assert colors.shape == (6, 3) and colors.dtype == np.uint8
    assert np.array_equal(colors[0], np.rint(ERROR_LOW * 255)) and np.array_equal(colors[-1], np.rint(ERROR_HIGH * 255))
    assert np.all(np.diff(colors[:, 0].astype(int)) >= 0)  # red grows


def test_vertex_errors_are_euclidean_distances():
    a, b = np.zeros((2, 3)), np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0]])
    assert np.allclose(scenes.vertex_errors(a, b), [5.0, 2.0])


def test_vertex_and_face_components_brute_force():
    rng = np.random.default_rng(2)
    vertices, bones, influences = 30, 6, 3
    indices = np.stack([rng.choice(bones, influences, replace=False) for _ in range(vertices)])
    weights = rng.dirichlet(np.ones(influences), size=vertices)
    components = [np.array([0, 3]), np.array([1, 2]), np.array([4, 5])]
    found = scenes.vertex_components(indices, weights, components)
    for v in range(vertices):
        totals = [sum(w for b, w in zip(indices[v], weights[v]) if b in c) for c in components]
        assert found[v] == int(np.argmax(totals))
    faces = rng.integers(0, vertices, size=(50, 3))
    per_face = scenes.face_components(faces, found)
    for t, corners in enumerate(found[faces]):
        counts = {c: list(corners).count(c) for c in corners}
        best = max(counts.values())
        assert per_face[t] == min(c for c, n in counts.items() if n == best)
    with pytest.raises(ValueError, match="no component"):
        scenes.vertex_components(indices, weights, components[:2])


def test_component_colors_differ_for_the_first_eight():
    colors = scenes.component_colors(10)
    assert len({tuple(c) for c in colors[:8]}) == 8 and np.array_equal(colors[8], colors[0])


def test_seam_frames_mark_every_jump():
    sources = np.array([[4, 5, 6, 20, 21, 3], [0, 1, 2, 3, 4, 5]])
    seams = scenes.seam_frames(sources)
    assert seams.tolist() == [[False, False, False, True, False, True], [False] * 6]


def test_seam_frames_of_several_clips_mark_playing_into_the_next_clips_first_frame():
    from skinsynth.pipeline.inputs.clips import Clips

    clips = Clips(("a", "b"), (6, 30))  # b begins at frame 6
    sources = np.array([[4, 5, 6, 7, 21, 22], [0, 1, 2, 3, 4, 5], [29, 30, 6, 7, 8, 0]])
    # brute force: a seam where the source is not the previous one's next frame of the same clip
    clip = lambda f: 0 if f < 6 else 1  # noqa: E731
    expected = [[k > 0 and not (row[k] == row[k - 1] + 1 and clip(row[k]) == clip(row[k - 1])) for k in range(6)]
                for row in sources]
    assert scenes.seam_frames(sources, clips).tolist() == expected
    assert expected[0] == [False, False, True, False, True, False]  # a's last (5) then b's first (6): a seam
    assert scenes.seam_frames(sources, Clips.single(36)).tolist() == scenes.seam_frames(sources).tolist()


def test_extrapolation_is_the_rms_distance_to_the_nearest_example_brute_force():
    rng = np.random.default_rng(3)
    training = rng.normal(size=(9, 4, 3))
    controls = rng.normal(size=(4, 3))
    distance, nearest = scenes.extrapolation(controls, training, unit=2.0)
    gaps = [np.sqrt(np.mean([np.sum((training[n, i] - controls[i]) ** 2) for i in range(4)])) for n in range(9)]
    assert nearest == int(np.argmin(gaps)) and distance == pytest.approx(min(gaps) / 2.0)
    assert scenes.extrapolation(training[5], training, 1.0) == (0.0, 5)


def test_extrapolation_scale_is_the_largest_nearest_neighbour_gap_brute_force():
    rng = np.random.default_rng(4)
    training = rng.normal(size=(7, 3, 3))
    gap = lambda a, b: np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))  # noqa: E731
    expected = max(min(gap(training[i], training[j]) for j in range(7) if j != i) for i in range(7))
    assert scenes.extrapolation_scale(training, 0.5) == pytest.approx(expected / 0.5)
    assert scenes.extrapolation_scale(training[:1], 1.0) == 0.05
    # a repeated pose (a periodic capture) is not its own neighbour
    repeated = np.concatenate([training, training[:3]])
    assert scenes.extrapolation_scale(repeated, 0.5) == pytest.approx(expected / 0.5)
    assert scenes.extrapolation_scale(np.repeat(training[:1], 4, axis=0), 1.0) == 0.05


def test_extrapolation_color_green_amber_red():
    assert np.array_equal(scenes.extrapolation_color(0.0, 0.1), scenes.INSIDE)
    assert np.array_equal(scenes.extrapolation_color(0.1, 0.1), scenes.EDGE)
    assert np.array_equal(scenes.extrapolation_color(0.5, 0.1), scenes.OUTSIDE)
    middle = scenes.extrapolation_color(0.05, 0.1).astype(float)
    assert np.allclose(middle, (scenes.INSIDE + scenes.EDGE) / 2, atol=0.5)


def test_resample_session_holds_each_move_until_the_next_brute_force():
    rng = np.random.default_rng(5)
    times = np.concatenate([[10.0], 10.0 + np.sort(rng.uniform(0.0, 2.0, size=12))])
    controls = rng.normal(size=(13, 2, 3))
    fps = 24.0
    trajectory = scenes.resample_session(times, controls, fps, end=12.5)
    assert len(trajectory) == int(2.5 * fps) + 1
    for k, frame in enumerate(trajectory):
        t = 10.0 + k / fps
        last = max(i for i in range(13) if times[i] <= t + 1e-9)
        assert np.array_equal(frame, controls[last])
    # a move exactly on a frame's time is that frame's
    exact = scenes.resample_session([0.0, 0.5], controls[:2], 2.0)
    assert np.array_equal(exact, controls[[0, 1]])
    assert len(scenes.resample_session([0.0], controls[:1], 30.0)) == 1


def test_side_by_side_steps_past_the_width():
    rest = np.array([[-1.0, 0.0, 0.0], [3.0, 5.0, 1.0]])
    assert np.allclose(scenes.side_by_side(rest), [4.8, 0.0, 0.0])
    assert np.allclose(scenes.side_by_side(np.zeros((2, 3))), [1.0, 0.0, 0.0])


def test_the_parts_of_an_error_map_cover_the_mesh_once():
    rng = np.random.default_rng(6)
    vertices, faces = random_mesh(rng)
    levels = scenes.error_levels(rng.uniform(0, 1, 40), faces, 0.5, 4)
    parts = scenes.split_by_key(faces, levels)
    triangles = np.concatenate([vertices[ids][local] for _, ids, local in parts])
    expected = np.concatenate([vertices[faces[levels == k]] for k, _, _ in parts])
    assert np.array_equal(triangles, expected) and len(triangles) == len(faces)


def test_planted_vertices_are_the_patches_planted_at_the_frame():
    # Two patches, {7, 2, 9} and {4, 2} (a vertex may sit in both), three frames.
    vertices, offsets = np.array([2, 7, 9, 2, 4]), np.array([0, 3, 5])
    planted = np.array([[True, False], [True, True], [False, False]])
    assert scenes.planted_vertices(vertices, offsets, planted, 0).tolist() == [2, 7, 9]
    assert scenes.planted_vertices(vertices, offsets, planted, 1).tolist() == [2, 4, 7, 9]  # each once, ascending
    none = scenes.planted_vertices(vertices, offsets, planted, 2)
    assert none.size == 0 and none.dtype == np.int64


def test_skeleton_lines_join_each_jointed_bone_to_its_parent_where_the_bones_carry_them():
    """The walker's true rig: every joint where both its bones put it, a line per jointed bone from
    its parent's joint, none for a bone marked free."""
    from skinsynth.pipeline.inputs.examples import walker

    _, _, rig = walker(frames=6, cycles=1, rings=6, segments=4, rig=True)
    jointed = rig.parents >= 0
    jointed[9] = False  # an arm hanging free: no line
    points, segments = scenes.skeleton_lines(rig.rotations[3], rig.translations[3], rig.joints, rig.parents, jointed)
    carried = np.einsum("bij,bj->bi", rig.rotations[3], rig.joints) + rig.translations[3]
    np.testing.assert_allclose(points, carried)
    by_parent = np.einsum("bij,bj->bi", rig.rotations[3][np.maximum(rig.parents, 0)], rig.joints) + \
        rig.translations[3][np.maximum(rig.parents, 0)]
    np.testing.assert_allclose(points[rig.parents >= 0], by_parent[rig.parents >= 0], atol=1e-12)  # joints hold
    lined = [b for b in range(10) if jointed[b]]
    assert segments.shape == (len(lined), 2, 3) == (8, 2, 3)
    np.testing.assert_allclose(segments[:, 0], points[rig.parents[lined]])
    np.testing.assert_allclose(segments[:, 1], points[lined])


def test_the_extrapolation_report_gives_each_trajectory_its_distances_and_one_line():
    rng = np.random.default_rng(3)
    training = rng.normal(size=(6, 4, 3))
    far = training[:3] + 10.0
    entries, lines = scenes.extrapolation_report(["near.npy", "far.npy"], [training[:3], far], training, 1.0)
    scale = scenes.extrapolation_scale(training, 1.0)
    assert [e["controls"] for e in entries] == ["near.npy", "far.npy"] and len(lines) == 2
    assert entries[0]["per_frame"] == [0.0, 0.0, 0.0] and entries[0]["frames_beyond_scale"] == 0
    assert entries[1]["frames_beyond_scale"] == 3 and entries[1]["scale"] == scale
    assert lines[1].startswith("extrapolation of far.npy: mean ") and "3 of 3 frames beyond" in lines[1]
