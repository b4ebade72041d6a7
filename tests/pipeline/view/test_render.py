"""The headless rasteriser (groundwork for ``skinsynth preview``) against analytic images."""

import numpy as np
import pytest
import trimesh

from skinsynth.pipeline.view.rasteriser import (BACKGROUND, MESH_COLOR, Camera, frame_bounds, lambert, look_at, project,
                                       render)

W, H = 160, 120


def background_mask(image):
    return np.all(image == (np.asarray(BACKGROUND) * 255 + 0.5).astype(np.uint8), axis=2)


def test_a_unit_cube_seen_head_on_is_its_front_square_in_its_lambert_shade():
    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    distance = 3.0
    camera = Camera(view=look_at((0.0, 0.0, distance), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), fov_y=np.radians(40.0))
    light = np.array([0.3, 0.5, 0.8])
    image = render(cube.vertices, cube.faces, camera, W, H, light=light)
    # the front face z = 0.5 projects to a square of half-size f·0.5/(d − 0.5) pixels about the centre
    focal = (H / 2) / np.tan(camera.fov_y / 2)
    half = focal * 0.5 / (distance - 0.5)
    x, y = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    inside = (np.abs(x - W / 2) < half - 1) & (np.abs(y - H / 2) < half - 1)
    outside = (np.abs(x - W / 2) > half + 1) | (np.abs(y - H / 2) > half + 1)
    covered = ~background_mask(image)
    assert covered[inside].all() and not covered[outside].any()
    shade = lambert(np.array([[0.0, 0.0, 1.0]]), light / np.linalg.norm(light))[0] * np.asarray(MESH_COLOR)
    assert np.abs(image[inside].astype(float) - shade * 255).max() <= 1.0


def test_the_nearer_triangle_wins_whatever_the_order():
    camera = Camera(view=look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0)))
    near = np.array([[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [0.0, 1.0, 1.0]])
    far = near + [0.2, 0.0, -1.0]
    vertices = np.concatenate([near, far])
    red, blue = np.tile([1.0, 0.0, 0.0], (3, 1)), np.tile([0.0, 0.0, 1.0], (3, 1))
    images = [render(vertices, faces, camera, W, H, vertex_colors=np.concatenate([red, blue]), light=[0, 0, 1.0])
              for faces in (np.array([[0, 1, 2], [3, 4, 5]]), np.array([[3, 4, 5], [0, 1, 2]]))]
    assert np.array_equal(images[0], images[1])
    centre = images[0][H // 2, W // 2]
    assert centre[0] > 200 and centre[2] < 10  # red: the nearer one


@pytest.mark.parametrize("preset", ["front", "side", "three-quarter"])
@pytest.mark.parametrize("up_axis", [1, 2])
def test_a_framed_camera_sees_the_whole_animation_upright(preset, up_axis):
    rng = np.random.default_rng(0)
    frames = rng.normal(size=(10, 200, 3)) * [1.0, 3.0, 0.5] + [5.0, -2.0, 1.0]
    if up_axis == 2:
        frames = frames[..., [0, 2, 1]] * [1, -1, 1]
    lower, upper = frames.reshape(-1, 3).min(axis=0), frames.reshape(-1, 3).max(axis=0)
    camera = frame_bounds(lower, upper, preset, up_axis=up_axis, aspect=W / H)
    screen = project(frames.reshape(-1, 3), camera, W, H)
    assert (screen[:, 2] > camera.near).all()
    assert (screen[:, 0] > 0).all() and (screen[:, 0] < W).all() and (screen[:, 1] > 0).all() and (screen[:, 1] < H).all()
    top = project(np.array([(lower + upper) / 2 + np.eye(3)[up_axis]]), camera, W, H)[0]
    assert top[1] < H / 2  # the up axis points up on screen


@pytest.mark.parametrize("up_axis", [1, 2])
def test_a_travelling_character_stays_in_frame_and_large_when_followed(up_axis):
    from skinsynth.pipeline.view.preview import Panel, Preview

    box = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    box.vertices[:, up_axis] += 0.2  # standing on the ground
    frames = 48
    ahead = 0 if up_axis == 2 else 2  # travels 20 of its sizes along a ground axis, bobbing
    path = np.zeros((frames, 3))
    path[:, ahead] = np.linspace(0.0, 8.0, frames)
    path[:, up_axis] = 0.05 * np.abs(np.sin(np.linspace(0.0, 6 * np.pi, frames)))
    vertices = box.vertices[None] + path[:, None]
    shown = {}
    for framing in ("auto", "fixed"):
        movie = Preview([Panel(vertices, box.faces, "")], size=(W, H), up_axis=up_axis, framing=framing, fps=24.0)
        assert movie.follow == (framing == "auto")
        spans = []
        for m in range(frames):
            camera, _ = movie.view(0, m)
            screen = project(vertices[m], camera, W, H)
            assert (screen[:, 0] >= 0).all() and (screen[:, 0] <= W).all()
            assert (screen[:, 1] >= 0).all() and (screen[:, 1] <= H).all()
            spans.append(np.ptp(screen[:, :2], axis=0).max())
        shown[framing] = np.array(spans)
    # followed, the box fills a good share of the frame every frame; fixed, it is a speck
    assert shown["auto"].min() > 0.3 * H > 3 * shown["fixed"].max(), (shown["auto"].min(), shown["fixed"].max())
    still = vertices[:1].repeat(frames, axis=0)  # a character that does not travel: one fixed camera
    assert not Preview([Panel(still, box.faces, "")], size=(W, H), up_axis=up_axis).follow
    image = movie[0]
    assert image.shape == (H, W, 3)


def test_a_crowd_shows_each_character_at_its_panels_height_and_a_comparison_keeps_one_camera():
    """Issue 68: a play crowd's characters stand apart on a grid; one camera framing them all made
    each panel show the whole grid and its character a speck. Where the panels' characters stand
    apart, each panel's camera centres on its own character, all as far away (the largest box);
    where they share a place (a prediction beside its truth), one camera frames them all."""
    from skinsynth.pipeline.view.preview import Panel, Preview

    box = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    box.vertices[:, 1] += 0.2
    frames = 8
    sway = np.zeros((frames, 3))
    sway[:, 0] = 0.02 * np.sin(np.linspace(0.0, np.pi, frames))
    grid = [np.array([x, 0.0, z]) for x in (0.0, 6.0) for z in (0.0, 6.0)]  # a crowd: 2 × 2, 15 sizes apart
    crowd = [Panel(box.vertices[None] + sway[:, None] + place, box.faces, f"character {k}")
             for k, place in enumerate(grid)]
    movie = Preview(crowd, size=(W, H), framing="fixed", fps=24.0)
    for k, panel in enumerate(crowd):
        camera, _ = movie.view(k, 0)
        screen = project(panel.vertices[0], camera, W, H)
        assert (screen[:, :2] >= 0).all() and (screen[:, 0] <= W).all() and (screen[:, 1] <= H).all()
        assert np.ptp(screen[:, 1]) > 0.5 * H  # its own panel's height, not a speck of the grid
    sizes = [np.ptp(project(p.vertices[0], movie.view(k, 0)[0], W, H)[:, 1]) for k, p in enumerate(crowd)]
    assert max(sizes) - min(sizes) < 0.02 * H  # all as far away
    truth = Panel(crowd[0].vertices + np.array([0.05, 0.0, 0.0]), box.faces, "truth")
    compared = Preview([crowd[0], truth], size=(W, H), framing="fixed", fps=24.0)
    assert compared.view(0, 0)[0] is compared.view(1, 0)[0]  # sharing a place: one camera
