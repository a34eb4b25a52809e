"""Obstruction3D: clear a target region and place a block on it (environments.md §4.3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden3d.kinematic3d.base_env import (
    PURPLE,
    RED,
    WOOD,
    ConstantBody,
    Kinematic3DConfig,
    Kinematic3DEnv,
    Rgba,
)
from kinder_garden3d.kinematic3d.geometry import Array, Part, quat_to_matrix
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE
from kinder_garden3d.kinematic3d.scene import BodySpec, BoxProbe

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Obstruction3DConfig(Kinematic3DConfig):
    """Obstruction3D settings (see :class:`Kinematic3DConfig` for the shared ones).

    Attributes:
        table_pos, table_half: The constant table (centre, half extents).
        region_half_low, region_half_high: Uniform range of the target region's half extents.
        block_scale: Block half extents in x and y as a fraction of the region's.
        block_half_z: Block half height.
        obstruction_half_low, obstruction_half_high: Uniform range of obstruction half extents.
        on_region_prob: Probability that an obstruction starts on the region.
        max_overhang: How far an obstruction's centre may lie past the region's edge, as a
            fraction of the obstruction's half extent.
        max_sampling_attempts: Draws per object before a reset gives up.
    """

    max_action_mag: float = 0.2
    max_collision_check_step: float | None = 0.005
    base_z: float = -0.4
    home_base_pose: tuple[float, float, float] = (-0.12, 0.0, 0.0)
    table_pos: Vec3 = (0.3, 0.0, -0.175)
    table_half: Vec3 = (0.2, 0.4, 0.25)
    region_half_low: Vec3 = (0.02, 0.02, 0.005)
    region_half_high: Vec3 = (0.05, 0.05, 0.005)
    block_scale: float = 0.8
    block_half_z: float = 0.025
    obstruction_half_low: Vec3 = (0.01, 0.01, 0.01)
    obstruction_half_high: Vec3 = (0.02, 0.02, 0.03)
    on_region_prob: float = 0.9
    max_overhang: float = 0.25
    max_sampling_attempts: int = 100_000
    camera_target: tuple[float, float, float] = (0.2, 0.0, -0.05)
    camera_distance: float = 1.3
    camera_pitch: float = -40.0


class Obstruction3DEnv(Kinematic3DEnv):
    """Place a block on a target region that obstructions may cover.

    ## Description
    A TidyBot++-style mobile manipulator stands at the edge of a table (the base is sunk so the
    arm mount is level with the table top). On the table lies a thin purple target region and a
    purple target block; `num_obstructions` small red boxes sit mostly on top of the region.
    The robot must pick up the block and put it down on the region, which usually requires
    moving the obstructions out of the way first. Grasping, releasing and collision checking
    follow the shared Kinematic3D mechanics: a close command grasps when exactly one movable
    object touches the end-effector marker; an open command releases only when the held object
    is within 5 mm of a surface (the table or the region); every motion is swept in 0.005
    increments and reverted on collision.

    ## Observation Space
    A (43 + 12N)-D float64 vector: `robot` (19), `target_region` (12), `target_block` (12), then
    the obstructions `obstruction0` … (12 each, sorted by name). Features:
    `Kinematic3DRobot` (19): `pos_base_x, pos_base_y, pos_base_rot, joint_1..joint_7,
    finger_state, grasp_active, grasp_tf_x … grasp_tf_qw`; `Kinematic3DCuboid` (12):
    `pose_x, pose_y, pose_z, pose_qx, pose_qy, pose_qz, pose_qw, grasp_active, object_type,
    half_extent_x, half_extent_y, half_extent_z`. Quaternions are ordered (x, y, z, w). The
    table is constant and not observed.

    ## Action Space
    An 11-D float32 Box: Δbase x, y, yaw and Δjoint 1..7, each bounded by ±0.2, and a gripper
    command in [−1, 1] (< −0.5 close, > 0.5 open).

    ## Reward
    −1 on every step.

    ## Starting State
    Upstream's initial state for the same seed. Robot at (−0.12, 0, 0) with base height −0.4,
    arm retracted, gripper open. Table centre (0.3, 0, −0.175), half extents (0.2, 0.4, 0.25).
    The region's half extents are uniform in [(0.02, 0.02, 0.005), (0.05, 0.05, 0.005)], and it
    lies fully on the table top. The block
    has 0.8 × the region's x/y half extents, half height 0.025, and lies on the table without
    touching the region. Each obstruction has half extents uniform in
    [(0.01, 0.01, 0.01), (0.02, 0.02, 0.03)] and starts on the region (a coin of probability 0.9
    per try; its centre may lie up to 25 % of its half extents past the region's edge) or
    elsewhere on the table off the region. All objects are axis-aligned and touch nothing but
    their support.

    ## Episode End
    Terminates when nothing is held and the block rests on the region: in the region's frame
    |z_block − z_region − (h_region + h_block)| ≤ 5 mm and all four bottom corners of the block
    lie within the region's half extents + 5 mm. The registered ids truncate after 500 steps.

    ## Arguments
    `num_obstructions` (default 2), `config` (an `Obstruction3DConfig`), `render_mode`.

    ## Version History
    * v0: first release in kinder-garden3d.

    ## Deviations
    Objects are sampled axis-aligned. Upstream registers no step limit; these ids use 500.
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
        num_obstructions: int = 2,
        config: Obstruction3DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if not isinstance(num_obstructions, int) or num_obstructions < 0:
            raise ValueError(f"num_obstructions must be an int >= 0, got {num_obstructions!r}")
        self.num_obstructions = num_obstructions
        self.region = Object("target_region", CUBOID_TYPE)
        self.block = Object("target_block", CUBOID_TYPE)
        self.obstructions = [
            Object(f"obstruction{i}", CUBOID_TYPE) for i in range(num_obstructions)
        ]
        super().__init__(config or Obstruction3DConfig(), render_mode=render_mode)
        self.config: Obstruction3DConfig
        self._probe = BoxProbe()

    def constant_bodies(self) -> dict[str, ConstantBody]:
        cfg = self.config
        table = BodySpec((Part("box", cfg.table_half),), WOOD)
        return {"table": ConstantBody(table, cfg.table_pos)}

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        return [self.block.name, *(o.name for o in self.obstructions)]

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        return ["table", self.region.name]

    def object_color(self, obj: Object) -> Rgba:
        return PURPLE if obj in (self.region, self.block) else RED

    def box_objects(self) -> list[Object]:
        return [self.robot, self.region, self.block, *sorted(self.obstructions)]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampler, draw for draw: the region's half extents and its pose on the
        table; the block's pose until it keeps off the region; then per obstruction its half
        extents and, until it touches nothing, a coin (``on_region_prob``) and a pose on the
        region (overhanging its edge by up to ``max_overhang`` of its own half extents) or on
        the table (then also off the region). Touching means within ``collision_distance``."""
        cfg = self.config
        table_c, table_h = np.array(cfg.table_pos), np.array(cfg.table_half)

        def on_top_of(c: Array, h: Array, half: Array, overhang: float) -> Array:
            lo = c - h - half * overhang
            hi = c + h + half * overhang
            z = c[2] + h[2] + half[2]
            if overhang == 0.0:
                lo, hi = c - h + half, c + h - half
            return rng.uniform((lo[0], lo[1], z), (hi[0], hi[1], z))

        def touches(c1: Array, h1: Array, c2: Array, h2: Array) -> bool:
            # pybullet's query decides, as upstream's (it misses sub-0.1 mm overlaps).
            return self._probe.touch(c1, h1, c2, h2, cfg.collision_distance)

        rh = rng.uniform(cfg.region_half_low, cfg.region_half_high)
        rc = on_top_of(table_c, table_h, rh, 0.0)
        bh = np.array([rh[0] * cfg.block_scale, rh[1] * cfg.block_scale, cfg.block_half_z])
        for _ in range(cfg.max_sampling_attempts):
            bc = on_top_of(table_c, table_h, bh, 0.0)
            if not touches(bc, bh, rc, rh):
                break
        else:
            raise self._reset_error("a block pose off the region")
        placed: list[tuple[Array, Array]] = []
        for _o in self.obstructions:
            oh = rng.uniform(cfg.obstruction_half_low, cfg.obstruction_half_high)
            for _ in range(cfg.max_sampling_attempts):
                others = [(bc, bh), *placed]
                if rng.uniform() < cfg.on_region_prob:
                    oc = on_top_of(rc, rh, oh, cfg.max_overhang)
                else:
                    oc = on_top_of(table_c, table_h, oh, 0.0)
                    others.append((rc, rh))
                if not any(touches(oc, oh, c, h) for c, h in others):
                    placed.append((oc, oh))
                    break
            else:
                raise self._reset_error("an obstruction pose")
        features = {
            self.robot: self.robot_features(),
            self.region: self.cuboid_features(rc, rh),
            self.block: self.cuboid_features(bc, bh),
        }
        for obj, (oc, oh) in zip(self.obstructions, placed, strict=True):
            features[obj] = self.cuboid_features(oc, oh)
        return ObjectCentricState.from_features(features)

    def close(self) -> None:
        """Release the pybullet clients (the scene's and the reset's box probe)."""
        self._probe.close()
        super().close()

    def goal_reached(self, state: ObjectCentricState) -> bool:
        if state.get(self.robot, "grasp_active") > 0.5:
            return False
        return block_on_region(
            state[self.block], state[self.region], self.config.min_placement_dist
        )


def block_on_region(block: np.ndarray, region: np.ndarray, tol: float) -> bool:
    """Whether a block (cuboid features) rests on a region (cuboid features)."""
    rrot = quat_to_matrix(region[3:7])
    local = rrot.T @ (block[:3] - region[:3])
    if abs(local[2] - (region[11] + block[11])) > tol:
        return False
    brot = quat_to_matrix(block[3:7])
    hx, hy, hz = block[9:12]
    corners = np.array([[sx * hx, sy * hy, -hz] for sx in (-1, 1) for sy in (-1, 1)])
    world = corners @ brot.T + block[:3]
    local_corners = (world - region[:3]) @ rrot
    return bool(np.all(np.abs(local_corners[:, :2]) <= region[9:11] + tol))
