"""The shared machinery of the Dynamic2D families: config, pymunk transitions, physics safety,
settling resets, feature bounds and rendering.

A family subclasses :class:`Dynamic2DEnv`, builds its objects and a :class:`~.physics.Scene` in
``__init__``, and implements ``_sample_initial_state(rng)`` (in upstream's draw order, settled
with its PD controller), ``_pd_specs``, ``goal_reached`` and, optionally, ``_draw_extras``.
"""

from __future__ import annotations

import abc
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState
from kinder_core.state import FloatArray
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.geometry import kin_robot_geometry, place, transform
from kinder_garden2d.dynamic2d.pd_physics import BodySpec, PDSettings, PDSpace
from kinder_garden2d.dynamic2d.physics import (
    GAP_EPS,
    PhysicsSettings,
    Scene,
    Simulation,
    StaticBox,
    shape_spec,
)
from kinder_garden2d.rendering import Canvas

ROBOT_BASE_COLOR = (70, 130, 180)
ROBOT_ARM_COLOR = (110, 110, 110)
ROBOT_GRIPPER_COLOR = (60, 60, 60)
ROBOT_FINGER_COLOR = (25, 25, 25)
OUTLINE = (20, 20, 20)


@dataclass(frozen=True)
class Dynamic2DConfig:
    """Constants every Dynamic2D family shares (each family's config subclasses this).

    Transitions (``controller``): ``"pd"`` (the default) is upstream kindergarden 0.2.5's: a PD
    controller (gains ``kp_*``/``kv_*``) sets the robot's velocities ``control_hz`` times per
    second of simulated time, physics runs at ``sim_hz``, and one action lasts
    ``(sim_hz // control_hz) ** 2 / sim_hz`` seconds (1 s with the defaults); see
    :mod:`~kinder_garden2d.dynamic2d.pd_physics`. ``"linear"`` is a kept alternative, off by
    default: each action lasts ``action_seconds`` of simulated time, integrated in substeps of
    ``substep_seconds``, and the robot follows its commanded motion exactly, spread evenly over
    the substeps (:mod:`~kinder_garden2d.dynamic2d.physics`).
    """

    controller: str = "pd"
    control_hz: int = 10
    sim_hz: int = 100
    kp_pos: float = 50.0
    kv_pos: float = 5.0
    kp_rot: float = 50.0
    kv_rot: float = 5.0
    # Upstream lets a freshly sampled scene settle this long (robot still) before the episode.
    stabilization_seconds: float = 1.0

    world_min_x: float = 0.0
    world_max_x: float = 1.0
    world_min_y: float = 0.0
    world_max_y: float = 1.0
    gravity: float = -9.8
    damping: float = 1.0  # pymunk: fraction of velocity kept per second
    action_seconds: float = 0.1
    substep_seconds: float = 0.02
    solver_iterations: int = 10
    warm_start: bool = True
    collision_slop: float = 0.001
    static_friction: float = 1.0
    static_elasticity: float = 0.99
    object_friction: float = 0.5
    robot_friction: float = 1.0
    wall_thickness: float = 1.0
    # Reset: settle until every object is slower than settle_speed_tol, at most this long.
    settle_max_seconds: float = 1.0
    settle_check_seconds: float = 0.1
    settle_speed_tol: float = 1e-3
    # Physics safety: a transition that leaves an object this far outside the world, faster than
    # max_speed / max_spin, or non-finite, is discarded (see the class docs).
    out_of_world_margin: float = 0.05
    max_speed: float = 20.0
    max_spin: float = 100.0
    max_reset_tries: int = 10_000
    render_width_px: int = 500

    def physics(self) -> PhysicsSettings:
        return PhysicsSettings(
            gravity=self.gravity,
            damping=self.damping,
            action_seconds=self.action_seconds,
            substep_seconds=self.substep_seconds,
            iterations=self.solver_iterations,
            collision_slop=self.collision_slop,
            static_friction=self.static_friction,
            static_elasticity=self.static_elasticity,
            object_friction=self.object_friction,
            robot_friction=self.robot_friction,
        )

    def walls(self) -> tuple[StaticBox, ...]:
        """Four thick static walls just outside the world box (z ALL)."""
        x0, x1, y0, y1, t = (
            self.world_min_x,
            self.world_max_x,
            self.world_min_y,
            self.world_max_y,
            self.wall_thickness,
        )
        return (
            StaticBox(x0 - t, x0, y0 - t, y1 + t),
            StaticBox(x1, x1 + t, y0 - t, y1 + t),
            StaticBox(x0, x1, y0 - t, y0),
            StaticBox(x0, x1, y1, y1 + t),
        )


