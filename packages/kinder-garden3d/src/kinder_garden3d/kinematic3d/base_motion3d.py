"""BaseMotion3D: drive the mobile base to a target point (environments.md §4.2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    FLOOR,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Part
from kinder_garden3d.kinematic3d.object_types import POINT_TYPE
from kinder_garden3d.kinematic3d.scene import BodySpec


@dataclass(frozen=True)
class BaseMotion3DConfig(Kinematic3DConfig):
    """BaseMotion3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        target_xy_bounds: (low, high) of the target's uniform x and y.
        target_z: Height of the (visual-only) target sphere.
        goal_tolerance: Base-to-target xy distance that counts as reached.
    """

    target_xy_bounds: tuple[float, float] = (-2.0, 2.0)
    target_z: float = 0.2
    check_base_collisions: bool = True
    goal_tolerance: float = 0.05
    camera_target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    camera_distance: float = 5.0
    camera_pitch: float = -60.0


class BaseMotion3DEnv(Kinematic3DEnv):
    """Drive the TidyBot++ base to a red target sphere on an empty floor.

    ## Description
    The simplest Kinematic3D task: a holonomic mobile manipulator (TidyBot++-style base, Kinova
    Gen3 arm in the retract pose, Robotiq 2F-85-style gripper) must bring its base centre within
    5 cm (xy) of a target point. The target is a visual-only red sphere of radius 0.05 m at
    z = 0.2 m. There are no obstacles; the floor is drawn but is not a collision object.
    Motion is kinematic ("teleport and check"): every action sets the new configuration
    directly after a collision check, as in all Kinematic3D environments.

    ## Observation Space
    A 22-D float64 vector: the robot (19 features) then the target (3). Features:
    `Kinematic3DRobot` (19): `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7,
    finger_state, grasp_active, grasp_tf_x, grasp_tf_y, grasp_tf_z, grasp_tf_qx, grasp_tf_qy,
    grasp_tf_qz, grasp_tf_qw` (quaternion order x, y, z, w); `Kinematic3DPoint` (3): `x, y, z`.
    The index table is in `metadata["observation_table"]`.

    ## Action Space
    An 11-D float32 Box: Δbase x, y (m) and yaw (rad), Δjoint 1..7 (rad), each bounded by
    ±0.4, and a gripper command in [−1, 1] (< −0.5 close, > 0.5 open). The base is clipped to
    ±10 m, joints 2, 4 and 6 to the Kinova URDF's limits (±2.41, ±2.66, ±2.23); the yaw wraps to
    [−π, π), the continuous joints do not (config `wrap_joints`).

    ## Reward
    −1 on every step.

    ## Starting State
    The base at the origin with yaw 0, the arm in the Kinova retract pose
    [0, −0.35, −π, −2.5, 0, −0.87, π/2], the gripper open. The target's x and y are uniform in
    [−2, 2]; it is resampled while the start already satisfies the goal.

    ## Episode End
    Terminates when the base's xy distance to the target is below 0.05 m. The registered id
    truncates after 200 steps.

    ## Arguments
    `config`: a `BaseMotion3DConfig` (frozen dataclass of defaults); `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    The initial target is upstream's for the same seed (its yaw is drawn and dropped: a sphere
    has none). Upstream's `reset(options={"init_state": ...})` puts the target at z = 0 where
    its seeded resets use 0.2 (a bug there); here a loaded state keeps its target height.
    Upstream registers no step limit; this id uses 200.
    Shared with every Kinematic3D env here: the robot is a primitive-shape model of the
    TidyBot++/Gen3/2F-85 (see `kinder_garden3d/robot/README.md`), not upstream's meshes; plain
    colours replace textures and there is no textured background (upstream `realistic_bg`);
    the overview camera looks from yaw 50° instead of 90° so the arm does not hide the scene;
    the grasp closes the pads until they touch, so `finger_state` stops at a different value
    than upstream's Robotiq linkage (5 cm cube: 0.17 against 0.20); collision verdicts near
    contact can differ with the robot's shapes.
    """

    def __init__(
        self, config: BaseMotion3DConfig | None = None, render_mode: str | None = "rgb_array"
    ) -> None:
        self.target = Object("target", POINT_TYPE)
        super().__init__(config or BaseMotion3DConfig(), render_mode=render_mode)
        self.config: BaseMotion3DConfig

    def constant_bodies(self) -> dict[str, ConstantBody]:
        floor = BodySpec((Part("box", (5.0, 5.0, 0.01)),), FLOOR, collide=False)
        return {"floor": ConstantBody(floor, (0.0, 0.0, -0.01), surface=False)}

    def object_color(self, obj: Object) -> Rgba:
        return (0.9, 0.1, 0.1, 1.0)

    def box_objects(self) -> list[Object]:
        return [self.robot, self.target]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        robot = self.robot_features()
        for _ in range(cfg.max_reset_tries):
            # Upstream draws (x, y, yaw) per try; the yaw of a sphere is not observed.
            lo, hi = cfg.target_xy_bounds
            xy = rng.uniform((lo, lo, -math.pi), (hi, hi, math.pi))[:2]
            state = ObjectCentricState.from_features(
                {self.robot: robot, self.target: [xy[0], xy[1], cfg.target_z]}
            )
            if not self.goal_reached(state):
                return state
        raise self._reset_error("a target away from the robot")

    def goal_reached(self, state: ObjectCentricState) -> bool:
        r, t = state[self.robot], state[self.target]
        return math.hypot(r[0] - t[0], r[1] - t[1]) < self.config.goal_tolerance
