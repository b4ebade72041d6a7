"""``skinsynth export``: the animation a model file holds, as USD or an OpenEXR vertex-animation texture."""

import click

from .options import check_max_width, device_option, texture_options, up_axis_option
from .common import FolderOutputs, report, summary_options, user_errors
from .outputs import TEXTURES, check_animation_output, check_texture_output, write_textures


@click.command("export")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(),
              help="Output: .usd/.usda/.usdc, .exr for a vertex-animation texture, or a folder (ending in /) for "
                   "an engine-ready one: textures, normals, the rest mesh with texel UVs (.obj/.glb), vat.json.")
@click.option("--as", "kind", type=click.Choice(["skel", "points"]), default="skel", show_default=True,
              help="USD only: UsdSkel skeleton with joint weights (editable), or a baked time-sampled mesh.")
@device_option("Where the skinning kernel runs: auto, cpu, cuda or cuda:N.")
@texture_options("Textures only: store 16-bit half floats instead of 32-bit.",
                 "EXR only: texture width limit; vertices wrap to more rows.")
@up_axis_option("USD stage up axis (default: the input's, as fit-skin recorded it).")
@summary_options
@user_errors
def export(path, output, kind, device, half, max_width, up_axis, quiet, as_json):
    """Export the animation of a model file.

    For a skin file this is the LBS reconstruction of the example frames, at the input's units,
    up axis, time codes and mesh prim path (as fit-skin recorded them): as UsdSkel (--as
    skel: joints, bind/rest transforms, animation and joint weights, so animators get curves),
    as a time-sampled mesh (--as points), or as an OpenEXR vertex-animation texture (.exr:
    per-vertex offsets from the rest pose, one row block per frame, bounds in the header).

    \b
    Examples:
      skinsynth export skin.h5 -o skin.usdc
      skinsynth export skin.h5 -o skin.usda --as points
      skinsynth export skin.h5 -o skin_vat.exr --half
    """
    from skinsynth.formats.skin_file import read_skin
    from skinsynth.gpu import lbs, resolve_device

    folders = FolderOutputs([path], [output])
    output_kind = check_animation_output(output, ("usd", "exr", "folder"), [path], folders)
    check_max_width(max_width)
    device = resolve_device(device)
    skin = read_skin(path)
    to_exr = output_kind in TEXTURES
    check_texture_output(output, output_kind, skin.rest_vertices.shape[0], skin.rotations.shape[0], max_width)
    if kind == "skel" and not to_exr:
        from skinsynth.formats.usd import write_skel_cache

        write_skel_cache(output, skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                         skin.rotations, skin.translations, skin.bone_rest_frames[:, :3, 3], skin.fps,
                         up_axis=up_axis, scene=skin.scene)
    else:
        frames = lbs(skin.rest_vertices, skin.bone_indices, skin.bone_weights, skin.rotations,
                     skin.translations, device=device)
        if to_exr:
            write_textures(output, output_kind, skin.rest_vertices, skin.faces, [("animation", frames)], skin.fps,
                           skin.scene, half, max_width, folders.guard(output))
        else:
            from skinsynth.formats.usd import write_points_cache

            write_points_cache(output, frames, skin.faces, skin.fps, up_axis=up_axis, scene=skin.scene)
    what = "vertex-animation texture" if to_exr else ("UsdSkel" if kind == "skel" else "point cache")
    summary = {"output": output, "frames": int(skin.rotations.shape[0]), "vertices": int(skin.rest_vertices.shape[0]),
               "kind": what, "joints": skin.bones if what == "UsdSkel" else None}
    report(summary, [f"wrote {output}: {skin.rotations.shape[0]} frames, {skin.rest_vertices.shape[0]} vertices"
                     + ("" if to_exr else f" ({'UsdSkel, ' + str(skin.bones) + ' joints' if kind == 'skel' else 'point cache'})")],
           as_json, quiet)
