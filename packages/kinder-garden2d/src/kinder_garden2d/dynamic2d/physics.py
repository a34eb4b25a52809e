"""pymunk simulation of Dynamic2D transitions (imported by the env modules only, never at package
import).

Exact replay. pymunk keeps hidden state between steps (cached contact impulses used to warm-start
the solver, the spatial index's history, shape ids that order the broad phase). To make every
transition a function of the observable state alone, :class:`Simulation` builds a *fresh*
``pymunk.Space`` from the state for each action, always adding bodies and shapes in the same order,
runs the action's substeps, and reads the state back. Two builds from equal states therefore run
bit-identical computations, in any process, whatever the env did before.

The robot is made of kinematic bodies that follow the commanded motion exactly (see
:meth:`Simulation.act`); objects are dynamic bodies unless held, when they are kinematic bodies
rigidly attached to the gripper.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymunk
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricState, Type
from kinder_garden2d.dynamic2d import object_types as ot
from kinder_garden2d.dynamic2d.geometry import (
    LocalShape,
    box,
    circle_shape,
    kin_robot_local,
    lobject_shape,
    rect_shape,
    tobject_shape,
    wrap_angle,
)

# Collision types (used to route contact callbacks).
CT_STATIC = 0
CT_DYNAMIC = 1
CT_ROBOT = 2
CT_FINGER = 3
CT_HELD = 4
CT_NON_GRASPABLE = 5

# The robot's parts and what it holds never collide with each other.
_ROBOT_GROUP = 1
# Category bits of the z-orders.
_CAT = {ot.Z_FLOOR: 0b001, ot.Z_SURFACE: 0b010, ot.Z_ALL: 0b100}
_MASK = {ot.Z_FLOOR: 0b101, ot.Z_SURFACE: 0b110, ot.Z_ALL: 0b111}
# A grasp needs the contact normal within this angle of the fingers' closing direction.
GRASP_NORMAL_TOL = 0.1
# A finger-gap change smaller than this is neither opening nor closing.
GAP_EPS = 1e-3


def z_filter(z: float, robot: bool = False) -> pymunk.ShapeFilter:
    """The shape filter of a z-order (FLOOR, SURFACE or ALL)."""
    key = min(_CAT, key=lambda k: abs(k - z))
    return pymunk.ShapeFilter(
        group=_ROBOT_GROUP if robot else 0, categories=_CAT[key], mask=_MASK[key]
    )


@dataclass(frozen=True)
class PhysicsSettings:
    """Physical constants and integration settings of one family."""

    gravity: float
    damping: float
    action_seconds: float
    substep_seconds: float
    iterations: int = 10
    collision_slop: float = 0.001
    static_friction: float = 1.0
    static_elasticity: float = 0.99
    object_friction: float = 0.5
    robot_friction: float = 1.0

    @property
    def substeps(self) -> int:
        n = round(self.action_seconds / self.substep_seconds)
        if n < 1 or abs(n * self.substep_seconds - self.action_seconds) > 1e-9:
            raise ValueError(
                f"action_seconds ({self.action_seconds}) must be a positive whole multiple of "
                f"substep_seconds ({self.substep_seconds})"
            )
        return n


@dataclass(frozen=True)
class StaticBox:
    """An axis-aligned static rectangle of the world (walls, tables), not part of the state."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float
    z: float = ot.Z_ALL

    @property
    def poly(self) -> NDArray[np.float64]:
        return box(self.xmin, self.xmax, self.ymin, self.ymax)


# -- object shapes from features -------------------------------------------------------------------
_SHAPES: dict[str, tuple[tuple[str, ...], Callable[..., LocalShape]]] = {
    "kin_rectangle": (("width", "height"), rect_shape),
    "dyn_rectangle": (("width", "height"), rect_shape),
    "lobject": (("width", "length_side1", "length_side2"), lobject_shape),
    "tobject": (("width", "length_horizontal", "length_vertical"), tobject_shape),
    "small_circle": (("radius",), circle_shape),
    "small_square": (("size", "size"), rect_shape),
    "dot_robot": (("radius",), circle_shape),
}


