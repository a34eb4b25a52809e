"""DynScoopPour2D: scoop small objects over a wall with an L-shaped tool (pymunk)."""

from __future__ import annotations

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
    uniform,
)
from kinder_garden2d.dynamic2d.geometry import (
    WorldShape,
    kin_robot_geometry,
    lobject_shape,
    overlaps,
    place,
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
    hook_width: float = 0.05
    hook_length_side1: float = 0.5
    hook_length_side2: float = 0.5
    hook_mass: float = 0.5
    hook_init_x: tuple[float, float] = (3.0, 3.3)
    hook_init_y: tuple[float, float] = (0.05, 0.7)
    hook_init_theta: float = -math.pi / 2
    circle_radius: tuple[float, float] = (0.0625, 0.0833)
    square_size: tuple[float, float] = (0.0833, 0.0893)
    small_mass: float = 0.1
    # Small objects start in distinct cells of a lattice left of the wall (jittered in their cell).
    lattice_x: tuple[float, float] = (0.1, 1.65)
    lattice_min_y: float = 0.0
    lattice_spacing: float = 0.18
    goal_min_x: float = 1.75
    goal_max_y: float = 0.75
    goal_max_speed_sq: float = 1e-4
    goal_fraction: float = 0.5
    # Weak gravity: a longer substep (g·dt² as small as 0.02 s gives at g = 9.8).
    substep_seconds: float = 0.05
    settle_max_seconds: float = 6.0
    settle_speed_tol: float = 5e-3


class DynScoopPour2DEnv(Dynamic2DEnv):
    """Scoop the small objects over the middle wall and pour them on the right.

    ## Description
    A side view with weak gravity (−1) and heavy damping (1% of velocity kept per second). A wall
    1.5 high divides the 3.5 × 3 world. Small orange discs and purple squares lie in a pile left of
    the wall; an L-shaped scoop (hook) stands right of it. The two-finger robot must grasp the scoop
    (the small objects cannot be grasped), scoop objects from the pile, carry them over the wall and
    pour them onto the right floor.

    The robot is kinematic and follows its commanded motion exactly over each action's 0.1 s
    (two 0.05 s substeps: gravity is only −1, so g·dt² stays below that of a 0.02 s substep
    at g = −9.8); touching a wall or the floor (directly or with the held scoop) returns it
    to its last pose and stops it for the rest of the action. Closing the fingers on the scoop
    grasps it (contact normal within 0.1 rad of the closing direction, centre of mass between the
    fingers, contact along the fingers); opening releases it with its velocity.

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
    Variant oN has N // 2 discs (radius U[0.0625, 0.0833]) and N − N // 2 squares (side
    U[0.0833, 0.0893]), mass 0.1 each, random angles, in distinct cells of a 0.18 lattice left of
    the wall (x ∈ [0.1, 1.65], from the floor up), jittered within their cells. The scoop (width
    0.05, arms 0.5, mass 0.5) stands at x ∈ [3.0, 3.3], y ∈ [0.05, 0.7], θ = −π/2 (handle up,
    foot to the left). The robot starts at x ∈ [0.5, 3.0], y ∈ [2.0, 2.5], θ ∈ [−π, −π/2], arm
    retracted, fingers open, touching nothing. Everything then settles under gravity until all
    speeds are below 0.005 (spins below 0.05; at most 6 s of simulated time); velocities are then
    zeroed.

    ## Episode End
    Terminates when at least half of the small objects rest on the right: x > 1.75, y < 0.75 and
    squared speed < 1e-4. Truncated after 1000 steps by the registered TimeLimit.

    ## Arguments
    * `num_objects` (default 10): number of small objects (N // 2 discs, the rest squares).
    * `config`: a `DynScoopPour2DConfig` or a mapping of field overrides.

    ## Deviations
    * Upstream draws the small objects anywhere in x ∈ [0.2, 1.45], y ∈ [0, 1.3], overlapping, and
      settles for 30 s; here they start apart on a jittered lattice and settle until at rest
      (at most 6 s), which gives the same kind of pile far faster.
    * The scoop's corner starts at x ∈ [3.0, 3.3] (upstream: [3.125, 3.5]) so that open fingers
      fit on both sides of its handle without touching the right wall.
    * Upstream's class default is 10 circles and no squares; the registered variants (and this
      class) split N into N // 2 circles and N − N // 2 squares.
    * Time: 0.1 s of simulated time per action in two 0.05 s substeps
      (upstream: 1.0 s in 100 of 0.01 s); the robot tracks its commanded motion exactly
      rather than through a PD controller.
    * Each transition is computed from the observed state alone (a fresh physics space per
      action), so `set_state` replays exactly.
    * A transition that leaves an object outside the world, non-finite, or faster than 20 m/s
      (100 rad/s) is discarded; `env.num_physics_reverts` counts them.

    ## References
    KinDER (RSS 2026), the Dynamic2D environments; pymunk (Chipmunk2D).

    ## Version History
    * v0: initial version.
    """

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
        cols = int((cfg.lattice_x[1] - cfg.lattice_x[0]) // cfg.lattice_spacing)
        rows = -(-self.num_objects // cols) + 1
        top = cfg.lattice_min_y + rows * cfg.lattice_spacing
        if cols < 1 or top > cfg.wall_height:
            raise ValueError(
                f"DynScoopPour2D: {self.num_objects} small objects do not fit left of the wall "
                f"(a {cols}-column lattice would reach y = {top:.2f} > wall height "
                f"{cfg.wall_height})"
            )
        self._lattice = (cols, rows)
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

    def _sample_unsettled(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        statics = [WorldShape((sb.poly,)) for sb in self.scene.statics]
        hook_geom = dict(
            width=cfg.hook_width,
            length_side1=cfg.hook_length_side1,
            length_side2=cfg.hook_length_side2,
            mass=cfg.hook_mass,
        )
        hook_local = lobject_shape(cfg.hook_width, cfg.hook_length_side1, cfg.hook_length_side2)
        for _ in range(cfg.max_reset_tries):
            feats: dict[Object, dict[str, float]] = {}
            hx, hy = uniform(rng, *cfg.hook_init_x), uniform(rng, *cfg.hook_init_y)
            hook = place(hook_local, hx, hy, cfg.hook_init_theta)
            if any(overlaps(hook, s) for s in statics):
                continue
            feats[self.hook] = object_values(
                hx, hy, cfg.hook_init_theta, ot.BROWN, ot.Z_ALL, **hook_geom
            )
            robot = cfg.robot_values(
                uniform(rng, *cfg.robot_init_x),
                uniform(rng, *cfg.robot_init_y),
                uniform(rng, *cfg.robot_init_theta),
            )
            shape = kin_robot_geometry([robot[f] for f in ot.KIN_ROBOT_FEATURES]).shape
            if any(overlaps(shape, s) for s in (hook, *statics)):
                continue
            feats[self.robot] = robot
            feats.update(self._sample_smalls(rng))
            return ObjectCentricState.from_features(feats)
        raise RuntimeError(
            f"DynScoopPour2D: could not place the scoop and the robot without overlaps in "
            f"{cfg.max_reset_tries} tries"
        )

    def _sample_smalls(self, rng: np.random.Generator) -> dict[Object, dict[str, float]]:
        cfg = self.config
        cols, rows = self._lattice
        s = cfg.lattice_spacing
        cells = rng.choice(cols * rows, size=self.num_objects, replace=False)
        feats: dict[Object, dict[str, float]] = {}
        # Circles first, then squares, each in name order: a fixed assignment of draws.
        for obj, cell in zip([*self.circles, *self.squares], cells.tolist()):
            cx = cfg.lattice_x[0] + (cell % cols + 0.5) * s
            cy = cfg.lattice_min_y + (cell // cols + 0.5) * s
            th = uniform(rng, -math.pi, math.pi)
            if obj.type == ot.SMALL_CIRCLE:
                r = uniform(rng, *cfg.circle_radius)
                extent, geom, color = r, dict(radius=r), ot.ORANGE
            else:
                size = uniform(rng, *cfg.square_size)
                extent, geom, color = size / math.sqrt(2), dict(size=size), ot.PURPLE
            slack = max(0.0, s / 2 - extent)
            x = cx + uniform(rng, -slack, slack)
            y = cy + uniform(rng, -slack, slack)
            feats[obj] = object_values(x, y, th, color, ot.Z_ALL, mass=cfg.small_mass, **geom)
        return feats

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
