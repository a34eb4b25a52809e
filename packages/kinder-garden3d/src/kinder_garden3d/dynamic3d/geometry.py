"""Small rigid-transform helpers (numpy only). Quaternions here are ordered (w, x, y, z), as in
MuJoCo and the Dynamic3D features."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def yaw_quat(yaw: float) -> Array:
    """The quaternion (w, x, y, z) of a rotation by ``yaw`` radians about z."""
    return np.array([math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])


def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a ⊗ b of (w, x, y, z) quaternions."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_to_matrix(q: Array) -> Array:
    """A (w, x, y, z) quaternion (normalised here) as a 3x3 rotation matrix."""
    w, x, y, z = np.asarray(q, dtype=float) / max(float(np.linalg.norm(q)), 1e-12)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quats_to_matrices(q: Array) -> Array:
    """Vectorised :func:`quat_to_matrix` for an (N, 4) array; returns (N, 3, 3)."""
    q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3, 3))
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - z * w)
    out[:, 0, 2] = 2 * (x * z + y * w)
    out[:, 1, 0] = 2 * (x * y + z * w)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - x * w)
    out[:, 2, 0] = 2 * (x * z - y * w)
    out[:, 2, 1] = 2 * (y * z + x * w)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def quat_yaw(q: Array) -> float:
    """The heading (rotation about world z of the body's x axis) of a (w, x, y, z) quaternion."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quats_yaw(q: Array) -> Array:
    """Vectorised :func:`quat_yaw` for an (N, 4) array; returns (N,)."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out: Array = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return out


def pose_matrices(pos: Array, rot: Array) -> Array:
    """Vectorised :func:`pose_matrix`: (N, 3) positions and (N, 3, 3) rotations to (N, 4, 4)."""
    t = np.zeros((len(pos), 4, 4))
    t[:, :3, :3] = rot
    t[:, :3, 3] = pos
    t[:, 3, 3] = 1.0
    return t


def pose_matrix(pos: Array | tuple[float, ...], rot: Array) -> Array:
    """A 4x4 homogeneous transform."""
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = pos
    return t


def rot_z(angle: float) -> Array:
    """Rotation matrix about z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rots_z(angle: Array) -> Array:
    """Vectorised :func:`rot_z` for (N,) angles; returns (N, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((len(angle), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = 1.0
    return out


def rots_axis(axis: Array | tuple[float, float, float], angle: Array) -> Array:
    """Vectorised :func:`rot_axis`: one unit axis, (N,) angles; returns (N, 3, 3)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    out: Array = np.eye(3) + s * k + (1.0 - c) * (k @ k)
    return out


def rot_axis(axis: Array | tuple[float, float, float], angle: float) -> Array:
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    out: Array = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)
    return out


def look_at_xyaxes(pos: Array | list[float], lookat: Array | list[float]) -> Array:
    """MuJoCo camera ``xyaxes`` (6 numbers) for a camera at ``pos`` looking at ``lookat``."""
    f = np.asarray(lookat, dtype=float) - np.asarray(pos, dtype=float)
    norm = float(np.linalg.norm(f))
    if norm < 1e-9:
        raise ValueError(f"camera position {pos} and lookat {lookat} coincide")
    f /= norm
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(f, up)
    if np.linalg.norm(right) < 1e-6:  # looking straight down or up: pick +x as screen right
        right = np.array([0.0, -1.0, 0.0]) if f[2] < 0 else np.array([0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, f)
    return np.concatenate([right, cam_up])
