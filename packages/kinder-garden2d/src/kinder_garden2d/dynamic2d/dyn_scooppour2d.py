"""DynScoopPour2D: scoop small objects over a wall with an L-shaped tool (pymunk)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinder_core import Object, ObjectCentricState, ObjectCentricStateSpace
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.base_env import (
    Dynamic2DEnv,
    KinRobotConfig,
    object_values,
    resolve_config,
    upstream_walls,
)
from kinder_garden2d.dynamic2d.geometry import (
    WorldShape,
    box,
    kin_robot_geometry,
    lobject_shape,
    overlaps,
    place,
)
from kinder_garden2d.dynamic2d.pd_physics import (
    CT_ARM,
    CT_FINGER,
    CT_ROBOT,
    BodySpec,
    PDSettings,
    dynamic_lobject,
    small_circle,
    small_square,
    static_rect,
)
from kinder_garden2d.dynamic2d.physics import Scene, StaticBox


@dataclass(frozen=True)
class DynScoopPour2DConfig(KinRobotConfig):
    """Constants of DynScoopPour2D (defaults follow the upstream environment)."""

    world_max_x: float = 3.5
    world_max_y: float = 3.0
    gravity: float = -1.0
    damping: float = 0.01
    robot_base_radius: float = 0.2
    robot_arm_length: float = 0.4
    gripper_base_width: float = 0.04
    gripper_base_height: float = 0.25
    finger_height: float = 0.04
    finger_width: float = 0.12
    max_dx: float = 0.03
    max_dy: float = 0.03
    max_dtheta: float = math.pi / 32
    max_darm: float = 0.08
    max_dgripper: float = 0.015
    robot_init_x: tuple[float, float] = (0.5, 3.0)
    robot_init_y: tuple[float, float] = (2.0, 2.5)
    robot_init_theta: tuple[float, float] = (-math.pi, -math.pi / 2)
    wall_center_x: float = 1.75
    wall_width: float = 0.1
    wall_height: float = 1.5
    hook_length_side1: float = 0.5
    hook_length_side2: float = 0.5
    hook_mass: float = 0.5
    small_mass: float = 0.1
    goal_min_x: float = 1.75
    goal_max_y: float = 0.75
    goal_max_speed_sq: float = 1e-4
    goal_fraction: float = 0.5
    # Weak gravity: a longer substep (g·dt² as small as 0.02 s gives at g = 9.8).
    substep_seconds: float = 0.05
    settle_max_seconds: float = 6.0
    settle_speed_tol: float = 5e-3
    # Upstream lets the freshly sampled (overlapping) small objects settle for 30 s.
    stabilization_seconds: float = 30.0
    # The hook's thickness, its position range and the small objects' size and position ranges
    # derive from the gripper and world sizes as upstream derives them (see the sampling).


class DynScoopPour2DEnv(Dynamic2DEnv):
    """Scoop the small objects over the middle wall and pour them on the right.

    ## Description
    A side view with weak gravity (−1) and heavy damping (1% of velocity kept per second). A wall
    1.5 high divides the 3.5 × 3 world. Small orange discs and purple squares lie in a pile left of
    the wall; an L-shaped scoop (hook) stands right of it. The two-finger robot must grasp the scoop
    (the small objects cannot be grasped), scoop objects from the pile, carry them over the wall and
    pour them onto the right floor.

    Transitions are upstream kindergarden 0.2.5's (see
    :mod:`~kinder_garden2d.dynamic2d.pd_physics`): a PD controller drives the robot towards the
    commanded target for 1 s of simulated time per action (10 control steps of 10 physics steps
    of 0.01 s), covering most of each step and keeping a residual velocity that the velocity
    features report; a robot contact with a static body puts the robot back where that control
    step began. The held scoop counts as part of the robot for static contacts.
    Closing the fingers on the scoop grasps it (the small objects cannot be grasped).

    ## Observation Space
    Object-centric states with `robot` (`kin_robot`, 24 features), `hook` (`hook` ⊂ `lobject`, 16)
    and the small objects `small_circle*` (`small_circle`, 14 each) and `small_square*`
    (`small_square`, 14 each). The Box view lists the robot, the hook, then the small objects
    sorted by name: 24 + 16 + 14N values. The hook's origin is its outer corner (arms along local
    −x and −y).

    ## Action Space
    `[dx, dy, dtheta, darm, dgripper]` (float64): ±0.03, ±0.03, ±π/32, ±0.08, ±0.015 (positive
    `dgripper` opens). Out-of-bound actions are clipped.

    ## Reward
    −1 per step.

    ## Starting State
    Upstream's sampling, draw for draw (the same seed gives upstream's initial state): the robot
    at x ∈ [0.5, 3.0], y ∈ [2.0, 2.5], θ ∈ [−π, −π/2] (arm retracted, fingers open); then the
    scoop (width 0.05, arms 0.5, mass 0.5; corner x ∈ [3.125, 3.5], y ∈ [0.05, 0.7],
    θ ∈ [−π/2, −π/2 + 0.001]) and the small objects (variant oN: N // 2 discs of radius
    U[0.0625, 0.0833], then N − N // 2 squares of side U[0.0833, 0.0893]; mass 0.1; anywhere in
    x ∈ [0.2, 1.45], y ∈ [0, 1.3], overlapping freely), redrawn until the robot touches neither
    the scoop nor a wall. Everything then settles for 30 s of simulated time, which pushes the
    small objects apart into a pile; the state is read back with its residual velocities. Discs
    keep their drawn angle (upstream never rotates a disc's body).

    ## Episode End
    Terminates when at least half of the small objects rest on the right: x > 1.75, y < 0.75 and
    squared speed < 1e-4. Truncated after 1000 steps by the registered TimeLimit.

    ## Arguments
    * `num_objects` (default 10): number of small objects (N // 2 discs, the rest squares).
    * `config`: a `DynScoopPour2DConfig` or a mapping of field overrides.

    ## Deviations
    * Upstream's class default is 10 circles and no squares; the registered variants (and this
      class) split N into N // 2 circles and N − N // 2 squares.
    * A held scoop is attached with the robot already in place. Upstream, reloading a state with
      a held scoop, attaches it before placing the robot (the scoop's offset is then measured
      from the robot's creation pose); since our transitions reload at every action, we keep the
      correct offset.
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
        num_objects: int = 10,
        config: DynScoopPour2DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = resolve_config(DynScoopPour2DConfig, config)
        super().__init__(cfg, render_mode)
        if int(num_objects) != num_objects or num_objects < 1:
            raise ValueError(f"num_objects must be an int >= 1, got {num_objects!r}")
        self.config: DynScoopPour2DConfig = cfg
        self.num_objects = int(num_objects)
        n_circles = self.num_objects // 2
        self.robot = Object("robot", ot.KIN_ROBOT)
        self.hook = Object("hook", ot.HOOK)
        self.circles = [Object(f"small_circle{i}", ot.SMALL_CIRCLE) for i in range(n_circles)]
        self.squares = [
            Object(f"small_square{i}", ot.SMALL_SQUARE) for i in range(self.num_objects - n_circles)
        ]
        self.smalls = sorted([*self.circles, *self.squares], key=lambda o: o.name)
        self._goal_idx: tuple[Any, Any] | None = None
        self.action_space = cfg.action_space()
        self.observation_space = ObjectCentricStateSpace([ot.DYNAMIC2D_OBJECT, ot.KIN_ROBOT])
        half = cfg.wall_width / 2
        self.middle_wall = StaticBox(
            cfg.wall_center_x - half, cfg.wall_center_x + half, cfg.world_min_y, cfg.wall_height
        )
        self.static_colors = ((self.middle_wall, ot.BLACK),)
        self.scene = Scene(
            settings=cfg.physics(),
            statics=(*cfg.walls(), self.middle_wall),
            robot=self.robot,
            objects=(self.hook, *self.smalls),
            graspable=frozenset({self.hook}),
        )

    def box_objects(self) -> list[Object]:
        return [self.robot, self.hook, *self.smalls]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """Upstream's sampling: the robot once, then the hook and every small object (left of
        the wall, overlapping freely) until the robot overlaps neither the hook nor a wall; then
        upstream's long settling pushes the small objects apart."""
        cfg = self.config
        gh, mx = cfg.gripper_base_height, cfg.wall_center_x
        x0, x1, y1 = cfg.world_min_x, cfg.world_max_x, cfg.world_max_y
        hw = gh / 5
        robot = cfg.robot_values(
            rng.uniform(cfg.robot_init_x[0], cfg.robot_init_x[1]),
            rng.uniform(cfg.robot_init_y[0], cfg.robot_init_y[1]),
            rng.uniform(cfg.robot_init_theta[0], cfg.robot_init_theta[1]),
        )
        robot_shape = kin_robot_geometry([robot[f] for f in ot.KIN_ROBOT_FEATURES]).shape
        statics = [
            WorldShape((box(x - w / 2, x + w / 2, y - h / 2, y + h / 2),))
            for _, x, y, w, h in upstream_walls(cfg, cfg.max_dx, cfg.max_dy)
        ]
        statics.append(WorldShape((self.middle_wall.poly,)))
        for _ in range(cfg.max_reset_tries):
            hx = rng.uniform((mx + x1) / 2 + 0.5, x1)
            hy = rng.uniform(gh / 5, y1 / 2 - 0.8)
            hth = rng.uniform(-np.pi / 2, -np.pi / 2 + 1e-3)
            feats: dict[Object, dict[str, float]] = {self.robot: robot}
            feats[self.hook] = object_values(
                hx,
                hy,
                hth,
                ot.BROWN,
                ot.Z_SURFACE,
                width=hw,
                length_side1=cfg.hook_length_side1,
                length_side2=cfg.hook_length_side2,
                mass=cfg.hook_mass,
            )
            for objs, kind in ((self.circles, "circle"), (self.squares, "square")):
                for obj in objs:
                    x = rng.uniform(x0 + 0.2, mx - 0.3)
                    y = rng.uniform(0.0, y1 / 2 - 0.2)
                    th = rng.uniform(-np.pi, np.pi)
                    if kind == "circle":
                        r = rng.uniform(gh / 4, gh / 3)
                        feats[obj] = object_values(
                            x, y, th, ot.ORANGE, ot.Z_SURFACE, radius=r, mass=cfg.small_mass
                        )
                    else:
                        size = rng.uniform(gh / 3, gh / 2.8)
                        feats[obj] = object_values(
                            x, y, th, ot.PURPLE, ot.Z_SURFACE, size=size, mass=cfg.small_mass
                        )
            hook = place(
                lobject_shape(hw, cfg.hook_length_side1, cfg.hook_length_side2), hx, hy, hth
            )
            if not any(overlaps(robot_shape, o) for o in (hook, *statics)):
                return self._pd_settle(ObjectCentricState.from_features(feats))
        raise RuntimeError(
            f"DynScoopPour2D: no hook pose clear of the robot in {cfg.max_reset_tries} draws"
        )

    def _pd_settings(self) -> PDSettings:
        return dataclasses.replace(
            super()._pd_settings(), static_stops=(CT_ROBOT, CT_FINGER, CT_ARM)
        )

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
                    cfg.wall_center_x, cfg.world_max_y / 4, 0.0, cfg.wall_width, cfg.wall_height
                ),
            )
        )
        h = state[self.hook]
        hook = dynamic_lobject(h, h[12], h[13], h[14], h[15], set_body_mass=False, held_ct=CT_ROBOT)
        specs.append(BodySpec("hook", self.hook, hook, "once"))
        for obj in self.circles:
            f = state[obj]
            specs.append(BodySpec(obj.name, obj, small_circle(f, f[12], f[13]), "keep"))
        for obj in self.squares:
            f = state[obj]
            specs.append(BodySpec(obj.name, obj, small_square(f, f[12], f[13]), "once"))
        return specs

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return self.num_poured(state) >= self.config.goal_fraction * self.num_objects

    def num_poured(self, state: ObjectCentricState) -> int:
        """How many small objects rest on the right of the wall (the goal's count)."""
        cfg = self.config
        if self._goal_idx is None or self._goal_idx[0] is not state.layout:
            self._goal_idx = (
                state.layout,
                state.layout.indices(self.smalls, ["x", "y", "vx", "vy"]),
            )
        p = state.data[self._goal_idx[1]]
        ok = (
            (p[:, 0] > cfg.goal_min_x)
            & (p[:, 1] < cfg.goal_max_y)
            & (p[:, 2] ** 2 + p[:, 3] ** 2 < cfg.goal_max_speed_sq)
        )
        return int(ok.sum())
