"""The rig's maths, on the floor every stage may import: rotations, quaternions and dual
quaternions (:mod:`.rotations`), a rig as a joint tree for engines (:mod:`.skeleton`: one root or a
fit's joint tree, parent-local transforms, binds, glTF influences; joints held, legs reached),
which bone moves a vertex (:mod:`.influence`), correctives as morph targets
(:mod:`.morph_targets`), inverse kinematics of a jointed rig towards skinned points
(:mod:`.inverse_kinematics`), and how far control poses go from a model's examples
(:mod:`.extrapolation`)."""
