"""The skeleton ``play`` and ``view`` pose a puppet's frames beyond its examples on (``--ik``): a
jointed skin's own, or the one a free skin's bones keep best (``pipeline/puppet/jointed_play.py``)."""


def skeleton_poses(puppet, skin, device):
    """:class:`~skinsynth.pipeline.puppet.jointed_play.ExamplePoses` of ``puppet`` (its skin as
    read), a free skin's skeleton found for it (``pipeline.skin.free_skin_skeleton``)."""
    from skinsynth.pipeline.puppet import example_poses

    found = None
    if skin.skeleton is None:
        from skinsynth.pipeline.skin import free_skin_skeleton

        found = free_skin_skeleton(skin.rest_vertices, skin.faces, skin.bone_indices, skin.bone_weights,
                                   skin.rotations, skin.translations, skin.examples, "XYZ".index(skin.scene.up_axis))
    return example_poses(puppet, skin, found, device)
