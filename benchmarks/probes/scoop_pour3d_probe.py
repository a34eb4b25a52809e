"""Probe of a scoop stroke in ScoopPour3D-o10 (the measurements behind the Limits section of
``kinder_gym.models.dynamic3d.scoop_pour3d``); not a skill, not tested.

For a seed: reset ``kinder/ScoopPour3D-o10-v0``; grasp the scoop's handle from the side (the
gripper across the handle, ``--grasp-pitch`` degrees down, fingers pre-closed to ``--preclose``
so that the lower pad clears the island, closing on the handle's top and bottom); drive the base
to x = −0.15 m in line with the cubes; tip the cup ``--tip`` degrees about the handle (pitching
the gripper down); lower its lowest corner to 2 mm above the bin floor; drag it ``--drag`` metres
away from the robot; turn it back to 20° in 20° steps pivoting on its lowest point (moving on
``--forward`` metres per step); lift 8 cm. It prints, at each stage, the number of cubes whose
centres are inside the cup (in the scoop's frame: within its walls and 2 mm or more below the
rim's plane) and the pinch point. A stage that cannot
be reached ends the run with the reason.

Usage:
    python benchmarks/probes/scoop_pour3d_probe.py [--seed 0] [--tip 100] [--drag 0.14]
        [--forward 0.0] [--grasp-pitch 15] [--preclose 0.65]
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from kinder_core import make_object_centric
from kinder_core.state import ObjectCentricState
from kinder_garden3d.dynamic3d.geometry import quat_yaw
from kinder_garden3d.robot.description import forward_kinematics, matrix_to_quat_xyzw
from kinder_gym.models.dynamic3d.scoop_pour3d import (
    ScoopContext,
    _rotation,
    abstract_atoms,
    handle_centre,
    scoop_context,
)
from kinder_gym.models.dynamic3d.tidybot import (
    GRIP_STEPS,
    HOME,
    READY,
    Dynamic3DController,
    Segment,
    SegmentSource,
    arm_joints,
    base_pose,
    ik_near,
    pinch_position,
)
from kinder_gym.motion_planning import FloatArray, wrap_angle
from kinder_gym.skills import SkillFailure, execute_skill

#: Corners of the scoop's bounding box in its body frame.
CORNERS = np.array(
    [[sx * 0.0425, sy * 0.025, sz * 0.02] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
)
#: Top of the bin floor (m).
FLOOR = 0.48
GAP = 0.002


def lowest(state: ObjectCentricState, ctx: ScoopContext) -> float:
    pose = np.asarray(state[ctx.scoop][:7])
    return float(pose[2] + (CORNERS @ _rotation(pose[3:7]).T)[:, 2].min())


def in_cup(state: ObjectCentricState, ctx: ScoopContext) -> int:
    pose = np.asarray(state[ctx.scoop][:7])
    rot = _rotation(pose[3:7])
    n = 0
    for c in ctx.cubes:
        local = rot.T @ (np.asarray(state[c][:3]) - pose[:3])
        n += int(abs(local[0] - 0.0175) < 0.025 and abs(local[1]) < 0.025 and abs(local[2]) < 0.018)
    return n


def side_quat(yaw: float, pitch: float) -> FloatArray:
    """Gripper orientation heading ``yaw``, ``pitch`` down, fingers closing in the vertical plane
    of the heading (across a horizontal handle that lies across the heading)."""
    a = np.array(
        [math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch)]
    )
    u = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    y = np.cross(a, u)
    y /= np.linalg.norm(y)
    return matrix_to_quat_xyzw(np.stack([np.cross(y, a), y, a], axis=1))


def pinch(s: ObjectCentricState, ctx: ScoopContext) -> FloatArray:
    return pinch_position(base_pose(s, ctx.robot), arm_joints(s, ctx.robot))


def line(
    s: ObjectCentricState,
    ctx: ScoopContext,
    target: FloatArray,
    yaw: float,
    pitch: float,
    grip: float,
    spacing: float = 0.03,
    tol: float = 0.005,
) -> list[SegmentSource]:
    base = base_pose(s, ctx.robot)
    q = arm_joints(s, ctx.robot)
    start = pinch_position(base, q)
    n = max(1, math.ceil(float(np.linalg.norm(target - start)) / spacing))
    out: list[SegmentSource] = []
    for k in range(1, n + 1):
        q = ik_near(start + (target - start) * k / n, side_quat(yaw, pitch), base, q)
        out.append(
            Segment(arm=tuple(q), gripper=grip, arm_tol=tol if k == n else 0.03, max_steps=80)
        )
    return out


Stage = Callable[[ObjectCentricState], Sequence[SegmentSource]]


def labelled(name: str, ctx: ScoopContext, f: Stage) -> Stage:
    def g(s: ObjectCentricState) -> Sequence[SegmentSource]:
        print(f"  {name:8s} cubes in cup {in_cup(s, ctx)}  pinch {np.round(pinch(s, ctx), 3)}")
        return f(s)

    return g


def handle_yaw(state: ObjectCentricState, ctx: ScoopContext) -> float:
    """Heading across the handle, the one nearer +x."""
    yaw = wrap_angle(quat_yaw(np.asarray(state[ctx.scoop][3:7])) + math.pi / 2)
    return yaw if abs(yaw) <= math.pi / 2 else wrap_angle(yaw + math.pi)


class Probe(Dynamic3DController):
    """Grasp (``stage == 0``) or stroke (``stage == 1``); see the module docstring."""

    args: argparse.Namespace

    def initiable(self, state: ObjectCentricState) -> bool:
        return True

    def plan(self, state: ObjectCentricState) -> list[SegmentSource]:
        ctx: ScoopContext = self.context
        a = self.args
        yaw = handle_yaw(state, ctx)
        p0 = math.radians(a.grasp_pitch)
        if a.stage == 0:
            h = handle_centre(state, ctx.scoop)
            approach = np.array(
                [math.cos(p0) * math.cos(yaw), math.cos(p0) * math.sin(yaw), -math.sin(p0)]
            )
            pre = h - 0.08 * approach

            def above(s: ObjectCentricState) -> list[SegmentSource]:
                q = ik_near(
                    pre + np.array([0, 0, 0.05]), side_quat(yaw, p0), base_pose(s, ctx.robot), READY
                )
                return [Segment(arm=tuple(q), gripper=a.preclose, arm_tol=0.01, max_steps=80)]

            def lift(s: ObjectCentricState) -> list[SegmentSource]:
                return line(
                    s, ctx, pinch(s, ctx) + np.array([0, 0, 0.1]), yaw, p0, 1.0, spacing=0.04
                )

            return [
                self.drive(np.array([h[0] - 0.68, h[1], 0.0]), HOME, 0.0, 0.01),
                labelled("above", ctx, above),
                labelled("down", ctx, lambda s: line(s, ctx, pre, yaw, p0, a.preclose)),
                labelled("in", ctx, lambda s: line(s, ctx, h, yaw, p0, a.preclose, 0.02)),
                Segment(gripper=1.0, arm_tol=1.0, base_tol=1.0, min_steps=GRIP_STEPS),
                labelled("lift", ctx, lift),
            ]
        cubes = np.array([state[c][:3] for c in ctx.cubes])
        yc = float(np.median(cubes[:, 1]))
        xs = float(cubes[:, 0].min()) - 0.03
        tip = p0 + math.radians(a.tip)

        def carry(s: ObjectCentricState) -> list[SegmentSource]:
            off = np.asarray(s[ctx.scoop][:2]) - pinch(s, ctx)[:2]
            target = np.array([xs, yc - off[1], 0.66])
            return line(s, ctx, target, yaw, p0 + math.radians(40), 1.0, spacing=0.05)

        def lower(s: ObjectCentricState) -> list[SegmentSource]:
            dz = lowest(s, ctx) - (FLOOR + GAP)
            return line(s, ctx, pinch(s, ctx) - np.array([0, 0, dz]), yaw, tip, 1.0, spacing=0.02)

        def drag(s: ObjectCentricState) -> list[SegmentSource]:
            return line(
                s, ctx, pinch(s, ctx) + np.array([a.drag, 0, 0]), yaw, tip, 1.0, spacing=0.02
            )

        def untip(new: float) -> Stage:
            def f(s: ObjectCentricState) -> list[SegmentSource]:
                here = pinch(s, ctx)
                pose = np.asarray(s[ctx.scoop][:7])
                corners = pose[:3] + CORNERS @ _rotation(pose[3:7]).T
                b = base_pose(s, ctx.robot)
                fk = forward_kinematics(
                    (float(b[0]), float(b[1]), float(b[2])), arm_joints(s, ctx.robot)
                )
                turn = (
                    Rotation.from_quat(side_quat(yaw, p0 + new)).as_matrix()
                    @ fk["pinch_site"][:3, :3].T
                )
                moved = here + (corners - here) @ turn.T
                dz = max(FLOOR + GAP + 0.002 - float(moved[:, 2].min()), 0.0)
                return line(
                    s, ctx, here + np.array([a.forward, 0, dz]), yaw, p0 + new, 1.0, tol=0.01
                )

            return f

        def lift(s: ObjectCentricState) -> list[SegmentSource]:
            return line(
                s, ctx, pinch(s, ctx) + np.array([0, 0, 0.08]), yaw, p0 + math.radians(20), 1.0
            )

        def tip_in_place(s: ObjectCentricState) -> list[SegmentSource]:
            return line(s, ctx, pinch(s, ctx), yaw, tip, 1.0)

        arm = arm_joints(state, ctx.robot)
        untips = [labelled(f"untip{d}", ctx, untip(math.radians(d))) for d in (80, 60, 40, 20)]
        return [
            self.drive(np.array([-0.15, yc, 0.0]), arm, 1.0, 0.01),
            labelled("carry", ctx, carry),
            labelled("tip", ctx, tip_in_place),
            labelled("lower", ctx, lower),
            labelled("drag", ctx, drag),
            *untips,
            labelled("lift", ctx, lift),
        ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tip", type=float, default=100.0, help="degrees")
    parser.add_argument("--drag", type=float, default=0.14, help="metres")
    parser.add_argument("--forward", type=float, default=0.0, help="metres per untip step")
    parser.add_argument("--grasp-pitch", type=float, default=15.0, help="degrees")
    parser.add_argument("--preclose", type=float, default=0.65)
    args = parser.parse_args()
    env = make_object_centric("kinder/ScoopPour3D-o10-v0")
    state = env.reset(seed=args.seed)[0]
    ctx = scoop_context(env, state)
    for stage, name in enumerate(("grasp", "stroke")):
        args.stage = stage
        probe = Probe((ctx.robot, ctx.scoop), ctx)
        probe.args = args
        print(name)
        try:
            out = execute_skill(probe, state, [], env.transition, 900)
        except SkillFailure as e:
            print(f"  failed: {e}")
            return
        state = out.states[-1]
        print(f"  end: {len(out.actions)} steps, cubes in cup {in_cup(state, ctx)}, "
              f"atoms {sorted(abstract_atoms(ctx, state))}")  # fmt: skip
    env.close()


if __name__ == "__main__":
    main()
