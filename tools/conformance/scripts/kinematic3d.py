"""Scripted Kinematic3D policies for the conformance recorder (numpy only; runs in either venv).

Each policy drives the mobile manipulator (action ``[dx, dy, dyaw, dq1..dq7, gripper]``) through
phases read off the state's features, so the recorded trajectories move the base, reach, make
contact, grasp, carry and place:

* ``to-target`` (BaseMotion3D): drive the base straight at the target.
* ``pick-<obj>`` (Table3D, Obstruction3D, Transport3D, KinematicShelf3D,
  KinematicCylinderShelf3D, PrplLab3D): drive the base (Transport3D, the shelf families and
  PrplLab3D: turn, then translate to stand 0.6 m from the object on its side away from the box,
  the shelf or the lab) so the object is in front of the arm, move the arm above the object
  with the tool pointing down,
  descend until the tool frame is 3 cm above the object's centre, close, lift 15 cm, carry
  (turn the base by 0.3 rad), lower back until the object is about 6 mm above where it started,
  and open.

The arm's joint targets come from a small damped-least-squares IK on the Kinova Gen3 chain
(joint origins of Kinova's published ``gen3.urdf``; base mount (0.1199, 0, 0.3948); the tool frame
12 cm out of the flange). It only needs to be accurate to a few millimetres: the policies
read the actual state at every step. See ``tools/conformance/README.md`` for the interface.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

SEEDS = [0, 1]
MAX_STEPS = 200

State = dict[str, float]
Policy = Callable[[State, int], "list[float] | None"]

_HALF_PI = math.pi / 2
#: (xyz, roll) of each joint's origin in its parent (all joint axes are z; pitch = yaw = 0).
_CHAIN = (
    ((0.0, 0.0, 0.15643), math.pi),
    ((0.0, 0.005375, -0.12838), _HALF_PI),
    ((0.0, -0.21038, -0.006375), -_HALF_PI),
    ((0.0, 0.006375, -0.21038), _HALF_PI),
    ((0.0, -0.20843, -0.006375), -_HALF_PI),
    ((0.0, 0.00017505, -0.10593), _HALF_PI),
    ((0.0, -0.10593, -0.00017505), -_HALF_PI),
)
_MOUNT = (0.1199, 0.0, 0.3948)
_FLANGE = 0.061525
_TOOL = 0.12


def _tf(xyz: tuple[float, float, float], roll: float, yaw: float) -> np.ndarray:
    c, s = math.cos(roll), math.sin(roll)
    cz, sz = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    m = np.eye(4)
    m[:3, :3] = rx @ rz
    m[:3, 3] = xyz
    return m


def tool_pose(base: np.ndarray, base_z: float, q: np.ndarray) -> np.ndarray:
    """World 4×4 pose of the tool frame for base (x, y, yaw) and 7 joints."""
    m = _tf((float(base[0]), float(base[1]), base_z), 0.0, float(base[2]))
    m = m @ _tf(_MOUNT, 0.0, 0.0)
    for (xyz, roll), qi in zip(_CHAIN, q, strict=True):
        m = m @ _tf(xyz, roll, float(qi))
    m = m @ _tf((0.0, 0.0, -_FLANGE), math.pi, 0.0)
    out: np.ndarray = m @ _tf((0.0, 0.0, _TOOL), 0.0, 0.0)
    return out


def solve_down(
    base: np.ndarray, base_z: float, q0: np.ndarray, target: np.ndarray, iters: int = 200
) -> np.ndarray:
    """Joints putting the tool frame at ``target`` with its z axis pointing down (yaw free)."""
    q = np.array(q0, dtype=float)

    def err(qq: np.ndarray) -> np.ndarray:
        m = tool_pose(base, base_z, qq)
        return np.concatenate([m[:3, 3] - target, np.cross(m[:3, 2], [0.0, 0.0, -1.0]) * 0.3])

    for _ in range(iters):
        e = err(q)
        if np.linalg.norm(e) < 1e-5:
            break
        jac = np.zeros((6, 7))
        for i in range(7):
            dq = np.zeros(7)
            dq[i] = 1e-6
            jac[:, i] = (err(q + dq) - e) / 1e-6
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), e)
        q -= np.clip(step, -0.2, 0.2)
    return q


def _robot(s: State) -> tuple[np.ndarray, np.ndarray]:
    base = np.array([s["robot.pos_base_x"], s["robot.pos_base_y"], s["robot.pos_base_rot"]])
    q = np.array([s[f"robot.joint_{i}"] for i in range(1, 8)])
    return base, q


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _toward(delta: np.ndarray, bound: float) -> tuple[list[float], bool]:
    """A step of at most ``bound`` per dimension along ``delta``; whether it arrives."""
    n = max(1, math.ceil(float(np.max(np.abs(delta))) / bound - 1e-9))
    return [float(v) for v in delta / n], n == 1


def _to_target(bound: float) -> Policy:
    def policy(s: State, t: int) -> list[float] | None:
        base, _ = _robot(s)
        delta = np.array([s["target.x"] - base[0], s["target.y"] - base[1], 0.0])
        if np.max(np.abs(delta[:2])) < 1e-9:
            return None
        step, _ = _toward(delta, bound)
        return [*step, *([0.0] * 7), 0.0]

    return policy


def _pick(
    obj: str, base_z: float, bound: float, avoid: str | None = None, top: float = 0.0
) -> Policy:
    """See the module docstring; with ``avoid`` the base first drives to stand 0.6 m from the
    object, on its side away from the object ``avoid``; ``top`` raises the arm's targets (the
    object's half height when it is taller than a cube)."""
    mem: dict[str, object] = {"phase": "drive" if avoid else "above"}

    def arm_to(s: State, target: np.ndarray, grip: float) -> list[float] | None:
        base, q = _robot(s)
        key = f"goal-{mem['phase']}"
        if key not in mem:
            mem[key] = solve_down(base, base_z, q, target)
        delta = np.asarray(mem[key]) - q
        if np.max(np.abs(delta)) < 1e-9:
            return None
        step, _ = _toward(delta, bound)
        return [0.0, 0.0, 0.0, *step, grip]

    def policy(s: State, t: int) -> list[float] | None:
        base, _ = _robot(s)
        centre = np.array([s[f"{obj}.pose_x"], s[f"{obj}.pose_y"], s[f"{obj}.pose_z"] + top])
        if "start" not in mem:
            mem["start"] = centre.copy()
        start = np.asarray(mem["start"])
        for _ in range(8):  # advance through finished phases
            phase = mem["phase"]
            act: list[float] | None
            if phase == "drive":
                # Stand 0.6 m from the object on the side away from ``avoid`` (Transport3D's box,
                # which usually lies next to the cubes); turn first, then translate.
                away = start[:2] - np.array([s[f"{avoid}.pose_x"], s[f"{avoid}.pose_y"]])
                goal = start[:2] + 0.6 * away / max(float(np.linalg.norm(away)), 1e-9)
                d = start[:2] - goal
                yaw = math.atan2(d[1], d[0])
                delta = np.array([0.0, 0.0, _wrap(yaw - base[2])])
                if abs(delta[2]) < 1e-9:
                    delta = np.array([goal[0] - base[0], goal[1] - base[1], 0.0])
                act = None
                if np.max(np.abs(delta)) > 1e-9:
                    step, _ = _toward(delta, bound)
                    act = [*step, *([0.0] * 7), 0.0]
            elif phase == "above":
                act = arm_to(s, start + np.array([0.0, 0.0, 0.15]), 0.0)
            elif phase == "down":
                act = arm_to(s, start + np.array([0.0, 0.0, 0.03]), 0.0)
            elif phase == "close":
                mem["phase"] = "lift"
                return [*([0.0] * 10), -1.0]
            elif phase == "lift":
                act = arm_to(s, start + np.array([0.0, 0.0, 0.18]), 0.0)
            elif phase == "carry":
                turned = float(mem.setdefault("turned", 0.0))  # type: ignore[arg-type]
                act = None
                if turned < 0.3 - 1e-9:
                    dyaw = min(0.1, 0.3 - turned)
                    mem["turned"] = turned + dyaw
                    act = [0.0, 0.0, dyaw, *([0.0] * 7), 0.0]
            elif phase == "lower":
                if "low" not in mem:
                    mem["low"] = centre + np.array([0.0, 0.0, -(centre[2] - start[2]) + 0.036])
                act = arm_to(s, np.asarray(mem["low"]), 0.0)
            elif phase == "open":
                mem["phase"] = "done"
                return [*([0.0] * 10), 1.0]
            else:
                return None
            if act is not None:
                return act
            order = ["drive", "above", "down", "close", "lift", "carry", "lower", "open"]
            mem["phase"] = order[order.index(str(phase)) + 1]
        return None

    return policy


