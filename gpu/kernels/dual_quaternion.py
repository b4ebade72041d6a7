"""Dual quaternions on the device: 8 numbers, real then dual part, each (w, x, y, z) scalar first,
as in ``pipeline.rotations``; that layout is kept in a ``vec8`` per bone, converted to warp's
(x, y, z, w) ``wp.quat`` only inside kernels, by the helpers here."""

from .. import runtime

wp = runtime.warp()

vec8 = wp.types.vector(length=8, dtype=wp.float32)

# Raw predictions d = M ξ + m stay in float64: M's entries reach 1e4–1e7 on real puppets (nearly
# repeated training poses, wide kernels) and cancel in the sum, which float32 turned into
# dual-quaternion errors of 3e-3 (1.7e-3 of the horse's diagonal).
vec8d = wp.types.vector(length=8, dtype=wp.float64)


@wp.func
def dq_real(d: vec8):
    """The real part q0 of d, as a wp.quat."""
    return wp.quat(d[1], d[2], d[3], d[0])


@wp.func
def dq_dual(d: vec8):
    """The dual part qe of d, as a wp.quat."""
    return wp.quat(d[5], d[6], d[7], d[4])


@wp.func
def dq_pack(q0: wp.quat, qe: wp.quat):
    """The vec8 of q0 + ε qe."""
    return vec8(q0[3], q0[0], q0[1], q0[2], qe[3], qe[0], qe[1], qe[2])
