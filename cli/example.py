"""``skinsynth example``: write a built-in procedural example sequence."""

import click

from .common import check_memory, report, summary_options, check_output_path, fail, user_errors

EXAMPLES = ("bending-bar",)


@click.command("example")
@click.argument("name", type=click.Choice(EXAMPLES))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Sequence file to write (.npz).")
@click.option("--frames", default=60, show_default=True, type=int, help="Number of frames.")
@click.option("--rings", default=40, show_default=True, type=int, help="Vertex rings along the bar.")
@click.option("--segments", default=16, show_default=True, type=int, help="Vertices around each ring.")
@click.option("--cycles", default=1, show_default=True, type=int, help="Bend-and-twist cycles over the frames.")
@click.option("--fps", default=24.0, show_default=True, type=click.FloatRange(min=0.0, min_open=True, max=1e6), help="Frame rate stored with the sequence.")
@summary_options
@user_errors
def example(name, output, frames, rings, segments, cycles, fps, quiet, as_json):
    """Write a built-in example mesh sequence (no download needed).

    bending-bar: a capped cylinder that bends into an arc and twists over one cycle, the kind of
    example of Feng et al. 2008 Table 1; its deformation is smooth but not itself skinned.

    \b
    Example:
      skinsynth example bending-bar -o bar.npz --frames 120
      skinsynth fit-skin bar.npz -o bar.skin.h5 --bones 8
    """
    from skinsynth.formats.meshseq import write_array_sequence
    from skinsynth.pipeline.examples import bending_bar

    check_output_path(output, (".npz",))
    if frames < 2 or rings < 2 or segments < 3 or cycles < 1 or not fps > 0:
        fail("--frames and --rings must be at least 2, --segments at least 3, --cycles at least 1, --fps positive")
    check_memory(frames * (rings * segments + 2) * 3 * 8 * 3, f"{frames} frames of {rings} × {segments} vertices")
    vertices, faces = bending_bar(frames=frames, rings=rings, segments=segments, cycles=cycles)
    write_array_sequence(output, vertices, faces, fps)
    report({"output": output, "name": name, "frames": frames, "vertices": int(vertices.shape[1]), "fps": fps},
           [f"wrote {output}: {name}, {frames} frames, {vertices.shape[1]} vertices"], as_json, quiet)