def scripts(env_id: str, feature_names: list[str]) -> dict[str, Policy]:
    """The policies for one Kinematic3D id (none for Packing3D)."""
    objects = sorted({n.split(".", 1)[0] for n in feature_names})
    if "BaseMotion3D" in env_id:
        return {"to-target": _to_target(0.4)}
    if "Table3D" in env_id:
        return {f"pick-{o}": _pick(o, 0.0, 0.4) for o in objects if o.startswith("cube")}
    if "Obstruction3D" in env_id:
        return {"pick-target_block": _pick("target_block", -0.4, 0.2)}
    if "Transport3D" in env_id:
        return {"pick-cube0": _pick("cube0", 0.0, 0.2, avoid="box0")}
    if "KinematicShelf3D" in env_id:
        return {"pick-cube0": _pick("cube0", 0.0, 0.2, avoid="shelf")}
    if "PrplLab3D" in env_id:
        return {"pick-cube0": _pick("cube0", 0.0, 0.4, avoid="prpl_lab")}
    if "KinematicCylinderShelf3D" in env_id:
        # From above the top of the 20 cm cylinder0 (the recording exercises the collision
        # and grasp checks; a side grasp needs a planner).
        return {"pick-cylinder0": _pick("cylinder0", 0.0, 0.2, avoid="shelf", top=0.1)}
    return {}
