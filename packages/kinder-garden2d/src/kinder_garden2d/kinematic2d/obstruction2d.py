"""Obstruction2D: place a block on a target surface that other blocks may obstruct."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden2d.geometry import obbs_from_anchor
from kinder_garden2d.kinematic2d.base import Kinematic2DConfig, Kinematic2DEnv
from kinder_garden2d.kinematic2d.crv import Bodies
from kinder_garden2d.kinematic2d.object_types import (
    OBSTRUCTION_RED,
    PURPLE,
    RECTANGLE,
    TABLE_GREY,
    TARGET_BLOCK,
    TARGET_SURFACE,
    ZOrder,
)
from kinder_garden2d.kinematic2d.predicates import is_on

GOLDEN_RATIO = (1 + 5**0.5) / 2


@dataclass(frozen=True)
class Obstruction2DConfig(Kinematic2DConfig):
    """Obstruction2D's constants (world φ × 1 with a table along the bottom)."""

    world_max_x: float = GOLDEN_RATIO
    world_max_y: float = 1.0
    table_height: float = 0.1
    robot_init_x: tuple[float, float] = (0.1, GOLDEN_RATIO - 0.1)
    robot_init_y: tuple[float, float] = (0.8, 0.9)
    robot_init_theta: float = -np.pi / 2
    block_size: tuple[float, float] = (0.05, 0.2)  # width and height each uniform in this range
    block_init_x: tuple[float, float] = (0.1, GOLDEN_RATIO - 0.1)
    surface_extra_width: tuple[float, float] = (0.02, 0.05)
    surface_init_x: tuple[float, float] = (0.1, GOLDEN_RATIO - 0.1)
    obstruction_size: tuple[float, float] = (0.05, 0.2)
    obstruction_on_target_prob: float = 0.9
    obstruction_init_x: tuple[float, float] = (0.1, GOLDEN_RATIO - 0.1)
    # Blocks rest this far above the table so that they do not touch it.
    rest_gap: float = 1e-6
    on_tolerance: float = 0.025
    render_dpi: int = 250


def table_bodies(config: Obstruction2DConfig) -> Bodies:
    """The table: a constant, static z-ALL strip along the bottom of the world."""
    c = config
    obb = obbs_from_anchor(0.0, 0.0, 0.0, c.world_max_x - c.world_min_x, c.table_height)
    return Bodies.of(obb, [ZOrder.ALL], static=True)


