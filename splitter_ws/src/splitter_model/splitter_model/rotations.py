"""Quaternions (scalar first, world <- base): the one rotation matrix and the Hamilton product.

:func:`quaternion_to_matrix_entries` is the formula, written once over scalars so
that it serves plain floats (the simulator's hot path), numpy scalars and CasADi
symbols (the simulator's generated kernels) alike. It takes a quaternion of any
non-zero norm (the integrator's stages are not unit) and divides the homogeneous
form by ``|q|^2``::

    R = [[w2 + x2 - y2 - z2, 2 (xy - wz),        2 (xz + wy)],
         [2 (xy + wz),        w2 - x2 + y2 - z2, 2 (yz - wx)],
         [2 (xz - wy),        2 (yz + wx),        w2 - x2 - y2 + z2]] / |q|^2

:func:`quaternion_to_matrix` is the same as a (3, 3) numpy array, for everything
that is not the hot path; :func:`quaternion_product` the Hamilton product over
scalars (the MPC's symbolic attitude kinematics), :func:`quaternion_multiply` as
numpy. ROS-free, numpy-only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

# below this squared norm a quaternion is no rotation (its direction is round-off)
_NORM2_MIN = 1e-24  # [-]


def quaternion_to_matrix_entries(qw: Any, qx: Any, qy: Any, qz: Any) -> tuple[Any, ...]:
    """Row-major world <- base rotation (9 entries) of a (not necessarily unit) quaternion.

    Floats, numpy scalars or CasADi symbols: only arithmetic.
    """
    n = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    ww, xx, yy, zz = qw * qw, qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    return (
        (ww + xx - yy - zz) * n,
        2.0 * (xy - wz) * n,
        2.0 * (xz + wy) * n,
        2.0 * (xy + wz) * n,
        (ww - xx + yy - zz) * n,
        2.0 * (yz - wx) * n,
        2.0 * (xz - wy) * n,
        2.0 * (yz + wx) * n,
        (ww - xx - yy + zz) * n,
    )


def quaternion_to_matrix(q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Rotation (3, 3) world <- base of a quaternion (w, x, y, z) of any non-zero norm.

    ValueError for a non-finite or zero quaternion.
    """
    w, x, y, z = np.asarray(q_wxyz, dtype=float).reshape(4).tolist()
    norm2 = w * w + x * x + y * y + z * z
    if not (math.isfinite(norm2) and norm2 >= _NORM2_MIN):
        raise ValueError(f"orientation {[w, x, y, z]} is not a rotation")
    return np.array(quaternion_to_matrix_entries(w, x, y, z)).reshape(3, 3)


def quaternion_product(p: Sequence[Any], q: Sequence[Any]) -> tuple[Any, Any, Any, Any]:
    """Hamilton product ``p (x) q`` of two indexable quaternions (floats or CasADi symbols)."""
    pw, px, py, pz = p[0], p[1], p[2], p[3]
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def quaternion_multiply(p_wxyz: ArrayLike, q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``p (x) q`` as a numpy array."""
    p = np.asarray(p_wxyz, dtype=float).reshape(4).tolist()
    q = np.asarray(q_wxyz, dtype=float).reshape(4).tolist()
    return np.array(quaternion_product(p, q))
