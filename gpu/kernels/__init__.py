"""The warp kernels and ``@wp.func`` helpers, defined at module level, one concept per module.

Each module here starts with ``wp = runtime.warp()``: importing it imports and initialises warp
(with skinsynth's kernel cache folder), so the launchers import these modules inside their
functions only and ``import skinsynth.gpu`` (or any launcher) imports no warp. A kernel
specialised on Python values (the number of influences K, whether rest offsets are added, the
control kernel's kind and degree) is built by a cached module-level function, one warp module
per variant (``module="unique"``), as warp's own examples build theirs: the values are
compile-time constants, so loops over them unroll.

dual_quaternion: the vec8 layouts and their quaternion parts; skinning: LBS and DQ skinning;
puppet: the puppet's run-time stages; simplex_qp and skin_fit: fit-skin's two solves.
"""
