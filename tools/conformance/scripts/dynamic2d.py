"""Scripted Dynamic2D policies for the conformance recorder (numpy-free, pure Python; runs in
either venv).

The two-finger robot (action ``[dx, dy, dtheta, darm, dgripper]``) and the dot robot (action
``[dx, dy]``) are steered by simple geometric rules read off the state's features, so the
recorded trajectories make contact with walls, push objects and grasp, carry and release them.
The rules read the state every step, so they work under upstream's PD controller, which moves the
robot only most of the way to each commanded target:

* ``hit-wall``: drive the base left (and a little up) into the left wall, then keep pushing.
* ``grasp-carry-<obj>`` (two-finger robot): turn the gripper to point down, rise to a safe height,
  move over the object's grasp point, descend until the gripper is just above it, close the
  fingers, lift, carry sideways and open the fingers.
* ``push-<obj>``: (two-finger robot) lower the open fingers beside the object and sweep right
  through it; (dot robot) go to the object's left and push right through it.

See ``tools/conformance/README.md`` for the interface.
"""

from __future__ import annotations

import math
from collections.abc import Callable

SEEDS = [0, 1]
MAX_STEPS = 80

State = dict[str, float]
Policy = Callable[[State, int], "list[float] | None"]
DOWN = -math.pi / 2


def _objects(names: list[str]) -> list[str]:
    seen: list[str] = []
    for n in names:
        obj = n.split(".", 1)[0]
        if obj not in seen:
            seen.append(obj)
    return seen


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _clip(v: float, m: float) -> float:
    return max(-m, min(m, v))


def _grasp_point(s: State, o: str) -> tuple[float, float, float]:
    """The point to grasp an object at (x, y) and its half-thickness below that point: a
    rectangle's centre, or the middle of an L-object's long arm."""
    x, y, th = s[f"{o}.x"], s[f"{o}.y"], s[f"{o}.theta"]
    if f"{o}.length_side1" in s:
        w = s[f"{o}.width"]
        lx, ly = -0.5 * s[f"{o}.length_side1"], -0.5 * w
        c, si = math.cos(th), math.sin(th)
        return x + c * lx - si * ly, y + si * lx + c * ly, w / 2
    if f"{o}.height" in s:
        return x, y, s[f"{o}.height"] / 2
    return x, y, s.get(f"{o}.radius", s.get(f"{o}.size", 0.1))


