"""Motion2D: drive the robot through walls with gaps into a target region."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_core.spaces import FeatureBounds
from kinder_garden2d.kinematic2d.base import Kinematic2DConfig, Kinematic2DEnv
from kinder_garden2d.kinematic2d.object_types import (
    BLACK,
    PURPLE,
    RECTANGLE,
    TARGET_REGION,
    ZOrder,
)
from kinder_garden2d.kinematic2d.predicates import robot_in_region


@dataclass(frozen=True)
class Motion2DConfig(Kinematic2DConfig):
    """Motion2D's constants (world 2.5 × 2.5)."""

    robot_init_x: tuple[float, float] = (0.25, 0.30)
    robot_init_y: tuple[float, float] = (0.30, 2.20)
    target_size: float = 0.25
    target_init_x: tuple[float, float] = (2.20, 2.25)
    target_init_y: tuple[float, float] = (0.30, 2.20)
    passage_min_x: float = 0.5
    passage_max_x: float = 1.99
    wall_width: float = 0.01
    gap_bottom: tuple[float, float] = (0.2, 2.3)
    gap_height: tuple[float, float] = (0.25, 0.40)


class Motion2DEnv(Kinematic2DEnv):
    """Motion2D: pure motion planning for a circular vacuum robot through narrow passages.

    ## Description
    A 2.5 × 2.5 world is split by `num_passages` thin vertical walls, each with one gap. The
    robot starts near the left edge and must bring its base centre into the purple target
    region near the right edge, threading every gap. Nothing can be moved: the task tests
    motion planning alone (the robot's arm and vacuum work but have nothing to pick).

    The robot ("CRV") is a circle of radius 0.1 with a telescoping arm (0.1 to 0.2) ending in a
    0.07 × 0.01 gripper; when the vacuum is on, a suction zone in front of the gripper carries
    any movable object it touches. A step whose proposed state would collide is discarded.

    ## Observation Space
    The Box view concatenates, in this order: `robot` (crv_robot: x, y, theta, base_radius,
    arm_joint, arm_length, vacuum, gripper_height, gripper_width), `target_region` (target_region:
    x, y, theta, static, color_r, color_g, color_b, z_order, width, height; anchored at its
    bottom-left corner), then `obstacle0` … `obstacle{2N−1}` (rectangle, same ten features) in
    sorted name order (`obstacle10` sorts before `obstacle2`). Passage `i` is the pair
    `obstacle{2i}` (below the gap) and `obstacle{2i+1}` (above it). Size: 19 + 20·N
    (p0: 19, p2: 59, p5: 119). The full index table is in the generated docs page.

    ## Action Space
    `Box(5, float32)`: `[dx, dy, dtheta, darm, vacuum]` with bounds ±0.05, ±0.05, ±π/16, ±0.1 and
    [0, 1]. The base moves by (dx, dy), the heading turns by dtheta (wrapped to [−π, π)), the
    arm extension changes by darm (clipped to [base_radius, arm_length]); `vacuum > 0.5` turns
    the suction on. Out-of-bound actions are clipped; NaN/inf or a wrong shape raise ValueError.

    ## Reward
    −1 on every step.

    ## Starting State
    Robot: x ~ U[0.25, 0.30], y ~ U[0.30, 2.20], θ ~ U[−π, π], arm retracted, vacuum off.
    Target region: a fixed 0.25 × 0.25 square with its bottom-left corner at x ~ U[2.20, 2.25],
    y ~ U[0.30, 2.20]. Passages: walls of width 0.01, equally spaced with left sides from 0.5
    to 1.98 (upstream's spacing); each gap's bottom edge ~ U[0.2, 2.3] and height
    ~ U[0.25, 0.40]. A gap reaching above the world leaves the upper obstacle at y > 2.5 with a
    negative height (as upstream; it lies outside the world). The robot never collides
    initially. The draws are upstream's, in its order, so a seed gives upstream's initial state.

    ## Episode End
    1. Termination: the robot's base centre lies in the target region (`robot_in_region`).
    2. Truncation (registered ids): after 3000 steps, the bilevel-planning evaluation budget
       of the paper's protocol (`max_eval_steps=3000`), so that no baseline is cut short by the
       environment; learners that want shorter episodes pass `max_episode_steps` to `make`.

    ## Arguments
    `num_passages` (int ≥ 0, default 3), `config` (`Motion2DConfig`), `render_mode`
    (`"rgb_array"` or None).

    ## Variants
    `kinder/Motion2D-p{0,1,2,3,4,5}-v0`: 0 to 5 passages.

    ## Deviations
    * The outer walls are 1.0 thick instead of 2 × the step size; they are not observed, and
      thicker walls also stop a held object swung on the arm from leaving the world.
    * Rendering is a numpy rasterizer (not matplotlib): same colours, the robot drawn on top.

    ## Version History
    * v0: initial version, re-implemented from the KinDER specification.
    """

    def __init__(
        self,
        num_passages: int = 3,
        config: Motion2DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        super().__init__(config or Motion2DConfig(), render_mode=render_mode)
        if int(num_passages) != num_passages or num_passages < 0:
            raise ValueError(f"Motion2DEnv: num_passages must be an int >= 0, got {num_passages!r}")
        self.num_passages = int(num_passages)
        self.target_region = Object("target_region", TARGET_REGION)
        self.obstacles = [Object(f"obstacle{i}", RECTANGLE) for i in range(2 * self.num_passages)]
        self._setup_world([self.target_region, *self.obstacles])

    def box_objects(self) -> list[Object]:
        return [self.robot, self.target_region, *sorted(self.obstacles)]

    def feature_bounds(self) -> FeatureBounds:
        """The base bounds, widened for an upper obstacle that upstream leaves above the world
        (y up to the highest gap top, height down to minus the overshoot)."""
        bounds = dict(super().feature_bounds())
        c = self.config
        assert isinstance(c, Motion2DConfig)
        over = c.gap_bottom[1] + c.gap_height[1] - c.world_max_y
        if over > 0 and self.num_passages > 0:
            bounds["y"] = (bounds["y"][0], c.world_max_y + over)
            bounds["height"] = (-over, bounds["height"][1])
        return bounds

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, Motion2DConfig)
        top = c.world_max_y
        # Upstream's wall spacing: the gaps between walls are equal and the last wall's left
        # side is at passage_max_x − wall_width.
        n, w = self.num_passages, c.wall_width
        spacing = (c.passage_max_x - c.passage_min_x - n * w) / (n - 1) if n > 1 else 0.0
        wall_xs = [c.passage_min_x + i * (w + spacing) for i in range(n)]
        static_rect = [1.0, *BLACK, ZOrder.ALL]

        def sample() -> ObjectCentricState | None:
            feats: dict[Object, list[float]] = {
                self.robot: self.robot_features(
                    rng.uniform(*c.robot_init_x),
                    rng.uniform(*c.robot_init_y),
                    rng.uniform(-np.pi, np.pi),
                ),
                self.target_region: [
                    rng.uniform(*c.target_init_x),
                    rng.uniform(*c.target_init_y),
                    rng.uniform(0.0, 0.0),  # upstream draws the region's theta from [0, 0]
                    1.0,
                    *PURPLE,
                    ZOrder.NONE,
                    c.target_size,
                    c.target_size,
                ],
            }
            for i, wx in enumerate(wall_xs):
                bottom = rng.uniform(*c.gap_bottom)
                # As upstream: a gap reaching above the world leaves the upper obstacle above the
                # top edge with a negative height (a box outside the world, inside the wall).
                gap_top = bottom + rng.uniform(*c.gap_height)
                feats[self.obstacles[2 * i]] = [
                    wx,
                    c.world_min_y,
                    0.0,
                    *static_rect,
                    c.wall_width,
                    bottom - c.world_min_y,
                ]
                feats[self.obstacles[2 * i + 1]] = [
                    wx,
                    gap_top,
                    0.0,
                    *static_rect,
                    c.wall_width,
                    top - gap_top,
                ]
            state = ObjectCentricState.from_features(feats)
            return None if self.world.in_collision(state.data) else state

        return self._rejection_sample(sample, "the robot clear of the passages")

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return robot_in_region(state, self.robot, self.target_region)