def shape_spec(t: Type) -> tuple[tuple[str, ...], Callable[..., LocalShape]]:
    """The geometry features and shape builder of a type (or of its nearest known ancestor)."""
    s: Type | None = t
    while s is not None:
        if s.name in _SHAPES:
            return _SHAPES[s.name]
        s = s.parent
    raise ValueError(f"Type {t.name!r} has no Dynamic2D shape")


@dataclass(frozen=True)
class _MassProps:
    shape: LocalShape
    cog: tuple[float, float]
    moment: float
    polys: tuple[list[tuple[float, float]], ...]


_mass_cache: dict[tuple[str, tuple[float, ...], float], _MassProps] = {}


def mass_props(
    type_name: str, builder: Callable[..., LocalShape], geom: tuple[float, ...], mass: float
) -> _MassProps:
    """Shape, centre of mass and moment about it (uniform density), cached per geometry."""
    key = (type_name, geom, mass)
    props = _mass_cache.get(key)
    if props is None:
        shape = builder(*geom)
        cog = shape.centroid
        total = shape.area
        moment = 0.0
        offset = (-cog[0], -cog[1])
        for p in shape.polys:
            m = mass * _area(p) / total
            moment += pymunk.moment_for_poly(m, [(float(v[0]), float(v[1])) for v in p], offset)
        if shape.radius > 0:
            m = mass * math.pi * shape.radius**2 / total
            moment += pymunk.moment_for_circle(m, 0, shape.radius)
        polys = tuple([(float(v[0]), float(v[1])) for v in p] for p in shape.polys)
        props = _MassProps(shape, cog, moment, polys)
        if len(_mass_cache) > 100_000:  # bounded: geometry is resampled every episode
            _mass_cache.clear()
        _mass_cache[key] = props
    return props


