"""The base class of the Kinematic2D environments: CRV robot, walls, bounds, rendering."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace
from kinder_core.spaces import FeatureBounds
from kinder_core.state import FloatArray, StateLayout
from kinder_garden2d.geometry import lshape_obbs, obb_corners
from kinder_garden2d.kinematic2d.crv import (
    Bodies,
    CRVActionLimits,
    KinematicWorld,
    PushFn,
    robot_geometry,
    world_walls,
)
from kinder_garden2d.kinematic2d.object_types import (
    CIRCLE,
    CRV_ROBOT,
    DOUBLE_RECTANGLE,
    KINEMATIC2D_TYPES,
    LOBJECT,
    ORANGE,
    ZOrder,
)
from kinder_garden2d.rendering import Canvas

T = TypeVar("T")

# The outer walls' colour (they are not observed; a grey that frames the world).
WALL_GREY = (0.35, 0.35, 0.35)
# Robot colours (RGB 0-255).
_ROBOT_BASE = (127, 127, 230)
_ROBOT_DARK = (40, 40, 40)


@dataclass(frozen=True)
class Kinematic2DConfig:
    """Constants shared by every Kinematic2D environment (families override the defaults)."""

    world_min_x: float = 0.0
    world_max_x: float = 2.5
    world_min_y: float = 0.0
    world_max_y: float = 2.5
    robot_base_radius: float = 0.1
    robot_arm_length: float = 0.2
    gripper_height: float = 0.07  # across the arm
    gripper_width: float = 0.01  # along the arm
    action_limits: CRVActionLimits = field(default_factory=CRVActionLimits)
    # Outer walls are this thick: far more than any body can travel in one step, so nothing
    # can tunnel out of the world.
    wall_thickness: float = 1.0
    # Bounded rejection sampling: a reset gives up with a RuntimeError after this many tries.
    max_sampling_tries: int = 10_000
    # Rendered image width in pixels per world unit (the upstream figures' dpi).
    render_dpi: int = 300
    # Antialiasing of rendered frames (see kinder_garden2d.rendering.Canvas).
    render_antialias: str = "analytic"
    render_supersample: int = 3

    @property
    def world_bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)``."""
        return (self.world_min_x, self.world_max_x, self.world_min_y, self.world_max_y)


def rgb255(color: Iterable[float]) -> tuple[int, int, int]:
    """A [0, 1] RGB colour as 0-255 ints."""
    r, g, b = (round(255 * min(max(float(c), 0.0), 1.0)) for c in color)
    return (r, g, b)


