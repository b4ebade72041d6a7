"""``skinsynth example``: write a built-in procedural example sequence."""

import click

from skinsynth.formats.output_file import check_output_path

from .options import FiniteFloatRange
from .common import fail, report, summary_options, user_errors

EXAMPLES = ("bending-bar", "walker", "humanoid", "quadruped")
#: The generated characters with known skeletons (pipeline/inputs/characters.py).
CHARACTER_EXAMPLES = ("humanoid", "quadruped")
MOTIONS = ("walk", "raise", "crouch", "jump", "graze")

#: Each example's defaults for the options that default per example.
DEFAULTS = {"bending-bar": {"frames": 60, "rings": 40, "segments": 16, "cycles": 1},
            "walker": {"frames": 48, "rings": 24, "segments": 10, "cycles": 2},
            "humanoid": {"frames": 48, "rings": 60, "segments": 10, "cycles": 2},
            "quadruped": {"frames": 48, "rings": 60, "segments": 10, "cycles": 2}}


@click.command("example")
@click.argument("name", type=click.Choice(EXAMPLES))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Sequence file to write (.npz).")
@click.option("--frames", type=int, show_default="bending-bar 60, walker 48, humanoid and quadruped 48 a motion",
              help="Number of frames (humanoid, quadruped: of each motion).")
@click.option("--rings", type=int, show_default="bending-bar 40, walker 24, humanoid and quadruped 60",
              help="Vertex rings along the bar (walker: along each leg, its other tubes as many per unit length; "
                   "humanoid, quadruped: per unit length of every bone's tube).")
@click.option("--segments", type=int, show_default="bending-bar 16, others 10", help="Vertices around each ring.")
@click.option("--cycles", type=int, show_default="bending-bar 1, others 2",
              help="Bend-and-twist cycles (walker: gait cycles; humanoid, quadruped: gait cycles of a walk) over the "
                   "frames.")
@click.option("--fps", default=24.0, show_default=True, type=FiniteFloatRange(min=0.0, min_open=True, max=1e6), help="Frame rate stored with the sequence.")
@click.option("--planted", is_flag=True,
              help="walker: walk forward with truly planted feet (legs by inverse kinematics) instead of in place.")
@click.option("--tempo", default=0.0, show_default=True, type=FiniteFloatRange(min=0.0, max=1.0, max_open=True),
              help="walker: speed up over the clip, from 1 − TEMPO to 1 + TEMPO times the mean: no two strides alike.")
@click.option("--event", is_flag=True,
              help="walker: stand 2 s, walk 4 s, stumble once, run off for 3 s (a one-time event; --frames and "
                   "--cycles follow from --fps).")
@click.option("--pivot", is_flag=True,
              help="walker: stand and turn 180° on the ball of the left foot, --cycles times (default 4: two whole "
                   "turns), 2 s each (--frames follows from --fps).")
@click.option("--limbs", default=1.0, show_default=True, type=FiniteFloatRange(min=0.5, max=2.0),
              help="humanoid, quadruped: the legs' and arms' length, times the default's (other proportions).")
@click.option("--motion", "motions", multiple=True, type=click.Choice(MOTIONS),
              help="humanoid (walk, raise, crouch, jump), quadruped (walk, graze): the motions, in order "
                   "(repeatable).  [default: all of the character's]")
