"""The 3D mapper: base and end-effector targets → the mobile manipulator's delta action.

One mapper (:class:`TidyBotTeleop`) serves every 3D env (Kinematic3D in pybullet and Dynamic3D in
MuJoCo: both take base ``(Δx, Δy, Δyaw)`` in the world frame, 7 arm joint deltas and a gripper
command; Tossing3D's 7 extra joint-velocity targets are sent as 0). It keeps **targets**: a base
pose in the world and an end-effector (``pinch_site``) pose in the *base frame* (so the hand rides
along when the base drives), and a gripper closure in [0, 1]. Each tick:

* the base action is ``target − measured`` (yaw wrapped), clipped to the action bounds;
* the arm action is ``IK(target) − measured joints`` (continuous joints the short way round),
  clipped to the bounds; the IK is the project's mink solver
  (:class:`kinder_garden3d.robot.ik.InverseKinematics`, fixed base, warm-started from the measured
  joints so the solution stays on its branch), solved only when the target moved. When IK cannot
  reach a target within 3 cm / 0.2 rad the arm keeps going to the last reachable solution
  (holding once there; ``info["ik_ok"]`` is False);
* the gripper command is the family's: Kinematic3D ``−1`` (close) when closure > 0.5 else ``+1``
  (open); Dynamic3D the closure itself (0 open … 1 closed).

Targets move at most ``Limits`` speeds per second (rate limiting), the end effector stays inside a
workspace box in front of the base, and a clipped action keeps its target so the robot catches up
over the next ticks.

Two kinds of input drive the targets:

* **Clutch poses** (web app: phone touch pads, WebXR controllers). Channels ``"base"`` and
  ``"arm"`` each carry the device's motion since the current grab began (a
  :class:`~kinder_gym.teleop.inputs.Pose` in the WebXR frame, computed by the device so the grab
  is anchored where the finger or grip went down). The first tick that sees a grab number captures
  the robot's pose as reference; the target is that reference moved by the device motion (1:1
  times ``scale``), converted by :func:`webxr_to_robot` (WebXR forward −z → robot +x, left −x →
  +y, up +y → +z) and taken relative to the robot's heading at the grab. Releasing a channel
  sets its target to the measured pose (the robot holds still); a new grab starts from there, so
  re-grasping never jumps. A grab that was interrupted (the channel released, its samples went
  stale, or a new episode started) is never resumed: the device must grab again. As in
  TidyBot++, the hand's target is held in the **world** while the base moves during an arm grab
  (another device driving the base): the device's motion moves the hand in the world frame the
  base had at the grab. With no channel engaged the deadman is released: the loop pauses.
* **Velocities** (keyboard and gamepad fallback, :data:`BINDINGS_3D`): the base moves in its own
  frame, the end effector in the base frame; the end-effector target may lead the measured hand
  by at most ``Limits.ee_lead`` so it never runs away when blocked.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from kinder_core import ObjectCentricEnv
from kinder_garden3d.kinematic3d.geometry import (
    quat_multiply,
    quat_yaw,
    yaw_quat,
)
from kinder_garden3d.robot.description import forward_kinematics, matrix_to_quat_xyzw
from kinder_garden3d.robot.description import robot_description as _robot_description
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_gym.teleop.inputs import InputState, Pose
from kinder_gym.teleop.mappers import (
    FINE,
    FloatArray,
    MapOutput,
    deadzone,
    keyboard_events,
    robot_type_name,
)
from kinder_gym.teleop.mappers import pad_events as _pad_events

ROBOT_FAMILIES_3D = {"Kinematic3DRobot": "kinematic", "Dynamic3DRobot": "dynamic"}
_LOW, _HIGH = _robot_description().arm_joint_limits
_CONTINUOUS = ~np.isfinite(_LOW)

BINDINGS_3D: tuple[tuple[str, str], ...] = (
    ("W/S A/D", "base fwd/back, left/right"),
    ("Q / E", "base turn left / right"),
    ("I/K J/L", "hand fwd/back, left/right"),
    ("U / O", "hand up / down"),
    ("arrows", "hand pitch / yaw"),
    ("Z / X", "hand roll"),
    ("Space", "gripper close/open (toggle)"),
    ("Shift (held)", "fine motion"),
    ("Enter / Bksp", "save / discard"),
    ("Ctrl+R / Esc", "restart seed / quit"),
    ("pad L stick", "base translate"),
    ("pad L1 / R1", "base turn"),
    ("pad R stick", "hand fwd/left"),
    ("pad LT / RT", "hand down / up"),
    ("pad Cross", "gripper toggle"),
)


@dataclasses.dataclass(frozen=True)
class Limits:
    """Rate limits and workspace of the targets (m, rad, per second)."""

    base_speed: float = 0.5
    base_yaw_speed: float = 1.5
    ee_speed: float = 0.3
    ee_rot_speed: float = 1.5
    ee_lead: float = 0.08
    """How far (m) a velocity-driven hand target may lead the measured hand."""
    workspace_low: tuple[float, float, float] = (-0.2, -0.8, 0.0)
    """End-effector box in the base frame (x forward, y left, z up from the floor)."""
    workspace_high: tuple[float, float, float] = (1.0, 0.8, 1.3)


def webxr_to_robot(pose: Pose) -> tuple[FloatArray, FloatArray]:
    """A WebXR-frame pose (+x right, +y up, +z back) in the robot's axes (+x forward, +y left,
    +z up): ``p = (−z, −x, y)``, ``q = (−qz, −qx, qy, qw)`` (a proper rotation, so quaternions map
    like vectors)."""
    x, y, z = pose.p
    qx, qy, qz, qw = pose.q
    return np.array([-z, -x, y], dtype=np.float64), np.array([-qz, -qx, qy, qw], dtype=np.float64)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _rotvec_quat(v: FloatArray) -> FloatArray:
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.array([0.0, 0.0, 0.0, 1.0])
    axis = v / angle
    return np.array([*(axis * math.sin(angle / 2)), math.cos(angle / 2)])


def _quat_angle(a: FloatArray, b: FloatArray) -> float:
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(a, b)))))


def _slerp(a: FloatArray, b: FloatArray, t: float) -> FloatArray:
    dot = float(np.dot(a, b))
    if dot < 0:
        b, dot = -b, -dot
    if dot > 0.9995:
        q = a + t * (b - a)
        return np.asarray(q / np.linalg.norm(q), dtype=np.float64)
    theta = math.acos(dot)
    q = (math.sin((1 - t) * theta) * a + math.sin(t * theta) * b) / math.sin(theta)
    return np.asarray(q, dtype=np.float64)


def _step_towards(current: FloatArray, goal: FloatArray, max_step: float) -> FloatArray:
    d = goal - current
    n = float(np.linalg.norm(d))
    return goal.copy() if n <= max_step else current + d * (max_step / n)


def ee_pose_in_base(arm: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The end effector's pose (position, quaternion xyzw) in the base frame."""
    tf = forward_kinematics((0.0, 0.0, 0.0), arm)["pinch_site"]
    return np.asarray(tf[:3, 3], dtype=np.float64), matrix_to_quat_xyzw(tf[:3, :3])


