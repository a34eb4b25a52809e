"""StickButton2D: press every button, using a stick for those on the table."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricState
from kinder_core.state import FloatArray
from kinder_garden2d.geometry import (
    obbs_from_anchor,
)
from kinder_garden2d.kinematic2d.base import Kinematic2DConfig, Kinematic2DEnv
from kinder_garden2d.kinematic2d.crv import Bodies, bodies_collide, robot_geometry
from kinder_garden2d.kinematic2d.object_types import (
    BLACK,
    BROWN,
    BUTTON_GREEN,
    BUTTON_RED,
    CIRCLE,
    RECTANGLE,
    ZOrder,
)
from kinder_garden2d.kinematic2d.predicates import all_pressed


@dataclass(frozen=True)
class StickButton2DConfig(Kinematic2DConfig):
    """StickButton2D's constants (world 3.5 × 2.5, table over the upper half)."""

    world_max_x: float = 3.5
    world_max_y: float = 2.5
    table_min_y: float = 1.25  # the table spans the full width from here to the top
    robot_init_x: tuple[float, float] = (0.3, 3.2)
    robot_init_y: tuple[float, float] = (0.3, 0.95)
    stick_width: float = 0.05
    stick_height: float = 1.25
    stick_init_x: tuple[float, float] = (0.0, 3.45)
    stick_init_y: tuple[float, float] = (0.625, 1.125)
    button_radius: float = 0.05


def table_bodies(config: StickButton2DConfig) -> Bodies:
    """The table: a constant, static z-FLOOR box over the upper part of the world (the robot base
    cannot enter it; the arm, gripper and SURFACE objects pass over it)."""
    c = config
    obb = obbs_from_anchor(
        c.world_min_x,
        c.table_min_y,
        0.0,
        c.world_max_x - c.world_min_x,
        c.world_max_y - c.table_min_y,
    )
    return Bodies.of(obb, [ZOrder.FLOOR], static=True)