@dataclass(frozen=True)
class KinRobotConfig(Dynamic2DConfig):
    """Dynamic2DConfig plus the two-finger robot's geometry and action bounds."""

    robot_base_radius: float = 0.24
    robot_arm_length: float = 0.48
    gripper_base_width: float = 0.06  # along the arm
    gripper_base_height: float = 0.32  # across the arm (also the largest finger gap)
    finger_height: float = 0.06  # across the arm (finger thickness)
    finger_width: float = 0.2  # along the arm (finger length)
    max_dx: float = 0.05
    max_dy: float = 0.05
    max_dtheta: float = math.pi / 16
    max_darm: float = 0.1
    max_dgripper: float = 0.02

    def action_space(self) -> gymnasium.spaces.Box:
        high = np.array(
            [self.max_dx, self.max_dy, self.max_dtheta, self.max_darm, self.max_dgripper]
        )
        return gymnasium.spaces.Box(-high, high, dtype=np.float64)

    def robot_values(self, x: float, y: float, theta: float) -> dict[str, float]:
        """Features of the robot at rest at (x, y, theta), arm retracted, fingers fully open."""
        vals = dict.fromkeys(ot.KIN_ROBOT_FEATURES, 0.0)
        vals.update(
            x=x,
            y=y,
            theta=theta,
            base_radius=self.robot_base_radius,
            arm_joint=self.robot_base_radius,
            arm_length=self.robot_arm_length,
            gripper_base_width=self.gripper_base_width,
            gripper_base_height=self.gripper_base_height,
            finger_gap=self.gripper_base_height,
            finger_height=self.finger_height,
            finger_width=self.finger_width,
        )
        return vals


def upstream_walls(
    cfg: Dynamic2DConfig, dx: float, dy: float
) -> list[tuple[str, float, float, float, float]]:
    """Upstream's four room walls as (name, x, y, width, height): centred boxes just outside the
    world, as thick as twice the largest base step (``dx``, ``dy``)."""
    x0, x1, y0, y1 = cfg.world_min_x, cfg.world_max_x, cfg.world_min_y, cfg.world_max_y
    side_h = y1 - y0
    horiz_w = 2 * 2 * abs(-dx) + x1 - x0
    return [
        ("right_wall", x1 + dx, (y0 + y1) / 2, 2 * dx, side_h),
        ("left_wall", x0 - dx, (y0 + y1) / 2, 2 * abs(-dx), side_h),
        ("top_wall", (x0 + x1) / 2, y1 + dy, horiz_w, 2 * dy),
        ("bottom_wall", (x0 + x1) / 2, y0 - dy, horiz_w, 2 * abs(-dy)),
    ]


def object_values(
    x: float,
    y: float,
    theta: float,
    color: tuple[float, float, float],
    z: float,
    static: float = 0.0,
    **extra: float,
) -> dict[str, float]:
    """Features of an object at rest (base features plus ``extra``)."""
    vals = dict(
        x=x,
        y=y,
        theta=theta,
        vx=0.0,
        vy=0.0,
        omega=0.0,
        static=float(static),
        held=0.0,
        color_r=color[0],
        color_g=color[1],
        color_b=color[2],
        z_order=z,
    )
    vals.update(extra)
    return vals


C = TypeVar("C", bound=Dynamic2DConfig)


