"""ClutteredStorage2D: store every block in a shelf that is already partly full."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_garden2d.geometry import obbs_from_anchor
from kinder_garden2d.kinematic2d.base import Kinematic2DConfig, Kinematic2DEnv
from kinder_garden2d.kinematic2d.crv import Bodies, bodies_collide, robot_geometry
from kinder_garden2d.kinematic2d.object_types import (
    BLACK,
    BLOCK_BLUE,
    PURPLE,
    SHELF,
    TARGET_BLOCK,
    ZOrder,
)
from kinder_garden2d.kinematic2d.predicates import is_inside_shelf


@dataclass(frozen=True)
class ClutteredStorage2DConfig(Kinematic2DConfig):
    """ClutteredStorage2D's constants (world 5 × 3, a bigger robot, a shelf along the top)."""

    world_max_x: float = 5.0
    world_max_y: float = 3.0
    robot_base_radius: float = 0.2
    robot_arm_length: float = 0.8
    gripper_height: float = 0.14
    gripper_width: float = 0.02
    robot_init_x: tuple[float, float] = (0.8, 4.2)
    robot_init_y: tuple[float, float] = (0.8, 1.825)
    shelf_height: float = 0.375  # the shelf strip spans the full width at the top of the world
    block_width: float = 0.28
    block_height: float = 0.04
    slot_padding: float = 0.0375  # extra opening width per block
    block_in_shelf_dy: float = 0.08  # stored blocks' centres are this far above the shelf's base
    block_in_shelf_max_rotation: float = np.pi / 16
    render_dpi: int = 200