@summary_options
@user_errors
def example(name, output, frames, rings, segments, cycles, fps, planted, tempo, event, pivot, limbs, motions, quiet,
            as_json):
    """Write a built-in example mesh sequence (no download needed).

    bending-bar: a capped cylinder that bends into an arc and twists over one cycle, the kind of
    example of Feng et al. 2008 Table 1; its deformation is smooth but not itself skinned.

    walker: an articulated figure (1.75 units tall, Y up, nine tubes in one mesh: chest, pelvis,
    head, legs, feet, arms) walking in place: the legs swing in antiphase, the stance foot stays
    on the ground (y = 0) while the other swings above it, the pelvis bobs, the arms swing
    opposite to the legs. Ten skinned parts with soft knees; the limbs hang from the torso by weak
    ties, so build-graph gives each leg a bone component of its own (fit it with 10 bones, one
    per part, or 12 for some slack). --rings counts the rings along a leg (the other tubes get as
    many per unit length). The default is two gait cycles in 48 frames (1 s a cycle at 24 fps),
    1,248 vertices; a whole number of cycles loops. On the spot each stance foot slides back (as
    on a treadmill); --planted walks forward instead, each stance foot exactly still on the ground
    while the body travels (1.06 units a cycle), so a whole number of cycles loops but for that
    travel. --event makes a clip with a one-time event, as captures have: the walker stands 2 s,
    walks 4 s, stumbles once and runs off (228 frames at 24 fps). --pivot makes a foot that turns on
    the spot: the walker steps in place with its left foot, then turns 180° about that foot's ball
    while the right foot swings round, the left sole flat on the floor and its ball still; twice
    per whole turn (192 frames at 24 fps by default, a loop).

    humanoid, quadruped: characters with known skeletons, to check a --skeleton fit against (docs/
    skeleton.md). One tube per bone, skinned as real skin is at a joint (half and half), posed by
    their own rig: the humanoid (17 bones, 1.75 tall in an A pose, Y up, facing +z, its left at +x)
    walks in place, raises its arms over its head, squats and jumps (the feet leave the ground);
    the quadruped (18 bones, its head at +z) walks and grazes. --frames frames each motion;
    --limbs lengthens or shortens the legs and arms.

    \b
    Example:
      skinsynth example bending-bar -o bar.npz --frames 120
      skinsynth fit-skin bar.npz -o bar.skin.h5 --bones 8
      skinsynth example walker -o walker.npz
      skinsynth example walker -o walking.npz --planted
      skinsynth example walker -o pivot.npz --pivot
      skinsynth fit-skin walker.npz -o walker.skin.h5 --bones 12
      skinsynth example humanoid -o humanoid.npz --limbs 1.2
      skinsynth fit-skin humanoid.npz -o humanoid.skin.h5 --bones 17 --skeleton
    """
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.inputs.examples import WALKER_EVENT_SECONDS, bending_bar, example_memory, walker, walker_event
    from skinsynth.pipeline.inputs.characters import CHARACTERS, character, character_memory
    from skinsynth.pipeline.inputs.pivot_walker import PIVOT_SECONDS, pivot_walker
    from skinsynth.pipeline.runtime.resources import check_memory

    defaults = DEFAULTS[name]
    frames = defaults["frames"] if frames is None else frames
    rings = defaults["rings"] if rings is None else rings
    segments = defaults["segments"] if segments is None else segments
    cycles = (4 if pivot else defaults["cycles"]) if cycles is None else cycles
    check_output_path(output, (".npz",))
    if frames < 2 or rings < 2 or segments < 3 or cycles < 1 or not fps > 0:
        fail("--frames and --rings must be at least 2, --segments at least 3, --cycles at least 1, --fps positive")
    if (planted or tempo or event or pivot) and name != "walker":
        fail(f"--planted, --tempo, --event and --pivot are the walker's, not the {name}'s")
    if name not in CHARACTER_EXAMPLES and (motions or limbs != 1.0):
        fail("--limbs and --motion are the humanoid's and the quadruped's")
    unknown = [m for m in motions if name in CHARACTER_EXAMPLES and m not in CHARACTERS[name][1]]
    if unknown:
        fail(f"the {name} has no motion {unknown[0]!r}: its motions are {', '.join(CHARACTERS[name][1])}")
    if sum((event, pivot, bool(planted or tempo))) > 1:
        fail("--event and --pivot each move at their own pace: they take neither each other nor --planted or --tempo")
    if event:
        frames = int(round(WALKER_EVENT_SECONDS * fps))
    if pivot:
        per_pivot = int(round(PIVOT_SECONDS * fps))
        if per_pivot < 12:
            fail(f"--pivot needs at least 12 frames a pivot ({PIVOT_SECONDS:g} s): --fps {fps:g} gives {per_pivot}")
        frames = cycles * per_pivot
    if name in CHARACTER_EXAMPLES:
        check_memory(*character_memory(name, len(motions or CHARACTERS[name][1]) * frames, limbs, rings, segments))
    else:
        check_memory(*example_memory(name, frames, rings, segments))
    if name in CHARACTER_EXAMPLES:
        vertices, faces, _ = character(name, list(motions) or None, frames, cycles, limbs, rings, segments)
        frames = len(vertices)
    elif event:
        vertices, faces = walker_event(fps=fps, rings=rings, segments=segments)
    elif pivot:
        vertices, faces, _ = pivot_walker(pivots=cycles, frames_per_pivot=per_pivot, rings=rings, segments=segments)
    elif name == "walker":
        vertices, faces = walker(frames=frames, cycles=cycles, rings=rings, segments=segments, planted=planted,
                                  tempo=tempo)
    else:
        vertices, faces = bending_bar(frames=frames, rings=rings, segments=segments, cycles=cycles)
    write_array_sequence(output, vertices, faces, fps)
    summary = {"output": output, "name": name, "frames": frames, "vertices": int(vertices.shape[1]), "fps": fps}
    if name == "walker":
        summary["planted"] = planted
        summary["event"] = event
        summary["pivot"] = pivot
    if name in CHARACTER_EXAMPLES:
        summary["motions"] = list(motions) or list(CHARACTERS[name][1])
        summary["limbs"] = limbs
    kind = ", planted" if planted else ", with an event" if event else ", pivoting" if pivot else ""
    report(summary, [f"wrote {output}: {name}{kind}, "
                     f"{frames} frames, "
                     f"{vertices.shape[1]} vertices"], as_json, quiet)
