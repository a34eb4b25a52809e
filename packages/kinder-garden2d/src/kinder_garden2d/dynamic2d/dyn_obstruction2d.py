"""DynObstruction2D: place a block on a target surface that other blocks may cover (pymunk)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinder_core import Object, ObjectCentricState, ObjectCentricStateSpace
from kinder_core.state import FloatArray, StateLayout
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.base_env import (
    Dynamic2DEnv,
    KinRobotConfig,
    object_values,
    resolve_config,
    upstream_walls,
)
from kinder_garden2d.dynamic2d.geometry import (
    RECT_FEATURES,
    BoolArray,
    WorldShape,
    are_on,
    is_on,
    kin_robot_geometry,
    overlaps,
    place,
    rect_polys,
    rect_shape,
    transform,
)
from kinder_garden2d.dynamic2d.pd_physics import (
    CT_ARM,
    CT_FINGER,
    CT_ROBOT,
    BodySpec,
    PDSettings,
    dynamic_rect,
    static_rect,
)
from kinder_garden2d.dynamic2d.physics import Scene, StaticBox
from kinder_garden2d.rendering import Canvas

GOLDEN = (1 + math.sqrt(5)) / 2


@dataclass(frozen=True)
class DynObstruction2DConfig(KinRobotConfig):
    """Constants of DynObstruction2D (defaults follow the upstream environment)."""

    world_max_x: float = 2 * GOLDEN  # 1 + √5 ≈ 3.236
    world_max_y: float = 2.0
    gravity: float = -9.8
    damping: float = 1.0
    table_height: float = 0.1
    table_color: tuple[float, float, float] = (0.75, 0.75, 0.75)
    block_width: tuple[float, float] = (0.16, 0.48)
    block_height: tuple[float, float] = (0.24, 0.48)
    block_mass: float = 1.0
    surface_padding: tuple[float, float] = (0.048, 0.12)  # surface width = block width + this
    obstruction_overlap_prob: float = 0.9
    # The robot's initial pose: x, y and θ uniform in these ranges (rejected if it collides).
    robot_init_x: tuple[float, float] = (0.2, 0.8)
    robot_init_y: tuple[float, float] = (0.2, 0.8)
    robot_init_theta: tuple[float, float] = (-math.pi / 2, math.pi / 2)
    goal_tolerance: float = 0.025
    settle_max_seconds: float = 1.0
    init_robot_pos: tuple[float, float] = (0.5, 0.5)  # where upstream creates the robot's bodies


class DynObstruction2DEnv(Dynamic2DEnv):
    """Put the target block on the target surface; obstructions may sit on the surface.

    ## Description
    A side view with gravity. A two-finger robot (floating base, prismatic arm, gripper) must
    place the purple target block so that it rests on the purple target surface, a strip of the
    grey table. Red obstruction blocks often stand on the surface; the robot may pick them up and
    put them elsewhere, or push them away. All blocks are dynamic pymunk bodies (mass 1) that fall,
    slide and topple; a block wider than the open fingers' inner gap (0.26) cannot be grasped.

    Transitions are upstream kindergarden 0.2.5's (see
    :mod:`~kinder_garden2d.dynamic2d.pd_physics`): an action sets a target pose (the deltas added
    to the current pose; arm and gap clipped to their ranges) and a PD controller (gains 50/5)
    drives the robot's kinematic bodies towards it for 1 s of simulated time (10 control steps of
    10 physics steps of 0.01 s), so the robot covers about 97% of a step and keeps a residual
    velocity, which the velocity features report and the next action's controller starts from. A
    robot part touching the table or a wall puts the robot back where that control step began, at
    rest. Closing fingers grasp a block when a left-finger contact's normal is within 0.1 rad of
    the closing direction, the block's centre lies between the fingers and the contact point lies
    on the first half of the fingers; the block then follows the gripper rigidly until the fingers
    open.

    ## Observation Space
    Object-centric states with objects `target_surface` (`target_surface`, 14 features),
    `target_block` (`target_block`, 15), `obstruction0..N-1` (`dyn_rectangle`, 15 each) and `robot`
    (`kin_robot`, 24). The Box view lists them in that order (the robot last, as upstream):
    14 + 15 + 15N + 24 values (68 for o1), unbounded as upstream's. Positions are body centres;
    angles are pymunk's (not wrapped), as upstream reports them.

    ## Action Space
    `[dx, dy, dtheta, darm, dgripper]` (float64): base translation (±0.05) and rotation (±π/16),
    arm extension change (±0.1, the arm stays within [base_radius, arm_length]) and finger-gap
    change (±0.02, positive opens; the gap stays within [2·finger_height, gripper_base_height]).
    Out-of-bound actions are clipped.

    ## Reward
    −1 per step.

    ## Starting State
    Upstream's sampling, draw for draw (the same seed gives upstream's initial state): the robot
    at x, y ∈ [0.2, 0.8], θ ∈ [−π/2, π/2] (arm retracted, fingers open); the target block (width
    U[0.16, 0.48], height U[0.24, 0.48]) and N obstructions (same ranges) 0.05 above the table,
    centres in [0.24, 3.0]; the target surface as wide as the block plus U[0.048, 0.12]; each
    obstruction over the surface with probability 0.9. Draws where anything overlaps, or the
    surface leaves the table, are redrawn. The blocks then fall and settle for 1 s (robot still);
    the state is read back from the simulation, residual velocities included.

    ## Episode End
    Terminates when the target block is on the target surface: its two lowest corners, moved
    down by 0.025, lie inside the surface. Truncated after 500 steps by the registered TimeLimit.

    ## Arguments
    * `num_obstructions` (default 2): number of red obstruction blocks.
    * `config`: a `DynObstruction2DConfig` or a mapping of field overrides (world size, physics,
      controller, robot geometry, sampling ranges).

    ## Deviations
    * Each transition is computed from the observed state alone (a fresh pymunk space per action,
      built as upstream builds it when reset from a state), so `set_state` replays exactly; it
      equals upstream's reload-then-step to 1e-9. Upstream's uninterrupted runs also carry
      Chipmunk's cached contact impulses between actions, which its state vector lacks.
    * Kept option, off by default: `controller="linear"` moves the robot exactly by the commanded
      deltas over 0.1 s (five 0.02 s substeps), reports the commanded average velocity and stops
      the robot at a static contact; it also discards transitions that leave an object outside
      the world or faster than 20 m/s (`env.num_physics_reverts`).

    ## References
    KinDER (RSS 2026), the Dynamic2D environments; pymunk (Chipmunk2D).

    ## Version History
    * v0: initial version.
    """

    has_pd = True

    def __init__(
        self,
        num_obstructions: int = 2,
        config: DynObstruction2DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = resolve_config(DynObstruction2DConfig, config)
        super().__init__(cfg, render_mode)
        if int(num_obstructions) != num_obstructions or num_obstructions < 0:
            raise ValueError(f"num_obstructions must be an int >= 0, got {num_obstructions!r}")
        self.config: DynObstruction2DConfig = cfg
        self.num_obstructions = int(num_obstructions)
        self.robot = Object("robot", ot.KIN_ROBOT)
        self.target_surface = Object("target_surface", ot.TARGET_SURFACE)
        self.target_block = Object("target_block", ot.TARGET_BLOCK)
        self.obstructions = [
            Object(f"obstruction{i}", ot.DYN_RECTANGLE) for i in range(self.num_obstructions)
        ]
        self.action_space = cfg.action_space()
        self.observation_space = ObjectCentricStateSpace([ot.DYNAMIC2D_OBJECT, ot.KIN_ROBOT])
        table = StaticBox(cfg.world_min_x, cfg.world_max_x, 0.0, cfg.table_height)
        self.static_colors = ((table, cfg.table_color),)
        blocks = (self.target_block, *self.obstructions)
        self.scene = Scene(
            settings=cfg.physics(),
            statics=(*cfg.walls(), table),
            robot=self.robot,
            objects=blocks,
            graspable=frozenset(blocks),
        )

    def box_objects(self) -> list[Object]:
        objs = sorted(
            [self.target_surface, self.target_block, *self.obstructions], key=lambda o: o.name
        )
        # Upstream's order: target surface, target block, obstructions (by name), robot last.
        return (
            [self.target_surface, self.target_block]
            + [o for o in objs if o not in (self.target_surface, self.target_block)]
            + [self.robot]
        )

    # -- sampling (upstream's procedure, draw for draw) ---------------------------------------
    def _sample_unsettled(self, rng: np.random.Generator) -> ObjectCentricState:
        """One candidate scene, drawn as upstream draws it, or a rejected one (see
        :meth:`_valid_unsettled`)."""
        cfg = self.config
        w_world = cfg.world_max_x - cfg.world_min_x
        table_y = cfg.world_min_y + cfg.table_height / 2
        block_y = table_y + cfg.table_height + 1e-6  # upstream's block pose y (bottom edge)
        r = cfg.robot_base_radius
        rx = rng.uniform(cfg.robot_init_x[0], cfg.robot_init_x[1])
        ry = rng.uniform(cfg.robot_init_y[0], cfg.robot_init_y[1])
        rth = rng.uniform(cfg.robot_init_theta[0], cfg.robot_init_theta[1])
        bx = rng.uniform(cfg.world_min_x + r, cfg.world_max_x - r)
        rng.uniform(block_y, block_y)  # upstream draws y and θ of fixed-range poses too
        rng.uniform(0.0, 0.0)
        bw = rng.uniform(*cfg.block_width)
        bh = rng.uniform(*cfg.block_height)
        sx = rng.uniform(cfg.world_min_x, cfg.world_max_x - r)
        rng.uniform(table_y, table_y)
        rng.uniform(0.0, 0.0)
        sw = bw + rng.uniform(*cfg.surface_padding)
        del w_world
        feats: dict[Object, dict[str, float]] = {}
        feats[self.target_surface] = object_values(
            sx, table_y, 0.0, ot.PURPLE, ot.Z_NONE, static=True, width=sw, height=cfg.table_height
        )
        feats[self.target_block] = object_values(
            bx, block_y + bh / 2, 0.0, ot.PURPLE, ot.Z_ALL, width=bw, height=bh, mass=cfg.block_mass
        )
        for obj in self.obstructions:
            ow = rng.uniform(*cfg.block_width)
            oh = rng.uniform(*cfg.block_height)
            if rng.uniform() < cfg.obstruction_overlap_prob:
                lo, hi = sx - ow, sx + sw
            else:
                lo, hi = cfg.world_min_x + r, cfg.world_max_x - r
            ox = rng.uniform(lo, hi)
            rng.uniform(block_y, block_y)
            rng.uniform(0.0, 0.0)
            feats[obj] = object_values(
                ox,
                block_y + oh / 2,
                0.0,
                ot.RED,
                ot.Z_ALL,
                width=ow,
                height=oh,
                mass=cfg.block_mass,
            )
        feats[self.robot] = cfg.robot_values(rx, ry, rth)
        return ObjectCentricState.from_features(feats)

    def _valid_unsettled(self, state: ObjectCentricState) -> bool:
        """Upstream's rejection rules: the goal does not hold, nothing overlaps (the robot, the
        blocks, the table and the walls; the target surface collides with nothing) and the
        surface lies within the table."""
        if self.goal_reached(state):
            return False
        cfg = self.config
        robot = kin_robot_geometry(state[self.robot]).shape
        blocks = [self._block_shape(state, o) for o in (self.target_block, *self.obstructions)]
        statics = [WorldShape((sb.poly,)) for sb in self._upstream_statics()]
        for i, blk in enumerate(blocks):
            if overlaps(robot, blk) or any(overlaps(blk, o) for o in blocks[i + 1 :]):
                return False
            if any(overlaps(blk, st) for st in statics):
                return False
        if any(overlaps(robot, st) for st in statics):
            return False
        s = state[self.target_surface]
        return bool(s[0] - s[12] / 2 >= cfg.world_min_x and s[0] + s[12] / 2 <= cfg.world_max_x)

    def _upstream_statics(self) -> list[StaticBox]:
        cfg = self.config
        boxes = [
            StaticBox(x - w / 2, x + w / 2, y - h / 2, y + h / 2)
            for _, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        boxes.append(StaticBox(cfg.world_min_x, cfg.world_max_x, 0.0, cfg.table_height))
        return boxes

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        for _ in range(self.config.max_reset_tries):
            state = self._sample_unsettled(rng)
            if self._valid_unsettled(state):
                return self._pd_settle(state)
        raise RuntimeError(
            f"DynObstruction2D: no valid initial state in {self.config.max_reset_tries} draws"
        )

    def _pd_settings(self) -> PDSettings:
        return dataclasses.replace(
            super()._pd_settings(),
            init_robot_pos=self.config.init_robot_pos,
            static_stops=(CT_ROBOT, CT_FINGER, CT_ARM),
        )

    def _pd_specs(self, state: ObjectCentricState) -> list[BodySpec]:
        cfg = self.config
        specs = [
            BodySpec(name, None, static_rect(x, y, 0.0, w, h))
            for name, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        w_world = cfg.world_max_x - cfg.world_min_x
        specs.append(
            BodySpec(
                "table",
                None,
                static_rect(
                    cfg.world_min_x + w_world / 2,
                    cfg.world_min_y + cfg.table_height / 2,
                    0.0,
                    w_world,
                    cfg.table_height,
                ),
            )
        )
        s = state[self.target_surface]
        specs.append(BodySpec("target_surface", None, static_rect(s[0], s[1], s[2], s[12], s[13])))
        for obj in (self.target_block, *self.obstructions):
            f = state[obj]
            specs.append(BodySpec(obj.name, obj, dynamic_rect(f, f[12], f[13], f[14])))
        return specs

    def _block_shape(self, state: ObjectCentricState, obj: Object) -> Any:
        f = state[obj]
        return place(rect_shape(f[12], f[13]), f[0], f[1], f[2])

    # -- task ------------------------------------------------------------------------------------
    def goal_reached(self, state: ObjectCentricState) -> bool:
        b = state[self.target_block]
        s = state[self.target_surface]
        block = transform(rect_shape(b[12], b[13]).polys[0], b[0], b[1], b[2])
        surface = transform(rect_shape(s[12], s[13]).polys[0], s[0], s[1], s[2])
        return is_on(block, surface, self.config.goal_tolerance)

    def goals_reached(self, data: FloatArray, layout: StateLayout) -> BoolArray:
        """:meth:`goal_reached` of every row of ``data``, in whole-array numpy with the same
        operations per row (:func:`rect_polys`, :func:`are_on`)."""
        idx = layout.indices([self.target_block, self.target_surface], RECT_FEATURES)
        b, s = data[:, idx[0]], data[:, idx[1]]
        block = rect_polys(b[:, 0], b[:, 1], b[:, 2], b[:, 3], b[:, 4])
        surface = rect_polys(s[:, 0], s[:, 1], s[:, 2], s[:, 3], s[:, 4])
        return are_on(block, surface, self.config.goal_tolerance)

    def _draw_extras(self, canvas: Canvas, state: ObjectCentricState) -> None:
        s = state[self.target_surface]
        poly = transform(rect_shape(s[12], s[13]).polys[0], s[0], s[1], s[2])
        canvas.polygon(poly, fill=(128, 0, 128))


__all__ = ["DynObstruction2DConfig", "DynObstruction2DEnv"]