class Kinematic2DEnv(ObjectCentricEnv):
    """Shared machinery of the Kinematic2D families (not registered itself).

    A family's ``__init__`` builds its objects and calls :meth:`_setup_world`; it implements
    ``_sample_initial_state`` and ``goal_reached``, and may extend ``_transition``.

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

    config: Kinematic2DConfig
    robot: Object
    world: KinematicWorld

    def __init__(self, config: Kinematic2DConfig, render_mode: str | None = "rgb_array") -> None:
        super().__init__(render_mode=render_mode)
        if not isinstance(config, Kinematic2DConfig):
            raise ValueError(f"{type(self).__name__}: config must be a Kinematic2DConfig")
        self.config = config
        self.action_space = config.action_limits.space()
        self.observation_space = ObjectCentricStateSpace(KINEMATIC2D_TYPES)
        self.robot = Object("robot", CRV_ROBOT)
        self._canvas: Canvas | None = None
        # Constant scenery to draw: (OBB rows, colour in [0, 1]).
        self._constant_drawing: list[tuple[FloatArray, tuple[float, float, float]]] = []

    def _setup_world(
        self,
        objects: Sequence[Object],
        extra_constants: Bodies | None = None,
        extra_drawing: Sequence[tuple[FloatArray, tuple[float, float, float]]] = (),
        push: PushFn | None = None,
    ) -> None:
        """Fix the objects, the constant bodies (walls plus ``extra_constants``) and how the
        constants are drawn."""
        c = self.config
        walls = world_walls(*c.world_bounds, thickness=c.wall_thickness)
        constants = walls if extra_constants is None else Bodies.concat([walls, extra_constants])
        self.layout = StateLayout.of([self.robot, *objects])
        self.world = KinematicWorld(self.layout, self.robot, constants, push=push)
        self._constant_drawing = [(walls.obbs, WALL_GREY), *extra_drawing]

    # -- contract -------------------------------------------------------------------------------
    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        state.data = self.world.transition(state.data, action)
        return state

    def feature_bounds(self) -> FeatureBounds:
        c = self.config
        size = max(c.world_max_x - c.world_min_x, c.world_max_y - c.world_min_y)
        unit = (0.0, 1.0)
        angle = (-np.pi, np.pi)
        z = (0.0, float(ZOrder.NONE))
        return {
            "x": (c.world_min_x, c.world_max_x),
            "y": (c.world_min_y, c.world_max_y),
            "theta": angle,
            "static": unit,
            "color_r": unit,
            "color_g": unit,
            "color_b": unit,
            "z_order": z,
            "width": (0.0, size),
            "height": (0.0, size),
            "radius": (0.0, size),
            "length_side1": (0.0, size),
            "length_side2": (0.0, size),
            "x1": (c.world_min_x, c.world_max_x),
            "y1": (c.world_min_y, c.world_max_y),
            "theta1": angle,
            "width1": (0.0, size),
            "height1": (0.0, size),
            "z_order1": z,
            "color_r1": unit,
            "color_g1": unit,
            "color_b1": unit,
            "base_radius": (0.0, size),
            "arm_joint": (0.0, size),
            "arm_length": (0.0, size),
            "vacuum": unit,
            "gripper_height": (0.0, size),
            "gripper_width": (0.0, size),
        }

    # -- helpers for families -------------------------------------------------------------------
    def robot_features(self, x: float, y: float, theta: float) -> list[float]:
        """A robot at a pose with the arm retracted and the vacuum off."""
        c = self.config
        r = c.robot_base_radius
        return [x, y, theta, r, r, c.robot_arm_length, 0.0, c.gripper_height, c.gripper_width]

    def _rejection_sample(
        self, sample: Callable[[], T | None], what: str, tries: int | None = None
    ) -> T:
        """Call ``sample`` until it returns a value (``None`` = rejected), at most ``tries``
        times, then raise a RuntimeError naming the env and ``what``."""
        n = self.config.max_sampling_tries if tries is None else tries
        for _ in range(n):
            out = sample()
            if out is not None:
                return out
        raise RuntimeError(
            f"{type(self).__name__}: could not place {what} after {n} sampling tries; the "
            f"configuration may leave no valid placement (config: {self.config})"
        )

    def held_objects(self, state: ObjectCentricState) -> list[Object]:
        """The objects the robot's suction holds in ``state`` (they move with the gripper)."""
        return self.world.held_objects(state.data)

    # -- rendering ------------------------------------------------------------------------------
    def _make_canvas(self) -> Canvas:
        c = self.config
        xmin, xmax, ymin, ymax = c.world_bounds
        pad_x, pad_y = (xmax - xmin) / 25, (ymax - ymin) / 25
        canvas = Canvas(
            (xmin - pad_x, xmax + pad_x, ymin - pad_y, ymax + pad_y),
            width_px=max(1, round((xmax - xmin) * c.render_dpi)),
            supersample=c.render_supersample,
            antialias=c.render_antialias,
        )
        # Scenery first, grown past the world's edge where it touches it, then the walls over
        # the margin: adjacent antialiased edges would otherwise leave a light seam.
        walls, *scenery = self._constant_drawing
        for obbs, color in [*scenery, walls]:
            for corners in obb_corners(obbs):
                if obbs is not walls[0]:
                    corners = _grow_to_margin(corners, c.world_bounds, max(pad_x, pad_y))
                canvas.polygon(corners, rgb255(color))
        canvas.keep_as_background()
        return canvas

    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        if self._canvas is None:
            self._canvas = self._make_canvas()
        canvas = self._canvas
        canvas.clear()  # free after finish(), which hands over the buffer
        draw_objects(canvas, self.world, state.data)
        draw_robot(canvas, state.data[self.world.robot_idx])
        return canvas.finish()


