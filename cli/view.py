"""``skinsynth view``: a local web page for any file skinsynth reads or writes: a puppet to pose by
hand and record (or playing a control trajectory, a motion-capture take's markers beside their
controls), a skin fit against its examples, a synthesis's animations, any sequence. This command
reads the file into the page's record and serves it; the page itself is the view stage's
(``pipeline/view/pages/``)."""

import os

import click
import numpy as np

from .common import report, summary_options, user_errors
from .options import FINITE_FLOAT, device_option, marker_take_options

#: Hosts only this machine can reach; any other makes the command warn.
LOOPBACK = ("127.0.0.1", "localhost", "::1")


@click.command("view")
@click.argument("path", type=click.Path())
@click.option("--port", default=8080, show_default=True, type=click.IntRange(0, 65535),
              help="Port to serve the page on (0: any free one).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; 0.0.0.0 lets anyone on the network open the page (a warning says so).")
@click.option("--no-open", is_flag=True, help="Do not open the page in a browser.")
@click.option("--animation", default=0, show_default=True, type=int, help="Synthesis file: the animation shown first.")
@click.option("--error-scale", default=0.01, show_default=True, type=FINITE_FLOAT,
              help="Skin file: the error shown full red, as a fraction of the rest pose's bounding-box diagonal.")
@click.option("--extrapolation-scale", default=None, type=FINITE_FLOAT,
              help="Puppet: the extrapolation indicator turns amber at this distance from the nearest training "
                   "example and red at twice it (RMS over the controls, the rest box's largest side = 1: a distance "
                   "between poses, not an error).  [default: the largest gap between a training example and its nearest "
                   "neighbour]")
@click.option("--record", "record_path", default=None, type=click.Path(dir_okay=False),
              help="Puppet: where the record button saves a drag session (.csv or .npy, a control trajectory "
                   "play reads; the page can change it).  [default: PUPPET_NAME.session.csv here]")
@click.option("--controls", "-c", "controls_path", default=None, type=click.Path(dir_okay=False),
              help="Puppet: a control trajectory to play on the page (a timeline; any file play reads: CSV, .npy, a "
                   "mesh sequence, or a motion-capture take .c3d, its markers drawn beside their controls; "
                   "docs/mocap.md).")
@click.option("--ik/--no-ik", default=True, show_default=True, help="Puppet: poses beyond its examples follow the "
              "controls with a skeleton, and frames whose skin the prediction tears are mended, as play does "
              "(docs/mocap.md); --no-ik shows the kernel CCA's prediction alone.")
@device_option("Puppet: where the run-time path runs (auto, cpu, cuda or cuda:N), as play.")
@marker_take_options
@summary_options
@user_errors
def view(path, port, host, no_open, animation, error_scale, extrapolation_scale, record_path, controls_path, ik,
         device, as_json, quiet, **take_options):
    """Look at PATH in a web browser: a page served on this machine until Ctrl-C.

    PATH: a puppet (train-kcca: drag its control points; every move is play's own prediction;
    an extrapolation indicator; reset to a training frame; record a session as a trajectory
    play reads; --controls plays a trajectory or a take), a skin file (its examples beside
    fit-skin's reconstruction, the error as colour), a synthesis file (any of its animations,
    components coloured, seams marked), or a sequence (a folder or glob of OBJ/PLY/OFF frames,
    .npz, .h5, USD, play's .h5). The page's client is served by the command itself: it works
    offline.

    \b
    Examples:
      skinsynth view horse.puppet.h5
      skinsynth view horse.skin.h5 --port 8081
      skinsynth view herd.h5 --animation 12 --no-open --json
      skinsynth view samba.puppet.h5 --controls serve.c3d --markers samba.layout.json
    """
    from skinsynth.formats.atomic import stop_if_received
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.view import serve

    from .marker_take import check_take_options

    if not error_scale > 0:
        raise OptionError(f"--error-scale must be positive (got {error_scale})")
    if extrapolation_scale is not None and not extrapolation_scale > 0:
        raise OptionError(f"--extrapolation-scale must be positive (got {extrapolation_scale})")
    check_take_options([controls_path] if controls_path else [], take_options)
    kind, scene, details, motions = _read(path, animation, error_scale, extrapolation_scale, record_path, device,
                                          controls_path, take_options, ik)
    lines = details.pop("lines", [])  # a take's, said before the URL
    if host not in LOOPBACK:
        _warn(f"--host {host}: anyone who can reach this machine on the network can open the page"
              + (" (and save sessions here)" if kind == "puppet" else ""))

    def listening(url, bound):
        summary = {"url": url, "host": host, "port": bound, "kind": kind, "path": str(path), **details}
        report(summary, lines + [f"viewing {path} ({kind}) at {url}; Ctrl-C stops"], as_json, quiet)

    try:
        serve(scene, host, port, f"skinsynth view {os.path.basename(str(path).rstrip('/'))}", listening,
              check_stop=stop_if_received, warn=_warn, open_browser=not no_open)
    finally:
        if motions is not None:
            motions.close()


