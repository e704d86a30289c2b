"""Rotations in numpy that more than one layer needs: the unit quaternion of a rotation
matrix (rod/charts.py's charts and outputs, io/beamdyn.py's Wiener–Milenkovic parameters), the
cross product's matrix and the rotation about an axis (joints, prescribed turns, contact)."""

from __future__ import annotations

import numpy as np


def quaternion_of_frame(D: np.ndarray) -> np.ndarray:
    """The unit quaternion (..., 4) of the rotation R = Dᵀ taking e_j to the rows d_j of D
    (Shepperd's method: the largest of the four squares first, for accuracy), q0 ≥ 0."""
    R = np.swapaxes(np.asarray(D, dtype=float), -1, -2)
    tr = np.trace(R, axis1=-2, axis2=-1)
    diag = np.diagonal(R, axis1=-2, axis2=-1)
    squares = np.concatenate([(1.0 + tr)[..., None], 1.0 + 2.0 * diag - tr[..., None]], -1)
    pick = np.argmax(squares, axis=-1)
    out = np.empty((*R.shape[:-2], 4))
    r = R
    for case in range(4):
        sel = pick == case
        if not sel.any():
            continue
        m = r[sel]
        big = 0.5 * np.sqrt(squares[sel, case])
        f = 0.25 / big
        if case == 0:
            q = [
                big,
                (m[:, 2, 1] - m[:, 1, 2]) * f,
                (m[:, 0, 2] - m[:, 2, 0]) * f,
                (m[:, 1, 0] - m[:, 0, 1]) * f,
            ]
        elif case == 1:
            q = [
                (m[:, 2, 1] - m[:, 1, 2]) * f,
                big,
                (m[:, 0, 1] + m[:, 1, 0]) * f,
                (m[:, 0, 2] + m[:, 2, 0]) * f,
            ]
        elif case == 2:
            q = [
                (m[:, 0, 2] - m[:, 2, 0]) * f,
                (m[:, 0, 1] + m[:, 1, 0]) * f,
                big,
                (m[:, 1, 2] + m[:, 2, 1]) * f,
            ]
        else:
            q = [
                (m[:, 1, 0] - m[:, 0, 1]) * f,
                (m[:, 0, 2] + m[:, 2, 0]) * f,
                (m[:, 1, 2] + m[:, 2, 1]) * f,
                big,
            ]
        out[sel] = np.stack(q, -1)
    return np.where(out[..., :1] < 0.0, -out, out)


def cross_matrix(v) -> np.ndarray:
    """[v×] (..., 3, 3), [v×] w = v × w, of v (..., 3), real or complex."""
    v = np.asarray(v)
    out = np.zeros((*v.shape[:-1], 3, 3), dtype=np.result_type(v.dtype, float))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return out - np.swapaxes(out, -1, -2)


def axis_rotation(n, alpha) -> np.ndarray:
    """exp(α [n×]) = I + sin α [n×] + (1 − cos α) [n×]² (Rodrigues): the right-handed turn by
    α [rad] about the unit axis n (3,); α real or complex, a number or an array (..., 3, 3)."""
    K = cross_matrix(n)
    alpha = np.asarray(alpha)[..., None, None]
    return np.eye(3) + np.sin(alpha) * K + (1.0 - np.cos(alpha)) * (K @ K)
