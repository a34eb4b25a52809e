"""Scripted Kinematic2D policies for the conformance recorder (numpy only; runs in either venv).

Each policy drives the CRV robot (action ``[dx, dy, dtheta, darm, vacuum]``) by simple geometric
rules read off the state's features, so the recorded trajectories make contact, grasp, carry,
press and push:

* ``grasp-<obj>``: turn towards a movable object, extend the arm, close in with small steps until
  blocked, switch the vacuum on, carry the object up and back while turning, then release it.
* ``suction-press-<button>``: approach a button with the vacuum already on (the suction zone
  touches it before the gripper does).
* ``hook-push`` (PushPullHook2D): grasp the hook below the table edge and sweep it sideways
  towards the movable button, then turn it one way and the other.
* ``to-target``: drive the base straight at the target region (Motion2D), sliding along nothing:
  steps into obstacles are rejected.

See ``tools/conformance/README.md`` for the interface.
"""

from __future__ import annotations

import math
from collections.abc import Callable

SEEDS = [0, 1]
MAX_STEPS = 150
MAX_DXY, MAX_DTH, MAX_DARM = 0.05, math.pi / 16, 0.1

State = dict[str, float]
Policy = Callable[[State, int], "list[float] | None"]


def _objects(names: list[str]) -> list[str]:
    seen: list[str] = []
    for n in names:
        obj = n.split(".", 1)[0]
        if obj not in seen:
            seen.append(obj)
    return seen


def _center(s: State, o: str) -> tuple[float, float]:
    """A point inside the object: circle centre, rectangle centre, or the L's long arm's centre."""
    x, y, th = s[f"{o}.x"], s[f"{o}.y"], s[f"{o}.theta"]
    c, si = math.cos(th), math.sin(th)
    if f"{o}.radius" in s:
        return x, y
    if f"{o}.length_side1" in s:
        lx, ly = -0.5 * s[f"{o}.length_side1"], -0.5 * s[f"{o}.width"]
    else:
        lx, ly = 0.5 * s[f"{o}.width"], 0.5 * s[f"{o}.height"]
    return x + c * lx - si * ly, y + si * lx + c * ly


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _clip(v: float, m: float) -> float:
    return max(-m, min(m, v))


def _approach(s: State, tx: float, ty: float, vacuum: float, slow_within: float) -> list[float]:
    """Turn towards (tx, ty), extend the arm and move closer (small steps when near)."""
    rx, ry, th = s["robot.x"], s["robot.y"], s["robot.theta"]
    dx, dy = tx - rx, ty - ry
    dist = math.hypot(dx, dy)
    dth = _clip(_wrap(math.atan2(dy, dx) - th), MAX_DTH)
    step = MAX_DXY if dist > slow_within else 0.01
    scale = step / dist if dist > 1e-9 else 0.0
    return [_clip(dx * scale, MAX_DXY), _clip(dy * scale, MAX_DXY), dth, MAX_DARM, vacuum]


def _carry_up_and_back(s: State, t: float) -> list[float] | None:
    """Carry: up then back, turning; ``None`` once done."""
    if t > 40:
        return None
    sign = 1.0 if t <= 20 else -1.0
    return [0.02 * sign, 0.04 * sign, 0.08 * sign, 0.0, 1.0]


def _sweep_towards(obj: str) -> Callable[[State, float], list[float] | None]:
    """Carry: move sideways towards ``obj`` for 50 steps, then turn one way and the other."""
    mem: dict[str, float] = {}

    def carry(s: State, t: float) -> list[float] | None:
        if "sign" not in mem:
            mem["sign"] = 1.0 if s[f"{obj}.x"] >= s["robot.x"] else -1.0
        if t <= 50:
            return [0.03 * mem["sign"], 0.0, 0.0, 0.0, 1.0]
        if t <= 70:
            return [0.0, 0.0, -0.05 * mem["sign"], 0.0, 1.0]
        if t <= 90:
            return [0.0, 0.0, 0.05 * mem["sign"], 0.0, 1.0]
        return None

    return carry


