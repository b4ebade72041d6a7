"""The rig's maths, on the floor every stage may import: rotations, quaternions and dual
quaternions (:mod:`.rotations`), a rig as a joint tree for engines (:mod:`.skeleton`: one root or a
fit's joint tree, parent-local transforms, binds, glTF influences; joints held, legs reached),
which bone moves a vertex (:mod:`.influence`), and correctives as morph targets
(:mod:`.morph_targets`)."""