def resolve_config(cls: type[C], config: C | Mapping[str, Any] | None) -> C:
    """The family's config: the defaults, a config instance, or a mapping of overrides."""
    if config is None:
        return cls()
    if isinstance(config, cls):
        return config
    if isinstance(config, Mapping):
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(config) - names)
        if unknown:
            raise ValueError(
                f"{cls.__name__} has no field(s) {unknown}; expected some of {sorted(names)}"
            )
        return dataclasses.replace(cls(), **config)
    raise ValueError(
        f"config must be a {cls.__name__}, a mapping of overrides or None, got {config!r}"
    )


def uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


class Dynamic2DEnv(ObjectCentricEnv):
    """Base of the Dynamic2D families (not registered itself).

    ## Description
    Base class.

    ## Observation Space
    See the families.

    ## Action Space
    See the families.

    ## Reward
    −1 per step.

    ## Starting State
    See the families.

    ## Episode End
    See the families.

    ## Version History
    * v0: initial version.
    """

    config: Dynamic2DConfig
    robot: Object
    scene: Scene
    static_colors: tuple[tuple[StaticBox, tuple[float, float, float]], ...] = ()

    def __init__(self, config: Dynamic2DConfig, render_mode: str | None) -> None:
        super().__init__(render_mode=render_mode)
        self.config = config
        config.physics().substeps  # noqa: B018 (validates the time settings early)
        if config.controller not in ("pd", "linear"):
            raise ValueError(f"controller must be 'pd' or 'linear', got {config.controller!r}")
        if config.control_hz < 1 or config.sim_hz % config.control_hz:
            raise ValueError(
                f"sim_hz ({config.sim_hz}) must be a positive multiple of control_hz "
                f"({config.control_hz})"
            )
        self.num_physics_reverts = 0
        self._warned_revert = False

    # -- upstream's PD transitions (controller "pd") -------------------------------------------
    @property
    def uses_pd(self) -> bool:
        """Whether transitions are upstream's PD-controlled ones (the default, for the families
        that implement :meth:`_pd_specs`)."""
        return self.config.controller == "pd" and self.has_pd

    has_pd = False  # families that build upstream's space set this

    def _pd_settings(self) -> PDSettings:
        """The family's PD physics settings (families override to add their specifics)."""
        cfg = self.config
        return PDSettings(
            gravity=cfg.gravity,
            damping=cfg.damping,
            collision_slop=cfg.collision_slop,
            control_hz=cfg.control_hz,
            sim_hz=cfg.sim_hz,
            kp_pos=cfg.kp_pos,
            kv_pos=cfg.kv_pos,
            kp_rot=cfg.kp_rot,
            kv_rot=cfg.kv_rot,
        )

    @abc.abstractmethod
    def _pd_specs(self, state: ObjectCentricState) -> list[BodySpec]:
        """How each object of ``state`` (and each constant object) enters upstream's space."""

    def _pd_space(self, state: ObjectCentricState) -> PDSpace:
        return PDSpace(self._pd_settings(), self.robot, state[self.robot], self._pd_specs(state))

    def _pd_settle(self, state: ObjectCentricState) -> ObjectCentricState:
        """Upstream's reset: the sampled scene settles for ``stabilization_seconds`` with the
        robot still; the state is then read back from the simulation (velocities included)."""
        sim = self._pd_space(state)
        sim.settle(self.config.stabilization_seconds)
        sim.write(state)
        return state

    def _pd_transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        sim = self._pd_space(state)
        sim.reindex()
        sim.act(action)
        sim.write(state)
        return state

    # -- family hooks --------------------------------------------------------------------------
    @abc.abstractmethod
    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        """A valid initial state drawn from ``rng``, in upstream's draw order (family-specific:
        the families draw and settle their objects differently)."""

    def _draw_extras(self, canvas: Canvas, state: ObjectCentricState) -> None:
        """Family-specific drawing under the objects (targets, goal outlines)."""

    # -- sampling ------------------------------------------------------------------------------
    def settle(self, state: ObjectCentricState) -> int:
        """Let the objects of ``state`` come to rest in place (robot still); velocities are then
        zeroed. Returns the substeps simulated."""
        cfg = self.config
        self.scene.index(state)
        dt = cfg.substep_seconds
        with Simulation(self.scene, state.data) as sim:
            steps = sim.settle(
                max_substeps=round(cfg.settle_max_seconds / dt),
                check_every=max(1, round(cfg.settle_check_seconds / dt)),
                speed_tol=cfg.settle_speed_tol,
            )
            sim.write(state.data)
        self._zero_velocities(state.data)
        return steps

    def _zero_velocities(self, data: FloatArray) -> None:
        scene = self.scene
        if len(scene.objects):
            data[scene.pose_idx[:, 3:]] = 0.0
        robot = data[scene.robot_slice]
        if scene.is_kin:
            robot[3:15] = 0.0
        else:
            robot[3:6] = 0.0

    # -- dynamics ------------------------------------------------------------------------------
    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        if self.uses_pd:
            return self._pd_transition(state, action)
        scene = self.scene
        scene.index(state)
        data = state.data
        before = data.copy()
        release = False
        if scene.is_kin:
            r = data[scene.robot_slice]
            gap = float(r[21])
            new_gap = min(max(gap + float(action[4]), 2 * float(r[22])), float(r[20]))
            release = new_gap > gap + GAP_EPS and bool(np.any(data[scene.held_idx] > 0.5))
        with Simulation(scene, data, release=release) as sim:
            if self.config.warm_start:
                sim.warm_start()
            sim.act(action)
            sim.write(data)
        if not self._physically_valid(data):
            # Tunnelling or a solver blow-up: discard the transition (everything stays put, at
            # rest) rather than let a broken state reach an observation.
            data[:] = before
            self._zero_velocities(data)
            self.num_physics_reverts += 1
            if not self._warned_revert:
                self._warned_revert = True
                gymnasium.logger.warn(
                    f"{type(self).__name__}: a transition left an object outside the world or "
                    f"moving implausibly fast; it was discarded (counted in num_physics_reverts)"
                )
        return state

    def _physically_valid(self, data: FloatArray) -> bool:
        cfg = self.config
        if not np.all(np.isfinite(data)):
            return False
        scene = self.scene
        if not len(scene.objects):
            return True
        p = data[scene.pose_idx]
        m = cfg.out_of_world_margin
        return bool(
            np.all(p[:, 0] >= cfg.world_min_x - m)
            and np.all(p[:, 0] <= cfg.world_max_x + m)
            and np.all(p[:, 1] >= cfg.world_min_y - m)
            and np.all(p[:, 1] <= cfg.world_max_y + m)
            and np.all(np.abs(p[:, 3:5]) <= cfg.max_speed)
            and np.all(np.abs(p[:, 5]) <= cfg.max_spin)
        )

    # -- bounds --------------------------------------------------------------------------------
    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        cfg = self.config
        m = cfg.out_of_world_margin
        size = max(cfg.world_max_x - cfg.world_min_x, cfg.world_max_y - cfg.world_min_y)
        v, w = cfg.max_speed, cfg.max_spin
        bounds: dict[str, tuple[float, float]] = {
            "x": (cfg.world_min_x - m, cfg.world_max_x + m),
            "y": (cfg.world_min_y - m, cfg.world_max_y + m),
            "theta": (-math.pi, math.pi),
            "vx": (-v, v),
            "vy": (-v, v),
            "omega": (-w, w),
            "static": (0.0, 1.0),
            "held": (0.0, 1.0),
            "color_r": (0.0, 1.0),
            "color_g": (0.0, 1.0),
            "color_b": (0.0, 1.0),
            "z_order": (0.0, ot.Z_NONE),
            "mass": (0.0, 100.0),
        }
        for f in (
            "width",
            "height",
            "length_side1",
            "length_side2",
            "length_horizontal",
            "length_vertical",
            "radius",
            "size",
            "base_radius",
            "arm_joint",
            "arm_length",
            "gripper_base_width",
            "gripper_base_height",
            "finger_gap",
            "finger_height",
            "finger_width",
        ):
            bounds[f] = (0.0, size)
        if self.scene.is_kin:
            hi = np.abs(self.action_space.high.astype(np.float64))
            t = cfg.action_seconds
            r = self.exemplar_state()[self.robot]
            reach = float(r[18] + r[19] / 2 + r[23] + r[20] / 2)
            lin = (float(np.hypot(hi[0], hi[1])) + hi[2] * reach + hi[3] + hi[4]) / t
            lin *= 1.01
            ang = float(hi[2] / t) * 1.01
            for part in ("base", "arm", "gripper_l", "gripper_r"):
                bounds[f"kin_robot.vx_{part}"] = (-lin, lin)
                bounds[f"kin_robot.vy_{part}"] = (-lin, lin)
                bounds[f"kin_robot.omega_{part}"] = (-ang, ang)
        if self.uses_pd:
            # Upstream's Box is unbounded: its PD-driven velocities and unwrapped angles have no
            # fixed range.
            return {k: (-math.inf, math.inf) for k in bounds}
        return bounds

    # -- rendering -----------------------------------------------------------------------------
    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        cfg = self.config
        canvas = Canvas(
            (cfg.world_min_x, cfg.world_max_x, cfg.world_min_y, cfg.world_max_y),
            width_px=cfg.render_width_px,
        )
        for sb, color in self.static_colors:
            canvas.polygon(sb.poly, fill=_rgb(color))
        self._draw_extras(canvas, state)
        held: list[Object] = []
        for obj in state:
            if obj == self.robot or obj.type.is_subtype_of(ot.KIN_RECTANGLE):
                continue
            if obj.type.name == "tobject" and state.get(obj, "static") > 0.5:
                continue  # goal outlines are family extras
            if state.get(obj, "held") > 0.5:
                held.append(obj)
                continue
            self._draw_object(canvas, state, obj)
        self._draw_robot(canvas, state)
        for obj in held:
            self._draw_object(canvas, state, obj)
        return canvas.image()

    def _draw_object(
        self, canvas: Canvas, state: ObjectCentricState, obj: Object, alpha: float = 1.0
    ) -> None:
        names, builder = shape_spec(obj.type)
        shape = builder(*(state.get(obj, n) for n in names))
        x, y, th = (state.get(obj, f) for f in ("x", "y", "theta"))
        color = _rgb([state.get(obj, c) for c in ("color_r", "color_g", "color_b")])
        ws = place(shape, x, y, th)
        lw = 0.006 * (self.config.world_max_x - self.config.world_min_x) / 3
        for p in ws.polys:
            canvas.polygon(p, fill=color, alpha=alpha, outline=OUTLINE, outline_width=lw)
        if len(ws.polys) > 1:  # hide the seams between the convex parts
            for p in ws.polys:
                canvas.polygon(p, fill=color, alpha=alpha)
        for cx, cy, r in ws.circles:
            canvas.circle((cx, cy), r, fill=color, alpha=alpha, outline=OUTLINE, outline_width=lw)

    def _draw_robot(self, canvas: Canvas, state: ObjectCentricState) -> None:
        f = state[self.robot]
        lw = 0.006 * (self.config.world_max_x - self.config.world_min_x) / 3
        if not self.scene.is_kin:
            canvas.circle(
                (f[0], f[1]), float(f[12]), fill=ROBOT_BASE_COLOR, outline=OUTLINE, outline_width=lw
            )
            return
        g = kin_robot_geometry(f)
        bx, by, br = g.base
        canvas.circle((bx, by), br, fill=ROBOT_BASE_COLOR, outline=OUTLINE, outline_width=lw)
        canvas.polygon(g.arm, fill=ROBOT_ARM_COLOR, outline=OUTLINE, outline_width=lw)
        canvas.polygon(g.gripper, fill=ROBOT_GRIPPER_COLOR, outline=OUTLINE, outline_width=lw)
        for finger in (g.finger_l, g.finger_r):
            canvas.polygon(finger, fill=ROBOT_FINGER_COLOR, outline=OUTLINE, outline_width=lw)
        # A heading mark on the base.
        tip = transform(np.array([[0.8 * br, 0.0]]), bx, by, float(f[2]))[0]
        canvas.line((bx, by), tip, width=lw * 2, color=OUTLINE)


def _rgb(c: tuple[float, float, float] | Any) -> tuple[int, int, int]:
    r, g, b = (min(255, max(0, round(255 * float(v)))) for v in c)
    return (r, g, b)
