"""The phone's AR viewer pose → clutch motion (TidyBot++'s "move the phone" reference capture).

In the page's ``immersive-ar`` session the phone sends its raw viewer pose (the camera's pose in
the session's ``local`` reference space, WebXR axes: +x right, +y up, +z back) with every XR
frame. :class:`ViewerClutch` turns that stream into the clutch poses every other device sends
(:class:`~kinder_gym.teleop.inputs.Pose`: the motion since the grab began), so the same mapper
(:class:`~kinder_gym.teleop.mapper3d.TidyBotTeleop`: frame conversion, workspace box, rate
limits, IK) drives the robot:

* the first enabled message of a grab captures the phone's reference pose (:meth:`update`);
  the motion is then ``p − p_ref`` (1:1, in the reference space) and ``q · q_ref⁻¹`` (the
  rotation in the reference space, applied to the robot's reference orientation by the mapper);
* positions are those of the phone's **centre**, not its camera: ``centre = p + R(q) · offset``
  with ``offset`` the centre seen from the camera in the camera's axes, so turning the phone in
  the hand turns the end effector without swinging it round the camera lens;
* a release (:meth:`release`) forgets the reference; the next grab captures a new one, so
  re-grasping never jumps.

Pure Python (no numpy): the hub runs it for every message in the server's thread.
"""

from __future__ import annotations

import math

from kinder_gym.teleop.inputs import Pose

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

#: The phone's centre seen from its camera, in the camera's WebXR axes (+x right, +y up, +z back),
#: metres: TidyBot++'s ``DEVICE_CAMERA_OFFSET`` (an iPhone 14 Pro, robot axes (0, 0.02, −0.04))
#: written in WebXR axes.
DEFAULT_CENTRE_OFFSET: Vec3 = (-0.02, -0.04, 0.0)


def quat_mul(a: Quat, b: Quat) -> Quat:
    """Hamilton product ``a · b`` of quaternions ordered (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quat_conj(q: Quat) -> Quat:
    return (-q[0], -q[1], -q[2], q[3])


def quat_rotate(q: Quat, v: Vec3) -> Vec3:
    """``v`` rotated by the unit quaternion ``q``."""
    x, y, z, _ = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), quat_conj(q))
    return (x, y, z)


def _normalised(q: Quat) -> Quat:
    n = math.sqrt(sum(c * c for c in q))
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def phone_centre(p: Vec3, q: Quat, offset: Vec3 = DEFAULT_CENTRE_OFFSET) -> Vec3:
    """Where the phone's centre is when its camera is at ``p`` turned by ``q``."""
    r = quat_rotate(q, offset)
    return (p[0] + r[0], p[1] + r[1], p[2] + r[2])


class ViewerClutch:
    """One channel's reference capture for one phone (module docstring).

    Args:
        offset: The phone's centre seen from the camera (camera axes, metres).
    """

    def __init__(self, offset: Vec3 = DEFAULT_CENTRE_OFFSET) -> None:
        self.offset = offset
        self.grab = 0
        self._ref: tuple[Vec3, Quat] | None = None

    @property
    def holding(self) -> bool:
        """Whether a grab is in progress (a reference is captured)."""
        return self._ref is not None

    def update(self, p: Vec3, q: Quat) -> Pose:
        """The motion since the grab began; the first call of a grab captures the reference (and
        gives zero motion)."""
        centre = phone_centre(p, q, self.offset)
        if self._ref is None:
            self.grab += 1
            self._ref = (centre, q)
        ref_p, ref_q = self._ref
        dp = (centre[0] - ref_p[0], centre[1] - ref_p[1], centre[2] - ref_p[2])
        dq = _normalised(quat_mul(q, quat_conj(ref_q)))
        return Pose(dp, dq, self.grab)

    def release(self) -> None:
        """End the grab: the next :meth:`update` captures a new reference."""
        self._ref = None
