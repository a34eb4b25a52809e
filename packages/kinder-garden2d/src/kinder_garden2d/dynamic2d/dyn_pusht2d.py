"""DynPushT2D: push a T-shaped block onto a goal pose with a dot robot (pymunk)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from kinder_core import Object, ObjectCentricState, ObjectCentricStateSpace
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.base_env import (
    Dynamic2DConfig,
    Dynamic2DEnv,
    object_values,
    resolve_config,
    upstream_walls,
)
from kinder_garden2d.dynamic2d.geometry import (
    WorldShape,
    box,
    circle_shape,
    overlaps,
    place,
    tobject_shape,
    wrap_angle,
)
from kinder_garden2d.dynamic2d.pd_physics import BodySpec, PDSettings, static_rect, tblock
from kinder_garden2d.dynamic2d.physics import Scene
from kinder_garden2d.rendering import Canvas


@dataclass(frozen=True)
class DynPushT2DConfig(Dynamic2DConfig):
    """Constants of DynPushT2D (defaults follow the upstream environment)."""

    world_max_x: float = 5.0
    world_max_y: float = 5.0
    gravity: float = 0.0
    damping: float = 0.0  # bodies keep no velocity: quasi-static pushing
    robot_radius: float = 0.1
    max_dx: float = 0.05
    max_dy: float = 0.05
    robot_init: tuple[float, float] = (1.0, 2.0)  # x and y range
    tee_width: tuple[float, float] = (0.10, 0.15)
    tee_length_horizontal: tuple[float, float] = (1.0, 1.25)
    tee_length_vertical: tuple[float, float] = (1.0, 1.25)
    tee_mass: float = 1.0
    tee_init: tuple[float, float] = (1.0, 4.0)  # x and y range of the block and of the goal
    goal_position_tolerance: float = 0.03
    goal_angle_tolerance: float = math.radians(8.0)
    settle_max_seconds: float = 0.0
    init_robot_pos: tuple[float, float] = (1.0, 1.0)  # where upstream creates the robot's body
    robot_color: tuple[float, float, float] = (50 / 255, 50 / 255, 1.0)
    tee_color: tuple[float, float, float] = (0.5, 0.5, 0.5)
    goal_color: tuple[float, float, float] = (0.5, 1.0, 0.5)


class DynPushT2DEnv(Dynamic2DEnv):
    """Push the T-shaped block onto the goal T (Diffusion Policy's PushT, in KinDER's style).

    ## Description
    A top-down 5 × 5 world without gravity. A dot robot (a kinematic disc of radius 0.1) pushes a
    dynamic T-shaped block (mass 1) until it matches the light-green goal T in position and
    orientation. Damping is 0, so the block keeps no velocity between substeps: pushing is
    quasi-static. Transitions are upstream kindergarden 0.2.5's: a PD controller (gains 50/5)
    drives the robot towards its position plus the action for 1 s of simulated time (10 control
    steps of 10 physics steps of 0.01 s); touching a wall puts it back where that control step
    began, at rest.

    ## Observation Space
    Object-centric states with `tblock` (`tobject`, 16 features), `robot` (`dot_robot`, 13) and
    `goal_tblock` (`tobject`, 16, static). The Box view lists them in that order: 45 float64
    values. A T's origin is the top-centre of its bar: the bar spans local x ∈ [−lh/2, lh/2],
    y ∈ [−w, 0], the stem x ∈ [−w/2, w/2], y ∈ [−w − lv, −w]. The block's angle is shifted by 2π
    once when it leaves [−π, π], as upstream does.

    ## Action Space
    `[dx, dy]` (float64), each in [−0.05, 0.05]: the robot's displacement. Out-of-bound actions
    are clipped.

    ## Reward
    −1 per step.

    ## Starting State
    Upstream's sampling, draw for draw (the same seed gives upstream's initial state): the robot
    at x, y ∈ [1, 2]; the block's pose x, y ∈ [1, 4], θ ∈ [−π, π], bar width U[0.10, 0.15], bar
    and stem lengths U[1.0, 1.25]; the goal pose likewise (the goal has the block's shape). Draws
    where the robot touches the block, the goal outline or a wall, or either T touches a wall, are
    redrawn; the scene then settles for 1 s.

    ## Episode End
    Terminates when |x − x_goal| < 0.03, |y − y_goal| < 0.03 and the *wrapped* angle difference
    is below 8°. Truncated after 1000 steps by the registered TimeLimit.

    ## Arguments
    * `num_tee` (default 1): kept for upstream compatibility; only 1 is supported.
    * `config`: a `DynPushT2DConfig` or a mapping of field overrides.

    ## Deviations
    * The goal compares the wrapped angle difference; upstream compares raw angles, so a block at
      θ = π − ε never matches a goal at −π + ε although the poses are almost identical.
    * Each transition is computed from the observed state alone (a fresh pymunk space per action,
      built as upstream builds it when reset from a state), so `set_state` replays exactly; it
      equals upstream's reload-then-step to 1e-9 (upstream's uninterrupted runs also carry
      Chipmunk's cached contact impulses between actions, which its state vector lacks).
    * Kept option, off by default: `controller="linear"` (the robot moves exactly by the commanded
      deltas over `action_seconds`, reports the commanded average velocity, and transitions that
      leave an object outside the world are discarded, `env.num_physics_reverts`).

    ## References
    Chi et al., Diffusion Policy (PushT); KinDER (RSS 2026).

    ## Version History
    * v0: initial version.
    """

    has_pd = True

    def __init__(
        self,
        num_tee: int = 1,
        config: DynPushT2DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = resolve_config(DynPushT2DConfig, config)
        super().__init__(cfg, render_mode)
        if num_tee != 1:
            raise ValueError(f"DynPushT2D supports exactly one T block, got num_tee={num_tee!r}")
        self.config: DynPushT2DConfig = cfg
        self.robot = Object("robot", ot.DOT_ROBOT)
        self.tblock = Object("tblock", ot.TOBJECT)
        self.goal_tblock = Object("goal_tblock", ot.TOBJECT)
        high = np.array([cfg.max_dx, cfg.max_dy])
        self.action_space = gymnasium.spaces.Box(-high, high, dtype=np.float64)
        self.observation_space = ObjectCentricStateSpace([ot.DYNAMIC2D_OBJECT])
        self.scene = Scene(
            settings=cfg.physics(),
            statics=cfg.walls(),
            robot=self.robot,
            objects=(self.tblock,),
            graspable=frozenset(),
        )

    def box_objects(self) -> list[Object]:
        return [self.tblock, self.robot, self.goal_tblock]

    def _sample_unsettled(self, rng: np.random.Generator) -> ObjectCentricState:
        """One candidate scene drawn as upstream draws it (see :meth:`_sample_initial_state`)."""
        cfg = self.config
        rx = rng.uniform(cfg.robot_init[0], cfg.robot_init[1])
        ry = rng.uniform(cfg.robot_init[0], cfg.robot_init[1])
        rng.uniform(0.0, 0.0)  # upstream draws the dot robot's (fixed) angle too
        tx = rng.uniform(cfg.tee_init[0], cfg.tee_init[1])
        ty = rng.uniform(cfg.tee_init[0], cfg.tee_init[1])
        tth = rng.uniform(-np.pi, np.pi)
        w = rng.uniform(*cfg.tee_width)
        lh = rng.uniform(*cfg.tee_length_horizontal)
        lv = rng.uniform(*cfg.tee_length_vertical)
        gx = rng.uniform(cfg.tee_init[0], cfg.tee_init[1])
        gy = rng.uniform(cfg.tee_init[0], cfg.tee_init[1])
        gth = rng.uniform(-np.pi, np.pi)
        geom = dict(width=w, length_horizontal=lh, length_vertical=lv, mass=cfg.tee_mass)
        return ObjectCentricState.from_features(
            {
                self.tblock: object_values(tx, ty, tth, cfg.tee_color, ot.Z_SURFACE, **geom),
                self.goal_tblock: object_values(
                    gx, gy, gth, cfg.goal_color, ot.Z_FLOOR, static=True, **geom
                ),
                self.robot: object_values(
                    rx, ry, 0.0, cfg.robot_color, ot.Z_ALL, radius=cfg.robot_radius
                ),
            }
        )

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's rejection sampling: the robot overlaps neither the block, the goal outline
        nor a wall, the block no wall, and the block would fit at the goal pose; then upstream's
        settling."""
        cfg = self.config
        walls = [
            WorldShape((box(x - w / 2, x + w / 2, y - h / 2, y + h / 2),))
            for _, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        for _ in range(cfg.max_reset_tries):
            state = self._sample_unsettled(rng)
            t, g, r = state[self.tblock], state[self.goal_tblock], state[self.robot]
            tee = tobject_shape(float(t[12]), float(t[13]), float(t[14]))
            block = place(tee, float(t[0]), float(t[1]), float(t[2]))
            goal = place(tee, float(g[0]), float(g[1]), float(g[2]))
            robot = place(circle_shape(cfg.robot_radius), float(r[0]), float(r[1]), 0.0)
            if any(overlaps(robot, o) for o in (block, goal, *walls)):
                continue
            if any(overlaps(shape, wall) for shape in (block, goal) for wall in walls):
                continue
            return self._pd_settle(state)
        raise RuntimeError(f"DynPushT2D: no valid initial state in {cfg.max_reset_tries} draws")

    def _pd_settings(self) -> PDSettings:
        return dataclasses.replace(
            super()._pd_settings(), init_robot_pos=self.config.init_robot_pos
        )

    def _pd_specs(self, state: ObjectCentricState) -> list[BodySpec]:
        specs = [
            BodySpec(name, None, static_rect(x, y, 0.0, w, h, angle_first=False))
            for name, x, y, w, h in upstream_walls(
                self.config, self.config.max_dx, self.config.max_dy
            )
        ]
        t = state[self.tblock]
        specs.append(BodySpec("tblock", self.tblock, tblock(t, t[12], t[13], t[14], t[15]), "once"))
        return specs

    def goal_reached(self, state: ObjectCentricState) -> bool:
        t, g = state[self.tblock], state[self.goal_tblock]
        cfg = self.config
        return bool(
            abs(t[0] - g[0]) < cfg.goal_position_tolerance
            and abs(t[1] - g[1]) < cfg.goal_position_tolerance
            and abs(wrap_angle(float(t[2] - g[2]))) < cfg.goal_angle_tolerance
        )

    def _draw_extras(self, canvas: Canvas, state: ObjectCentricState) -> None:
        g = state[self.goal_tblock]
        goal = place(tobject_shape(g[12], g[13], g[14]), g[0], g[1], g[2])
        r, gr, b = (round(255 * float(c)) for c in g[8:11])
        for p in goal.polys:
            canvas.polygon(p, fill=(r, gr, b), outline=(40, 120, 40), outline_width=0.02)
        for p in goal.polys:
            canvas.polygon(p, fill=(r, gr, b))
