"""The kernels' numpy references (numpy only, never warp): what each kernel computes, in float64.

``pipeline`` computes with them where it needs no device (training, evaluation); the kernel tests
compare every launch against them. skinning: linear-blend and dual-quaternion skinning; puppet:
the trained puppet's run-time stages and their composition (with the closed forms of quaternion
arithmetic they need: an oracle independent of ``pipeline.rotations``).
"""
