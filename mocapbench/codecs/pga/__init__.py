"""``pga-ik``: Tournier et al., "Motion Compression using Principal Geodesics Analysis" (INRIA RR-6648, 2008).

Modules
-------
codec
    The registered codec: the stream format, the encoder's closed loop and the decoder.
so3
    Quaternion/rotation-vector helpers around :class:`scipy.spatial.transform.Rotation` and a batched Rodrigues
    formula for the decoder's inner loop.
karcher
    Intrinsic (Karcher) mean on SO(3)^n by the fixed-point iteration.
geodesics
    Principal geodesic analysis (tangent-space approximation) and the product-of-exponentials pose model, §3.3.
lifting
    Interpolating lifting scheme (split, cubic predict, details) for R^3 and SO(3) trajectories, §3.5.
ik
    PGA-based inverse kinematics with an analytic Jacobian and Levenberg–Marquardt, §3.4 and §3.6.
model_motion
    A motion made from a fitted pose model (tests and benchmarks).
"""

from mocapbench.codecs.pga.codec import PgaIkCodec

__all__ = ["PgaIkCodec"]
