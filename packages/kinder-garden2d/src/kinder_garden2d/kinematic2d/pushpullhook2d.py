"""PushPullHook2D: use a hook to push a button into another one on a table."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinder_core import Object, ObjectCentricState
from kinder_core.state import FloatArray
from kinder_garden2d.geometry import lshape_obbs, obb_circle_overlap
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
    While the robot holds the hook and it overlaps the movable button, the button moves by the
    vector from the hook outline's closest point to the button's centre (upstream's rule: a few
    millimetres per step, not the overlap depth); the step is then checked for collisions.

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
    y ~ U[1.30, 1.95]. The hook and the buttons are redrawn (the robot is drawn once) until
    nothing collides (the target button checked as if it were on the SURFACE layer) and the
    buttons' centres are 0.15 to 0.30 apart. The draws are upstream's, in its order, so a seed
    gives upstream's initial state.

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
        self._hook_idx = idx(
            [self.hook], ["x", "y", "theta", "width", "length_side1", "length_side2"]
        )[0]
        self._movable_idx = idx([self.movable_button], ["x", "y", "radius"])[0]
        self._target_idx = idx([self.target_button], ["x", "y", "radius"])[0]
        self._color_idx = idx(
            [self.movable_button, self.target_button], ["color_r", "color_g", "color_b"]
        )

    def box_objects(self) -> list[Object]:
        return [self.robot, self.hook, self.movable_button, self.target_button]

    def _push(self, world: KinematicWorld, data: FloatArray, held: IntArray) -> IntArray:
        """Upstream's contact rule (in place): while the robot holds the hook or the movable
        button and it overlaps the other, that other one moves by the vector from the hook's
        boundary point closest to the button's centre to that centre.

        The step is the centre's distance to the L's outline, not the overlap depth, so a
        pushed button moves a few millimetres per step (the same vector moves the hook when
        the button is the held object).
        """
        hook, button = world.index[self.hook], world.index[self.movable_button]
        hook_held, button_held = hook in held, button in held
        if hook_held == button_held:
            return _EMPTY
        lx, ly, lth, lw, l1, l2 = data[self._hook_idx]
        circle = data[self._movable_idx]
        if not obb_circle_overlap(lshape_obbs(lx, ly, lth, lw, l1, l2), circle[None]).any():
            return _EMPTY
        px, py = lshape_closest_boundary_point(lx, ly, lth, lw, l1, l2, circle[0], circle[1])
        dx, dy = circle[0] - px, circle[1] - py
        if hook_held:
            data[self._movable_idx[0]] += dx
            data[self._movable_idx[1]] += dy
            return np.array([button], dtype=np.intp)
        data[self._hook_idx[0]] += dx
        data[self._hook_idx[1]] += dy
        return np.array([hook], dtype=np.intp)

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, PushPullHook2DConfig)
        r = c.button_radius

        # Upstream's draws, in its order: the robot pose once (its bounds keep it clear of the
        # walls and the table), then the hook pose and each button's (x, y) until the hook and
        # the buttons touch nothing and the buttons' centres are 0.15 to 0.30 apart.
        robot = self.robot_features(
            rng.uniform(*c.robot_init_x),
            rng.uniform(*c.robot_init_y),
            rng.uniform(-np.pi, np.pi),
        )
        rg = robot_geometry(robot)
        robot_b = Bodies.of(
            np.stack([rg.arm, rg.gripper]), [ZOrder.SURFACE] * 2, [rg.base], [ZOrder.ALL], owner=-1
        )
        low = (c.button_init_x[0], c.button_init_y[0])
        high = (c.button_init_x[1], c.button_init_y[1])

        def sample() -> ObjectCentricState | None:
            hook = (
                rng.uniform(*c.hook_init_x),
                rng.uniform(*c.hook_init_y),
                rng.uniform(*c.hook_init_theta),
            )
            m = [float(v) for v in rng.uniform(low, high)]
            t = [float(v) for v in rng.uniform(low, high)]
            lo, hi = c.button_init_distance
            if not lo < math.dist(m, t) < hi:
                return None
            hook_boxes = lshape_obbs(*hook, c.hook_width, c.hook_side1, c.hook_side2)
            parts = [
                Bodies.of(hook_boxes, [ZOrder.SURFACE] * 2, owner=0),
                Bodies.of(circles=[[*m, r]], circle_z=[ZOrder.SURFACE], owner=1),
                Bodies.of(circles=[[*t, r]], circle_z=[ZOrder.SURFACE], owner=2),
            ]
            for i, a in enumerate(parts):
                if bodies_collide(a, robot_b) or bodies_collide(a, self.world.constants):
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


def lshape_closest_boundary_point(
    x: float, y: float, theta: float, width: float, side1: float, side2: float, px: float, py: float
) -> tuple[float, float]:
    """The point of an L-shape's outline closest to ``(px, py)``.

    The outline is the L's six edges in upstream's order (outer corner at ``(x, y)``; the long
    side along -x, the short side along -y, before rotation by ``theta``); ties go to the first
    edge, as upstream's strict ``<`` scan does.
    """
    local = np.array(
        [(0, 0), (-side1, 0), (-side1, -width), (-width, -width), (-width, -side2), (0, -side2)],
        dtype=np.float64,
    )
    c, s = math.cos(theta), math.sin(theta)
    vx = (local[:, 0] * c - local[:, 1] * s) + x
    vy = (local[:, 0] * s + local[:, 1] * c) + y
    x1, y1 = vx, vy
    x2, y2 = np.roll(vx, -1), np.roll(vy, -1)
    dx, dy = x2 - x1, y2 - y1
    t = np.clip(((px - x1) * dx + (py - y1) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
    cx, cy = x1 + t * dx, y1 + t * dy
    k = int(np.argmin(np.hypot(cx - px, cy - py)))
    return float(cx[k]), float(cy[k])