def _kin_scripts(objs: list[str], bounds: tuple[float, float, float]) -> dict[str, Policy]:
    max_dxy, max_dth, max_dgrip = bounds

    def hit_wall(s: State, k: int) -> list[float] | None:
        if k >= 40:
            return None
        return [-max_dxy, 0.2 * max_dxy, 0.0, 0.0, 0.0]

    def grasp_carry(o: str) -> Policy:
        mem: dict[str, float] = {"phase": 0.0, "t": 0.0}

        def policy(s: State, k: int) -> list[float] | None:
            gx, gy, hh = _grasp_point(s, o)
            rx, ry, th = s["robot.x"], s["robot.y"], s["robot.theta"]
            arm = s["robot.arm_joint"]
            safe = gy + hh + arm + 0.35
            low = gy + hh + arm + 0.05
            phase = int(mem["phase"])
            mem["t"] += 1
            dth = _clip(_wrap(DOWN - th), max_dth)
            if phase == 0:  # turn down and rise
                if abs(_wrap(DOWN - th)) < 0.02 and abs(safe - ry) < 0.01:
                    mem["phase"], mem["t"] = 1.0, 0.0
                return [0.0, _clip(safe - ry, max_dxy), dth, 0.0, 0.0]
            if phase == 1:  # over the grasp point
                if abs(gx - rx) < 0.005 or mem["t"] > 60:
                    mem["phase"], mem["t"] = 2.0, 0.0
                return [_clip(gx - rx, max_dxy), _clip(safe - ry, max_dxy), dth, 0.0, 0.0]
            if phase == 2:  # descend
                if abs(low - ry) < 0.005 or mem["t"] > 30:
                    mem["phase"], mem["t"] = 3.0, 0.0
                return [_clip(gx - rx, max_dxy), _clip(low - ry, max_dxy), dth, 0.0, 0.0]
            if phase == 3:  # close
                if mem["t"] > 12:
                    mem["phase"], mem["t"] = 4.0, 0.0
                return [0.0, 0.0, 0.0, 0.0, -max_dgrip]
            if phase == 4:  # lift
                if mem["t"] > 8:
                    mem["phase"], mem["t"] = 5.0, 0.0
                return [0.0, max_dxy, 0.0, 0.0, 0.0]
            if phase == 5:  # carry
                if mem["t"] > 8:
                    mem["phase"], mem["t"] = 6.0, 0.0
                return [max_dxy, 0.0, 0.0, 0.0, 0.0]
            if mem["t"] > 6:
                return None
            return [0.0, 0.0, 0.0, 0.0, max_dgrip]  # open

        return policy

    def push(o: str) -> Policy:
        mem: dict[str, float] = {"phase": 0.0, "t": 0.0}

        def policy(s: State, k: int) -> list[float] | None:
            gx, gy, hh = _grasp_point(s, o)
            rx, ry, th = s["robot.x"], s["robot.y"], s["robot.theta"]
            arm, fw = s["robot.arm_joint"], s["robot.finger_width"]
            side = gx - 0.35
            safe = gy + hh + arm + 0.35
            low = gy + arm + fw  # fingertips level with the grasp point
            phase = int(mem["phase"])
            mem["t"] += 1
            dth = _clip(_wrap(DOWN - th), max_dth)
            if phase == 0:  # turn down, rise and go to the object's left
                if (abs(side - rx) < 0.01 and abs(safe - ry) < 0.01) or mem["t"] > 60:
                    mem["phase"], mem["t"] = 1.0, 0.0
                return [_clip(side - rx, max_dxy), _clip(safe - ry, max_dxy), dth, 0.0, 0.0]
            if phase == 1:  # lower the fingers beside it
                if abs(low - ry) < 0.01 or mem["t"] > 30:
                    mem["phase"], mem["t"] = 2.0, 0.0
                return [_clip(side - rx, max_dxy), _clip(low - ry, max_dxy), dth, 0.0, 0.0]
            if mem["t"] > 20:
                return None
            return [max_dxy, 0.0, 0.0, 0.0, 0.0]  # sweep right

        return policy

    out: dict[str, Policy] = {"hit-wall": hit_wall}
    for o in objs:
        out[f"grasp-carry-{o}"] = grasp_carry(o)
        out[f"push-{o}"] = push(o)
    return out


def _dot_scripts(objs: list[str], max_dxy: float) -> dict[str, Policy]:
    def hit_wall(s: State, k: int) -> list[float] | None:
        if k >= 60:
            return None
        return [-max_dxy, 0.2 * max_dxy]

    def push(o: str) -> Policy:
        mem: dict[str, float] = {"phase": 0.0, "t": 0.0}

        def policy(s: State, k: int) -> list[float] | None:
            ox, oy = s[f"{o}.x"], s[f"{o}.y"]
            rx, ry = s["robot.x"], s["robot.y"]
            mem["t"] += 1
            if mem["phase"] == 0.0:
                tx, ty = ox - 0.6, oy
                if math.hypot(tx - rx, ty - ry) < 0.01 or mem["t"] > 80:
                    mem["phase"], mem["t"] = 1.0, 0.0
                return [_clip(tx - rx, max_dxy), _clip(ty - ry, max_dxy)]
            if mem["t"] > 30:
                return None
            return [max_dxy, _clip(oy - ry, max_dxy)]

        return policy

    out: dict[str, Policy] = {"hit-wall": hit_wall}
    for o in objs:
        out[f"push-{o}"] = push(o)
    return out


def scripts(env_id: str, feature_names: list[str]) -> dict[str, Policy]:
    """The scripted policies for one Dynamic2D id (see the module docstring)."""
    objs = _objects(feature_names)
    if "robot.finger_gap" in feature_names:
        family = env_id.split("/", 1)[1].split("-", 1)[0]
        max_dth = math.pi / 48 if family == "DynPushPullHook2D" else math.pi / 16
        targets = ["target_block"] if family == "DynObstruction2D" else ["hook"]
        return _kin_scripts(targets, (0.05, max_dth, 0.02))
    return _dot_scripts([o for o in objs if o.startswith("tblock")][:1], 0.05)
