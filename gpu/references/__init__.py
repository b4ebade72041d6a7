"""The kernels' numpy references (numpy only, never warp): what each kernel computes, in float64.

``pipeline`` computes with them where it needs no device (training, evaluation); the kernel tests
compare every launch against them. dual_quaternions: the quaternion and dual-quaternion arithmetic
they share with ``pipeline.rotations``; skinning: linear-blend and dual-quaternion skinning;
puppet: the trained puppet's run-time stages and their composition.
"""
