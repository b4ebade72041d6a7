"""The mesh's geometry, on the floor every stage may import: normals, edges, accelerations, sizes,
grids and inside-the-mesh tests (:mod:`.geometry`), and material UVs split at their seams
(:mod:`.uv_seams`)."""
