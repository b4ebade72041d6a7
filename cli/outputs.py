"""The one registry of animation outputs that ``export``, ``play`` and ``synthesize`` write, chosen
by the path (like trimesh's exchange registry): a USD cache, one OpenEXR vertex-animation texture,
an HDF5 vertex animation, a glTF binary (.glb) skinned mesh with its clips, an Alembic point cache
or a skinned FBX (.abc, .fbx, through Blender), or an engine-ready VAT folder (a path ending in a
separator).

Each command says which kinds it writes; the registry checks an output before any work (its
suffix, that it is no input, the folder rules of :mod:`skinsynth.formats.output_folder`, the
texture's size) and writes the textures, the one kind every command shares whole, and
synthesize's outputs beside its bone motions (:func:`write_synthesis_outputs`). Other USD writes
stay in the commands: a skin's single rig and a crowd of played characters are different stages."""

import contextlib
import os
from dataclasses import dataclass

from skinsynth.formats.output_file import check_output_path

from .options import check_max_width

#: kind: the suffixes it is written to ("folder": a path ending in a separator).
KINDS = {"usd": (".usd", ".usda", ".usdc"), "exr": (".exr",), "h5": (".h5", ".hdf5"), "gltf": (".glb",),
         "abc": (".abc",), "fbx": (".fbx",), "folder": (os.sep,)}
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


def check_bone_texture_output(path, bones, frame_count, max_width):
    """Before any work, for a bone-animation texture folder (``--as bones``): ``--max-width``,
    and the texture of ``frame_count`` frames (every clip's, end to end) of ``bones`` bones."""
    from skinsynth.formats.bone_textures import check_bone_texture_size

    check_max_width(max_width)
    check_bone_texture_size(path, bones, frame_count, max_width)


def write_bone_textures(path, skin, clips, half, max_width, guard, label=None):
    """Write ``clips`` ((name, rotations (F, B, 3, 3), translations (F, B, 3)) of the skin's
    bones, their LBS transforms, consumed in order) as a bone-animation texture folder
    (:mod:`skinsynth.formats.bone_textures`: every clip in one bones.exr, the skin's four
    influences on rest.glb). ``guard``: the folder's inputs and other outputs
    (:meth:`~skinsynth.cli.common.FolderOutputs.guard`); ``label`` names the input in a refusal
    (a skin too wide). Returns the bytes of bones.exr."""
    from skinsynth.formats.bone_textures import write_bone_texture_folder
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.rig.skeleton import bone_texels, texture_influences

    try:
        influences = texture_influences(skin.bone_indices, skin.bone_weights)
    except ValueError as error:
        raise OptionError(f"{label or path}: {error}") from None
    texels = ((name, bone_texels(rotations, translations)) for name, rotations, translations in clips)
    uv_split = None
    if skin.face_uvs is not None:  # the rest mesh's material UVs, one per vertex in rest.glb
        from skinsynth.pipeline.mesh.uv_seams import split_uv_seams

        uv_split = split_uv_seams(skin.faces, skin.face_uvs, len(skin.rest_vertices))
    write_bone_texture_folder(path, skin.rest_vertices, skin.faces, influences, texels, skin.rotations.shape[1],
                              skin.fps, skin.scene, max_width, half, **guard, uv_split=uv_split)
    return os.path.getsize(os.path.join(path, "bones.exr"))


def write_textures(path, kind, rest_vertices, faces, animations, fps, scene, half, max_width, guard):
    """Write ``animations`` ((name, vertices (F, V, 3)) pairs of one rest mesh, consumed once) as
    textures: the engine-ready folder (with each frame's vertex normals), or, for .exr, the one
    animation's offsets texture. ``guard``: the folder's inputs and other outputs
    (:meth:`~skinsynth.cli.common.FolderOutputs.guard`)."""
    from skinsynth.formats.exr import check_half_range, write_vat
    from skinsynth.formats.vat_bundle import write_vat_folder
    from skinsynth.pipeline.mesh.geometry import vertex_normals

    if kind == "folder":
        with_normals = ((name, vertices, vertex_normals(vertices, faces)) for name, vertices in animations)
        return write_vat_folder(path, rest_vertices, faces, with_normals, fps, scene, max_width=max_width, half=half,
                                **guard)
    (_, vertices), = animations
    if half:
        check_half_range(path, vertices - rest_vertices)
    return write_vat(path, rest_vertices, vertices, fps, max_width=max_width, half=half)


def write_gltf(path, skin, clips, up_axis, quantize=None, root_motion=False, label=None, morph=None, skeleton=None):
    """Write a skin's rig and ``clips`` ((name, rotations (F, B, 3, 3), translations (F, B, 3)),
    consumed in order) as one .glb: the arrays of ``pipeline.rig.skeleton.gltf_scene`` (its
    ``quantize``, ``root_motion``, ``morph`` and ``skeleton``), laid out by ``formats.gltf``.
    ``label`` names the input in a refusal (a skin too wide)."""
    from skinsynth.formats.gltf import Clip, SkinnedScene, write_skinned_glb
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.rig.skeleton import gltf_scene

    try:
        rig, clips, names = gltf_scene(skin, clips, up_axis, quantize, root_motion, morph, skeleton)
    except ValueError as error:
        raise OptionError(f"{label or path}: {error}") from None
    write_skinned_glb(path, SkinnedScene(**rig, clips=[Clip(**clip) for clip in clips], target_names=names,
                                         mesh_name=skin.scene.prim_path.rsplit("/", 1)[-1] or "mesh"))