class Obstruction2DEnv(Kinematic2DEnv):
    """Obstruction2D: put the target block on the target surface, clearing obstructions first.

    ## Description
    A φ × 1 world (φ ≈ 1.618) with a grey table along the bottom (height 0.1). A purple strip
    of the table top is the target surface; the purple target block rests elsewhere on the
    table, and `num_obstructions` red blocks rest on the table, most of them (probability 0.9
    each) overlapping the target surface in x, so they must be moved away first. The robot picks
    blocks up with its vacuum gripper (from above: it starts pointing down) and puts them down;
    there is no gravity, so released blocks stay where they are.

    ## Observation Space
    The Box view concatenates, in this order: `robot` (crv_robot: x, y, theta, base_radius,
    arm_joint, arm_length, vacuum, gripper_height, gripper_width), `target_surface`
    (target_surface), `target_block` (target_block), then `obstruction0` …
    `obstruction{N−1}` (rectangle) in sorted name order. Every rectangle has x, y, theta,
    static, color_r, color_g, color_b, z_order, width, height, anchored at its bottom-left
    corner. Size: 29 + 10·N (o0: 29, o4: 69).

    ## Action Space
    `Box(5, float32)`: `[dx, dy, dtheta, darm, vacuum]` with bounds ±0.05, ±0.05, ±π/16, ±0.1 and
    [0, 1]. The base moves by (dx, dy), the heading turns by dtheta (wrapped to [−π, π)), the
    arm extension changes by darm (clipped to [base_radius, arm_length]); `vacuum > 0.5` turns
    the suction on, and every movable object touching the suction zone then moves rigidly with
    the gripper. A step whose proposed state collides is discarded.

    ## Reward
    −1 on every step.

    ## Starting State
    Robot: x ~ U[0.1, φ − 0.1], y ~ U[0.8, 0.9], θ = −π/2 (pointing down), arm retracted,
    vacuum off. Target block: width and height ~ U[0.05, 0.2], resting on the table
    (y = 0.1 + 1e-6), x ~ U[0.1, φ − 0.1]. Target surface: y = 0, height 0.1 (the table's top
    layer), x ~ U[0.1, φ − 0.1], width = block width + U[0.02, 0.05]. Each obstruction: size
    ~ U[0.05, 0.2]², resting on the table, x ~ U[surface.x − w, surface.x + surface.width] with
    probability 0.9, else x ~ U[0.1, φ − 0.1]. A draw is rejected (up to 10 000 times) if any
    two things collide, the surface sticks out of the table, or the goal already holds. The
    draws are upstream's, in its order, so a seed gives upstream's initial state.

    ## Episode End
    1. Termination: `is_on(target_block, target_surface, tol=0.025)`: the block's two lowest
       vertices, each moved down by 0.025, lie in the target surface.
    2. Truncation (registered ids): after 3000 steps, the bilevel-planning evaluation budget
       of the paper's protocol (`max_eval_steps=3000`); pass `max_episode_steps` to `make` for
       shorter episodes.

    ## Arguments
    `num_obstructions` (int ≥ 0, default 2), `config` (`Obstruction2DConfig`), `render_mode`.

    ## Variants
    `kinder/Obstruction2D-o{0,1,2,3,4}-v0`: 0 to 4 obstructions.

    ## Deviations
    * The target surface is always drawn (over the table, under the blocks); upstream sometimes
      hid it (prpl-mono issue #37).
    * Obstructions placed "anywhere" draw x from [0, φ − w] (upstream's exact range is
      unspecified).
    * The outer walls are 1.0 thick instead of 2 × the step size (not observed).
    * Rendering is a numpy rasterizer (not matplotlib).

    ## Version History
    * v0: initial version, re-implemented from the KinDER specification.
    """

    def __init__(
        self,
        num_obstructions: int = 2,
        config: Obstruction2DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = config or Obstruction2DConfig()
        super().__init__(cfg, render_mode=render_mode)
        if int(num_obstructions) != num_obstructions or num_obstructions < 0:
            raise ValueError(
                f"Obstruction2DEnv: num_obstructions must be an int >= 0, got {num_obstructions!r}"
            )
        self.num_obstructions = int(num_obstructions)
        self.target_surface = Object("target_surface", TARGET_SURFACE)
        self.target_block = Object("target_block", TARGET_BLOCK)
        self.obstructions = [
            Object(f"obstruction{i}", RECTANGLE) for i in range(self.num_obstructions)
        ]
        table = table_bodies(cfg)
        self._setup_world(
            [self.target_surface, self.target_block, *self.obstructions],
            table,
            [(table.obbs, TABLE_GREY)],
        )

    def box_objects(self) -> list[Object]:
        return [self.robot, self.target_surface, self.target_block, *sorted(self.obstructions)]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, Obstruction2DConfig)
        rest_y = c.table_height + c.rest_gap

        def sample() -> ObjectCentricState | None:
            # Upstream's draws, in its order (a pose is x, y, theta, each drawn even where its
            # bounds are one value): robot pose, block pose, block width and height, surface
            # pose, surface extra width, then per obstruction its width, height, on-target
            # coin and pose.
            rx, ry = rng.uniform(*c.robot_init_x), rng.uniform(*c.robot_init_y)
            rth = rng.uniform(c.robot_init_theta, c.robot_init_theta)
            feats: dict[Object, list[float]] = {self.robot: self.robot_features(rx, ry, rth)}
            bx, by, bth = (
                rng.uniform(*c.block_init_x),
                rng.uniform(rest_y, rest_y),
                rng.uniform(0, 0),
            )
            bw, bh = rng.uniform(*c.block_size), rng.uniform(*c.block_size)
            feats[self.target_block] = [bx, by, bth, 0.0, *PURPLE, ZOrder.ALL, bw, bh]
            sx, sy, sth = rng.uniform(*c.surface_init_x), rng.uniform(0, 0), rng.uniform(0, 0)
            sw = bw + rng.uniform(*c.surface_extra_width)
            feats[self.target_surface] = [
                sx,
                sy,
                sth,
                1.0,
                *PURPLE,
                ZOrder.NONE,
                sw,
                c.table_height,
            ]
            for obstruction in self.obstructions:
                w, h = rng.uniform(*c.obstruction_size), rng.uniform(*c.obstruction_size)
                if rng.uniform() < c.obstruction_on_target_prob:
                    x = rng.uniform(sx - w, sx + sw)
                else:
                    x = rng.uniform(*c.obstruction_init_x)
                y, th = rng.uniform(rest_y, rest_y), rng.uniform(0, 0)
                feats[obstruction] = [x, y, th, 0.0, *OBSTRUCTION_RED, ZOrder.ALL, w, h]
            if sx < c.world_min_x or sx + sw > c.world_max_x:
                return None
            # Every block rests upright on the table, so two blocks collide exactly when their
            # x-intervals meet: a cheap early rejection before the exact check below.
            spans = sorted(
                (f[0], f[0] + f[8])
                for o, f in feats.items()
                if o is not self.robot and o is not self.target_surface
            )
            if any(b0 <= a1 for (_, a1), (b0, _) in itertools.pairwise(spans)):
                return None
            state = ObjectCentricState.from_features(feats)
            if self.goal_reached(state) or self.world.in_collision(state.data):
                return None
            return state

        return self._rejection_sample(sample, "the blocks and the target surface")

    def goal_reached(self, state: ObjectCentricState) -> bool:
        c = self.config
        assert isinstance(c, Obstruction2DConfig)
        return is_on(state, self.target_block, self.target_surface, c.on_tolerance)