class StickButton2DEnv(Kinematic2DEnv):
    """StickButton2D: press all buttons; those on the table are only reachable with a stick.

    ## Description
    A 3.5 × 2.5 world whose upper half (y ≥ 1.25) is a table. The robot's base cannot enter the
    table, but its arm and gripper, and the stick, pass over it. `num_buttons` red buttons lie
    anywhere in the world; a button turns green, for good, as soon as the robot (base, arm or
    gripper, or its suction zone while the vacuum is on) or the stick touches it. The robot
    reaches only about 0.15 into the table (y ≈ 1.405), so buttons further up must be pressed
    with the stick, which the robot picks up with its vacuum gripper.

    ## Observation Space
    The Box view concatenates, in this order: `robot` (crv_robot: x, y, theta, base_radius,
    arm_joint, arm_length, vacuum, gripper_height, gripper_width), `stick` (rectangle: x, y,
    theta, static, color_r, color_g, color_b, z_order, width, height; anchored at its bottom-left
    corner), then `button0` … `button{N−1}` (circle: x, y, theta, static, color_r, color_g,
    color_b, z_order, radius) in sorted name order (`button10` sorts before `button2`). A
    button's colour is red (0.9, 0, 0) until pressed and green (0, 0.9, 0) after. Size:
    19 + 9·N (b1: 28, b10: 109).

    ## Action Space
    `Box(5, float32)`: `[dx, dy, dtheta, darm, vacuum]` with bounds ±0.05, ±0.05, ±π/16, ±0.1 and
    [0, 1]. The base moves by (dx, dy), the heading turns by dtheta (wrapped to [−π, π)), the
    arm extension changes by darm (clipped to [base_radius, arm_length]); `vacuum > 0.5` turns
    the suction on, and every movable object touching the suction zone then moves rigidly with
    the gripper. A step whose proposed state collides is discarded.

    ## Reward
    −1 on every step, except 0 on the step that presses the last button.

    ## Starting State
    Robot on the floor: x ~ U[0.3, 3.2], y ~ U[0.3, 0.95], θ ~ U[−π, π], arm retracted, vacuum
    off. Stick (0.05 × 1.25, brown, movable, z SURFACE, upright) with its bottom-left corner at
    x ~ U[0, 3.45], y ~ U[0.625, 1.125], so it straddles the table edge; redrawn until it
    touches neither the robot nor the walls. Buttons (radius 0.05, static) with centres uniform
    over the world shrunk by the radius, each redrawn until it touches neither the robot nor the
    stick (checked on the SURFACE layer; buttons may overlap each other, as upstream's check
    skips static pairs), then stored with z-order NONE so they never block anything. The draws
    are upstream's, in its order, so a seed gives upstream's initial state.

    ## Episode End
    1. Termination: every button is pressed (`all_pressed`).
    2. Truncation (registered ids): after 3000 steps, the bilevel-planning evaluation budget
       of the paper's protocol (`max_eval_steps=3000`); pass `max_episode_steps` to `make` for
       shorter episodes.

    ## Arguments
    `num_buttons` (int ≥ 1, default 3), `config` (`StickButton2DConfig`), `render_mode`.

    ## Variants
    `kinder/StickButton2D-b{1,2,3,5,10}-v0`: 1 to 10 buttons.

    ## Deviations
    * The outer walls are 1.0 thick instead of 2 × the step size (not observed; stops a held
      stick swung on the arm from leaving the world).
    * Rendering is a numpy rasterizer (not matplotlib).

    ## Version History
    * v0: initial version, re-implemented from the KinDER specification.
    """

    def __init__(
        self,
        num_buttons: int = 3,
        config: StickButton2DConfig | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        cfg = config or StickButton2DConfig()
        super().__init__(cfg, render_mode=render_mode)
        if int(num_buttons) != num_buttons or num_buttons < 1:
            raise ValueError(
                f"StickButton2DEnv: num_buttons must be an int >= 1, got {num_buttons!r}"
            )
        self.num_buttons = int(num_buttons)
        self.stick = Object("stick", RECTANGLE)
        self.buttons = [Object(f"button{i}", CIRCLE) for i in range(self.num_buttons)]
        table = table_bodies(cfg)
        self._setup_world([self.stick, *self.buttons], table, [(table.obbs, BLACK)])
        idx = self.layout.indices
        self._stick_idx = idx([self.stick], ["x", "y", "theta", "width", "height"])[0]
        self._button_circle_idx = idx(self.buttons, ["x", "y", "radius"])
        self._button_color_idx = idx(self.buttons, ["color_r", "color_g", "color_b"])

    def box_objects(self) -> list[Object]:
        return [self.robot, self.stick, *sorted(self.buttons)]

    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        c = self.config
        assert isinstance(c, StickButton2DConfig)
        r = c.button_radius
        feats: dict[Object, list[float]] = {}
        # Upstream's draws, in its order: the robot pose (never rejected; its bounds keep it
        # clear of the walls and the table), then the stick pose (x, y and a theta drawn from
        # [0, 0]) until the stick touches neither the robot nor the walls, then each button's
        # (x, y) until it touches neither the robot nor the stick (static objects are not
        # checked against each other, so buttons may overlap one another).
        robot = self.robot_features(
            rng.uniform(*c.robot_init_x), rng.uniform(*c.robot_init_y), rng.uniform(-np.pi, np.pi)
        )
        robot_b = _robot_bodies(robot)

        def one_stick() -> list[float] | None:
            sx, sy = rng.uniform(*c.stick_init_x), rng.uniform(*c.stick_init_y)
            th = rng.uniform(0.0, 0.0)
            stick_b = Bodies.of(
                obbs_from_anchor(sx, sy, th, c.stick_width, c.stick_height), [ZOrder.SURFACE]
            )
            if bodies_collide(stick_b, robot_b) or bodies_collide(stick_b, self.world.constants):
                return None
            return [sx, sy, th, 0.0, *BROWN, ZOrder.SURFACE, c.stick_width, c.stick_height]

        stick = self._rejection_sample(one_stick, "the stick clear of the robot and the walls")
        feats[self.robot] = robot
        feats[self.stick] = stick
        movers = Bodies.concat(
            [robot_b, Bodies.of(obbs_from_anchor(*stick[:3], *stick[8:10]), [ZOrder.SURFACE])]
        )
        low = (c.world_min_x + r, c.world_min_y + r)
        high = (c.world_max_x - r, c.world_max_y - r)
        for button in self.buttons:

            def one_button() -> tuple[float, float] | None:
                x, y = rng.uniform(low, high)
                probe = Bodies.of(circles=[[x, y, r]], circle_z=[ZOrder.SURFACE])
                return None if bodies_collide(probe, movers) else (float(x), float(y))

            x, y = self._rejection_sample(one_button, f"{button.name} clear of the robot and stick")
            feats[button] = [x, y, 0.0, 1.0, *BUTTON_RED, ZOrder.NONE, r]
        return ObjectCentricState.from_features(feats)

    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        state = super()._transition(state, action)
        press_touched_buttons(
            state.data,
            state.data[self.world.robot_idx],
            state.data[self._stick_idx][None],
            self._button_circle_idx,
            self._button_color_idx,
        )
        return state

    def goal_reached(self, state: ObjectCentricState) -> bool:
        return all_pressed(state, self.buttons)

    def reward(
        self,
        state: ObjectCentricState,
        action: FloatArray,
        next_state: ObjectCentricState,
        terminated: bool,
    ) -> float:
        return 0.0 if terminated else -1.0


def _robot_bodies(robot: list[float]) -> Bodies:
    g = robot_geometry(robot)
    return Bodies.of([g.arm, g.gripper], [ZOrder.SURFACE] * 2, [g.base], [ZOrder.ALL], owner=-1)


def press_touched_buttons(
    data: FloatArray,
    robot: FloatArray,
    pressers: FloatArray,
    button_circle_idx: NDArray[np.intp],
    button_color_idx: NDArray[np.intp],
) -> None:
    """Turn green (in place) every button that the robot's base, arm or gripper, its suction zone
    while the vacuum is on, or one of the ``pressers`` rectangles (rows ``[x, y, theta, width,
    height]``), touches. Upstream tests the button against every body of the robot, the suction
    zone included (it ignores z-orders there), so a vacuum that is on presses what it overlaps.

    Pressed buttons stay pressed, so only the others are tested, and only those within reach of
    the robot or a presser get the exact shape tests.
    """
    colors = data[button_color_idx]
    unpressed = np.flatnonzero(np.any(np.abs(colors - BUTTON_GREEN) > 1e-6, axis=1))
    if not unpressed.size:
        return
    buttons = data[button_circle_idx[unpressed]]
    x, y, th, br, aj, _, vac, gh, gw = robot.tolist()
    c, s = math.cos(th), math.sin(th)
    boxes = [
        (x + 0.5 * aj * c, y + 0.5 * aj * s, c, s, 0.5 * aj, 0.25 * gw),  # arm
        (x + aj * c, y + aj * s, c, s, 0.5 * gw, 0.5 * gh),  # gripper
    ]
    reach = aj + 0.5 * gw
    if vac > 0.5:  # the suction zone, as in robot_geometry
        boxes.append((x + (aj + 1.5 * gw) * c, y + (aj + 1.5 * gw) * s, c, s, 0.5 * gw, 0.5 * gh))
        reach = aj + 2.0 * gw
    # Bounding circles: the robot's reach, and each presser's circumcircle.
    near = [(x, y, max(br, math.hypot(reach, 0.5 * gh)))]
    for px, py, pth, pw, ph in pressers.tolist():
        pc, ps = math.cos(pth), math.sin(pth)
        cx = px + 0.5 * (pc * pw - ps * ph)
        cy = py + 0.5 * (ps * pw + pc * ph)
        boxes.append((cx, cy, pc, ps, 0.5 * pw, 0.5 * ph))
        near.append((cx, cy, 0.5 * math.hypot(pw, ph)))
    pressed = []
    for k, (bx, by, r) in zip(unpressed.tolist(), buttons.tolist()):
        if not any(math.hypot(bx - nx, by - ny) <= nr + r for nx, ny, nr in near):
            continue
        if math.hypot(bx - x, by - y) <= br + r or any(
            _circle_touches_box(bx, by, r, box) for box in boxes
        ):
            pressed.append(k)
    if pressed:
        data[button_color_idx[pressed]] = BUTTON_GREEN


def _circle_touches_box(
    x: float, y: float, r: float, box: tuple[float, float, float, float, float, float]
) -> bool:
    cx, cy, c, s, hw, hh = box
    dx, dy = x - cx, y - cy
    ex = max(abs(dx * c + dy * s) - hw, 0.0)
    ey = max(abs(dy * c - dx * s) - hh, 0.0)
    return ex * ex + ey * ey <= r * r
