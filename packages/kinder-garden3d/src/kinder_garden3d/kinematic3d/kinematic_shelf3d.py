"""KinematicShelf3D: pick blocks up from the floor and put them on a shelf (the pybullet family
upstream registers as ``KinematicShelf3D``; not the MuJoCo ``Shelf3D``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    WOOD,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Array, Part
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE, FIXTURE_TYPE
from kinder_garden3d.kinematic3d.scene import BoxProbe
from kinder_garden3d.kinematic3d.table3d import floor_bodies

Vec3 = tuple[float, float, float]

#: Block colours, cycled by index (upstream wraps its blocks in book-cover textures).
BLOCK_COLORS: tuple[Rgba, ...] = (
    (0.85, 0.25, 0.2, 1.0),
    (0.2, 0.45, 0.8, 1.0),
    (0.25, 0.65, 0.3, 1.0),
    (0.9, 0.7, 0.15, 1.0),
    (0.55, 0.3, 0.7, 1.0),
)


@dataclass(frozen=True)
class ShelfGeometry:
    """An open bookshelf: ``num_layers`` horizontal boards between two side supports.

    Board ``i``'s centre is ``i * (spacing + board_thickness)`` above the shelf frame (so board 0
    is centred on the frame), unless ``layer_offsets`` lists the board centres' heights
    explicitly. The side supports span from the bottom of board 0 to the top of the highest
    board slot, just outside the boards along x.

    Attributes:
        width, depth: Board size along x and y (m).
        board_thickness: Board height (m).
        spacing: Clear height between neighbouring boards (m).
        support_width: Thickness of each side support along x (m).
        num_layers: Number of board slots.
        omitted_layers: Board indices left out (the supports keep their full height).
    """

    width: float = 0.60198
    depth: float = 0.254
    board_thickness: float = 0.0127
    spacing: float = 0.254
    support_width: float = 0.0127
    num_layers: int = 4
    omitted_layers: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if self.num_layers < 1:
            raise ValueError(f"num_layers must be >= 1, got {self.num_layers}")
        for name in ("width", "depth", "board_thickness", "spacing", "support_width"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if set(self.omitted_layers) >= set(range(self.num_layers)):
            raise ValueError(
                f"omitted_layers {self.omitted_layers} leaves no board of {self.num_layers}"
            )

    def board_offsets(self) -> list[float]:
        """Height of each present board's centre above the shelf frame, ascending."""
        pitch = self.spacing + self.board_thickness
        return [i * pitch for i in range(self.num_layers) if i not in self.omitted_layers]

    def parts(self) -> list[Part]:
        """The boards, then the two side supports, in the shelf frame."""
        t = self.board_thickness
        board = (self.width / 2.0, self.depth / 2.0, t / 2.0)
        parts = [Part("box", board, (0.0, 0.0, z)) for z in self.board_offsets()]
        height = (self.num_layers - 1) * self.spacing + self.num_layers * t
        support = (self.support_width / 2.0, self.depth / 2.0, height / 2.0)
        x = self.width / 2.0 + self.support_width / 2.0
        z = height / 2.0 - t / 2.0
        parts += [Part("box", support, (sx, 0.0, z)) for sx in (-x, x)]
        return parts

    def surface_heights(self, shelf_z: float) -> list[float]:
        """World height of each present board's top face for a shelf frame at ``shelf_z``."""
        return [shelf_z + z + self.board_thickness / 2.0 for z in self.board_offsets()]


@dataclass(frozen=True)
class KinematicShelf3DConfig(Kinematic3DConfig):
    """KinematicShelf3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        shelf_pos: Position of the shelf frame (the centre of the bottom board).
        shelf: The shelf's boards and supports.
        block_half: Half extents of every block.
        floor_region: (x_min, x_max, y_min, y_max) where the block centres start.
        robot_footprint_half, robot_footprint_half_z: Half extents of the base's collision box
            in upstream's robot (0.548 × 0.508 × 0.365 m, standing on the floor), which sampled
            blocks may not touch.
        max_sampling_attempts: Draws per block before a reset gives up.
        gripper_open_threshold: Largest finger state at the goal (an open gripper).
        on_shelf_z_tolerance: A block counts as on the shelf when its centre is above
            ``shelf_pos.z + shelf.spacing − on_shelf_z_tolerance``.
        floor_collides: Make the floor a collision object and a surface (upstream has no floor
            body at all; off by default, the floor is only drawn).
    """

    max_action_mag: float = 0.2
    shelf_pos: Vec3 = (2.0, 2.4, 0.02)
    shelf: ShelfGeometry = ShelfGeometry()
    block_half: Vec3 = (0.05, 0.025, 0.025)
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


