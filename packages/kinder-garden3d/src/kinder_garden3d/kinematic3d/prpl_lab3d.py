"""PrplLab3D: pick cubes off a lab's floor and raise them to its countertop (the pybullet family
upstream registers as ``PrplLab3D``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    GREY,
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

#: The lab's furniture as boxes (centre, half extents) in the lab frame: the axis-aligned
#: bounding boxes of the collision links of upstream's PRPL lab model (cabinets, doors, drawers,
#: handles, countertops, sink, stove and fridge), measured in upstream's pybullet scene; links
#: thinner than 5 mm are left out.
LAB_BOXES: tuple[tuple[Vec3, Vec3], ...] = (
    ((0.4175, -0.4003, 0.7950), (0.4195, 0.4023, 0.8870)),
    ((0.4175, -0.1550, 1.9001), (0.4205, 0.1580, 0.1510)),
    ((0.4170, -0.3210, 1.8991), (0.4200, 0.0130, 0.1500)),
    ((0.4308, -0.3460, 1.8337), (0.0742, 0.0170, 0.0061)),
    ((2.1900, -0.1619, 1.7996), (0.4570, 0.1639, 0.2505)),
    ((1.9620, -0.3210, 1.8236), (0.2290, 0.0120, 0.2245)),
    ((2.1349, -0.3460, 1.6388), (0.0061, 0.0170, 0.0742)),
    ((2.4170, -0.3210, 1.8236), (0.2290, 0.0120, 0.2245)),
    ((2.2441, -0.3460, 1.6388), (0.0061, 0.0170, 0.0742)),
    ((2.9470, -0.1619, 1.6481), (0.3040, 0.1639, 0.4020)),
    ((2.7955, -0.3210, 1.6721), (0.1525, 0.0120, 0.3760)),
    ((2.8919, -0.3460, 1.3738), (0.0061, 0.0170, 0.0742)),
    ((3.0975, -0.3210, 1.6721), (0.1525, 0.0120, 0.3760)),
    ((3.0011, -0.3460, 1.3738), (0.0061, 0.0170, 0.0742)),
    ((1.9502, -0.5902, 0.3726), (0.2315, 0.0130, 0.3569)),
    ((2.1246, -0.6152, 0.5644), (0.0061, 0.0170, 0.0742)),
    ((2.4082, -0.5902, 0.3726), (0.2315, 0.0130, 0.3569)),
    ((2.2338, -0.6152, 0.5644), (0.0061, 0.0170, 0.0742)),
    ((2.1792, -0.2940, 0.4829), (0.4605, 0.3182, 0.5772)),
    ((2.1826, -0.1435, 0.9487), (0.0402, 0.0864, 0.0409)),
    ((2.9427, -0.2947, 0.7771), (0.3070, 0.3175, 0.0505)),
    ((3.5664, -0.9324, 0.3671), (0.3170, 0.3040, 0.4605)),
    ((3.5614, -0.9324, 0.1364), (0.3029, 0.3050, 0.1208)),
    ((3.5614, -0.9324, 0.6098), (0.3029, 0.3050, 0.1208)),
    ((3.5614, -0.9324, 0.3731), (0.3029, 0.3050, 0.1208)),
    ((3.7553, -0.7495, 1.6116), (0.1639, 0.4920, 0.4030)),
    ((3.5962, -0.5040, 1.6356), (0.0120, 0.2465, 0.3770)),
    ((3.5712, -0.6944, 1.3434), (0.0170, 0.0061, 0.0742)),
    ((3.5962, -0.9940, 1.6356), (0.0120, 0.2465, 0.3770)),
    ((3.5712, -0.8036, 1.3434), (0.0170, 0.0061, 0.0742)),
    ((3.5714, -1.6225, 0.4544), (0.6918, 0.6945, 0.5510)),
    ((3.2332, -1.8857, 0.7242), (0.0311, 0.0294, 0.0382)),
    ((3.2333, -1.7957, 0.7236), (0.0311, 0.0294, 0.0382)),
    ((3.2336, -1.6194, 0.7223), (0.0311, 0.0294, 0.0382)),
    ((3.2338, -1.4444, 0.7211), (0.0311, 0.0294, 0.0382)),
    ((3.2340, -1.3544, 0.7204), (0.0311, 0.0294, 0.0382)),
    ((3.7461, -1.6224, 1.4708), (0.1716, 0.3602, 0.2288)),
    ((3.5408, -1.6134, 1.4718), (0.0682, 0.3568, 0.2284)),
    ((3.2201, -1.6219, 0.3851), (0.0631, 0.3769, 0.2879)),
    ((3.7350, -3.6786, 0.8783), (0.3947, 0.3643, 0.9923)),
    ((3.5591, -3.9462, 1.2222), (0.0364, 0.0371, 0.0379)),
    ((3.5297, -3.4253, 1.2281), (0.0429, 0.0375, 0.0402)),
    ((3.6012, -3.6918, 0.8223), (0.2033, 0.2554, 0.0183)),
    ((3.5732, -3.6955, 1.5268), (0.0502, 0.2890, 0.2149)),
    ((2.9447, -0.5935, 0.3644), (0.3232, 0.3065, 0.3516)),
    ((3.5777, -0.2942, 0.7771), (0.3320, 0.3170, 0.0505)),
    ((1.2850, -0.1550, 1.6481), (0.4520, 0.1570, 0.4020)),
    ((1.0595, -0.3210, 1.6721), (0.2265, 0.0120, 0.3760)),
    ((1.2299, -0.3460, 1.3638), (0.0061, 0.0170, 0.0742)),
    ((1.5095, -0.3210, 1.6721), (0.2275, 0.0130, 0.3770)),
    ((1.3391, -0.3460, 1.3638), (0.0061, 0.0170, 0.0742)),
    ((0.2082, -0.7685, 0.8390), (0.2113, 0.0505, 0.8420)),
    ((0.6258, -0.7685, 0.8390), (0.2113, 0.0505, 0.8420)),
    ((1.2667, -0.2952, 0.3671), (0.4580, 0.3190, 0.4615)),
    ((1.2757, -0.3204, 0.3731), (0.4580, 0.3179, 0.1208)),
    ((1.2757, -0.3204, 0.1364), (0.4580, 0.3179, 0.1208)),
    ((1.2757, -0.3204, 0.6098), (0.4580, 0.3179, 0.1208)),
)

ORANGE: Rgba = (1.0, 0.5, 0.0, 1.0)


@dataclass(frozen=True)
class PrplLab3DConfig(Kinematic3DConfig):
    """PrplLab3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        lab_pos: Position of the lab frame (its boxes are given relative to it).
        lab_boxes: The lab's furniture, (centre, half extents) per box in the lab frame.
        counter_top_z: Height of the countertop's top face.
        block_half: Half extents of every cube.
        floor_region: (x_min, x_max, y_min, y_max) where the cube centres start.
        robot_footprint_half, robot_footprint_half_z: Half extents of the base's collision box
            in upstream's robot (0.548 × 0.508 × 0.365 m at yaw 0, standing on the floor),
            which sampled cubes may not touch.
        max_sampling_attempts: Draws per cube before a reset gives up.
        goal_below_counter: A cube counts as on the counter when its centre is at least
            ``counter_top_z − goal_below_counter`` high.
        floor_collides: Make the floor a collision object (upstream has no floor body; off by
            default, the floor is only drawn).
    """

    max_action_mag: float = 0.4
    home_base_pose: tuple[float, float, float] = (0.3, 0.0, math.pi / 2)
    lab_pos: Vec3 = (-1.0, 2.0, 0.0)
    lab_boxes: tuple[tuple[Vec3, Vec3], ...] = LAB_BOXES
    counter_top_z: float = 0.8276
    block_half: Vec3 = (0.05, 0.025, 0.025)
    floor_region: tuple[float, float, float, float] = (-1.0, 1.6, -1.5, -0.2)
    robot_footprint_half: tuple[float, float] = (0.274, 0.254)
    robot_footprint_half_z: float = 0.1825
    max_sampling_attempts: int = 100_000
    goal_below_counter: float = 0.05
    floor_collides: bool = False
    camera_target: tuple[float, float, float] = (0.6, 0.3, 0.5)
    camera_distance: float = 4.2
    camera_yaw: float = -30.0
    camera_pitch: float = -35.0


class PrplLab3DEnv(Kinematic3DEnv):
    """Raise every cube from the lab's floor to countertop height and let go of it.

    ## Description
    A TidyBot++-style mobile manipulator stands at (0.3, 0) facing +y, towards a run of lab
    furniture (cabinets, drawers, countertops, a sink, a stove, a fridge) 1.2 m away;
    `num_cubes` orange 10 × 5 × 5 cm cubes lie on the floor between x = −1 and 1.6,
    y = −1.5 and −0.2, behind and beside the robot. Every cube must end up with its centre
    no lower than 5 cm below the countertop's top (z = 0.8276), not held. As upstream, a held
    cube can be released anywhere (the lab always counts as its support), so a cube let go of
    in the air stays there. Motions are collision-checked at their endpoint against the lab
    and the cubes and reverted on collision; a close command grasps when exactly one cube
    touches the end-effector marker.

    ## Observation Space
    A (26 + 12N)-D float64 vector: `robot` (19), `prpl_lab` (7), then `cube0` … (12 each), the
    order of upstream kindergarden 0.2.5. Features: `Kinematic3DRobot` (19):
    `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7, finger_state, grasp_active,
    grasp_tf_x … grasp_tf_qw`; `Kinematic3DFixture` (7): `pose_x, pose_y, pose_z, pose_qx,
    pose_qy, pose_qz, pose_qw` (the lab frame, at (−1, 2, 0)); `Kinematic3DCuboid` (12):
    `pose_x … pose_qw, grasp_active, object_type, half_extent_x, half_extent_y,
    half_extent_z`. Quaternions are ordered (x, y, z, w).

    ## Action Space
    An 11-D float32 Box: Δbase x, y, yaw and Δjoint 1..7, each bounded by ±0.4, and a gripper
    command in [−1, 1] (< −0.5 close, > 0.5 open). The base stays within ±10 m; only the arm and
    the held object are collision-checked (not the base), as upstream.

    ## Reward
    −1 on every step.

    ## Starting State
    Upstream's initial state for the same seed. Robot at (0.3, 0) with yaw π/2, arm retracted,
    gripper open. Each cube in turn (`cube0` first) lies flat on the floor (centre z = 0.025),
    axis-aligned, its centre uniform in [−1, 1.6] × [−1.5, −0.2], drawn again while it touches
    the base's 0.508 × 0.548 m footprint or a cube placed before (the lab is out of reach of
    that region).

    ## Episode End
    Terminates when no cube is held and every cube's centre is at z ≥ 0.7776 (5 cm below the
    countertop's top). The registered ids truncate after 500 steps.

    ## Arguments
    `num_cubes` (default 2), `config` (a `PrplLab3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    The lab is built from boxes: each collision link of upstream's lab model becomes its
    axis-aligned bounding box, so the furniture is slightly larger than upstream's meshes
    where they are not boxes (the sink, the stove, open doors), and collision verdicts near
    the furniture can differ. Plain colours replace upstream's textures; the floor is drawn
    but is not a body (as upstream, which has none; `floor_collides` adds one). Upstream
    registers no step limit; these ids use 500.
    Shared with every Kinematic3D env here: the robot is a primitive-shape model of the
    TidyBot++/Gen3/2F-85 (see `kinder_garden3d/robot/README.md`), not upstream's meshes; there
    is no textured background (upstream `realistic_bg`); the overview camera is ours; the grasp
    closes the pads until they touch, so `finger_state` stops at a different value than
    upstream's Robotiq linkage; collision verdicts near contact can differ with the robot's
    shapes.
    """

    def __init__(
        self,
        num_cubes: int = 2,
        config: PrplLab3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_cubes, int) or num_cubes < 1:
            raise ValueError(f"num_cubes must be an int >= 1, got {num_cubes!r}")
        self.num_cubes = num_cubes
        self.lab = Object("prpl_lab", FIXTURE_TYPE)
        self.cubes = [Object(f"cube{i}", CUBOID_TYPE) for i in range(num_cubes)]
        super().__init__(config or PrplLab3DConfig(), render_mode=render_mode)
        self.config: PrplLab3DConfig
        self._probe = BoxProbe()

    def constant_bodies(self) -> dict[str, ConstantBody]:
        return floor_bodies(self.config.floor_collides, surface=False)

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [c.name for c in self.cubes]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return [self.lab.name]

    def object_color(self, obj: Object) -> Rgba:
        return GREY if obj == self.lab else ORANGE

    def object_parts(self, state: ObjectCentricState, obj: Object) -> list[Part]:
        if obj == self.lab:
            return [Part("box", half, centre) for centre, half in self.config.lab_boxes]
        return super().object_parts(state, obj)

    def box_objects(self) -> list[Object]:
        return [self.robot, self.lab, *self.cubes]

    def base_footprint(self) -> tuple[Array, Array]:
        """Centre and half extents of the base's collision box at the home pose (its yaw is a
        multiple of π/2, so the box stays axis-aligned)."""
        cfg = self.config
        fx, fy = cfg.robot_footprint_half
        x, y, yaw = cfg.home_base_pose
        if abs(math.sin(yaw)) > 0.5:
            fx, fy = fy, fx
        half = np.array([fx, fy, cfg.robot_footprint_half_z])
        return np.array([x, y, half[2]]), half

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampler, draw for draw: each cube in order, uniform over ``floor_region``
        at a constant height, rejecting a draw that comes within ``collision_distance`` of the
        base's collision box or a cube placed before (by pybullet's query, as upstream)."""
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
            self.lab: [*cfg.lab_pos, 0.0, 0.0, 0.0, 1.0],
        }
        for cube, c in zip(self.cubes, centres, strict=True):
            features[cube] = self.cuboid_features(c, cfg.block_half)
        return ObjectCentricState.from_features(features)

    def _try_release(self, state: ObjectCentricState, held: Object, carried: list[Object]) -> None:
        """Let go wherever the cube is: upstream's lab counts as the support of any object."""
        robot = state[self.robot]
        robot[10] = 0.0
        robot[11] = 0.0
        robot[12:19] = 0.0
        state[held][7] = 0.0

    def close(self) -> None:
        """Release the pybullet clients (the scene's and the reset's box probe)."""
        self._probe.close()
        super().close()

    def goal_reached(self, state: ObjectCentricState) -> bool:
        min_z = self.config.counter_top_z - self.config.goal_below_counter
        return all(state[c][7] < 0.5 and state[c][2] >= min_z for c in self.cubes)