def _hook_handle(s: State) -> tuple[float, float]:
    """The point of the hook's long arm at y = 1.1, below the table edge (PushPullHook2D)."""
    x, y, th, w = s["hook.x"], s["hook.y"], s["hook.theta"], s["hook.width"]
    c, si = math.cos(th), math.sin(th)
    u = (y - 0.5 * w * c - 1.1) / si if abs(si) > 1e-6 else 0.0
    u = max(0.0, min(s["hook.length_side1"], u))
    return x - c * u + si * 0.5 * w, y - si * u - c * 0.5 * w


def grasp_policy(
    obj: str,
    target: Callable[[State], tuple[float, float]] | None = None,
    carry: Callable[[State, float], list[float] | None] = _carry_up_and_back,
) -> Policy:
    """Approach ``obj`` (or the point ``target`` gives), grasp it, carry it, release it."""
    mem: dict[str, float] = {"phase": 0.0, "t": 0.0, "last_x": -1.0, "last_y": -1.0, "still": 0}

    def policy(s: State, k: int) -> list[float] | None:
        del k
        rx, ry = s["robot.x"], s["robot.y"]
        moved = math.hypot(rx - mem["last_x"], ry - mem["last_y"]) > 1e-12
        mem["still"] = 0 if moved else mem["still"] + 1
        mem["last_x"], mem["last_y"] = rx, ry
        mem["t"] += 1
        if mem["phase"] == 0:  # approach until blocked or out of time
            tx, ty = _center(s, obj) if target is None else target(s)
            reach = s["robot.arm_length"] + 0.3
            if mem["still"] >= 2 or mem["t"] > 90:
                mem["phase"], mem["t"] = 1, 0
            else:
                return _approach(s, tx, ty, 0.0, reach)
        if mem["phase"] == 1:  # vacuum on, nudge forward
            if mem["t"] > 3:
                mem["phase"], mem["t"] = 2, 0
            th = s["robot.theta"]
            return [0.005 * math.cos(th), 0.005 * math.sin(th), 0.0, 0.0, 1.0]
        if mem["phase"] == 2:
            action = carry(s, mem["t"])
            if action is not None:
                return action
            mem["phase"], mem["t"] = 3, 1
        if mem["t"] > 4:  # release and retract
            return None
        return [0.0, -0.02, 0.0, -MAX_DARM, 0.0]

    return policy


def press_policy(button: str) -> Policy:
    """Approach a button with the vacuum on, with small steps near it."""

    def policy(s: State, k: int) -> list[float] | None:
        if k >= 100 or s[f"{button}.color_g"] > 0.5:
            return None
        tx, ty = _center(s, button)
        return _approach(s, tx, ty, 1.0, s["robot.arm_length"] + 0.3)

    return policy


def target_policy() -> Policy:
    """Drive the base at the target region's centre (Motion2D)."""

    def policy(s: State, k: int) -> list[float] | None:
        if k >= 120:
            return None
        tx, ty = _center(s, "target_region")
        a = _approach(s, tx, ty, 0.0, 0.0)
        a[3] = -MAX_DARM
        return a

    return policy


def scripts(env_id: str, feature_names: list[str]) -> dict[str, Policy]:
    """The policies for one id: grasps of up to three movable objects, suction presses of up to
    two buttons, and the Motion2D target run."""
    del env_id
    objs = [o for o in _objects(feature_names) if o != "robot"]
    names = set(feature_names)
    out: dict[str, Policy] = {}
    if "target_region.x" in names and "target_block.x" not in names:
        out["to-target"] = target_policy()
    fixed = ("button", "target_", "wall", "obstacle", "shelf")
    movable = [o for o in objs if f"{o}.static" in names and not o.startswith(fixed)]
    if "target_block" in objs:
        movable = ["target_block", *[o for o in movable if o != "target_block"]]
    for o in movable[:3]:
        out[f"grasp-{o}"] = grasp_policy(o)
    if "hook.length_side1" in names and "movable_button.x" in names:
        out["hook-push"] = grasp_policy("hook", _hook_handle, _sweep_towards("movable_button"))
    buttons = [o for o in objs if o.startswith("button") and f"{o}.color_g" in names]
    for b in buttons[:2]:
        out[f"suction-press-{b}"] = press_policy(b)
    return out