class ClutteredStorage2DEnv(Kinematic2DEnv):
    """ClutteredStorage2D: put every block into the shelf, around the blocks already there.

    ## Description
    A 5 × 3 world with a shelf strip along the top (y from 2.625 to 3). Most of the strip is
    solid (two black bookends, z ALL); one purple opening (z NONE) can hold blocks. Of the
    `num_blocks` thin blue blocks (0.28 × 0.04, z SURFACE), `num_blocks // 2` start inside the
    opening and the rest lie on the floor. The opening is only as wide as the stored blocks need
    (0.3175 per block, at least one slot), so the robot must rearrange the stored blocks to make
    room, e.g. by standing them upright, before inserting the others. The robot here is larger:
    base radius 0.2, arm up to 0.8, gripper 0.14 × 0.02.

    ## Observation Space
    The Box view concatenates, in this order: `robot` (crv_robot: x, y, theta, base_radius,
    arm_joint, arm_length, vacuum, gripper_height, gripper_width), `shelf` (shelf, a
    double_rectangle: x, y, theta, static, color_r, color_g, color_b, z_order, width, height
    of the whole strip, then x1, y1, theta1, width1, height1, z_order1, color_r1, color_g1,
    color_b1 of the opening), then `block0` … `block{N−1}` (target_block: x, y, theta, static,
    color_r, color_g, color_b, z_order, width, height, anchored at the bottom-left corner) in
    sorted name order. Size: 28 + 10·N (b1: 38, b15: 178).

    ## Action Space
    `Box(5, float32)`: `[dx, dy, dtheta, darm, vacuum]` with bounds ±0.05, ±0.05, ±π/16, ±0.1 and
    [0, 1]. The base moves by (dx, dy), the heading turns by dtheta (wrapped to [−π, π)), the
    arm extension changes by darm (clipped to [base_radius, arm_length]); `vacuum > 0.5` turns
    the suction on, and every movable object touching the suction zone then moves rigidly with
    the gripper. A step whose proposed state collides is discarded.

    ## Reward
    −1 on every step.

    ## Starting State
    Robot: x ~ U[0.8, 4.2], y ~ U[0.8, 1.825], θ ~ U[−π, π], arm retracted, vacuum off. Shelf:
    strip at x = 0, y = 2.625, 5 × 0.375; opening of width 0.3175 · max(1, N // 2) and the
    strip's height, x1 ~ U[0, 5 − width1]. The N // 2 stored blocks are centred in equal slots
    of the opening, 0.08 above its base, each turned by U[−π/16, π/16] about its centre. The
    other blocks: anchor (bottom-left corner, as upstream) uniform in the robot's start box,
    θ ~ U[−π, π], redrawn until nothing collides. The draws are upstream's, in its order, so a
    seed gives upstream's initial state.

    ## Episode End
    1. Termination: every block is inside the shelf opening (`is_inside_shelf` for each: all
       four vertices in the opening rectangle).
    2. Truncation (registered ids): after 3000 steps, the bilevel-planning evaluation budget
       of the paper's protocol (`max_eval_steps=3000`); pass `max_episode_steps` to `make` for
       shorter episodes.

    ## Arguments
    `num_blocks` (odd int ≥ 1, default 3), `config` (`ClutteredStorage2DConfig`),
    `render_mode`.

    ## Variants
    `kinder/ClutteredStorage2D-b{1,3,7,15}-v0`: 1, 3, 7 or 15 blocks.

    ## Deviations
    * The stored blocks sit in equal slots of the opening (centre of slot k at
      x1 + (k + ½) · width1 / n) rather than upstream's padded linspace; both keep
      0.01875 of clearance on each side of a level block.
    * The outer walls are 1.0 thick instead of 2 × the step size (not observed; stops a held
      block swung on the 0.8 arm from leaving the world).
    * Rendering is a numpy rasterizer (not matplotlib), at 200 pixels per world unit.

    ## Version History
    * v0: initial version, re-implemented from the KinDER specification.
    """

    def __init__(
        self,
        num_blocks: int = 3,
        config: ClutteredStorage2DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        super().__init__(config or ClutteredStorage2DConfig(), render_mode=render_mode)
        if int(num_blocks) != num_blocks or num_blocks < 1 or num_blocks % 2 == 0:
            raise ValueError(
                f"ClutteredStorage2DEnv: num_blocks must be an odd int >= 1, got {num_blocks!r}"
            )
        self.num_blocks = int(num_blocks)
        self.shelf = Object("shelf", SHELF)
        self.blocks = [Object(f"block{i}", TARGET_BLOCK) for i in range(self.num_blocks)]
        self._setup_world([self.shelf, *self.blocks])

    def box_objects(self) -> list[Object]:
        return [self.robot, self.shelf, *sorted(self.blocks)]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, ClutteredStorage2DConfig)
        n_in = self.num_blocks // 2
        bw, bh = c.block_width, c.block_height
        shelf_y = c.world_max_y - c.shelf_height
        width1 = (bw + c.slot_padding) * max(1, n_in)

        def sample() -> ObjectCentricState | None:
            # Upstream's draws, in its order: the robot pose, the opening's pose (x, then y and
            # theta from one-value ranges), the stored blocks' rotations, then each floor
            # block's pose (its anchor, the bottom-left corner, as upstream) until it touches
            # nothing.
            robot = self.robot_features(
                rng.uniform(*c.robot_init_x),
                rng.uniform(*c.robot_init_y),
                rng.uniform(-np.pi, np.pi),
            )
            x1 = rng.uniform(c.world_min_x, c.world_max_x - width1)
            y1, th1 = rng.uniform(shelf_y, shelf_y), rng.uniform(0.0, 0.0)
            feats: dict[Object, list[float]] = {
                self.robot: robot,
                self.shelf: [
                    *(c.world_min_x, y1, th1, 1.0, *BLACK, ZOrder.ALL),
                    *(c.world_max_x - c.world_min_x, c.shelf_height),
                    *(x1, y1, th1, width1, c.shelf_height, ZOrder.NONE, *PURPLE),
                ],
            }
            block = [0.0, *BLOCK_BLUE, ZOrder.SURFACE, bw, bh]  # static, colour, z-order, size
            rotations = rng.uniform(
                -c.block_in_shelf_max_rotation, c.block_in_shelf_max_rotation, size=n_in
            )
            for k, th in enumerate(rotations.tolist()):
                cx = x1 + (k + 0.5) * width1 / n_in
                cy = shelf_y + c.block_in_shelf_dy
                feats[self.blocks[k]] = [*_anchor_from_centre(cx, cy, th, bw, bh), th, *block]
            rg = robot_geometry(robot)
            placed = Bodies.concat(
                [
                    Bodies.of(
                        np.stack([rg.arm, rg.gripper]),
                        [ZOrder.SURFACE] * 2,
                        [rg.base],
                        [ZOrder.ALL],
                    ),
                    self.world.constants,
                    Bodies.of(
                        obbs_from_anchor(
                            [c.world_min_x, x1 + width1],
                            shelf_y,
                            0.0,
                            [x1 - c.world_min_x, c.world_max_x - x1 - width1],
                            c.shelf_height,
                        ),
                        [ZOrder.ALL] * 2,
                    ),
                    *(
                        Bodies.of(
                            obbs_from_anchor(feats[b][0], feats[b][1], feats[b][2], bw, bh),
                            [ZOrder.SURFACE],
                        )
                        for b in self.blocks[:n_in]
                    ),
                ]
            )
            for k in range(n_in, self.num_blocks):

                def one(placed: Bodies = placed) -> tuple[float, float, float, Bodies] | None:
                    x, y = rng.uniform(*c.robot_init_x), rng.uniform(*c.robot_init_y)
                    th = rng.uniform(-np.pi, np.pi)
                    probe = Bodies.of(obbs_from_anchor(x, y, th, bw, bh), [ZOrder.SURFACE])
                    return None if bodies_collide(probe, placed) else (x, y, th, probe)

                x, y, th, probe = self._rejection_sample(one, f"block{k} clear of everything")
                feats[self.blocks[k]] = [x, y, th, *block]
                placed = Bodies.concat([placed, probe])
            state = ObjectCentricState.from_features(feats)
            return None if self.world.in_collision(state.data) else state

        return self._rejection_sample(sample, "the robot and the blocks")

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return all(is_inside_shelf(state, b, self.shelf) for b in self.blocks)


def _anchor_from_centre(cx: float, cy: float, th: float, w: float, h: float) -> tuple[float, float]:
    """The bottom-left anchor of a ``w`` × ``h`` rectangle turned by ``th`` with this centre."""
    c, s = np.cos(th), np.sin(th)
    return cx - c * w / 2 + s * h / 2, cy - s * w / 2 - c * h / 2