def usd_joint_tree(skeleton, rotations, translations, root_motion=None):
    """The :class:`~skinsynth.formats.usd.JointTree` of a skin's /skin/skeleton (``skin.skeleton``)
    for rotations (..., B, 3, 3) and translations (..., B, 3) under a root joint moving by
    ``root_motion`` (or None: fixed): ``pipeline.rig.skeleton.joint_tree_arrays``."""
    from skinsynth.formats.usd import JointTree
    from skinsynth.pipeline.rig.skeleton import joint_tree_arrays

    return JointTree(**joint_tree_arrays(skeleton, rotations, translations, root_motion))


@dataclass
class SynthesisOutputs:
    """What synthesize writes beside its bone motions, each None where not asked for: ``usd`` a
    folder of one USD point cache per animation, ``crowd`` one USD stage with every animation on a
    grid, ``gltf`` one .glb of the rig with every animation a clip (``root_motion``: its root joint
    carries the ground motion), ``exr`` an engine-ready VAT folder (``half``, ``max_width``),
    ``plots`` a folder of PNGs of the first ``plot_count`` animations."""

    usd: str | None
    crowd: str | None
    gltf: str | None
    root_motion: bool
    exr: str | None
    plots: str | None
    plot_count: int
    half: bool
    max_width: int

    @property
    def skinned(self):
        """Whether any of them needs the animations' vertices."""
        return bool(self.usd or self.crowd or self.exr or self.plots)


def write_synthesis_outputs(outputs, skin, motions, up_axis, device, folders, threads, label, clips=None):
    """Write ``outputs`` (:class:`SynthesisOutputs`) of ``motions`` (F (A, M, B, 3, 3), t (A, M, B, 3),
    sources (C, A, M) of ``skin``'s bones): the vertex caches, skinned on ``device`` (``threads``
    on the CPU), the .glb (``label`` names the input in a refusal), the plots (``clips``: the
    input's several clips, None for one). ``folders``: the command's
    :class:`~skinsynth.cli.common.FolderOutputs`. Returns the paths written, in that order."""
    from skinsynth.pipeline.synthesis import acceleration_plots

    count, written = motions.F.shape[0], []
    if outputs.usd or outputs.crowd or outputs.exr:
        written += _write_vertex_caches(outputs, skin, motions, up_axis, device, folders, threads)
    if outputs.gltf is not None:
        write_gltf(outputs.gltf, skin, ((f"animation_{a:04d}", motions.F[a], motions.t[a]) for a in range(count)),
                   up_axis, root_motion=outputs.root_motion, label=label, skeleton=skin.skeleton)
        written.append(outputs.gltf)
    if outputs.plots is not None:  # matplotlib (0.5 s to import) only when asked
        from skinsynth.formats.plots import write_synthesis_plots
        plots = acceleration_plots(skin, motions.F, motions.t, motions.sources, min(outputs.plot_count, count), device,
                                   clips)
        written += write_synthesis_plots(outputs.plots, plots, None if clips is None else clips.starts,
                                         **folders.guard(outputs.plots))
    return written


def _write_vertex_caches(outputs, skin, motions, up_axis, device, folders, threads):
    """synthesize's vertex caches: one USD point cache per animation and the VAT folder, each
    animation skinned once for both, then the crowd (skinned again, each animation in its cell
    of a grid). Returns the paths written."""
    import numpy as np

    from skinsynth.formats.output_folder import atomic_folder
    from skinsynth.pipeline.mesh.geometry import grid_offsets, largest_side
    from skinsynth.pipeline.synthesis import SkinnedAnimations

    count, written = motions.F.shape[0], []
    names = [f"animation_{a:04d}" for a in range(count)]
    if outputs.usd or outputs.exr:
        with SkinnedAnimations(skin, motions.F, motions.t, np.zeros((count, 3)), device, threads) as frames, \
                (atomic_folder(outputs.usd, **folders.guard(outputs.usd)) if outputs.usd
                 else contextlib.nullcontext()) as usd_tmp:
            animations = ((name, frames[a]) for a, name in enumerate(names))  # each skinned once, for both outputs
            if outputs.usd:
                from skinsynth.formats.usd import write_points_caches

                animations = write_points_caches(usd_tmp, animations, skin.faces, skin.fps, up_axis, skin.scene)
            if outputs.exr:
                write_textures(outputs.exr, "folder", skin.rest_vertices, skin.faces, animations, skin.fps,
                               skin.scene, outputs.half, outputs.max_width, folders.guard(outputs.exr))
            else:
                for _ in animations:
                    pass
        written += [os.path.join(outputs.usd, f"{name}.usdc") for name in names] if outputs.usd else []
        written += [outputs.exr] if outputs.exr else []
    if outputs.crowd:
        from skinsynth.formats.usd import write_points_characters

        offsets = grid_offsets(count, 1.5 * largest_side(skin.rest_vertices), up_axis)
        with SkinnedAnimations(skin, motions.F, motions.t, offsets, device, threads) as characters:
            write_points_characters(outputs.crowd, characters, skin.faces, skin.fps, names=names, up_axis=up_axis,
                                    scene=skin.scene)
        written.append(outputs.crowd)
    return written
