"""DynPushPullHook2D: use a hook to pull a block, surrounded by obstructions, down to a wall."""

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
    convex_penetration,
    kin_robot_geometry,
    lobject_shape,
    overlaps,
    place,
    rect_shape,
    transform,
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
    hook_width: float = 0.32 / 3
    hook_length_side1: float = 1.4
    hook_length_side2: float = 0.583
    hook_mass: float = 1.0
    hook_init_x: tuple[float, float] = (1.4, 3.393)
    hook_init_y: tuple[float, float] = (0.875, 1.167)
    hook_init_theta: tuple[float, float] = (-math.pi / 12, math.pi / 12)
    target_size: tuple[float, float] = (0.16, 0.477)
    target_init_x: tuple[float, float] = (0.583, 2.917)
    target_init_y: tuple[float, float] = (2.333, 2.917)
    obstruction_size: tuple[float, float] = (0.12, 0.583)
    obstruction_std: float = 0.25
    block_mass: float = 1.0
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

    The robot is kinematic and follows its commanded motion exactly over each action's 0.1 s
    (five 0.02 s substeps); a static contact (walls, or the middle wall for the base) returns it to
    its last pose and stops it for the rest of the action. Closing the fingers on the hook or a
    block grasps it (contact normal within 0.1 rad of the closing direction, centre of mass between
    the fingers, contact along the fingers); opening releases it with its velocity. Held objects
    push the others with the robot's infinite mass.

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
    Robot x, y ∈ [0.3, 0.4], θ ∈ [0, π/2], arm retracted, fingers open. Hook (width 0.107, arms
    1.4 and 0.583, mass 1) at x ∈ [1.4, 3.393], y ∈ [0.875, 1.167], θ ∈ [−π/12, π/12]. Target
    square (side U[0.16, 0.477], mass 1) at x ∈ [0.583, 2.917], y ∈ [2.333, 2.917], θ ∈ [−π, π).
    Obstructions (sides U[0.12, 0.583], mass 1, θ ∈ [−π, π)) are Gaussian (σ 0.25) around the
    target. Everything is sampled free of overlaps with everything else and with the walls.

    ## Episode End
    Terminates when the target block overlaps the middle wall. Truncated after 500 steps by the
    registered TimeLimit (the paper's evaluation budget for o5).

    ## Arguments
    * `num_obstructions` (default 3): number of obstruction blocks.
    * `config`: a `DynPushPullHook2DConfig` or a mapping of field overrides.

    ## Deviations
    * Time: 0.1 s of simulated time per action in five 0.02 s substeps
      (upstream: 1.0 s in 100 of 0.01 s); the robot tracks its commanded motion exactly
      rather than through a PD controller.
    * Each transition is computed from the observed state alone (a fresh physics space per
      action), so `set_state` replays exactly.
    * The hook's mass (1) and the obstructions' orientation (uniform) are our choices; upstream's
      are not specified.
    * A transition that leaves an object outside the world, non-finite, or faster than 20 m/s
      (100 rad/s) is discarded; `env.num_physics_reverts` counts them.

    ## References
    KinDER (RSS 2026), the Dynamic2D environments; pymunk (Chipmunk2D).

    ## Version History
    * v0: initial version.
    """

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

    def _sample_unsettled(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        statics = [WorldShape((sb.poly,)) for sb in self.scene.statics]
        lo = np.array([cfg.world_min_x, cfg.world_min_y])
        hi = np.array([cfg.world_max_x, cfg.world_max_y])
        tries = 100  # per object
        for _ in range(max(1, cfg.max_reset_tries // tries)):
            robot = cfg.robot_values(
                uniform(rng, *cfg.robot_init),
                uniform(rng, *cfg.robot_init),
                uniform(rng, *cfg.robot_init_theta),
            )
            feats: dict[Object, dict[str, float]] = {self.robot: robot}
            placed = [kin_robot_geometry([robot[f] for f in ot.KIN_ROBOT_FEATURES]).shape]

            hook_geom = dict(
                width=cfg.hook_width,
                length_side1=cfg.hook_length_side1,
                length_side2=cfg.hook_length_side2,
                mass=cfg.hook_mass,
            )
            side = uniform(rng, *cfg.target_size)
            todo: list[tuple[Object, dict[str, float], tuple[float, float, float]]] = [
                (self.hook, hook_geom, ot.BROWN),
                (self.target_block, dict(width=side, height=side, mass=cfg.block_mass), ot.ORANGE),
            ]
            for o in self.obstructions:
                w, h = uniform(rng, *cfg.obstruction_size), uniform(rng, *cfg.obstruction_size)
                todo.append((o, dict(width=w, height=h, mass=cfg.block_mass), ot.BROWN))
            ok = True
            for obj, geom, color in todo:
                for _ in range(tries):
                    x, y, th = self._sample_pose(rng, obj, feats)
                    shape = self._shape(obj, x, y, th, geom)
                    if _fits(shape, lo, hi, [*placed, *statics]):
                        feats[obj] = object_values(x, y, th, color, ot.Z_SURFACE, **geom)
                        placed.append(shape)
                        break
                else:
                    ok = False
                    break
            if ok:
                return ObjectCentricState.from_features(feats)
        raise RuntimeError(
            f"DynPushPullHook2D: could not place the hook, the target and "
            f"{self.num_obstructions} obstructions without overlaps in {cfg.max_reset_tries} tries"
        )

    def _sample_pose(
        self, rng: np.random.Generator, obj: Object, feats: dict[Object, dict[str, float]]
    ) -> tuple[float, float, float]:
        cfg = self.config
        if obj == self.hook:
            return (
                uniform(rng, *cfg.hook_init_x),
                uniform(rng, *cfg.hook_init_y),
                uniform(rng, *cfg.hook_init_theta),
            )
        if obj == self.target_block:
            return (
                uniform(rng, *cfg.target_init_x),
                uniform(rng, *cfg.target_init_y),
                uniform(rng, -math.pi, math.pi),
            )
        target = feats[self.target_block]
        return (
            float(rng.normal(target["x"], cfg.obstruction_std)),
            float(rng.normal(target["y"], cfg.obstruction_std)),
            uniform(rng, -math.pi, math.pi),
        )

    def _shape(self, obj: Object, x: float, y: float, th: float, g: dict[str, float]) -> WorldShape:
        if obj == self.hook:
            local = lobject_shape(g["width"], g["length_side1"], g["length_side2"])
        else:
            local = rect_shape(g["width"], g["height"])
        return place(local, x, y, th)

    def goal_reached(self, state: ObjectCentricState) -> bool:
        b = state[self.target_block]
        block = transform(rect_shape(b[12], b[13]).polys[0], b[0], b[1], b[2])
        return convex_penetration(block, self.middle_wall.poly) > 0.0


def _fits(shape: WorldShape, lo: np.ndarray, hi: np.ndarray, others: list[WorldShape]) -> bool:
    """Inside the world box [lo, hi] and overlapping none of ``others``."""
    inside = all(bool(np.all((p >= lo) & (p <= hi))) for p in shape.polys)
    return inside and not any(overlaps(shape, s) for s in others)
