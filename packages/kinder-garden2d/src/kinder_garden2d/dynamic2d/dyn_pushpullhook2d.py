"""DynPushPullHook2D: use a hook to pull a block, surrounded by obstructions, down to a wall."""

from __future__ import annotations

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
    box,
    convex_penetration,
    convex_penetrations,
    kin_robot_geometry,
    lobject_shape,
    overlaps,
    place,
    rect_polys,
    rect_shape,
    transform,
)
from kinder_garden2d.dynamic2d.pd_physics import (
    BodySpec,
    dynamic_lobject,
    dynamic_rect,
    static_rect,
)
from kinder_garden2d.dynamic2d.physics import Scene, StaticBox


@dataclass(frozen=True)
class DynPushPullHook2DConfig(KinRobotConfig):
    """Constants of DynPushPullHook2D (defaults follow the upstream environment)."""

    world_max_x: float = 3.5
    world_max_y: float = 3.5
    gravity: float = 0.0
    damping: float = 0.01  # bodies keep 1% of their velocity per second
    max_dtheta: float = math.pi / 48
    wall_height: float = 0.05
    robot_init: tuple[float, float] = (0.3, 0.4)  # x and y range
    robot_init_theta: tuple[float, float] = (0.0, math.pi / 2)
    hook_mass: float = 1.0
    hook_init_theta: tuple[float, float] = (-math.pi / 12, math.pi / 12)
    obstruction_std: float = 0.25
    block_mass: float = 1.0
    # The hook's thickness and arm lengths, the target's side range, the obstructions' size
    # range and the hook's and target's position ranges derive from the world and gripper sizes
    # as upstream derives them (see hook_shape() and the sampling).
    settle_max_seconds: float = 0.0