class KinematicShelf3DEnv(Kinematic3DEnv):
    """Pick every block up from the floor and put it on the shelf.

    ## Description
    A TidyBot++-style mobile manipulator stands at the origin among `num_cubes` 10 × 5 × 5 cm
    blocks lying on the floor; a four-board bookshelf stands 3 m away at (2.0, 2.4). Every
    block must end up on the shelf above its bottom board, with the gripper open. Blocks can be
    released only onto the shelf (within 5 mm of it): the floor is not a surface, so a grasped
    block stays in the hand until it reaches the shelf. The other blocks obstruct grasps and
    motions. Motions are collision-checked at their endpoint and reverted on collision; a
    close command grasps when exactly one block touches the end-effector marker.

    ## Observation Space
    A (26 + 12N)-D float64 vector: `robot` (19), `shelf` (7), then `cube0` … (12 each), the
    order of upstream kindergarden 0.2.5. Features: `Kinematic3DRobot` (19):
    `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7, finger_state, grasp_active,
    grasp_tf_x … grasp_tf_qw`; `Kinematic3DFixture` (7): `pose_x, pose_y, pose_z, pose_qx,
    pose_qy, pose_qz, pose_qw`; `Kinematic3DCuboid` (12): `pose_x … pose_qw, grasp_active,
    object_type, half_extent_x, half_extent_y, half_extent_z`. Quaternions are ordered
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
    apart between two 0.0127 m side supports. Each block in turn (`cube0` first) lies flat on
    the floor (centre z = 0.025), axis-aligned, its centre uniform in [−1, 1]², drawn again
    while it touches the base's 0.548 × 0.508 m footprint or a block placed before.

    ## Episode End
    Terminates when the gripper is open (finger state ≤ 0.01) and every block's centre is
    above z = 0.224 (0.05 below the second board's underside, i.e. on the shelf above the
    bottom board). The registered ids truncate after 500 steps (o5: 1000, o10: 2000, 200 a
    block: BP's plans take about 115 steps a block).

    ## Arguments
    `num_cubes` (default 2), `config` (a `KinematicShelf3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    Upstream's docs say the gripper must be closed at the goal; its code (and this env)
    requires finger state ≤ 0.01, which is the open gripper. Colours replace upstream's book and
    wood textures; the floor is drawn but is not a body (as upstream, which has none;
    `floor_collides` adds one). Upstream registers no step limit; these ids use 500 (o5: 1000,
    o10: 2000).
    Shared with every Kinematic3D env here: the robot is a primitive-shape model of the
    TidyBot++/Gen3/2F-85 (see `kinder_garden3d/robot/README.md`), not upstream's meshes; there
    is no textured background (upstream `realistic_bg`); the overview camera is placed to see
    both the robot and the shelf; the grasp closes the pads until they touch, so `finger_state`
    stops at a different value than upstream's Robotiq linkage; collision verdicts near contact
    can differ with the robot's shapes.
    """

    def __init__(
        self,
        num_cubes: int = 2,
        config: KinematicShelf3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_cubes, int) or num_cubes < 1:
            raise ValueError(f"num_cubes must be an int >= 1, got {num_cubes!r}")
        self.num_cubes = num_cubes
        self.shelf = Object("shelf", FIXTURE_TYPE)
        self.cubes = [Object(f"cube{i}", CUBOID_TYPE) for i in range(num_cubes)]
        super().__init__(config or KinematicShelf3DConfig(), render_mode=render_mode)
        self.config: KinematicShelf3DConfig
        self._probe = BoxProbe()

    def constant_bodies(self) -> dict[str, ConstantBody]:
        return floor_bodies(self.config.floor_collides)

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [b.name for b in self.cubes]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return [*super().surface_names(state), self.shelf.name]

    def object_color(self, obj: Object) -> Rgba:
        if obj == self.shelf:
            return WOOD
        return BLOCK_COLORS[self.cubes.index(obj) % len(BLOCK_COLORS)]

    def object_parts(self, state: ObjectCentricState, obj: Object) -> list[Part]:
        if obj == self.shelf:
            return self.config.shelf.parts()
        return super().object_parts(state, obj)

    def box_objects(self) -> list[Object]:
        return [self.robot, self.shelf, *self.cubes]

    def base_footprint(self) -> tuple[Array, Array]:
        """Centre and half extents of the base's collision box at the home pose."""
        cfg = self.config
        fx, fy = cfg.robot_footprint_half
        half = np.array([fx, fy, cfg.robot_footprint_half_z])
        return np.array([cfg.home_base_pose[0], cfg.home_base_pose[1], half[2]]), half

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampler, draw for draw: each block in order, uniform over ``floor_region``
        at a constant height, rejecting a draw that comes within ``collision_distance`` of the
        base's collision box or a block placed before (by pybullet's query, as upstream)."""
        cfg = self.config
        centres = self._probe.place_boxes(
            rng,
            len(self.cubes),
            cfg.floor_region,
            np.array(cfg.block_half),
            [self.base_footprint()],
            cfg.collision_distance,
            cfg.max_sampling_attempts,
        )
        if centres is None:
            raise self._reset_error("a collision-free floor position")
        features = {
            self.robot: self.robot_features(),
            self.shelf: [*cfg.shelf_pos, 0.0, 0.0, 0.0, 1.0],
        }
        for cube, c in zip(self.cubes, centres, strict=True):
            features[cube] = self.cuboid_features(c, cfg.block_half)
        return ObjectCentricState.from_features(features)

    def close(self) -> None:
        """Release the pybullet clients (the scene's and the reset's box probe)."""
        self._probe.close()
        super().close()

    def goal_reached(self, state: ObjectCentricState) -> bool:
        cfg = self.config
        if state.get(self.robot, "finger_state") > cfg.gripper_open_threshold:
            return False
        min_z = cfg.shelf_pos[2] + cfg.shelf.spacing - cfg.on_shelf_z_tolerance
        return all(state[b][2] >= min_z for b in self.cubes)
