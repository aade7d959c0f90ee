"""SO(3) through quaternions in numpy: the twins of rotations.py's UFL (scalar part
first, R(q/|q|) a = q a conj(q) / |q|^2), for tests, the set-up of a model and the checks
that load no UFL (``dolfin-rod check``)."""

from __future__ import annotations

import numpy as np

CONJ = np.array([1.0, -1, -1, -1])     # q * CONJ = conj(q)


def _hamilton_tensor() -> np.ndarray:
    """H with (p q)_i = H_ijk p_j q_k."""
    h = np.zeros((4, 4, 4))
    for j, k, i, sign in ((0, 0, 0, 1), (1, 1, 0, -1), (2, 2, 0, -1), (3, 3, 0, -1),
                          (0, 1, 1, 1), (1, 0, 1, 1), (2, 3, 1, 1), (3, 2, 1, -1),
                          (0, 2, 2, 1), (1, 3, 2, -1), (2, 0, 2, 1), (3, 1, 2, 1),
                          (0, 3, 3, 1), (1, 2, 3, 1), (2, 1, 3, -1), (3, 0, 3, 1)):
        h[i, j, k] = sign
    return h


_HAMILTON = _hamilton_tensor()
_FEW = 256     # entries up to which one einsum call beats 28 array operations


def np_qmul(p, q):
    """Hamilton product p q (broadcasting over leading axes): for few quaternions one
    einsum with the structure tensor (9.6 us at 9 nodes, the rod's commit after every
    step), else by components (31 us at 9 nodes, 3.4x faster than einsum at 1e5 and 3x
    faster than with np.cross)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if p.size <= _FEW and q.size <= _FEW:
        return np.einsum("ijk,...j,...k->...i", _HAMILTON, p, q)
    a0, a1, a2, a3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    b0, b1, b2, b3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0], axis=-1)


def np_quaternion_from_rotation_vector(theta):
    """q = (cos(|theta|/2), sin(|theta|/2) theta/|theta|) with a series near 0 (no 0/0)."""
    theta = np.asarray(theta, dtype=float)
    a = np.linalg.norm(theta, axis=-1)
    half = 0.5 * a
    # sin(a/2)/a = 1/2 sinc(a/2/pi) in numpy's normalised sinc: smooth at a = 0
    k = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half)[..., None], k[..., None] * theta], axis=-1)


def np_rotation_matrix(q):
    q = np.asarray(q, dtype=float)
    w, x, y, z = q
    n2 = q @ q
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ]) / n2


def np_quaternion_from_matrix(R):
    """Unit quaternions (q0 >= 0) of rotation matrices R (..., 3, 3) (Shepperd's method:
    from the largest of the four squares |q_i|^2, no cancellation)."""
    R = np.asarray(R, dtype=float)
    trace = np.trace(R, axis1=-2, axis2=-1)
    squares = np.stack([1 + trace, 1 + 2 * R[..., 0, 0] - trace,
                        1 + 2 * R[..., 1, 1] - trace, 1 + 2 * R[..., 2, 2] - trace], -1) / 4
    k = np.argmax(squares, axis=-1)[..., None]
    big = np.sqrt(np.take_along_axis(squares, k, -1))
    off = (R - np.swapaxes(R, -1, -2)) / 4      # q0 q_i terms
    sym = (R + np.swapaxes(R, -1, -2)) / 4      # q_i q_j terms
    products = np.stack([
        np.stack([squares[..., 0], off[..., 2, 1], off[..., 0, 2], off[..., 1, 0]], -1),
        np.stack([off[..., 2, 1], squares[..., 1], sym[..., 0, 1], sym[..., 0, 2]], -1),
        np.stack([off[..., 0, 2], sym[..., 0, 1], squares[..., 2], sym[..., 1, 2]], -1),
        np.stack([off[..., 1, 0], sym[..., 0, 2], sym[..., 1, 2], squares[..., 3]], -1)], -2)
    q = np.take_along_axis(products, k[..., None], -2)[..., 0, :] / big
    return q * np.where(q[..., :1] < 0, -1.0, 1.0)


def np_rotation_angle(q) -> float:
    """Angle in [0, 2 pi] of the rotation *path* end q (q = -1 is a full turn, 2 pi)."""
    q = np.asarray(q, dtype=float)
    return float(2.0 * np.arctan2(np.linalg.norm(q[1:]), q[0]))


def np_rotation_vector(q):
    """Rotation vector of q with angle in [0, 2 pi] (exact near angle 0, no 0/0 there)."""
    q = np.asarray(q, dtype=float) / np.linalg.norm(q)
    s = np.linalg.norm(q[1:])
    if q[0] > 0 and s < 1e-8:  # angle/sin(angle/2) = 2/cos(angle/2) + O(angle^2)
        return 2.0 * q[1:] / q[0]
    return 2.0 * np.arctan2(s, q[0]) * q[1:] / max(s, 1e-300)
