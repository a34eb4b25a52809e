"""How fast Tossing3D's robot can move the pinch point with the bundled 11-D action, and how far
a cube released at that speed could fly (why the Tossing3D planning model does not toss).

From ``kinder/Tossing3D-o1-v0``'s seeded reset, for every sign pattern of the three pitch joints
(arm joints 2, 4, 6 at ±0.1 rad per action, the others still) the base drives toward +x at the
full 0.1 m per action for ``--steps`` actions. The pinch point's world speed is the forward-
kinematics displacement per action (0.1 s; a slight underestimate of the instantaneous peak).
Reported: the base's and the joints' speeds in the last action, the fastest pinch speed over all
patterns, and the ballistic range of a release at that speed at the best angle from ``--height``
metres (no drag) — an upper bound on a toss from behind the barrier. The bin's centre stands
1.3–2.1 m beyond the barrier line (x = 1.3), which the released cube must also pass.

Usage:
    python benchmarks/speed/tossing_speed.py [--steps 15] [--height 1.0]
"""

from __future__ import annotations

import argparse
import itertools
import math

import numpy as np

from kinder_core import make_object_centric
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position

G = 9.81


def best_range(speed: float, height: float) -> float:
    """Largest horizontal distance of a projectile launched at ``speed`` from ``height``."""
    best = 0.0
    for deg in np.linspace(0.0, 90.0, 181):
        a = math.radians(float(deg))
        vx, vz = speed * math.cos(a), speed * math.sin(a)
        t = (vz + math.sqrt(vz * vz + 2 * G * height)) / G
        best = max(best, vx * t)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=15, help="actions per swing")
    parser.add_argument("--height", type=float, default=1.0, help="release height (m)")
    args = parser.parse_args()
    env = make_object_centric("kinder/Tossing3D-o1-v0")
    start = env.reset(seed=0)[0]
    robot = env.objects["robot"]  # type: ignore[attr-defined]
    top = 0.0
    for signs in itertools.product((-1.0, 1.0), repeat=3):
        state = start
        prev = pinch_position(base_pose(state, robot), arm_joints(state, robot))
        for _ in range(args.steps):
            action = np.zeros(11)
            action[0] = 0.1
            action[[4, 6, 8]] = 0.1 * np.array(signs)
            new = env.transition(state, action)[0]
            pinch = pinch_position(base_pose(new, robot), arm_joints(new, robot))
            top = max(top, float(np.linalg.norm(pinch - prev)) / 0.1)
            base_speed = (new.get(robot, "pos_base_x") - state.get(robot, "pos_base_x")) / 0.1
            joint_speed = abs(arm_joints(new, robot)[1] - arm_joints(state, robot)[1]) / 0.1
            state, prev = new, pinch
        print(
            f"joints 2,4,6 signs {signs}: base {base_speed:.2f} m/s, joint 2 {joint_speed:.2f} "
            f"rad/s in the last action"
        )
    reach = best_range(top, args.height)
    print(f"fastest pinch speed {top:.2f} m/s; best range from {args.height} m: {reach:.2f} m")
    env.close()


if __name__ == "__main__":
    main()
