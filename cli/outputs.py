"""The one registry of animation outputs that ``export``, ``play`` and ``synthesize`` write, chosen
by the path (like trimesh's exchange registry): a USD cache, one OpenEXR vertex-animation texture,
an HDF5 vertex animation, a glTF binary (.glb) skinned mesh with its clips, or an engine-ready VAT
folder (a path ending in a separator).

Each command says which kinds it writes; the registry checks an output before any work (its
suffix, that it is no input, the folder rules of :mod:`skinsynth.formats.output_folder`, the
texture's size) and writes the textures, the one kind every command shares whole. USD writes
stay in the commands: a skin's single rig, a crowd of characters and one cache per synthesized
animation are different stages."""

import os

from .common import check_output_path
from .options import check_max_width

#: kind: the suffixes it is written to ("folder": a path ending in a separator).
KINDS = {"usd": (".usd", ".usda", ".usdc"), "exr": (".exr",), "h5": (".h5", ".hdf5"), "gltf": (".glb",),
         "folder": (os.sep,)}
TEXTURES = ("exr", "folder")


def output_kind(path):
    """The kind of ``path``: "folder" when it ends in a separator, else by its suffix (None when
    no kind has it)."""
    text = str(path)
    if text.endswith(("/", os.sep)):
        return "folder"
    lower = text.lower()
    return next((kind for kind, suffixes in KINDS.items() if kind != "folder" and lower.endswith(suffixes)), None)


def check_animation_output(path, kinds, inputs, folders):
    """Refuse, before any work, an output none of ``kinds`` writes (one line naming the suffixes),
    a file that is one of ``inputs``, or a folder that could cost the user a file (``folders``,
    a :class:`~skinsynth.cli.common.FolderOutputs`); returns the kind."""
    kind = output_kind(path)
    if kind == "folder" and "folder" in kinds:
        folders.check(path)
        return kind
    check_output_path(path, tuple(s for k in kinds if k != "folder" for s in KINDS[k]), inputs=inputs)
    return kind


def check_texture_output(path, kind, vertex_count, frame_count, max_width, characters=1):
    """Before any work, for a texture kind: ``--max-width``, the texture's size, and one texture
    per .exr (several characters need a folder)."""
    from skinsynth.formats.vat_bundle import check_texture_size
    from skinsynth.pipeline.errors import OptionError

    check_max_width(max_width)
    if kind not in TEXTURES:
        return
    check_texture_size(path, vertex_count, frame_count, max_width)
    if kind == "exr" and characters > 1:
        raise OptionError(f"{path}: {characters} characters make {characters} textures; give a folder "
                          f"(-o {str(path)[:-4]}/) for one texture each")


def write_textures(path, kind, rest_vertices, faces, animations, fps, scene, half, max_width, guard):
    """Write ``animations`` ((name, vertices (F, V, 3)) pairs of one rest mesh, consumed once) as
    textures: the engine-ready folder (with each frame's vertex normals), or, for .exr, the one
    animation's offsets texture. ``guard``: the folder's inputs and other outputs
    (:meth:`~skinsynth.cli.common.FolderOutputs.guard`)."""
    from skinsynth.formats.exr import check_half_range, write_vat
    from skinsynth.formats.vat_bundle import write_vat_folder
    from skinsynth.pipeline.geometry import vertex_normals

    if kind == "folder":
        with_normals = ((name, vertices, vertex_normals(vertices, faces)) for name, vertices in animations)
        return write_vat_folder(path, rest_vertices, faces, with_normals, fps, scene, max_width=max_width, half=half,
                                **guard)
    (_, vertices), = animations
    if half:
        check_half_range(path, vertices - rest_vertices)
    return write_vat(path, rest_vertices, vertices, fps, max_width=max_width, half=half)


def write_gltf(path, skin, clips, up_axis, quantize=None, root_motion=False, label=None):
    """Write a skin's rig and ``clips`` ((name, rotations (F, B, 3, 3), translations (F, B, 3)),
    consumed in order) as one .glb, in glTF's Y up and metres from ``up_axis`` and the skin's
    metersPerUnit; ``quantize`` 8 or 16 bit weights; ``root_motion`` the ground motion on the
    root (``pipeline.skeleton``). ``label`` names the input in a refusal (a skin too wide)."""
    from skinsynth.formats.gltf import Clip, SkinnedScene, write_skinned_glb
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.skeleton import gltf_clip, gltf_rig

    centres = skin.bone_rest_frames[:, :3, 3]
    axes = dict(up_axis=up_axis, meters_per_unit=skin.scene.meters_per_unit)
    try:
        rig = gltf_rig(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights, centres, **axes,
                       quantize=quantize)
    except ValueError as error:
        raise OptionError(f"{label or path}: {error}") from None
    ground = (skin.rest_vertices, skin.bone_indices, skin.bone_weights) if root_motion else None
    clips = [Clip(**gltf_clip(name, rotations, translations, centres, skin.fps, **axes, ground=ground))
             for name, rotations, translations in clips]
    write_skinned_glb(path, SkinnedScene(**rig, clips=clips,
                                         mesh_name=skin.scene.prim_path.rsplit("/", 1)[-1] or "mesh"))
