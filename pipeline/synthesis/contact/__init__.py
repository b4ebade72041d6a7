"""Ground contact in synthesis (docs/contact.md): the input's contact patches (:mod:`.patches`),
the plants kept on the output (:mod:`.planting`, its loops compiled in :mod:`.planting_loops`),
the merged rig's lowest point kept in the input's range (:mod:`.ground`), and the feet measures
(:mod:`.measures`)."""
