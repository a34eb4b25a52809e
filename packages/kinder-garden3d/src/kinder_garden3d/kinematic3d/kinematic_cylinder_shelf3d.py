"""KinematicCylinderShelf3D: stand tall cylinders from the floor on a shelf (the pybullet family
upstream registers as ``KinematicCylinderShelf3D``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    WOOD,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Part, rect_distance_2d
from kinder_garden3d.kinematic3d.kinematic_shelf3d import ShelfGeometry
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, FIXTURE_TYPE
from kinder_garden3d.kinematic3d.table3d import floor_bodies

Vec3 = tuple[float, float, float]

#: The ``object_type`` feature of a cylinder (upstream's value; solid cuboids have −1).
CYLINDER = 1.0


@dataclass(frozen=True)
class KinematicCylinderShelf3DConfig(Kinematic3DConfig):
    """KinematicCylinderShelf3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        shelf_pos: Position of the shelf frame (the centre of the bottom board).
        shelf: The shelf's boards and supports.
        cylinder_radius: Radius of every cylinder.
        cylinder_heights: Heights, cycled by cylinder index.
        cylinder_colors: Colours, cycled by cylinder index.
        floor_region: (x_min, x_max, y_min, y_max) where the cylinder centres start.
        robot_footprint_half, robot_footprint_half_z: Half extents of the base's collision box
            in upstream's robot (0.548 × 0.508 × 0.365 m, standing on the floor), which sampled
            cylinders may not touch.
        max_sampling_attempts: Draws per cylinder before a reset gives up.
        gripper_open_threshold: Largest finger state at the goal (an open gripper).
        on_shelf_z_tolerance: Largest distance between a placed cylinder's centre height and
            its resting height on some board.
        floor_collides: Make the floor a collision object and a surface (upstream has no floor
            body at all; off by default, the floor is only drawn).
    """

    max_action_mag: float = 0.2
    shelf_pos: Vec3 = (2.0, 2.4, 0.02)
    shelf: ShelfGeometry = field(default_factory=ShelfGeometry)
    cylinder_radius: float = 0.03
    cylinder_heights: tuple[float, ...] = (0.20, 0.15, 0.175)
    cylinder_colors: tuple[Rgba, ...] = (
        (0.8, 0.2, 0.2, 1.0),
        (0.2, 0.5, 0.8, 1.0),
        (0.2, 0.7, 0.3, 1.0),
        (0.8, 0.6, 0.2, 1.0),
        (0.6, 0.3, 0.7, 1.0),
    )
    floor_region: tuple[float, float, float, float] = (-1.0, 1.0, -1.0, 1.0)
    robot_footprint_half: tuple[float, float] = (0.274, 0.254)
    robot_footprint_half_z: float = 0.1825
    max_sampling_attempts: int = 100_000
    gripper_open_threshold: float = 0.01
    on_shelf_z_tolerance: float = 0.05
    floor_collides: bool = False
    camera_target: tuple[float, float, float] = (0.9, 1.1, 0.2)
    camera_distance: float = 3.6
    camera_yaw: float = 20.0
    camera_pitch: float = -40.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.cylinder_radius > 0:
            raise ValueError(f"cylinder_radius must be > 0, got {self.cylinder_radius}")
        if not self.cylinder_heights or min(self.cylinder_heights) <= 0:
            raise ValueError(f"cylinder_heights must be positive, got {self.cylinder_heights}")
        if not self.cylinder_colors:
            raise ValueError("cylinder_colors must name at least one colour")

    def cylinder_height(self, index: int) -> float:
        """Height of cylinder ``index``."""
        return self.cylinder_heights[index % len(self.cylinder_heights)]


class KinematicCylinderShelf3DEnv(Kinematic3DEnv):
    """Stand every tall cylinder from the floor upright on a shelf board.

    ## Description
    A TidyBot++-style mobile manipulator stands at the origin among `num_cylinders` upright
    cylinders (radius 3 cm; heights 20, 15 and 17.5 cm, cycled) on the floor; a four-board
    bookshelf stands 3 m away at (2.0, 2.4). Every cylinder must end up standing on one of
    the shelf's boards, inside its footprint, with the gripper open. The cylinders are meant
    to be grasped from the side (any horizontal approach angle works: they are round), so that
    they can stand upright between the boards. The grasp rule is nevertheless the shared one,
    as in upstream: a close command grasps when exactly one object touches the end-effector
    marker, the fingers close until they touch it, and the grasp is undone if the robot then
    collides; nothing checks the approach direction, so a grasp from above the top also holds.
    Cylinders can be released only onto the shelf (within 5 mm of it). Motions are
    collision-checked at their endpoint and reverted on collision.

    ## Observation Space
    A (26 + 12N)-D float64 vector: `robot` (19), `shelf` (7), then `cylinder0` … (12 each),
    the order of upstream kindergarden 0.2.5. Features: `Kinematic3DRobot` (19):
    `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7, finger_state, grasp_active,
    grasp_tf_x … grasp_tf_qw`; `Kinematic3DFixture` (7): `pose_x, pose_y, pose_z, pose_qx,
    pose_qy, pose_qz, pose_qw`; `Kinematic3DCuboid` (12): `pose_x … pose_qw, grasp_active,
    object_type, half_extent_x, half_extent_y, half_extent_z`. A cylinder has object_type 1
    and half extents (radius, radius, height / 2), as upstream. Quaternions are ordered
    (x, y, z, w).

    ## Action Space
    An 11-D float32 Box: Δbase x, y, yaw and Δjoint 1..7, each bounded by ±0.2, and a gripper
    command in [−1, 1] (< −0.5 close, > 0.5 open). The base stays within ±10 m; only the arm and
    the held object are collision-checked (not the base), as upstream.

    ## Reward
    −1 on every step.

    ## Starting State
    Upstream's initial state for the same seed. Robot at the origin, arm retracted, gripper
    open. The shelf frame is at (2.0, 2.4, 0.02): four 0.602 × 0.254 × 0.0127 m boards 0.254 m
    apart between two 0.0127 m side supports. Each cylinder in turn (`cylinder0` first) stands
    upright on the floor, its centre uniform in [−1, 1]², drawn again while it touches the
    base's 0.548 × 0.508 m footprint or a cylinder placed before.

    ## Episode End
    Terminates when the gripper is open (finger state ≤ 0.01) and every cylinder's centre lies
    within the shelf's footprint (|x − 2.0| ≤ 0.301, |y − 2.4| ≤ 0.127) at a height within
    0.05 m of its resting height on some board (board top + height / 2). The registered ids
    truncate after 500 steps.

    ## Arguments
    `num_cylinders` (default 1), `config` (a `KinematicCylinderShelf3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    Upstream's docs say the gripper must be closed at the goal; its code (and this env)
    requires finger state ≤ 0.01, which is the open gripper. Its docs also say a side grasp is
    required; its code (and this env) accepts any grasp the shared rule accepts. Upstream's
    optional staging boxes,
    per-cylinder radii and start regions and explicit board layouts (all off in its registered
    ids) are not offered; the shelf's `omitted_layers` is. Colours replace upstream's wood
    texture; the floor is drawn but is not a body (as upstream, which has none;
    `floor_collides` adds one). Upstream registers no step limit; these ids use 500. Starting
    cylinders are rejected by an exact circle-and-box test where upstream asks pybullet (which
    can differ within about 0.1 mm of contact).
    Shared with every Kinematic3D env here: the robot is a primitive-shape model of the
    TidyBot++/Gen3/2F-85 (see `kinder_garden3d/robot/README.md`), not upstream's meshes; there
    is no textured background (upstream `realistic_bg`); the overview camera is placed to see
    both the robot and the shelf; the grasp closes the pads until they touch, so `finger_state`
    stops at a different value than upstream's Robotiq linkage; collision verdicts near contact
    can differ with the robot's shapes.
    """

    def __init__(
        self,
        num_cylinders: int = 1,
        config: KinematicCylinderShelf3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_cylinders, int) or num_cylinders < 1:
            raise ValueError(f"num_cylinders must be an int >= 1, got {num_cylinders!r}")
        self.num_cylinders = num_cylinders
        self.shelf = Object("shelf", FIXTURE_TYPE)
        self.cylinders = [Object(f"cylinder{i}", CUBOID_TYPE) for i in range(num_cylinders)]
        super().__init__(config or KinematicCylinderShelf3DConfig(), render_mode=render_mode)
        self.config: KinematicCylinderShelf3DConfig

    def constant_bodies(self) -> dict[str, ConstantBody]:
        return floor_bodies(self.config.floor_collides)

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [c.name for c in self.cylinders]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return [*super().surface_names(state), self.shelf.name]

    def object_color(self, obj: Object) -> Rgba:
        if obj == self.shelf:
            return WOOD
        colors = self.config.cylinder_colors
        return colors[self.cylinders.index(obj) % len(colors)]

    def object_parts(self, state: ObjectCentricState, obj: Object) -> list[Part]:
        if obj == self.shelf:
            return self.config.shelf.parts()
        f = state[obj]
        if f[8] == CYLINDER:
            return [Part("cylinder", (float(f[9]), float(f[11])))]
        return super().object_parts(state, obj)

    def box_objects(self) -> list[Object]:
        return [self.robot, self.shelf, *self.cylinders]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampler, draw for draw: each cylinder in order, uniform over
        ``floor_region`` at its standing height, rejecting a draw that comes within
        ``collision_distance`` of the base's collision box or a cylinder placed before."""
        cfg = self.config
        x0, x1, y0, y1 = cfg.floor_region
        r, dist = cfg.cylinder_radius, cfg.collision_distance
        fx, fy = cfg.robot_footprint_half
        base_xy = (cfg.home_base_pose[0], cfg.home_base_pose[1])
        placed: list[tuple[float, float]] = []
        features: dict[Object, list[float]] = {
            self.robot: self.robot_features(),
            self.shelf: [*cfg.shelf_pos, 0.0, 0.0, 0.0, 1.0],
        }
        for i, cylinder in enumerate(self.cylinders):
            # Every cylinder and the base box stand on the floor, so their heights overlap and
            # contact is decided in the plane.
            half_h = cfg.cylinder_height(i) / 2.0
            for _ in range(cfg.max_sampling_attempts):
                x, y, _z = (float(v) for v in rng.uniform((x0, y0, half_h), (x1, y1, half_h)))
                if rect_distance_2d((x, y), (0.0, 0.0), base_xy, (fx, fy)) <= r + dist:
                    continue
                if any(math.hypot(x - px, y - py) <= 2.0 * r + dist for px, py in placed):
                    continue
                break
            else:
                raise self._reset_error("a collision-free floor position")
            placed.append((x, y))
            features[cylinder] = self.cuboid_features((x, y, half_h), (r, r, half_h), CYLINDER)
        return ObjectCentricState.from_features(features)

    def goal_reached(self, state: ObjectCentricState) -> bool:
        cfg = self.config
        if state.get(self.robot, "finger_state") > cfg.gripper_open_threshold:
            return False
        sx, sy, sz = cfg.shelf_pos
        surfaces = cfg.shelf.surface_heights(sz)
        for i, cylinder in enumerate(self.cylinders):
            x, y, z = (float(v) for v in state[cylinder][:3])
            if abs(x - sx) > cfg.shelf.width / 2.0 or abs(y - sy) > cfg.shelf.depth / 2.0:
                return False
            rest = cfg.cylinder_height(i) / 2.0
            if not any(abs(z - (top + rest)) <= cfg.on_shelf_z_tolerance for top in surfaces):
                return False
        return True