def _grow_to_margin(
    corners: FloatArray, bounds: tuple[float, float, float, float], pad: float
) -> FloatArray:
    """Push the sides of an axis-aligned box that lie on the world's edge out by ``pad``."""
    xmin, xmax, ymin, ymax = bounds
    out: FloatArray = corners.copy()
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    if not np.allclose(np.sort(corners[:, 0]), [lo[0], lo[0], hi[0], hi[0]]):
        return out  # rotated: leave it
    for axis, (edge_lo, edge_hi) in enumerate(((xmin, xmax), (ymin, ymax))):
        out[np.isclose(corners[:, axis], edge_lo) & np.isclose(lo[axis], edge_lo), axis] -= pad
        out[np.isclose(corners[:, axis], edge_hi) & np.isclose(hi[axis], edge_hi), axis] += pad
    return out


def _draw_order(world: KinematicWorld, data: FloatArray) -> list[int]:
    """Static objects first (targets and regions, then walls and shelves), then the movable ones,
    each by ascending z-order: a block stored inside a shelf's opening is drawn over the shelf."""
    z = data[world.layout.indices(world.objects, ["z_order"])[:, 0]]
    static = data[world.static_idx] > 0.5
    key = [(0 if s else 1, zz, i) for i, (zz, s) in enumerate(zip(z, static))]
    return [i for *_, i in sorted(key)]


def draw_objects(canvas: Canvas, world: KinematicWorld, data: FloatArray) -> None:
    """Draw every non-robot object of a state in its colour."""
    layout = world.layout
    for i in _draw_order(world, data):
        obj = world.objects[i]
        f = data[layout.slice_of(obj)]
        color = rgb255(f[4:7])
        t = obj.type
        if t.is_subtype_of(CIRCLE):
            canvas.circle(f[:2], f[8], color, outline=_ROBOT_DARK, outline_width=0.004)
        elif t.is_subtype_of(LOBJECT):
            for corners in obb_corners(lshape_obbs(*f[[0, 1, 2, 8, 9, 10]])):
                canvas.polygon(corners, color)
        elif t.is_subtype_of(DOUBLE_RECTANGLE):
            x, y, th, w, h, x1, y1, th1, w1, h1 = f[[0, 1, 2, 8, 9, 10, 11, 12, 13, 14]]
            for ax, aw in ((x, x1 - x), (x1 + w1, x + w - x1 - w1)):
                canvas.polygon(_rect(ax, y, th, aw, h), color)
            canvas.polygon(_rect(x1, y1, th1, w1, h1), rgb255(f[16:19]))
        else:
            canvas.polygon(
                _rect(f[0], f[1], f[2], f[8], f[9]), color, outline=_ROBOT_DARK, outline_width=0.004
            )


def _rect(x: float, y: float, th: float, w: float, h: float) -> FloatArray:
    c, s = np.cos(th), np.sin(th)
    return np.array(
        [
            [x, y],
            [x + c * w, y + s * w],
            [x + c * w - s * h, y + s * w + c * h],
            [x - s * h, y + c * h],
        ]
    )


def draw_robot(canvas: Canvas, robot: FloatArray) -> None:
    """Draw the robot: base, arm, gripper and (while the vacuum is on) the suction zone."""
    g = robot_geometry(robot)
    canvas.circle(g.base[:2], g.base[2], _ROBOT_BASE, outline=_ROBOT_DARK, outline_width=0.006)
    canvas.polygon(obb_corners(g.arm)[0], _ROBOT_DARK)
    canvas.polygon(obb_corners(g.gripper)[0], _ROBOT_DARK)
    if g.vacuum_on:
        canvas.polygon(obb_corners(g.suction)[0], rgb255(ORANGE), alpha=0.8)