def _area(p: NDArray[np.float64]) -> float:
    x, y = p[:, 0], p[:, 1]
    return abs(0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


# -- the scene: which objects are simulated and where their features live --------------------------
@dataclass
class Scene:
    """What a family simulates: its static boxes, its objects, its robot and settings.

    Built once per state layout. ``objects`` are the simulated (non-static) objects in a fixed
    order; ``graspable`` those the fingers may pick up.
    """

    settings: PhysicsSettings
    statics: tuple[StaticBox, ...]
    robot: Object
    objects: tuple[Object, ...]
    graspable: frozenset[Object]

    def __post_init__(self) -> None:
        self._indexed_layout: Any = None
        self.is_kin = self.robot.type.is_subtype_of(ot.KIN_ROBOT)

    def index(self, state: ObjectCentricState) -> None:
        """Precompute feature indices for this state's layout (once per layout)."""
        layout = state.layout
        if self._indexed_layout is layout:
            return
        objs = list(self.objects)
        self.pose_idx = layout.indices(objs, ["x", "y", "theta", "vx", "vy", "omega"])
        self.held_idx = layout.indices(objs, ["held"])[:, 0]
        self.z_idx = layout.indices(objs, ["z_order"])[:, 0]
        self.geom: list[tuple[str, Callable[..., LocalShape], NDArray[np.intp], int]] = []
        for o in objs:
            names, builder = shape_spec(o.type)
            mass_i = layout.index(o, "mass")
            self.geom.append((o.type.name, builder, layout.indices([o], list(names))[0], mass_i))
        self.robot_slice = layout.slice_of(self.robot)
        self._indexed_layout = layout


# -- one transition ------------------------------------------------------------------------------
class Simulation:
    """A fresh pymunk space holding one state; run :meth:`act` or :meth:`settle`, then
    :meth:`write` the result into a state array."""

    def __init__(self, scene: Scene, data: NDArray[np.float64], release: bool = False) -> None:
        st = scene.settings
        self.scene = scene
        self.dt = st.substep_seconds
        space = pymunk.Space()
        space.gravity = (0.0, st.gravity)
        space.damping = st.damping
        space.iterations = st.iterations
        space.collision_slop = st.collision_slop
        self.space = space
        for sb in scene.statics:
            shape = pymunk.Poly(space.static_body, [tuple(v) for v in sb.poly.tolist()])
            shape.friction = st.static_friction
            shape.elasticity = st.static_elasticity
            shape.filter = z_filter(sb.z)
            shape.collision_type = CT_STATIC
            space.add(shape)

        # Objects.
        poses = data[scene.pose_idx]
        held = data[scene.held_idx] > 0.5
        if release:
            held[:] = False
        self.released = release
        zs = data[scene.z_idx]
        self.bodies: list[pymunk.Body] = []
        self.shapes: list[list[pymunk.Shape]] = []
        self.shape_owner: dict[pymunk.Shape, int] = {}
        self.held: int = -1
        for i, obj in enumerate(scene.objects):
            tname, builder, gidx, mass_i = scene.geom[i]
            props = mass_props(tname, builder, tuple(data[gidx].tolist()), float(data[mass_i]))
            x, y, th, vx, vy, w = poses[i].tolist()
            if held[i]:
                body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
                if self.held >= 0:
                    raise ValueError(
                        f"state has more than one held object ({scene.objects[self.held].name}, "
                        f"{obj.name}); the robot holds at most one"
                    )
                self.held = i
            else:
                body = pymunk.Body(float(data[mass_i]), props.moment)
            # Order matters: pymunk rotates about the centre of mass, so set the angle before the
            # origin's position.
            body.center_of_gravity = props.cog
            body.angle = th
            body.position = (x, y)
            body.velocity = (vx, vy)
            body.angular_velocity = w
            shapes: list[pymunk.Shape] = [pymunk.Poly(body, p) for p in props.polys]
            if props.shape.radius > 0:
                shapes.append(pymunk.Circle(body, props.shape.radius))
            graspable = obj in scene.graspable
            ct = CT_HELD if held[i] else (CT_DYNAMIC if graspable else CT_NON_GRASPABLE)
            filt = z_filter(float(zs[i]), robot=bool(held[i]))
            for s in shapes:
                s.friction = st.object_friction
                s.filter = filt
                s.collision_type = ct
                self.shape_owner[s] = i
            space.add(body, *shapes)
            self.bodies.append(body)
            self.shapes.append(shapes)

        # Robot.
        self.robot_f = data[scene.robot_slice].copy()
        self.blocked = False
        if scene.is_kin:
            self._build_kin_robot()
        else:
            self._build_dot_robot()
        for ct in (CT_ROBOT, CT_FINGER, CT_HELD):
            space.on_collision(ct, CT_STATIC, pre_solve=self._on_static)

    # -- robot construction ----------------------------------------------------------------------
    def _robot_body(
        self, polys: Sequence[NDArray[np.float64]], ct: int, z: float, radius: float = 0.0
    ) -> pymunk.Body:
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        shapes: list[pymunk.Shape] = [
            pymunk.Poly(body, [tuple(v) for v in p.tolist()]) for p in polys
        ]
        if radius > 0:
            shapes.append(pymunk.Circle(body, radius))
        for s in shapes:
            s.friction = self.scene.settings.robot_friction
            s.filter = z_filter(z, robot=True)
            s.collision_type = ct
        self.space.add(body, *shapes)
        return body

    def _build_dot_robot(self) -> None:
        f = self.robot_f
        self.base = self._robot_body((), CT_ROBOT, ot.Z_ALL, radius=float(f[12]))
        self.base.position = (float(f[0]), float(f[1]))

    def _build_kin_robot(self) -> None:
        f = self.robot_f
        self.radius, self.arm_len = float(f[16]), float(f[18])
        self.gw, self.gh, self.fh, self.fw = float(f[19]), float(f[20]), float(f[22]), float(f[23])
        arm, grip, left, _ = kin_robot_local(
            0.0, self.arm_len, self.gw, self.gh, 0.0, self.fh, self.fw
        )
        # Finger bodies have their origin at the finger centre (left/right made at zero gap).
        fc = self.gw / 2 + self.fw / 2
        finger = left - np.array([fc, 0.0])
        self.base = self._robot_body((), CT_ROBOT, ot.Z_ALL, radius=self.radius)
        self.gripper = self._robot_body((arm, grip), CT_ROBOT, ot.Z_SURFACE)
        self.finger_l = self._robot_body((finger,), CT_FINGER, ot.Z_SURFACE)
        self.finger_r = self._robot_body((finger,), CT_FINGER, ot.Z_SURFACE)
        self.q = [float(f[0]), float(f[1]), float(f[2]), float(f[17]), float(f[21])]
        if self.held >= 0:
            self._attach(self.held)
        self._place_kin(self.q)

    # -- kinematics --------------------------------------------------------------------------------
    def _kin_points(
        self, q: Sequence[float]
    ) -> tuple[float, float, float, float, float, float, float, float]:
        """Gripper centre and finger centres for robot configuration q = (x, y, θ, arm, gap)."""
        x, y, th, arm, gap = q
        c, s = math.cos(th), math.sin(th)
        gx, gy = x + arm * c, y + arm * s
        fo = self.gw / 2 + self.fw / 2
        h = gap / 2
        return (
            gx,
            gy,
            gx + fo * c - h * s,
            gy + fo * s + h * c,
            gx + fo * c + h * s,
            gy + fo * s - h * c,
            c,
            s,
        )

    def _place_kin(self, q: Sequence[float]) -> None:
        gx, gy, lx, ly, rx, ry, _, _ = self._kin_points(q)
        th = q[2]
        for body, (px, py) in (
            (self.base, (q[0], q[1])),
            (self.gripper, (gx, gy)),
            (self.finger_l, (lx, ly)),
            (self.finger_r, (rx, ry)),
        ):
            body.position = (px, py)
            body.angle = th
            body.velocity = (0.0, 0.0)
            body.angular_velocity = 0.0
        if self.held >= 0:
            b = self.bodies[self.held]
            self._set_cog(b, *self._held_pose(q))
            b.velocity = (0.0, 0.0)
            b.angular_velocity = 0.0

    @staticmethod
    def _set_cog(b: pymunk.Body, cx: float, cy: float, th: float) -> None:
        """Place a body so that its centre of mass is at (cx, cy) with angle th."""
        ox, oy = _rot(b.center_of_gravity, th)
        b.angle = th
        b.position = (cx - ox, cy - oy)

    def _attach(self, i: int) -> None:
        """Record the rigid transform from the gripper to object i's centre of mass."""
        b = self.bodies[i]
        gx, gy, *_, c, s = self._kin_points(self.q)
        cog = b.local_to_world(b.center_of_gravity)
        dx, dy = cog[0] - gx, cog[1] - gy
        self.held_rel = (c * dx + s * dy, -s * dx + c * dy, b.angle - self.q[2])
        self.held = i

    def _held_pose(self, q: Sequence[float]) -> tuple[float, float, float]:
        """World centre of mass and angle of the held object for configuration q."""
        gx, gy, *_, c, s = self._kin_points(q)
        u, v, dth = self.held_rel
        return gx + c * u - s * v, gy + s * u + c * v, q[2] + dth

    # -- contact callbacks -------------------------------------------------------------------------
    def _on_static(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        self.blocked = True
        arbiter.process_collision = False

    def _on_finger(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        a, b = arbiter.shapes
        i = self.shape_owner.get(b, self.shape_owner.get(a, -1))
        if i < 0 or not self._grasp_open:
            return
        gx, gy, *_, c, s = self._kin_points(self._q_step)
        n = arbiter.normal
        if abs(n[0] * c + n[1] * s) > math.sin(GRASP_NORMAL_TOL):
            return
        body = self.bodies[i]
        cog = body.local_to_world(body.center_of_gravity)
        if abs(-(cog[0] - gx) * s + (cog[1] - gy) * c) > self.gh / 2:
            return
        lo, hi = self.gw / 2 - 1e-6, self.gw / 2 + self.fw + 1e-6
        for pt in arbiter.contact_point_set.points:
            for p in (pt.point_a, pt.point_b):
                along = (p[0] - gx) * c + (p[1] - gy) * s
                if lo <= along <= hi:
                    self._candidates.add(i)
                    return

    # -- running -----------------------------------------------------------------------------------
    def warm_start(self) -> None:
        """Prime the contact solver: one substep with the robot still, then every object is put
        back exactly as the state says. The contacts (and their impulses) found in that substep
        warm-start the first real substep, as they would in an uninterrupted simulation; without
        this, resting stacks creep a little at every action boundary."""
        saved = [
            (b.angle, b.position, b.velocity, b.angular_velocity)
            for i, b in enumerate(self.bodies)
            if i != self.held
        ]
        self.space.step(self.dt)
        dyn = (b for i, b in enumerate(self.bodies) if i != self.held)
        for b, (a, p, v, w) in zip(dyn, saved):
            b.angle = a
            b.position = p
            b.velocity = v
            b.angular_velocity = w
        self.blocked = False

    def act(self, action: NDArray[np.float64]) -> None:
        """Run one action: the robot moves linearly from its pose to the commanded one over the
        action's substeps (reaching it exactly unless stopped by a static contact)."""
        if self.scene.is_kin:
            self._act_kin(action)
        else:
            self._act_dot(action)

    def _act_dot(self, action: NDArray[np.float64]) -> None:
        n, dt = self.scene.settings.substeps, self.dt
        base = self.base
        x, y = self.robot_f[0], self.robot_f[1]
        tx, ty = x + float(action[0]), y + float(action[1])
        self.robot_v = (0.0, 0.0)
        stopped = False
        for k in range(n):
            if stopped:
                self.space.step(dt)
                continue
            rem = n - k
            nx, ny = x + (tx - x) / rem, y + (ty - y) / rem
            v = ((nx - x) / dt, (ny - y) / dt)
            base.velocity = v
            self.space.step(dt)
            if self.blocked:
                base.position = (x, y)
                base.velocity = (0.0, 0.0)
                self.robot_v = (0.0, 0.0)
                stopped = True
                continue
            x, y = nx, ny
            self.robot_v = v
        self.robot_f[0], self.robot_f[1] = x, y

    def _act_kin(self, action: NDArray[np.float64]) -> None:
        n, dt = self.scene.settings.substeps, self.dt
        q = list(self.q)
        target = [
            q[0] + float(action[0]),
            q[1] + float(action[1]),
            q[2] + float(action[2]),
            min(max(q[3] + float(action[3]), self.radius), self.arm_len),
            min(max(q[4] + float(action[4]), 2 * self.fh), self.gh),
        ]
        closing = target[4] < q[4] - GAP_EPS
        if self.held >= 0 and target[4] < q[4]:
            target[4] = q[4]  # a held object stops the fingers
        self._grasp_open = closing and self.held < 0
        self._candidates: set[int] = set()
        if self._grasp_open:
            self.space.on_collision(CT_FINGER, CT_DYNAMIC, post_solve=self._on_finger)
        bodies = (self.base, self.gripper, self.finger_l, self.finger_r)
        pts = self._kin_points(q)
        hold = self._held_pose(q) if self.held >= 0 else None
        self.vel = [(0.0, 0.0, 0.0)] * 5
        stopped = False
        for k in range(n):
            if stopped:
                self.space.step(dt)
                continue
            rem = n - k
            nq = [a + (b - a) / rem for a, b in zip(q, target)]
            npts = self._kin_points(nq)
            w = (nq[2] - q[2]) / dt
            vel = [
                ((nq[0] - q[0]) / dt, (nq[1] - q[1]) / dt, w),
                ((npts[0] - pts[0]) / dt, (npts[1] - pts[1]) / dt, w),
                ((npts[2] - pts[2]) / dt, (npts[3] - pts[3]) / dt, w),
                ((npts[4] - pts[4]) / dt, (npts[5] - pts[5]) / dt, w),
            ]
            for body, (vx, vy, vw) in zip(bodies, vel):
                body.velocity = (vx, vy)
                body.angular_velocity = vw
            nhold = None
            if hold is not None:
                nhold = self._held_pose(nq)
                hv = ((nhold[0] - hold[0]) / dt, (nhold[1] - hold[1]) / dt, w)
                hb = self.bodies[self.held]
                hb.velocity = (hv[0], hv[1])
                hb.angular_velocity = w
                vel.append(hv)
            self._q_step = nq
            self.space.step(dt)
            if self.blocked:
                self._place_kin(q)
                self.vel = [(0.0, 0.0, 0.0)] * 5
                stopped = True
                self._candidates.clear()
                continue
            q, pts, hold = nq, npts, nhold
            self.vel = vel
            if self._candidates:
                if len(self._candidates) == 1:
                    self._grasp(self._candidates.pop(), q)
                    hold = self._held_pose(q)
                    target[4] = q[4]
                else:  # more than one object between the fingers: abort and open
                    target[4] = self.gh
                self._grasp_open = False
                self._candidates.clear()
        self.q = q

    def _grasp(self, i: int, q: list[float]) -> None:
        body = self.bodies[i]
        body.body_type = pymunk.Body.KINEMATIC
        for s in self.shapes[i]:
            f = s.filter
            s.filter = pymunk.ShapeFilter(group=_ROBOT_GROUP, categories=f.categories, mask=f.mask)
            s.collision_type = CT_HELD
        self.q = q
        self._attach(i)

    def settle(self, max_substeps: int, check_every: int, speed_tol: float) -> int:
        """Step with the robot still until every object moves slower than ``speed_tol`` (m/s,
        and rad/s for spin), checked every ``check_every`` substeps; returns the substeps run."""
        dt = self.dt
        self.vel = [(0.0, 0.0, 0.0)] * 5
        self.robot_v = (0.0, 0.0)
        dyn = [b for i, b in enumerate(self.bodies) if i != self.held]
        k = 0
        while k < max_substeps:
            for _ in range(min(check_every, max_substeps - k)):
                self.space.step(dt)
                k += 1
            if all(
                abs(b.velocity[0]) < speed_tol
                and abs(b.velocity[1]) < speed_tol
                and abs(b.angular_velocity) < speed_tol
                for b in dyn
            ):
                break
        if self.scene.is_kin:
            self._place_kin(self.q)
        return k

    # -- read back ---------------------------------------------------------------------------------
    def write(self, data: NDArray[np.float64]) -> None:
        """Write the simulated state into ``data`` (a state array of the scene's layout)."""
        scene = self.scene
        rows = []
        for b in self.bodies:
            p, v = b.position, b.velocity
            rows.append((p[0], p[1], wrap_angle(b.angle), v[0], v[1], b.angular_velocity))
        if rows:
            data[scene.pose_idx] = np.array(rows)
            held = np.zeros(len(rows))
            if self.held >= 0:
                held[self.held] = 1.0
            data[scene.held_idx] = held
        f = self.robot_f
        if scene.is_kin:
            x, y, th, arm, gap = self.q
            f[0], f[1], f[2], f[17], f[21] = x, y, wrap_angle(th), arm, gap
            f[3:15] = np.array(self.vel[:4]).reshape(-1)
        else:
            f[3], f[4], f[5] = self.robot_v[0], self.robot_v[1], 0.0
        data[scene.robot_slice] = f


def _rot(v: Any, th: float) -> tuple[float, float]:
    c, s = math.cos(th), math.sin(th)
    return c * v[0] - s * v[1], s * v[0] + c * v[1]
