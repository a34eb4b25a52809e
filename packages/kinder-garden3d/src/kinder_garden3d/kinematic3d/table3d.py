"""Table3D: lift a cube off a table (environments.md §4.4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    FLOOR,
    PURPLE,
    WOOD,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Part
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE
from kinder_garden3d.kinematic3d.scene import BodySpec, BoxProbe

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Table3DConfig(Kinematic3DConfig):
    """Table3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        table_pos, table_half: The (observed) table's centre and half extents.
        cube_half: Half edge of the cubes.
        lift_height: How far above the table top a held cube's centre must be.
        floor_collides: Make the floor a collision object and a surface (upstream's Table3D has
            neither: its floor is only drawn; off by default).
    """

    table_pos: Vec3 = (0.6, 0.0, 0.2)
    table_half: Vec3 = (0.2, 0.4, 0.2)
    cube_half: float = 0.025
    lift_height: float = 0.1
    floor_collides: bool = False
    camera_target: tuple[float, float, float] = (0.35, 0.0, 0.3)
    camera_distance: float = 1.8
    camera_pitch: float = -35.0


def floor_body() -> ConstantBody:
    """Upstream's floor object: a 6 × 6 × 0.01 m box centred at z = −0.01, so its top face is
    at z = −0.005, 5 mm below the objects standing at z = 0 (a surface and a collision object)."""
    return ConstantBody(BodySpec((Part("box", (3.0, 3.0, 0.005)),), FLOOR), (0.0, 0.0, -0.01))


def floor_bodies(collides: bool, surface: bool = True) -> dict[str, ConstantBody]:
    """The floor entry of an env's ``constant_bodies``: upstream's floor as a collision body
    (a support surface unless ``surface`` is False) when it ``collides``, else drawn only."""
    floor = floor_body()
    if collides:
        return {"floor": ConstantBody(floor.spec, floor.pos, surface=surface)}
    visual = BodySpec(floor.spec.parts, floor.spec.rgba, collide=False)
    return {"floor": ConstantBody(visual, floor.pos, surface=False)}


class Table3DEnv(Kinematic3DEnv):
    """Pick up any cube from a table and hold it above the table.

    ## Description
    A TidyBot++-style mobile manipulator stands on the floor next to a wooden table with
    `num_cubes` purple 5 cm cubes on it. The task is to grasp a cube and lift it more than 0.1 m
    above the table top. The table is an observed (but immovable) object; the floor is a
    constant collision object. Motions are checked for collisions at their endpoint and reverted
    on collision; a close command grasps when exactly one cube touches the end-effector marker.

    ## Observation Space
    A (31 + 12N)-D float64 vector: `robot` (19), `table` (12), then `cube0` … (12 each, sorted
    by name). Features: `Kinematic3DRobot` (19): `pos_base_x, pos_base_y, pos_base_rot,
    joint_1..joint_7, finger_state, grasp_active, grasp_tf_x … grasp_tf_qw`;
    `Kinematic3DCuboid` (12): `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw,
    grasp_active, object_type, half_extent_x, half_extent_y, half_extent_z`. Quaternions are
    ordered (x, y, z, w).

    ## Action Space
    An 11-D float32 Box: Δbase x, y, yaw and Δjoint 1..7, each bounded by ±0.4, and a gripper
    command in [−1, 1] (< −0.5 close, > 0.5 open). The base stays within ±10 m; only the
    arm and the held object are collision-checked (not the base), as upstream.

    ## Reward
    −1 on every step.

    ## Starting State
    Upstream's initial state for the same seed. Robot at the origin, arm retracted, gripper
    open. Table centre (0.6, 0, 0.2), half extents (0.2, 0.4, 0.2), so its top is at z = 0.4.
    All cubes (half edge 0.025) are drawn uniformly on the table top, axis-aligned, and drawn
    again together while two of them touch.

    ## Episode End
    Terminates when some cube is held with its centre more than 0.1 m above the table top. The
    registered ids truncate after 300 steps.

    ## Arguments
    `num_cubes` (default 2), `config` (a `Table3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    The upstream docs say −0.01 per step; the upstream code (and this env) gives −1. As
    upstream, the floor is only drawn (`floor_collides` makes it a collision object and a
    surface). Upstream registers no step
    limit; these ids use 300.
    Shared with every Kinematic3D env here: the robot is a primitive-shape model of the
    TidyBot++/Gen3/2F-85 (see `kinder_garden3d/robot/README.md`), not upstream's meshes; plain
    colours replace textures and there is no textured background (upstream `realistic_bg`);
    the overview camera looks from yaw 50° instead of 90° so the arm does not hide the scene;
    the grasp closes the pads until they touch, so `finger_state` stops at a different value
    than upstream's Robotiq linkage (5 cm cube: 0.17 against 0.20); collision verdicts near
    contact can differ with the robot's shapes.
    """

    def __init__(
        self,
        num_cubes: int = 2,
        config: Table3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_cubes, int) or num_cubes < 1:
            raise ValueError(f"num_cubes must be an int >= 1, got {num_cubes!r}")
        self.num_cubes = num_cubes
        self.table = Object("table", CUBOID_TYPE)
        self.cubes = [Object(f"cube{i}", CUBOID_TYPE) for i in range(num_cubes)]
        super().__init__(config or Table3DConfig(), render_mode=render_mode)
        self.config: Table3DConfig
        self._probe = BoxProbe()

    def constant_bodies(self) -> dict[str, ConstantBody]:
        return floor_bodies(self.config.floor_collides)

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [c.name for c in self.cubes]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return [*super().surface_names(state), self.table.name]

    def object_color(self, obj: Object) -> Rgba:
        return WOOD if obj == self.table else PURPLE

    def box_objects(self) -> list[Object]:
        return [self.robot, self.table, *sorted(self.cubes)]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        tx, ty, tz = cfg.table_pos
        thx, thy, thz = cfg.table_half
        h = cfg.cube_half
        top = tz + thz
        low, high = (tx - thx + h, ty - thy + h, top + h), (tx + thx - h, ty + thy - h, top + h)
        for _ in range(cfg.max_reset_tries):
            # Upstream's order of draws: every cube, then the pairwise check (touching cubes,
            # within collision_distance, are rejected).
            # pybullet's query decides, as upstream's (it misses sub-0.1 mm overlaps).
            draws = [rng.uniform(low, high) for _ in self.cubes]
            centres = [(float(d[0]), float(d[1])) for d in draws]
            half = np.array([h, h, h])
            if any(
                self._probe.touch(a, half, b, half, cfg.collision_distance)
                for i, a in enumerate(draws)
                for b in draws[i + 1 :]
            ):
                continue
            features = {
                self.robot: self.robot_features(),
                self.table: self.cuboid_features(cfg.table_pos, cfg.table_half),
            }
            for cube, (x, y) in zip(self.cubes, centres, strict=True):
                features[cube] = self.cuboid_features((x, y, top + h), (h, h, h))
            return ObjectCentricState.from_features(features)
        raise self._reset_error("collision-free cube positions")

    def close(self) -> None:
        """Release the pybullet clients (the scene's and the reset's box probe)."""
        self._probe.close()
        super().close()

    def goal_reached(self, state: ObjectCentricState) -> bool:
        held = self.held_object(state)
        if held is None or held not in self.cubes:
            return False
        table = state[self.table]
        top = table[2] + table[11]
        return bool(state[held][2] - top > self.config.lift_height)
