"""A contact sheet of skeletons: each skin's rest pose from the front and the side, its skin coloured by
the chain of the bone that dominates it, the joints and bones drawn, each chain's name at its first
joint (issue 65: look at what the names say).

Colours: legs red (left) and blue (right), the hind legs paler; arms orange (left) and cyan (right);
neck and head green; tail purple; the trunk (``body``, ``spine_…``, ``hips_…``) grey; a bone on no
named chain white. Bones: black for a fixed joint, magenta for a sliding one; the root's joint yellow.

    python benchmarks/skeleton_sheet.py OUT.png SKIN.h5 [SKIN.h5 …]

It prints one JSON line: the sheet written and, per skin, its chains (bones per chain).
"""

import argparse
import json
import re

import numpy as np
from skeleton_truth import chain_of

COLOURS = {"leg_l": (0.9, 0.2, 0.2), "leg_r": (0.2, 0.3, 0.9), "leg_front_l": (0.9, 0.2, 0.2),
           "leg_front_r": (0.2, 0.3, 0.9), "leg_back_l": (0.95, 0.6, 0.6), "leg_back_r": (0.55, 0.65, 0.95),
           "arm_l": (0.95, 0.6, 0.1), "arm_r": (0.1, 0.75, 0.8), "neck": (0.2, 0.7, 0.2), "tail": (0.6, 0.2, 0.7),
           "trunk": (0.55, 0.55, 0.55)}
UNNAMED = (0.95, 0.95, 0.95)


def panel(skin, preset, size=480):
    """One view (size, size, 3) uint8 of a skin's rest pose, named and drawn (module notes)."""
    from PIL import Image, ImageDraw, ImageFont

    from skinsynth.pipeline.rig.influence import dense_weights
    from skinsynth.pipeline.rig.skeleton import bone_names
    from skinsynth.pipeline.view.rasteriser import frame_bounds, project, render

    rest = skin.rest_vertices
    up = 1 if skin.scene.up_axis == "Y" else 2
    skeleton = skin.skeleton
    names, parents = bone_names(skeleton), np.asarray(skeleton["parents"])
    joints, jointed = np.asarray(skeleton["joints"]), np.asarray(skeleton["jointed"], bool)
    owner = dense_weights(skin.bone_indices, skin.bone_weights, skin.bones).argmax(axis=1)
    colours = np.array([COLOURS.get(chain_of(name), UNNAMED) for name in names])
    camera = frame_bounds(rest.min(axis=0), rest.max(axis=0), preset, up_axis=up, aspect=1.0)
    picture = Image.fromarray(render(rest, skin.faces, camera, size, size, vertex_colors=colours[owner], up_axis=up))
    draw, font = ImageDraw.Draw(picture), ImageFont.load_default()
    screen = project(joints, camera, size, size)[:, :2]
    for bone in np.flatnonzero(parents >= 0):
        draw.line([tuple(screen[parents[bone]]), tuple(screen[bone])], width=2,
                  fill=(0, 0, 0) if jointed[bone] else (255, 0, 255))
    for bone, (x, y) in enumerate(screen):
        draw.ellipse([x - 3, y - 3, x + 3, y + 3], fill=(255, 255, 0) if parents[bone] < 0 else (0, 0, 0))
        if names[bone] == "body" or (names[bone].endswith("_01") and not names[bone].startswith("chain_")):
            draw.text((x + 4, y - 4), re.sub(r"_\d+$", "", names[bone]), fill=(0, 0, 0), font=font)
    return np.asarray(picture)


def main():
    from PIL import Image, ImageDraw

    from skinsynth.formats.skin_file import read_skin
    from skinsynth.pipeline.rig.chain_labels import named_chains

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output")
    parser.add_argument("skins", nargs="+")
    options = parser.parse_args()
    rows, chains = [], {}
    for path in options.skins:
        skin = read_skin(path)
        if skin.skeleton is None:
            raise SystemExit(f"{path}: no skeleton (fit it with --skeleton)")
        row = Image.fromarray(np.concatenate([panel(skin, "front"), panel(skin, "side")], axis=1))
        ImageDraw.Draw(row).text((6, 6), path.rsplit("/", 1)[-1], fill=(0, 0, 0))
        rows.append(np.asarray(row))
        chains[path] = named_chains(skin.skeleton.get("names"))
    Image.fromarray(np.concatenate(rows, axis=0)).save(options.output)
    print(json.dumps({"sheet": options.output, "chains": chains}))


if __name__ == "__main__":
    main()
