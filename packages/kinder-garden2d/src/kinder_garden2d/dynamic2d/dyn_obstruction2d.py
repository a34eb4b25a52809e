"""DynObstruction2D: place a block on a target surface that other blocks may cover (pymunk)."""

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
    is_on,
    kin_robot_geometry,
    overlaps,
    place,
    rect_shape,
    transform,
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
    # Centres of the target surface and the blocks stay this far from the side walls, so that the
    # robot can reach them from above.
    reach_margin: float = 0.4
    obstruction_overlap_prob: float = 0.9
    robot_init_y: tuple[float, float] = (1.0, 1.6)
    robot_init_theta: tuple[float, float] = (-math.pi / 2, math.pi / 2)
    goal_tolerance: float = 0.025
    settle_max_seconds: float = 1.0


class DynObstruction2DEnv(Dynamic2DEnv):
    """Put the target block on the target surface; obstructions may sit on the surface.

    ## Description
    A side view with gravity. A two-finger robot (floating base, prismatic arm, gripper) must
    place the purple target block so that it rests on the purple target surface, a strip of the
    grey table. Red obstruction blocks often stand on the surface; the robot may pick them up and
    put them elsewhere, or push them away. All blocks are dynamic pymunk bodies (mass 1) that fall,
    slide and topple; a block wider than the open fingers' gap (0.26 between the finger faces)
    cannot be grasped, and toppling can make a block ungraspable.

    The robot is kinematic: each action moves it by the commanded deltas, spread evenly over the
    action's simulated time (0.1 s, five 0.02 s substeps). If any robot part (or what it holds)
    touches the table or a wall, the robot returns to its last pose, stops for the rest of that
    action, and nothing else about the action changes. Closing the fingers on a block grasps it
    when the contact normal is within 0.1 rad of the closing direction, the block's centre of mass
    lies between the fingers, and the contact is along the fingers; the block is then rigidly
    attached until the fingers open, when it is released with its current velocity. Two blocks
    between the closing fingers abort the grasp and the fingers open.

    ## Observation Space
    Object-centric states with objects `target_surface` (`target_surface`, 14 features),
    `target_block` (`target_block`, 15), `obstruction0..N-1` (`dyn_rectangle`, 15 each) and `robot`
    (`kin_robot`, 24). The Box view lists them in that order (the robot last, as upstream):
    14 + 15 + 15N + 24 values (68 for o1). Positions are body centres; velocities are of the
    centre of mass; angles are wrapped to [−π, π).

    ## Action Space
    `[dx, dy, dtheta, darm, dgripper]` (float64): base translation (±0.05) and rotation (±π/16),
    arm extension change (±0.1, the arm stays within [base_radius, arm_length]) and finger-gap
    change (±0.02, positive opens; the gap stays within [2·finger_height, gripper_base_height]).
    Out-of-bound actions are clipped.

    ## Reward
    −1 per step.

    ## Starting State
    A table across the bottom of a 3.236 × 2 world. The target block (width U[0.16, 0.48], height
    U[0.24, 0.48]) and N obstructions (same size ranges) stand on the table; the target surface is
    as wide as the block plus U[0.048, 0.12]. Each obstruction overlaps the surface horizontally
    with probability 0.9. Centres stay 0.4 from the side walls. Samples where blocks overlap or the
    goal already holds are redrawn. The robot starts above the blocks (x in the world less 0.3 at
    each side, y ∈ [1.0, 1.6], θ ∈ [−π/2, π/2]), arm retracted, fingers open, touching nothing.
    The blocks then settle (at most 1 s of simulated time; velocities are zeroed afterwards).

    ## Episode End
    Terminates when the target block is on the target surface: its two lowest corners, moved
    down by 0.025, lie inside the surface. Truncated after 500 steps by the registered TimeLimit.

    ## Arguments
    * `num_obstructions` (default 2): number of red obstruction blocks.
    * `config`: a `DynObstruction2DConfig` or a mapping of field overrides (world size, physics,
      time per action, robot geometry, sampling ranges).

    ## Deviations
    * Time: one action is 0.1 s of simulated time in five 0.02 s substeps (upstream integrates
      1.0 s per action in 100 substeps of 0.01 s, although its comments say 10 Hz). Contacts are
      solved with 10 iterations, and each action starts with one priming substep that is then
      undone (`warm_start`), so resting stacks do not creep. `action_seconds`,
      `substep_seconds`, `solver_iterations` and `warm_start` in the config change this.
    * The robot follows its commanded motion exactly (a linear interpolation over the action)
      instead of upstream's PD velocity controller (gains 50/5); actions therefore mean exactly
      "move by this delta" when nothing blocks the robot.
    * Each transition is computed from the observed state alone (a fresh physics space per
      action), so `set_state` replays exactly; contact impulses are not carried across actions.
    * Blocks and the surface keep 0.4 from the side walls; the robot starts above the blocks
      (upstream: x, y ∈ [0.2, 0.8], which can overlap the table and the blocks).
    * A held block stops the closing fingers; a grasp needs the geometric conditions above on a
      contact with either finger.
    * A transition that leaves an object outside the world, non-finite, or faster than 20 m/s
      (100 rad/s) is discarded (tunnelling safety); `env.num_physics_reverts` counts them.

    ## References
    KinDER (RSS 2026), the Dynamic2D environments; pymunk (Chipmunk2D).

    ## Version History
    * v0: initial version.
    """

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

    # -- sampling --------------------------------------------------------------------------------
    def _sample_unsettled(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        lo_x, hi_x = cfg.world_min_x + cfg.reach_margin, cfg.world_max_x - cfg.reach_margin
        top = cfg.table_height
        statics = [WorldShape((sb.poly,)) for sb in self.scene.statics]
        tries = 100  # per object
        for _ in range(max(1, cfg.max_reset_tries // tries)):
            sw = 0.0
            feats: dict[Object, dict[str, float]] = {}
            spans: list[tuple[float, float]] = []  # x-extents of the blocks on the table
            ok = True
            for obj in (self.target_block, *self.obstructions):
                for _ in range(tries):
                    w, h = uniform(rng, *cfg.block_width), uniform(rng, *cfg.block_height)
                    if obj == self.target_block:
                        sw = w + uniform(rng, *cfg.surface_padding)
                        sx = uniform(rng, max(lo_x, sw / 2), min(hi_x, cfg.world_max_x - sw / 2))
                        x = uniform(rng, lo_x, hi_x)
                        if abs(x - sx) < (sw - w) / 2 + cfg.goal_tolerance:
                            continue  # the goal would already hold
                    elif rng.uniform() < cfg.obstruction_overlap_prob:
                        reach = sw / 2 + w / 2
                        x = uniform(rng, max(lo_x, sx - reach), min(hi_x, sx + reach))
                    else:
                        x = uniform(rng, lo_x, hi_x)
                    if any(x + w / 2 > a and x - w / 2 < b for a, b in spans):
                        continue
                    spans.append((x - w / 2, x + w / 2))
                    color = ot.PURPLE if obj == self.target_block else ot.RED
                    feats[obj] = object_values(
                        x,
                        top + h / 2,
                        0.0,
                        color,
                        ot.Z_ALL,
                        width=w,
                        height=h,
                        mass=cfg.block_mass,
                    )
                    break
                else:
                    ok = False
                    break
            if not ok:
                continue
            feats[self.target_surface] = object_values(
                sx, top / 2, 0.0, ot.PURPLE, ot.Z_NONE, static=True, width=sw, height=top
            )
            blocks = [
                place(rect_shape(f["width"], f["height"]), f["x"], f["y"], 0.0)
                for o, f in feats.items()
                if o != self.target_surface
            ]
            for _ in range(tries):
                robot = cfg.robot_values(
                    uniform(rng, cfg.world_min_x + 0.3, cfg.world_max_x - 0.3),
                    uniform(rng, *cfg.robot_init_y),
                    uniform(rng, *cfg.robot_init_theta),
                )
                shape = kin_robot_geometry([robot[f] for f in ot.KIN_ROBOT_FEATURES]).shape
                if not any(overlaps(shape, o) for o in (*blocks, *statics)):
                    feats[self.robot] = robot
                    return ObjectCentricState.from_features(feats)
        raise RuntimeError(
            f"DynObstruction2D: could not place the target block, {self.num_obstructions} "
            f"obstructions and the robot without overlaps in {cfg.max_reset_tries} tries"
        )

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

    def _draw_extras(self, canvas: Canvas, state: ObjectCentricState) -> None:
        s = state[self.target_surface]
        poly = transform(rect_shape(s[12], s[13]).polys[0], s[0], s[1], s[2])
        canvas.polygon(poly, fill=(128, 0, 128))


__all__ = ["DynObstruction2DConfig", "DynObstruction2DEnv"]