class DynPushPullHook2DEnv(Dynamic2DEnv):
    """Pull the target block down to the middle wall with the hook.

    ## Description
    A top-down 3.5 × 3.5 world without gravity and with heavy damping (bodies keep 1% of their
    velocity per second). A wall across the middle (height 0.05) is at floor level: the robot's
    base cannot cross it, but its arm, gripper, fingers, the hook and the blocks pass over it. The
    robot starts in the lower half with an L-shaped hook; the orange target block sits in the
    upper half among brown obstructions. The robot must grasp the hook, reach over the wall and
    drag the target down until it overlaps the wall.

    Transitions are upstream kindergarden 0.2.5's (see
    :mod:`~kinder_garden2d.dynamic2d.pd_physics`): a PD controller drives the robot towards the
    commanded target for 1 s of simulated time per action (10 control steps of 10 physics steps
    of 0.01 s), covering most of each step and keeping a residual velocity that the velocity
    features report; a robot contact with a static body puts the robot back where that control
    step began. Closing the fingers on the hook or a block grasps it (as in
    DynObstruction2D); opening releases it.

    ## Observation Space
    Object-centric states with `robot` (`kin_robot`, 24 features), `hook` (`hook` ⊂ `lobject`, 16),
    `target_block` (`target_block` ⊂ `dyn_rectangle`, 15) and `obstruction0..N-1`
    (`dyn_rectangle`, 15 each). The Box view lists them in that order: 24 + 16 + 15 + 15N values.
    An L-object's origin is its outer corner: arm 1 (`length_side1`) runs along local −x, arm 2
    (`length_side2`) along local −y, both `width` thick.

    ## Action Space
    `[dx, dy, dtheta, darm, dgripper]` (float64): ±0.05, ±0.05, ±π/48, ±0.1, ±0.02 (positive
    `dgripper` opens). Out-of-bound actions are clipped.

    ## Reward
    −1 per step.

    ## Starting State
    Upstream's sampling, draw for draw (the same seed gives upstream's initial state): robot
    x, y ∈ [0.3, 0.4], θ ∈ [0, π/2], arm retracted, fingers open; then the target square (side
    U[0.16, 0.477], mass 1; x ∈ [0.583, 2.917], y ∈ [2.333, 2.917], θ ∈ [−π, π]) and the hook
    (width 0.107, arms 1.4 and 0.583, mass 1; corner x ∈ [1.4, 3.393], y ∈ [0.875, 1.167],
    θ ∈ [−π/12, π/12]) together until neither overlaps the hook, the robot or a wall; then each
    obstruction (sides U[0.12, 0.583], θ ∈ [−π, π]) Gaussian (σ 0.25) around the target until it
    overlaps nothing. The scene then settles for 1 s (nothing moves without gravity).

    ## Episode End
    Terminates when the target block overlaps the middle wall. Truncated after 500 steps by the
    registered TimeLimit (the paper's evaluation budget for o5).

    ## Arguments
    * `num_obstructions` (default 3): number of obstruction blocks.
    * `config`: a `DynPushPullHook2DConfig` or a mapping of field overrides.

    ## Deviations
    * Each transition is computed from the observed state alone (a fresh pymunk space per action,
      built as upstream builds it when reset from a state), so `set_state` replays exactly; it
      equals upstream's reload-then-step to 1e-9 (upstream's uninterrupted runs also carry
      Chipmunk's cached contact impulses between actions, which its state vector lacks).
    * Kept option, off by default: `controller="linear"` (the robot moves exactly by the commanded
      deltas over `action_seconds`, reports the commanded average velocity, and transitions that
      leave an object outside the world are discarded, `env.num_physics_reverts`).

    ## References
    KinDER (RSS 2026), the Dynamic2D environments; pymunk (Chipmunk2D).

    ## Version History
    * v0: initial version.
    """

    has_pd = True

    def __init__(
        self,
        num_obstructions: int = 3,
        config: DynPushPullHook2DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = resolve_config(DynPushPullHook2DConfig, config)
        super().__init__(cfg, render_mode)
        if int(num_obstructions) != num_obstructions or num_obstructions < 0:
            raise ValueError(f"num_obstructions must be an int >= 0, got {num_obstructions!r}")
        self.config: DynPushPullHook2DConfig = cfg
        self.num_obstructions = int(num_obstructions)
        self.robot = Object("robot", ot.KIN_ROBOT)
        self.hook = Object("hook", ot.HOOK)
        self.target_block = Object("target_block", ot.TARGET_BLOCK)
        self.obstructions = [
            Object(f"obstruction{i}", ot.DYN_RECTANGLE) for i in range(self.num_obstructions)
        ]
        self.action_space = cfg.action_space()
        self.observation_space = ObjectCentricStateSpace([ot.DYNAMIC2D_OBJECT, ot.KIN_ROBOT])
        mid = (cfg.world_min_y + cfg.world_max_y) / 2
        self.middle_wall = StaticBox(
            cfg.world_min_x,
            cfg.world_max_x,
            mid - cfg.wall_height / 2,
            mid + cfg.wall_height / 2,
            z=ot.Z_FLOOR,
        )
        self.static_colors = (
            (StaticBox(cfg.world_min_x, cfg.world_max_x, mid, cfg.world_max_y), (0.93, 0.9, 0.85)),
            (StaticBox(cfg.world_min_x, cfg.world_max_x, cfg.world_min_y, mid), (0.88, 0.9, 0.93)),
            (self.middle_wall, ot.BLACK),
        )
        objs = (self.hook, self.target_block, *sorted(self.obstructions, key=lambda o: o.name))
        self.scene = Scene(
            settings=cfg.physics(),
            statics=(*cfg.walls(), self.middle_wall),
            robot=self.robot,
            objects=objs,
            graspable=frozenset(objs),
        )

    def box_objects(self) -> list[Object]:
        return [
            self.robot,
            self.hook,
            self.target_block,
            *sorted(self.obstructions, key=lambda o: o.name),
        ]

    # -- sampling (upstream's procedure, draw for draw) ---------------------------------------
    def hook_shape(self) -> tuple[float, float, float]:
        """The hook's (width, length_side1, length_side2), from the world and gripper sizes."""
        cfg = self.config
        return (
            cfg.gripper_base_height / 3,
            (cfg.world_min_y + cfg.world_max_y) * 2 / 5,
            (cfg.world_min_y + cfg.world_max_y) / 6,
        )

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """The robot, then the target and hook together, then each obstruction (a Gaussian
        around the target), each redrawn until it collides with nothing, then upstream's settling.
        """
        cfg = self.config
        hw, hl1, hl2 = self.hook_shape()
        x0, x1, y0, y1 = cfg.world_min_x, cfg.world_max_x, cfg.world_min_y, cfg.world_max_y
        robot = cfg.robot_values(
            rng.uniform(cfg.robot_init[0], cfg.robot_init[1]),
            rng.uniform(cfg.robot_init[0], cfg.robot_init[1]),
            rng.uniform(cfg.robot_init_theta[0], cfg.robot_init_theta[1]),
        )
        robot_shape = kin_robot_geometry([robot[f] for f in ot.KIN_ROBOT_FEATURES]).shape
        walls = [
            WorldShape((box(x - w / 2, x + w / 2, y - h / 2, y + h / 2),))
            for _, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        tries = cfg.max_reset_tries
        for _ in range(tries):
            tx = rng.uniform(x0 + hl2, x1 - hl2)
            ty = rng.uniform((y0 + y1) / 2 + hl2, y1 - hl2)
            tth = rng.uniform(-np.pi, np.pi)
            side = rng.uniform(cfg.gripper_base_height / 2, hl2 - hw)
            hx = rng.uniform(x0 + hl1, x1 - hw)
            hy = rng.uniform(hl2 * 1.5, (y0 + y1) / 2 - hl2)
            hth = rng.uniform(cfg.hook_init_theta[0], cfg.hook_init_theta[1])
            target_shape = place(rect_shape(side, side), tx, ty, tth)
            hook = place(lobject_shape(hw, hl1, hl2), hx, hy, hth)
            if not any(overlaps(a, b) for a in (target_shape, robot_shape) for b in (hook, *walls)):
                break
        else:
            raise RuntimeError(f"DynPushPullHook2D: no target and hook pose in {tries} draws")
        feats: dict[Object, dict[str, float]] = {
            self.robot: robot,
            self.hook: object_values(
                hx,
                hy,
                hth,
                ot.BROWN,
                ot.Z_SURFACE,
                width=hw,
                length_side1=hl1,
                length_side2=hl2,
                mass=cfg.hook_mass,
            ),
            self.target_block: object_values(
                tx, ty, tth, ot.ORANGE, ot.Z_SURFACE, width=side, height=side, mass=cfg.block_mass
            ),
        }
        placed = [robot_shape, target_shape, hook, *walls]
        for obj in sorted(self.obstructions, key=lambda o: o.name):
            for _ in range(tries):
                ox, oy = rng.normal(loc=(tx, ty), scale=cfg.obstruction_std, size=(2,))
                if not (x0 < ox < x1 and y0 < oy < y1):
                    continue
                oth = rng.uniform(-np.pi, np.pi)
                ow = rng.uniform(cfg.robot_base_radius / 2, hl2)
                oh = rng.uniform(cfg.robot_base_radius / 2, hl2)
                shape = place(rect_shape(ow, oh), ox, oy, oth)
                if not any(overlaps(shape, other) for other in placed):
                    break
            else:
                raise RuntimeError(f"DynPushPullHook2D: no pose for {obj.name} in {tries} draws")
            placed.append(shape)
            feats[obj] = object_values(
                float(ox),
                float(oy),
                oth,
                ot.BROWN,
                ot.Z_SURFACE,
                width=ow,
                height=oh,
                mass=cfg.block_mass,
            )
        return self._pd_settle(ObjectCentricState.from_features(feats))

    def _pd_specs(self, state: ObjectCentricState) -> list[BodySpec]:
        cfg = self.config
        specs = [
            BodySpec(name, None, static_rect(x, y, 0.0, w, h))
            for name, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        specs.append(
            BodySpec(
                "middle_wall",
                None,
                static_rect(
                    (cfg.world_min_x + cfg.world_max_x) / 2,
                    (cfg.world_min_y + cfg.world_max_y) / 2,
                    0.0,
                    cfg.world_max_x - cfg.world_min_x,
                    cfg.wall_height,
                ),
            )
        )
        h = state[self.hook]
        specs.append(
            BodySpec("hook", self.hook, dynamic_lobject(h, h[12], h[13], h[14], h[15]), "wrap")
        )
        for obj in (self.target_block, *self.obstructions):
            f = state[obj]
            specs.append(BodySpec(obj.name, obj, dynamic_rect(f, f[12], f[13], f[14]), "wrap"))
        return specs

    def goal_reached(self, state: ObjectCentricState) -> bool:
        b = state[self.target_block]
        block = transform(rect_shape(b[12], b[13]).polys[0], b[0], b[1], b[2])
        return convex_penetration(block, self.middle_wall.poly) > 0.0

    def goals_reached(self, data: FloatArray, layout: StateLayout) -> BoolArray:
        """:meth:`goal_reached` of every row of ``data``, in whole-array numpy with the same
        operations per row (:func:`rect_polys`, :func:`convex_penetrations`)."""
        b = data[:, layout.indices([self.target_block], RECT_FEATURES)[0]]
        block = rect_polys(b[:, 0], b[:, 1], b[:, 2], b[:, 3], b[:, 4])
        wall = np.broadcast_to(self.middle_wall.poly, (len(data), *self.middle_wall.poly.shape))
        out: BoolArray = convex_penetrations(block, wall) > 0.0
        return out
