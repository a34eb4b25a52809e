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
from kinder_garden3d.kinematic3d.geometry import Part, quat_to_matrix, rects_overlap_2d
from kinder_garden3d.kinematic3d.object_types import CUBOID_TYPE
from kinder_garden3d.kinematic3d.scene import BodySpec

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
        max_overhang: Largest overhang of an obstruction past the region edge, as a fraction of
            its own footprint.
        placement_margin: Clearance kept between sampled objects.
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
    placement_margin: float = 0.005
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
    Robot at (−0.12, 0, 0) with base height −0.4, arm retracted, gripper open. Table centre
    (0.3, 0, −0.175), half extents (0.2, 0.4, 0.25). The region's half extents are uniform in
    [(0.02, 0.02, 0.005), (0.05, 0.05, 0.005)], and it lies fully on the table top. The block
    has 0.8 × the region's x/y half extents, half height 0.025, and lies on the table without
    touching the region. Each obstruction has half extents uniform in
    [(0.01, 0.01, 0.01), (0.02, 0.02, 0.03)] and starts on the region (probability 0.9, with at
    most 25 % overhang) or elsewhere on the table. All objects are axis-aligned and
    collision-free.

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
    robot self-collisions are not checked; touching counts as a collision only past 0.1 mm of
    penetration.
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
        cfg = self.config
        tx, ty, tz = cfg.table_pos
        thx, thy, thz = cfg.table_half
        top = tz + thz
        margin = cfg.placement_margin

        def on_table(hx: float, hy: float) -> tuple[float, float]:
            return (
                float(rng.uniform(tx - thx + hx, tx + thx - hx)),
                float(rng.uniform(ty - thy + hy, ty + thy - hy)),
            )

        for _ in range(cfg.max_reset_tries):
            rh = rng.uniform(cfg.region_half_low, cfg.region_half_high)
            rxy = on_table(rh[0], rh[1])
            bh = np.array([rh[0] * cfg.block_scale, rh[1] * cfg.block_scale, cfg.block_half_z])
            bxy = on_table(bh[0], bh[1])
            if rects_overlap_2d(bxy, (bh[0], bh[1]), rxy, (rh[0], rh[1]), margin):
                continue
            placed: list[tuple[tuple[float, float], tuple[float, float], float, float]] = [
                (rxy, (rh[0], rh[1]), top, top + 2 * rh[2]),
                (bxy, (bh[0], bh[1]), top, top + 2 * bh[2]),
            ]
            obstructions = []
            ok = True
            for _o in self.obstructions:
                oh = rng.uniform(cfg.obstruction_half_low, cfg.obstruction_half_high)
                on_region = rng.uniform() < cfg.on_region_prob
                for _try in range(50):
                    if on_region:
                        slack = 2 * cfg.max_overhang * oh[:2]  # 25 % of the footprint
                        lim = np.maximum(rh[:2] - oh[:2] + slack, 0.0)
                        oxy = (
                            float(rxy[0] + rng.uniform(-lim[0], lim[0])),
                            float(rxy[1] + rng.uniform(-lim[1], lim[1])),
                        )
                        base = top + 2 * rh[2]
                    else:
                        oxy = on_table(oh[0], oh[1])
                        base = top
                    z0, z1 = base, base + 2 * oh[2]
                    clash = any(
                        rects_overlap_2d(oxy, (oh[0], oh[1]), c, h, margin)
                        and z0 < pz1 - 1e-9
                        and pz0 < z1 - 1e-9
                        for c, h, pz0, pz1 in placed
                    )
                    # Obstructions must also keep off the region unless they stand on it.
                    if base == top and rects_overlap_2d(oxy, (oh[0], oh[1]), rxy, (rh[0], rh[1])):
                        clash = True
                    if not clash:
                        placed.append((oxy, (oh[0], oh[1]), z0, z1))
                        obstructions.append(((oxy[0], oxy[1], base + oh[2]), oh))
                        break
                else:
                    ok = False
                    break
            if not ok:
                continue
            features = {
                self.robot: self.robot_features(),
                self.region: self.cuboid_features((rxy[0], rxy[1], top + rh[2]), rh),
                self.block: self.cuboid_features((bxy[0], bxy[1], top + bh[2]), bh),
            }
            for obj, (pos, oh) in zip(self.obstructions, obstructions, strict=True):
                features[obj] = self.cuboid_features(pos, oh)
            return ObjectCentricState.from_features(features)
        raise self._reset_error("a collision-free table layout")

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