@dataclasses.dataclass
class _Clutch:
    grab: int
    robot: tuple[FloatArray, FloatArray]
    base: FloatArray
    """The base target (x, y, yaw) at the grab: the frame the device's motion is taken in."""


class TidyBotTeleop:
    """The 3D mapper (module docstring).

    Args:
        env: A Kinematic3D or Dynamic3D env (Box view).
        hz: The loop's control rate (for the per-tick rate limits).
        limits: Target speeds and workspace.
        scale: Device motion → robot motion factor for clutch poses.
    """

    def __init__(
        self,
        env: gymnasium.Env[Any, Any],
        hz: float = 10.0,
        limits: Limits | None = None,
        scale: float = 1.0,
    ) -> None:
        robot = robot_type_name(env)
        if robot not in ROBOT_FAMILIES_3D:
            raise ValueError(
                f"No 3D teleop mapping for robot type {robot!r}; expected one of "
                f"{sorted(ROBOT_FAMILIES_3D)}"
            )
        if not isinstance(env.action_space, spaces.Box) or env.action_space.shape[0] < 11:
            raise ValueError("The 3D mapper needs the 11-D (or longer) mobile-manipulator action")
        self.family = ROBOT_FAMILIES_3D[robot]
        self.low = np.asarray(env.action_space.low, dtype=np.float64)
        self.high = np.asarray(env.action_space.high, dtype=np.float64)
        self.dt = 1.0 / float(hz)
        self.limits = limits or Limits()
        self.scale = float(scale)
        self._ik = InverseKinematics(free_base=False)
        self.reset(env)

    # -- state ----------------------------------------------------------------------------------
    def measured(self, env: gymnasium.Env[Any, Any]) -> tuple[FloatArray, FloatArray]:
        """The measured base pose (x, y, yaw) and 7 arm joints."""
        model = env.unwrapped
        assert isinstance(model, ObjectCentricEnv)
        state = model.get_state()
        robot = state.get_object_from_name("robot")
        values = np.asarray(state[robot][:10], dtype=np.float64)
        return values[:3].copy(), values[3:10].copy()

    def reset(self, env: gymnasium.Env[Any, Any]) -> None:
        base, arm = self.measured(env)
        self.base_target = base
        self.ee_p, self.ee_q = ee_pose_in_base(arm)
        self.gripper = 0.0
        # Grabs seen before this reset are over: a device still holding one must grab again.
        ended: dict[str, set[int]] = getattr(self, "_ended", {})
        for channel, grab in getattr(self, "_last_grab", {}).items():
            ended.setdefault(channel, set()).add(grab)
        self._ended = ended
        self._last_grab: dict[str, int] = {}
        self._clutch: dict[str, _Clutch] = {}
        self._ik_target: tuple[FloatArray, FloatArray] | None = None
        self._ik_goal = arm
        self._ik_ok = True

    # -- the mapping ----------------------------------------------------------------------------
    def __call__(self, state: InputState, env: gymnasium.Env[Any, Any]) -> MapOutput:
        base, arm = self.measured(env)
        events = frozenset(keyboard_events(state) | _pad_events(state))
        if "gripper" in state.scalars:
            self.gripper = min(1.0, max(0.0, float(state.scalars["gripper"])))
        if "space" in state.pressed or "pad_a" in state.pressed:
            self.gripper = 0.0 if self.gripper > 0.5 else 1.0
        if state.poses or state.source == "web":
            self._clutch_update(state, base, arm)
        else:
            self._velocity_update(state, base, arm)
        info: dict[str, Any] = {
            "gripper": self.gripper,
            "base_target": [float(v) for v in self.base_target],
            "ee_target": [float(v) for v in self.ee_p],
            "engaged": sorted(state.engaged),
        }
        if not state.enabled:
            self._hold(base, arm)
            info["ik_ok"] = self._ik_ok
            return MapOutput(None, events, info)
        action = self.action(base, arm)
        info["ik_ok"] = self._ik_ok
        return MapOutput(action, events, info)

    def _hold(
        self, base: FloatArray, arm: FloatArray, channels: tuple[str, ...] = ("base", "arm")
    ) -> None:
        if "base" in channels:
            self.base_target = base.copy()
        if "arm" in channels:
            self.ee_p, self.ee_q = ee_pose_in_base(arm)
            self._ik_target = None
            self._ik_goal = arm.copy()

    def _clutch_update(self, s: InputState, base: FloatArray, arm: FloatArray) -> None:
        lim = self.limits
        for channel in ("base", "arm"):
            engaged = channel in s.engaged and channel in s.poses
            if engaged and s.poses[channel].grab in self._ended.get(channel, ()):
                engaged = False  # an interrupted grab: wait for a new one
            if not engaged:
                if channel in self._clutch:
                    self._ended.setdefault(channel, set()).add(self._clutch.pop(channel).grab)
                    self._hold(base, arm, (channel,))
                continue
            pose = s.poses[channel]
            self._last_grab[channel] = pose.grab
            dp, dq = webxr_to_robot(pose)
            dp = dp * self.scale
            ref = self._clutch.get(channel)
            if ref is None or ref.grab != pose.grab:
                if ref is not None:  # a new grab without a release in between: hold first
                    self._ended.setdefault(channel, set()).add(ref.grab)
                    self._hold(base, arm, (channel,))
                robot_ref = (
                    (base.copy(), yaw_quat(float(base[2])))
                    if channel == "base"
                    else (self.ee_p.copy(), self.ee_q.copy())
                )
                ref = self._clutch[channel] = _Clutch(pose.grab, robot_ref, self.base_target.copy())
            if channel == "base":
                yaw0 = float(ref.robot[0][2])
                c, s_ = math.cos(yaw0), math.sin(yaw0)
                goal_xy = ref.robot[0][:2] + np.array(
                    [c * dp[0] - s_ * dp[1], s_ * dp[0] + c * dp[1]]
                )
                goal_yaw = yaw0 + quat_yaw(dq)
                xy = _step_towards(self.base_target[:2], goal_xy, lim.base_speed * self.dt)
                dyaw = _wrap(goal_yaw - float(self.base_target[2]))
                max_yaw = lim.base_yaw_speed * self.dt
                yaw = float(self.base_target[2]) + max(-max_yaw, min(max_yaw, dyaw))
                self.base_target = np.array([xy[0], xy[1], _wrap(yaw)])
            else:
                goal_p, goal_q = self._in_base_now(
                    ref.base, ref.robot[0] + dp, quat_multiply(dq, ref.robot[1])
                )
                goal_p = np.clip(goal_p, lim.workspace_low, lim.workspace_high)
                self._move_ee(goal_p, goal_q / np.linalg.norm(goal_q))

    def _in_base_now(
        self, base_ref: FloatArray, p: FloatArray, q: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """A pose given in the frame of base pose ``base_ref`` (x, y, yaw), in the frame of the
        current base target (the same pose in the world)."""
        now = self.base_target
        dyaw = float(base_ref[2] - now[2])
        c, s_ = math.cos(dyaw), math.sin(dyaw)
        shift = base_ref[:2] - now[:2]
        cy, sy = math.cos(float(now[2])), math.sin(float(now[2]))
        p_now = np.array(
            [
                c * p[0] - s_ * p[1] + cy * shift[0] + sy * shift[1],
                s_ * p[0] + c * p[1] - sy * shift[0] + cy * shift[1],
                p[2],
            ]
        )
        return p_now, quat_multiply(yaw_quat(dyaw), q)

    def _move_ee(self, goal_p: FloatArray, goal_q: FloatArray) -> None:
        lim = self.limits
        self.ee_p = _step_towards(self.ee_p, goal_p, lim.ee_speed * self.dt)
        angle = _quat_angle(self.ee_q, goal_q)
        max_angle = lim.ee_rot_speed * self.dt
        t = 1.0 if angle <= max_angle else max_angle / angle
        self.ee_q = _slerp(self.ee_q, goal_q, t)

    def _velocity_update(self, s: InputState, base: FloatArray, arm: FloatArray) -> None:
        lim = self.limits
        held = s.buttons
        gain = FINE if ("left shift" in held or "right shift" in held) else 1.0

        def key(plus: str, minus: str) -> float:
            return gain * (float(plus in held) - float(minus in held))

        fwd = key("w", "s") + deadzone(s.axis("pad_ly"))
        left = key("a", "d") - deadzone(s.axis("pad_lx"))
        turn = key("q", "e") + float("pad_l1" in held) - float("pad_r1" in held)
        v = np.clip([fwd, left], -1.0, 1.0) * lim.base_speed * self.dt
        c, s_ = math.cos(float(base[2])), math.sin(float(base[2]))
        w = max(-1.0, min(1.0, turn)) * lim.base_yaw_speed * self.dt
        self.base_target = base + np.array([c * v[0] - s_ * v[1], s_ * v[0] + c * v[1], w])
        self.base_target[2] = _wrap(float(self.base_target[2]))

        hand = np.array(
            [
                key("i", "k") + deadzone(s.axis("pad_ry")),
                key("j", "l") - deadzone(s.axis("pad_rx")),
                key("u", "o") + s.axis("pad_rt") - s.axis("pad_lt"),
            ]
        )
        rot = np.array([key("x", "z"), key("down", "up"), key("left", "right")])
        if np.any(hand != 0.0) or np.any(rot != 0.0):
            measured_p, _ = ee_pose_in_base(arm)
            p = self.ee_p + np.clip(hand, -1.0, 1.0) * lim.ee_speed * self.dt
            p = measured_p + _step_towards(np.zeros(3), p - measured_p, lim.ee_lead)
            self.ee_p = np.clip(p, lim.workspace_low, lim.workspace_high)
            dq = _rotvec_quat(np.clip(rot, -1.0, 1.0) * lim.ee_rot_speed * self.dt)
            q = quat_multiply(dq, self.ee_q)
            self.ee_q = q / np.linalg.norm(q)

    def _arm_goal(self, arm: FloatArray) -> FloatArray:
        target = (self.ee_p, self.ee_q)
        last = self._ik_target
        if (
            last is not None
            and np.array_equal(last[0], target[0])
            and np.array_equal(last[1], target[1])
        ):
            return self._ik_goal
        result = self._ik.solve(
            self.ee_p,
            self.ee_q,
            initial_arm_joints=arm,
            restarts=0,
            max_iterations=60,
            position_tolerance=1e-3,
            orientation_tolerance=1e-2,
        )
        self._ik_target = (self.ee_p.copy(), self.ee_q.copy())
        self._ik_ok = result.position_error < 0.03 and result.orientation_error < 0.2
        if self._ik_ok:
            self._ik_goal = np.asarray(result.arm_joints, dtype=np.float64)
        return self._ik_goal

    def action(self, base: FloatArray, arm: FloatArray) -> FloatArray:
        """The clipped action that moves the measured configuration towards the targets."""
        action = np.zeros_like(self.low)
        d_base = self.base_target - base
        d_base[2] = _wrap(float(d_base[2]))
        d_arm = self._arm_goal(arm) - arm
        d_arm[_CONTINUOUS] = (d_arm[_CONTINUOUS] + math.pi) % (2.0 * math.pi) - math.pi
        action[:3] = d_base
        action[3:10] = d_arm
        if self.family == "kinematic":
            action[10] = -1.0 if self.gripper > 0.5 else 1.0
        else:
            action[10] = self.gripper
        return np.asarray(np.clip(action, self.low, self.high), dtype=np.float64)
