"""Transport3D: move cubes and a box from the floor onto a table (environments.md §4.5)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    BLUE,
    WOOD,
    YELLOW,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Array, Part, cuboid_parts, rect_distance_2d
from kinder_garden3d.kinematic3d.object_types import CONTAINER, CUBOID_TYPE
from kinder_garden3d.kinematic3d.scene import BoxProbe
from kinder_garden3d.kinematic3d.table3d import floor_body

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Transport3DConfig(Kinematic3DConfig):
    """Transport3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        table_pos, table_half: The (observed) table's centre and half extents.
        box_half: Outer half extents of the open-top box (walls 0.01 m).
        cube_half: Half edge of the cubes.
        floor_region: (x_min, x_max, y_min, y_max) where the box and cubes start.
        robot_footprint_half, robot_footprint_half_z: Half extents of the base's collision box
            in upstream's robot (0.548 × 0.508 × 0.365 m, standing on the floor), which sampled
            objects may not touch.
        cube_box_preference: A cube is kept only when its footprint is closer to the box's than
            to the table's by more than this (upstream's rule, which puts cubes near the box).
        max_sampling_attempts: Draws per object before a reset gives up.
        goal_min_z: Smallest centre height of every cube and box at the goal.
        goal_ee_clearance: Smallest end-effector distance to every cube and box at the goal.
        goal_max_finger: Largest finger state (open gripper) at the goal.
    """

    max_action_mag: float = 0.2
    min_placement_dist: float = 0.01
    table_pos: Vec3 = (0.6, 0.0, 0.2)
    table_half: Vec3 = (0.2, 0.4, 0.2)
    box_half: Vec3 = (0.1, 0.15, 0.1)
    cube_half: float = 0.025
    floor_region: tuple[float, float, float, float] = (-1.5, 1.5, -1.5, 1.5)
    robot_footprint_half: tuple[float, float] = (0.274, 0.254)
    robot_footprint_half_z: float = 0.1825
    cube_box_preference: float = 0.05
    max_sampling_attempts: int = 100_000
    goal_min_z: float = 0.3
    goal_ee_clearance: float = 0.2
    goal_max_finger: float = 0.01
    camera_target: tuple[float, float, float] = (0.0, 0.0, 0.2)
    camera_distance: float = 2.6
    camera_pitch: float = -45.0


class Transport3DEnv(Kinematic3DEnv):
    """Put every cube and the box on the table, then let go and step back.

    ## Description
    A TidyBot++-style mobile manipulator, an open-top blue box and `num_cubes` yellow 5 cm cubes
    on the floor, and a wooden table. Everything must end up on the table. The box is a
    container: while it is held, every cube whose centre lies inside it is carried along, so
    the cubes can be transported in one trip. A held object can be released only onto a surface
    (the floor, the table or the box) within 5 mm. Motions are collision-checked at their
    endpoint and reverted on collision.

    ## Observation Space
    A (43 + 12N)-D float64 vector: `robot` (19), `table` (12), `box0` (12), then `cube0` … (12
    each, sorted by name), the order of upstream kindergarden 0.2.5. Features:
    `Kinematic3DRobot` (19): `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7,
    finger_state, grasp_active, grasp_tf_x … grasp_tf_qw`;
    `Kinematic3DCuboid` (12): `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw,
    grasp_active, object_type, half_extent_x, half_extent_y, half_extent_z` (the box has
    object_type −1 for every cuboid, as upstream; the box is nevertheless an open-top container
    with 0.01 m walls). Quaternions are ordered
    (x, y, z, w).

    ## Action Space
    An 11-D float32 Box: Δbase x, y, yaw and Δjoint 1..7, each bounded by ±0.2, and a gripper
    command in [−1, 1] (< −0.5 close, > 0.5 open). The base stays within ±10 m; only the
    arm and the held object are collision-checked (not the base), as upstream.

    ## Reward
    −1 on every step.

    ## Starting State
    Upstream's initial state for the same seed. Robot at the origin, arm retracted, gripper
    open. Table centre (0.6, 0, 0.2), half extents (0.2, 0.4, 0.2). The box (half extents
    (0.1, 0.15, 0.1)) and then each cube stand on the floor with centres uniform in
    [−1.5, 1.5]², axis-aligned, not touching the base's 0.548 × 0.508 m footprint, the table or
    each other; a cube is kept only when it lies nearer the box than the table (by 5 cm). The
    floor's top face is 5 mm below them.

    ## Episode End
    Terminates when the gripper is open (finger state ≤ 0.01), the end effector is at least
    0.2 m from every cube and box centre, and every cube and box centre is at z ≥ 0.3 (on the
    table, whose top is at 0.4). The registered ids truncate after 500 steps.

    ## Arguments
    `num_cubes` (default 2), `config` (a `Transport3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.
    * v0 (spaces update): `box0` comes before the cubes in the vector, as upstream 0.2.5.

    ## Deviations
    Upstream can release a held box anywhere (pybullet finds the box within any distance of
    itself, a surface); here the box needs another surface. Colours replace upstream's
    textures. Upstream registers no step limit; these ids use 500.
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
        config: Transport3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_cubes, int) or num_cubes < 0:
            raise ValueError(f"num_cubes must be an int >= 0, got {num_cubes!r}")
        self.num_cubes = num_cubes
        self.table = Object("table", CUBOID_TYPE)
        self.box = Object("box0", CUBOID_TYPE)
        self.cubes = [Object(f"cube{i}", CUBOID_TYPE) for i in range(num_cubes)]
        super().__init__(config or Transport3DConfig(), render_mode=render_mode)
        self.config: Transport3DConfig
        self._probe = BoxProbe()

    def constant_bodies(self) -> dict[str, ConstantBody]:
        return {"floor": floor_body()}

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [*(c.name for c in self.cubes), self.box.name]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return ["floor", self.table.name, self.box.name]

    def object_color(self, obj: Object) -> Rgba:
        if obj == self.table:
            return WOOD
        return BLUE if obj == self.box else YELLOW

    def box_objects(self) -> list[Object]:
        return [self.robot, self.table, self.box, *sorted(self.cubes)]

    def object_parts(self, state: ObjectCentricState, obj: Object) -> list[Part]:
        # The box is open-topped whatever its object_type feature says (upstream writes −1 for
        # every cuboid, the box included).
        if obj == self.box:
            return cuboid_parts(CONTAINER, state[obj][9:12])
        return super().object_parts(state, obj)

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampler, draw for draw: the box, then each cube, uniform over
        ``floor_region`` (centres; x, y and a constant z per draw), rejecting a draw that comes
        within ``collision_distance`` of the base's collision box, the table or an object placed
        before (by pybullet's query, as upstream); a cube must also lie nearer the box than the
        table (``cube_box_preference``)."""
        cfg = self.config
        x0, x1, y0, y1 = cfg.floor_region
        fx, fy = cfg.robot_footprint_half
        base_h = np.array([fx, fy, cfg.robot_footprint_half_z])
        base_c = np.array([cfg.home_base_pose[0], cfg.home_base_pose[1], base_h[2]])
        table_c, table_h = np.array(cfg.table_pos), np.array(cfg.table_half)
        obstacles = [(base_c, base_h), (table_c, table_h)]
        bh, h = np.array(cfg.box_half), cfg.cube_half
        box_c = self._draw(rng, (x0, y0, bh[2]), (x1, y1, bh[2]), bh, obstacles)
        obstacles.append((box_c, bh))
        cubes: list[Array] = []
        for _cube in self.cubes:
            half = np.array([h, h, h])
            near = (box_c, bh, table_c, table_h)
            c = self._draw(rng, (x0, y0, h), (x1, y1, h), half, obstacles, near)
            obstacles.append((c, half))
            cubes.append(c)
        features = {
            self.robot: self.robot_features(),
            self.table: self.cuboid_features(cfg.table_pos, cfg.table_half),
            self.box: self.cuboid_features(box_c, bh),
        }
        for cube, c in zip(self.cubes, cubes, strict=True):
            features[cube] = self.cuboid_features(c, (h, h, h))
        return ObjectCentricState.from_features(features)

    def _draw(
        self,
        rng: np.random.Generator,
        low: Vec3,
        high: Vec3,
        half: Array,
        obstacles: list[tuple[Array, Array]],
        near_box: tuple[Array, Array, Array, Array] | None = None,
    ) -> Array:
        cfg = self.config
        for _ in range(cfg.max_sampling_attempts):
            c = rng.uniform(low, high)
            xy = (float(c[0]), float(c[1]))
            if near_box is not None:
                box_c, box_h, table_c, table_h = near_box
                to_box = rect_distance_2d(xy, (0.0, 0.0), _xy(box_c), _xy(box_h))
                to_table = rect_distance_2d(xy, (0.0, 0.0), _xy(table_c), _xy(table_h))
                if to_box >= to_table + cfg.cube_box_preference:
                    continue
            if not any(
                self._probe.touch(c, half, oc, oh, cfg.collision_distance) for oc, oh in obstacles
            ):
                return np.asarray(c, dtype=np.float64)
        raise self._reset_error("a collision-free floor position")

    def close(self) -> None:
        """Release the pybullet clients (the scene's and the reset's box probe)."""
        self._probe.close()
        super().close()

    def goal_reached(self, state: ObjectCentricState) -> bool:
        cfg = self.config
        if state.get(self.robot, "finger_state") > cfg.goal_max_finger:
            return False
        items = [*self.cubes, self.box]
        if any(state[o][2] < cfg.goal_min_z for o in items):
            return False
        ee, _ = self.ee_pose(state)
        return all(np.linalg.norm(state[o][:3] - ee) >= cfg.goal_ee_clearance for o in items)


def _xy(v: Array) -> tuple[float, float]:
    return float(v[0]), float(v[1])
