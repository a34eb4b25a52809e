"""PushPullHook2D: use a hook to push a button into another one on a table."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_core.state import FloatArray
from kinder_garden2d.geometry import circle_push_out_of_obb, lshape_obbs, obb_circle_overlap
from kinder_garden2d.kinematic2d.base import Kinematic2DEnv
from kinder_garden2d.kinematic2d.crv import (
    Bodies,
    IntArray,
    KinematicWorld,
    bodies_collide,
    robot_geometry,
)
from kinder_garden2d.kinematic2d.object_types import (
    BLACK,
    BROWN,
    BUTTON_BLUE,
    BUTTON_GREEN,
    BUTTON_RED,
    CIRCLE,
    LOBJECT,
    ZOrder,
)
from kinder_garden2d.kinematic2d.predicates import all_pressed
from kinder_garden2d.kinematic2d.stickbutton2d import StickButton2DConfig, table_bodies

_EMPTY = np.zeros(0, dtype=np.intp)


@dataclass(frozen=True)
class PushPullHook2DConfig(StickButton2DConfig):
    """PushPullHook2D's constants (StickButton2D's world and table, plus the hook and buttons)."""

    hook_width: float = 0.05
    hook_side1: float = 1.25  # the long arm (handle)
    hook_side2: float = 0.625  # the short arm (hook)
    hook_init_x: tuple[float, float] = (0.0, 3.45)
    hook_init_y: tuple[float, float] = (1.25 - 0.3125, 1.25 + 0.3125)
    hook_init_theta: tuple[float, float] = (np.pi / 4, 3 * np.pi / 4)
    button_init_x: tuple[float, float] = (1.25, 2.35)
    button_init_y: tuple[float, float] = (1.30, 1.95)
    button_init_distance: tuple[float, float] = (0.15, 0.30)  # open interval
    press_distance: float = 0.10  # 2 × button radius


class PushPullHook2DEnv(Kinematic2DEnv):
    """PushPullHook2D: push a movable button into a fixed one with an L-shaped hook.

    ## Description
    The world of StickButton2D: 3.5 × 2.5 with a table over the upper half that the robot's base
    cannot enter. On the table lie a blue movable button and a red target button, out of the
    robot's reach. An L-shaped brown hook lies across the table edge. The robot picks up the
    hook with its vacuum gripper and uses it to push (or pull, with the inside of the L) the
    movable button until the two buttons' centres are closer than 0.10; both then turn green.
    While the robot holds an object that runs into a movable object, that object is pushed out
    of the way (by the smallest translation that separates them) instead of blocking the step.

    ## Observation Space
    The Box view concatenates, in this order: `robot` (crv_robot: x, y, theta, base_radius,
    arm_joint, arm_length, vacuum, gripper_height, gripper_width), `hook` (lobject: x, y,
    theta, static, color_r, color_g, color_b, z_order, width, length_side1, length_side2),
    `movable_button` and `target_button` (circle: x, y, theta, static, color_r, color_g,
    color_b, z_order, radius). The hook is anchored at the outer corner of its L: in its own
    frame (rotated by theta about the anchor) the long arm spans [−length_side1, 0] × [−width,
    0] and the short arm [−width, 0] × [−length_side2, 0]. Size: 38.

    ## Action Space
    `Box(5, float32)`: `[dx, dy, dtheta, darm, vacuum]` with bounds ±0.05, ±0.05, ±π/16, ±0.1 and
    [0, 1]. The base moves by (dx, dy), the heading turns by dtheta (wrapped to [−π, π)), the
    arm extension changes by darm (clipped to [base_radius, arm_length]); `vacuum > 0.5` turns
    the suction on, and every movable object touching the suction zone then moves rigidly with
    the gripper. A step whose proposed state collides is discarded.

    ## Reward
    −1 on every step, except 0 on the step that reaches the goal.

    ## Starting State
    Robot on the floor: x ~ U[0.3, 3.2], y ~ U[0.3, 0.95], θ ~ U[−π, π], arm retracted, vacuum
    off. Hook (width 0.05, arms 1.25 and 0.625, z SURFACE): anchor x ~ U[0, 3.45],
    y ~ U[0.9375, 1.5625], θ ~ U[π/4, 3π/4]. Movable button (radius 0.05, blue, z SURFACE) and
    target button (radius 0.05, red, static, stored with z NONE): centres x ~ U[1.25, 2.35],
    y ~ U[1.30, 1.95]. Everything is redrawn until nothing collides (the target button checked
    as if it were on the SURFACE layer) and the buttons' centres are 0.15 to 0.30 apart.

    ## Episode End
    1. Termination: both buttons are green (`all_pressed`).
    2. Truncation (registered id): after 3000 steps, the bilevel-planning evaluation budget
       of the paper's protocol (`max_eval_steps=3000`); pass `max_episode_steps` to `make` for
       shorter episodes.

    ## Arguments
    `config` (`PushPullHook2DConfig`), `render_mode`.

    ## Variants
    `kinder/PushPullHook2D-v0` only.

    ## Deviations
    * Pushing moves a touched circle by the minimum translation that separates it from the held
      object's boxes (two passes over the L's boxes); upstream moves it by the vector between
      the shapes' closest points. Only circles are pushed (the movable button is the only
      movable object besides the hook).
    * Pressed buttons stay green even if pushed apart again (latching, as in StickButton2D).
    * The L-shape convention above is this implementation's (the anchor is the L's outer
      corner).
    * The outer walls are 1.0 thick instead of 2 × the step size (not observed).
    * Rendering is a numpy rasterizer (not matplotlib).

    ## Version History
    * v0: initial version, re-implemented from the KinDER specification.
    """

    def __init__(
        self, config: PushPullHook2DConfig | None = None, render_mode: str | None = "rgb_array"
    ) -> None:
        cfg = config or PushPullHook2DConfig()
        super().__init__(cfg, render_mode=render_mode)
        self.hook = Object("hook", LOBJECT)
        self.movable_button = Object("movable_button", CIRCLE)
        self.target_button = Object("target_button", CIRCLE)
        table = table_bodies(cfg)
        self._setup_world(
            [self.hook, self.movable_button, self.target_button],
            table,
            [(table.obbs, BLACK)],
            push=self._push,
        )
        idx = self.layout.indices
        self._movable_idx = idx([self.movable_button], ["x", "y", "radius"])[0]
        self._target_idx = idx([self.target_button], ["x", "y", "radius"])[0]
        self._color_idx = idx(
            [self.movable_button, self.target_button], ["color_r", "color_g", "color_b"]
        )

    def box_objects(self) -> list[Object]:
        return [self.robot, self.hook, self.movable_button, self.target_button]

    def _push(self, world: KinematicWorld, data: FloatArray, held: IntArray) -> IntArray:
        """Push the movable button out of the held object's boxes (in place)."""
        button = world.index[self.movable_button]
        if button in held:
            return _EMPTY
        bodies = world.object_bodies(data)
        boxes = bodies.obbs[np.isin(bodies.rowner, held)]
        circle = data[self._movable_idx].copy()
        if not boxes.size or not obb_circle_overlap(boxes, circle[None]).any():
            return _EMPTY
        for _ in range(2):
            for box in boxes:
                circle[:2] += circle_push_out_of_obb(box, circle)
        data[self._movable_idx[:2]] = circle[:2]
        return np.array([button], dtype=np.intp)

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, PushPullHook2DConfig)
        r = c.button_radius

        def sample() -> ObjectCentricState | None:
            robot = self.robot_features(
                rng.uniform(*c.robot_init_x),
                rng.uniform(*c.robot_init_y),
                rng.uniform(-np.pi, np.pi),
            )
            hook = (
                rng.uniform(*c.hook_init_x),
                rng.uniform(*c.hook_init_y),
                rng.uniform(*c.hook_init_theta),
            )
            m = [rng.uniform(*c.button_init_x), rng.uniform(*c.button_init_y)]
            t = [rng.uniform(*c.button_init_x), rng.uniform(*c.button_init_y)]
            lo, hi = c.button_init_distance
            if not lo < math.dist(m, t) < hi:
                return None
            rg = robot_geometry(robot)
            hook_boxes = lshape_obbs(*hook, c.hook_width, c.hook_side1, c.hook_side2)
            parts = [
                Bodies.of(
                    np.stack([rg.arm, rg.gripper]),
                    [ZOrder.SURFACE] * 2,
                    [rg.base],
                    [ZOrder.ALL],
                    owner=-1,
                ),
                Bodies.of(hook_boxes, [ZOrder.SURFACE] * 2, owner=0),
                Bodies.of(circles=[[*m, r]], circle_z=[ZOrder.SURFACE], owner=1),
                Bodies.of(circles=[[*t, r]], circle_z=[ZOrder.SURFACE], owner=2),
            ]
            for i, a in enumerate(parts):
                if bodies_collide(a, self.world.constants):
                    return None
                if any(bodies_collide(a, b) for b in parts[i + 1 :]):
                    return None
            return ObjectCentricState.from_features(
                {
                    self.robot: robot,
                    self.hook: [
                        *hook,
                        0.0,
                        *BROWN,
                        ZOrder.SURFACE,
                        c.hook_width,
                        c.hook_side1,
                        c.hook_side2,
                    ],
                    self.movable_button: [*m, 0.0, 0.0, *BUTTON_BLUE, ZOrder.SURFACE, r],
                    self.target_button: [*t, 0.0, 1.0, *BUTTON_RED, ZOrder.NONE, r],
                }
            )

        return self._rejection_sample(sample, "the hook and the buttons")

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        state = super()._transition(state, action)
        c = self.config
        assert isinstance(c, PushPullHook2DConfig)
        d = state.data
        mx, my, _ = d[self._movable_idx]
        tx, ty, _ = d[self._target_idx]
        if math.hypot(mx - tx, my - ty) < c.press_distance:
            d[self._color_idx] = BUTTON_GREEN
        return state

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return all_pressed(state, [self.movable_button, self.target_button])

    def reward(
        self,
        state: ObjectCentricState,
        action: FloatArray,
        next_state: ObjectCentricState,
        terminated: bool,
    ) -> float:
        return 0.0 if terminated else -1.0