def _warn(message):
    """A warning line on stderr: the command's, and the page's while it stays up."""
    click.echo(f"warning: {message}", err=True)


def _read(path, animation, error_scale, extrapolation_scale, record_path, device, controls_path=None,
          take_options=None, ik=True):
    """(kind, the page's view record, summary details, an open synthesis file or None)."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.model import read_header
    from skinsynth.pipeline.errors import OptionError

    if str(path).lower().endswith((".h5", ".hdf5")) and os.path.isfile(path):
        try:
            stage, _ = read_header(path)
        except FormatError:
            stage = None  # not a skinsynth model file: a sequence or play's characters
        if stage == "puppet":
            return ("puppet", *puppet_view(path, extrapolation_scale, record_path, device, controls_path,
                                           take_options, ik), None)
        if controls_path is not None:
            raise OptionError(f"--controls plays a trajectory on a puppet (train-kcca's file), and {path} is "
                              f"{'a ' + repr(stage) + ' file' if stage else 'a sequence'}")
        if stage == "synthesis":
            return ("synthesis", *_synthesis(path, animation))
        if stage in ("skin", "controls", "graph"):  # each carries the skin it was made from
            return ("skin", *_skin(path, error_scale, contacts=stage == "graph"), None)
        if stage is not None:
            raise FormatError(path, f"a '{stage}' file holds no animation view can show")
    if controls_path is not None:
        raise OptionError(f"--controls plays a trajectory on a puppet (train-kcca's file), and {path} is a sequence")
    return ("sequence", *_sequence(path), None)


def puppet_view(path, extrapolation_scale=None, record_path=None, device="auto", controls_path=None,
                take_options=None, ik=True):
    """The puppet page's :class:`~skinsynth.pipeline.view.pages.PuppetView` of the puppet at ``path``
    and its summary details (with ``lines``, a take's text, said before the URL); controls_path:
    a trajectory it plays (any file play reads; a .c3d take read with ``take_options``,
    ``marker_take_options``'s values by name), every frame as play plays it; ik: as play's --ik
    (a dragged pose beyond the examples on the skeleton; a trajectory's torn frames mended)."""
    from skinsynth.formats.puppet_file import read_puppet
    from skinsynth.gpu import resolve_device
    from skinsynth.pipeline.mesh.geometry import largest_side
    from skinsynth.pipeline.puppet import DevicePlayer, host_inputs, play_beyond_examples, puppet_from_record
    from skinsynth.pipeline.view import PuppetView
    from skinsynth.pipeline.view import extrapolation_scale as default_scale

    from .skeleton_poses import skeleton_poses

    record, _, skin = read_puppet(path)
    puppet = puppet_from_record(record)
    device = resolve_device(device)
    training = skin.examples[puppet.train_frames][:, puppet.control_indices]  # (n_p, n_c, 3) world
    in_place = host_inputs(puppet, training)[1]
    unit = largest_side(skin.rest_vertices)
    trajectory, played = (None, {}) if controls_path is None else _trajectory(
        controls_path, path, record, puppet, skin, take_options or {}, in_place, unit)
    # uploaded once, warm for every move; as play: the solver whenever the puppet has one
    solver = puppet.translations is not None
    player = DevicePlayer(puppet, device, translation_solver=solver)
    poses = skeleton_poses(puppet, skin, device) if ik else None

    def play_path(controls, fps=None):
        """World controls (N, n_c, 3) -> vertices (N, V, 3) float32: play's path (its torn frames
        mended where ``fps`` is given: a trajectory's)."""
        vertices = player.play(np.asarray(controls, dtype=np.float64))
        if poses is not None:
            play_beyond_examples(puppet, poses, np.asarray(controls, dtype=np.float64), vertices, device, solver,
                                 fps=fps)
        return vertices

    def predict(controls):
        """World controls (n_c, 3) -> vertices (V, 3) float32: play's path, one frame."""
        return play_path(np.asarray(controls)[None])[0]

    if trajectory is not None:
        trajectory.vertices = play_path(trajectory.controls, trajectory.fps)

    predict(training[0])  # compile or load the kernels now
    scale = extrapolation_scale or default_scale(in_place, unit)
    stem = os.path.basename(str(path))
    stem = stem[:-len(".puppet.h5")] if stem.endswith(".puppet.h5") else os.path.splitext(stem)[0]
    scene = PuppetView(faces=skin.faces, predict=predict, place=lambda c: host_inputs(puppet, np.asarray(c)[None])[1][0],
                       controls=training[0], training_frames=np.asarray(puppet.train_frames), training_controls=training,
                       training_in_place=in_place, unit=unit, scale=scale, fps=skin.fps, up_axis=skin.scene.up_axis,
                       record_path=record_path or f"{stem}.session.csv", save=_save_trajectory, size=unit,
                       trajectory=trajectory)
    return scene, {"controls": int(len(puppet.control_indices)), "device": device, "skinning": puppet.skinning,
                   "extrapolation_scale": scale, "record": scene.record_path, **played}


def _trajectory(controls_path, path, record, puppet, skin, take_options, training_in_place, unit):
    """(the :class:`~skinsynth.pipeline.view.pages.TrajectoryView` of ``--controls``, summary details
    ``trajectory`` and the take's ``lines``): read as play reads it, every frame's extrapolation
    computed once; frames are predicted as shown."""
    from skinsynth.formats.trajectories import read_control_trajectories
    from skinsynth.pipeline.puppet import host_inputs
    from skinsynth.pipeline.view import TrajectoryView, extrapolation_distances

    from .marker_take import is_take, take_controls

    take = take_controls(controls_path, puppet, record, skin, take_options, path) if is_take(controls_path) else None
    if take is None:
        controls = read_control_trajectories(controls_path, len(puppet.control_indices), puppet.control_indices,
                                             skin.rest_vertices.shape[0])
    else:
        controls = take.controls
    distances, nearest = extrapolation_distances(host_inputs(puppet, controls)[1], training_in_place, unit)
    fps = float(skin.fps if take is None else take.fps)
    trajectory = TrajectoryView(controls=controls, fps=fps, distances=distances, nearest=nearest,
                                name=os.path.basename(str(controls_path)),
                                **({} if take is None else {"markers": take.markers, "labels": tuple(take.labels),
                                                            "start_time": take.start_time}))
    summary = {"path": str(controls_path), "frames": int(len(controls)), "fps": fps,
               "extrapolation_worst": float(distances.max()), "extrapolation_worst_frame": int(np.argmax(distances))}
    if take is not None:
        summary["take"] = take.summary
    return trajectory, {"trajectory": summary, **({"lines": list(take.lines)} if take is not None else {})}


def _save_trajectory(path, trajectory):
    """A recorded session (F, n_c, 3) as a control-trajectory file ``play`` reads."""
    from skinsynth.formats.trajectories import write_control_trajectories
    from skinsynth.pipeline.errors import OptionError

    try:
        write_control_trajectories(path, trajectory)
    except ValueError as error:
        raise OptionError(str(error)) from None


def _skin(path, error_scale, contacts=False):
    """The skin view; contacts: also a graph file's input ground contacts (/graph/contacts), if any."""
    from skinsynth.formats.graph_file import read_graph_contacts
    from skinsynth.formats.model import read_model
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.view import skin_view

    model = read_model(path, groups=("mesh", "examples", "skin") + (("graph",) if contacts else ()))
    skin = read_skin(path, model)
    found = read_graph_contacts(path, model, skin) if contacts else None
    return (skin_view(skin, error_scale, found),
            {"frames": int(skin.examples.shape[0]), "error_scale": error_scale,
             **({"contact_patches": int(found.offsets.size - 1)} if found is not None else {})})


def _synthesis(path, animation):
    """The synthesis view, reading one animation at a time from the file, held open while served."""
    import contextlib

    from skinsynth.formats.errors import FormatError, require_finite
    from skinsynth.formats.model import read_model
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.formats.synthesis_file import component_bones, open_motions, read_sources, synthesis_count
    from skinsynth.pipeline.inputs.clips import Clips
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.view import synthesis_view, vertex_components

    skin = read_skin(path, read_model(path, groups=("mesh", "examples", "skin")))
    count = synthesis_count(path)
    if count == 0:
        raise FormatError(path, "the synthesis holds no animation")
    if not 0 <= animation < count:
        raise OptionError(f"--animation {animation}: the file holds animations 0..{count - 1}")
    stack = contextlib.ExitStack()
    F, t = stack.enter_context(open_motions(path))
    try:
        components = component_bones(path)
        owner = vertex_components(skin.bone_indices, skin.bone_weights, components)
    except BaseException:
        stack.close()
        raise
    clips = Clips(skin.clip_names, skin.clip_frames) if len(skin.clip_frames) > 1 else None
    scene = synthesis_view(skin, (F, t), lambda a: read_sources(path, [a])[:, 0], owner, len(components), animation,
                           clips, lambda what, values: require_finite(path, what, values))
    return scene, {"animations": count, "frames": int(F.shape[1]), "components": len(components)}, stack


def _sequence(path):
    """Any sequence preview reads (frame files, .npz/.h5, USD, play's .h5): the panels it shows."""
    from skinsynth.pipeline.view import SequenceView

    from .preview import _panels

    panels, fps, up = _panels(path, [], None, False, False, 0.01)
    parts = [(panel.title, panel.vertices, panel.faces) for panel in panels]
    return SequenceView(parts=parts, fps=fps, up_axis=up), {"frames": int(min(len(v) for _, v, _ in parts)),
                                                             "meshes": len(parts)}
