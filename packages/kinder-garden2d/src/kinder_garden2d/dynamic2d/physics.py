"""pymunk simulation of Dynamic2D transitions (imported by the env modules only, never at package
import).

Exact replay. Chipmunk keeps hidden state between steps (cached contact impulses used to
warm-start the solver, the spatial index's history, the shape ids that order the broad phase).
To make every transition a function of the observable state alone, :class:`Simulation` builds a
*fresh* Chipmunk space for each action, sets every body from the state (pose, velocity, type, mass,
centre of mass), always adds bodies and shapes in the same order, runs the action's substeps, reads
the state back and removes everything again. Two runs from equal states are therefore
bit-identical computations, in any process, whatever the env did before.

Speed. Building pymunk's Python objects costs far more than the physics of a short action, so the
simulation talks to Chipmunk through pymunk's cffi binding (``pymunk._chipmunk_cffi``, pinned by
the ``pymunk>=7.1,<8`` requirement): bodies and shapes are created once per object geometry and
reused, a space is a few C calls, and contact callbacks use pymunk's own trampolines.

The robot is made of kinematic bodies that follow the commanded motion exactly (see
:meth:`Simulation.act`); objects are dynamic bodies unless held, when they are kinematic bodies
rigidly attached to the gripper.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import pymunk
from numpy.typing import NDArray
from pymunk._chipmunk_cffi import ffi, lib

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
_DYNAMIC = lib.CP_BODY_TYPE_DYNAMIC
_KINEMATIC = lib.CP_BODY_TYPE_KINEMATIC


def _filter(z: float, robot: bool) -> tuple[int, int, int]:
    f = _FILTERS.get((z, robot))
    if f is None:
        key = min(_CAT, key=lambda k: abs(k - z))
        f = _FILTERS[(z, robot)] = (_ROBOT_GROUP if robot else 0, _CAT[key], _MASK[key])
    return f


_FILTERS: dict[tuple[float, bool], tuple[int, int, int]] = {}


class _RawBody:
    """A Chipmunk body and its shapes, owned by Python (freed with it)."""

    def __init__(
        self,
        polys: Sequence[Sequence[tuple[float, float]]],
        radius: float,
        friction: float,
        elasticity: float = 0.0,
        static: bool = False,
    ) -> None:
        self.body = ffi.gc(
            lib.cpBodyNewStatic() if static else lib.cpBodyNew(1.0, 1.0), lib.cpBodyFree
        )
        self.shapes = []
        for p in polys:
            verts = ffi.new("cpVect[]", [tuple(v) for v in p])
            self.shapes.append(lib.cpPolyShapeNewRaw(self.body, len(p), verts, 0.0))
        if radius > 0:
            self.shapes.append(lib.cpCircleShapeNew(self.body, radius, (0.0, 0.0)))
        self.shapes = [ffi.gc(sh, lib.cpShapeFree) for sh in self.shapes]
        for sh in self.shapes:
            lib.cpShapeSetFriction(sh, friction)
            lib.cpShapeSetElasticity(sh, elasticity)
        self.addresses = [int(ffi.cast("uintptr_t", sh)) for sh in self.shapes]
        self._contact: tuple[float, bool, int] | None = None

    def set_contact(self, z: float, robot: bool, ct: int) -> None:
        key = (z, robot, ct)
        if key == self._contact:
            return
        self._contact = key
        f = _filter(z, robot)
        for sh in self.shapes:
            lib.cpShapeSetFilter(sh, f)
            lib.cpShapeSetCollisionType(sh, ct)


@dataclass
class Scene:
    """What a family simulates: its static boxes, its objects, its robot and settings.

    ``objects`` are the simulated (non-static) objects in a fixed order; ``graspable`` those the
    fingers may pick up. The scene also caches the Chipmunk bodies of each object geometry.
    """

    settings: PhysicsSettings
    statics: tuple[StaticBox, ...]
    robot: Object
    objects: tuple[Object, ...]
    graspable: frozenset[Object]

    def __post_init__(self) -> None:
        self._indexed_layout: Any = None
        self.is_kin = self.robot.type.is_subtype_of(ot.KIN_ROBOT)
        st = self.settings
        self.static_body = _RawBody(
            [[tuple(v) for v in sb.poly.tolist()] for sb in self.statics],
            0.0,
            st.static_friction,
            st.static_elasticity,
            static=True,
        )
        for sh, sb in zip(self.static_body.shapes, self.statics):
            lib.cpShapeSetFilter(sh, _filter(sb.z, False))
            lib.cpShapeSetCollisionType(sh, CT_STATIC)
        self._bodies: dict[tuple[Any, ...], _RawBody] = {}

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

    def raw_body(self, key: tuple[Any, ...], make: Callable[[], _RawBody]) -> _RawBody:
        """The cached Chipmunk body for ``key`` (object slot and geometry)."""
        body = self._bodies.get(key)
        if body is None:
            if len(self._bodies) > 4096:  # geometry is resampled every episode: stay bounded
                self._bodies.clear()
            body = self._bodies[key] = make()
        return body


class _Handler:
    """The object pymunk's callback trampolines expect behind a collision handler."""

    def __init__(self, space: Any, ptr: Any, pre: Any = None, post: Any = None) -> None:
        self._space = space
        self._pre_solve = pre
        self._post_solve = post
        self.data: dict[str, Any] = {"pre_solve": None, "post_solve": None}
        self._handle = ffi.new_handle(self)
        ptr.userData = self._handle
        if pre is not None:
            ptr.preSolveFunc = lib.ext_cpCollisionPreSolveFunc
        if post is not None:
            ptr.postSolveFunc = lib.ext_cpCollisionPostSolveFunc


# -- one transition ------------------------------------------------------------------------------
class Simulation:
    """A fresh Chipmunk space holding one state; run :meth:`act` or :meth:`settle`, then
    :meth:`write` the result into a state array and :meth:`close` (or use as a context manager)."""

    def __init__(self, scene: Scene, data: NDArray[np.float64], release: bool = False) -> None:
        st = scene.settings
        self.scene = scene
        self.dt = st.substep_seconds
        space = ffi.gc(lib.cpSpaceNew(), lib.cpSpaceFree)
        lib.cpSpaceSetGravity(space, (0.0, st.gravity))
        lib.cpSpaceSetDamping(space, st.damping)
        lib.cpSpaceSetIterations(space, st.iterations)
        lib.cpSpaceSetCollisionSlop(space, st.collision_slop)
        self.space = space
        self._added_shapes: list[Any] = []
        self._added_bodies: list[Any] = []
        self._add_body(scene.static_body.body)
        for sh in scene.static_body.shapes:
            self._add_shape(sh)

        poses = data[scene.pose_idx]
        held = data[scene.held_idx] > 0.5
        if release:
            held[:] = False
        zs = data[scene.z_idx]
        self.bodies: list[Any] = []
        self.raws: list[_RawBody] = []
        self.shape_owner: dict[int, int] = {}
        self.held: int = -1
        self.zs = zs
        for i, obj in enumerate(scene.objects):
            tname, builder, gidx, mass_i = scene.geom[i]
            geom = tuple(data[gidx].tolist())
            mass = float(data[mass_i])
            props = mass_props(tname, builder, geom, mass)
            raw = scene.raw_body(
                (i, tname, geom),
                partial(_RawBody, props.polys, props.shape.radius, st.object_friction),
            )
            body = raw.body
            # Re-initialise the reused body: Chipmunk carries a bias velocity (from penetration
            # correction) from one step to the next, which must not leak between transitions.
            lib.cpBodySetType(body, _DYNAMIC)
            lib.cpBodyInit(body, 1.0, 1.0)
            x, y, th, vx, vy, w = poses[i].tolist()
            if held[i]:
                if self.held >= 0:
                    raise ValueError(
                        f"state has more than one held object ({scene.objects[self.held].name}, "
                        f"{obj.name}); the robot holds at most one"
                    )
                self.held = i
                lib.cpBodySetType(body, _KINEMATIC)
            else:
                lib.cpBodySetType(body, _DYNAMIC)
                lib.cpBodySetMass(body, mass)
                lib.cpBodySetMoment(body, props.moment)
            # Order matters: Chipmunk rotates about the centre of mass, so set the angle before
            # the origin's position.
            lib.cpBodySetCenterOfGravity(body, props.cog)
            lib.cpBodySetAngle(body, th)
            lib.cpBodySetPosition(body, (x, y))
            lib.cpBodySetVelocity(body, (vx, vy))
            lib.cpBodySetAngularVelocity(body, w)
            graspable = obj in scene.graspable
            ct = CT_HELD if held[i] else (CT_DYNAMIC if graspable else CT_NON_GRASPABLE)
            raw.set_contact(float(zs[i]), bool(held[i]), ct)
            self._add_body(body)
            for sh, addr in zip(raw.shapes, raw.addresses):
                self._add_shape(sh)
                self.shape_owner[addr] = i
            self.bodies.append(body)
            self.raws.append(raw)

        self.robot_f = data[scene.robot_slice].copy()
        self.blocked = False
        self._handlers = [
            _Handler(
                self, lib.cpSpaceAddCollisionHandler(space, ct, CT_STATIC), pre=self._on_static
            )
            for ct in (CT_ROBOT, CT_FINGER, CT_HELD)
        ]
        if scene.is_kin:
            self._build_kin_robot()
        else:
            self._build_dot_robot()

    def _add_body(self, body: Any) -> None:
        lib.cpSpaceAddBody(self.space, body)
        self._added_bodies.append(body)

    def _add_shape(self, shape: Any) -> None:
        lib.cpSpaceAddShape(self.space, shape)
        self._added_shapes.append(shape)

    def close(self) -> None:
        """Take every body and shape out of the space (they are reused by later transitions)."""
        for sh in reversed(self._added_shapes):
            lib.cpSpaceRemoveShape(self.space, sh)
        for b in reversed(self._added_bodies):
            lib.cpSpaceRemoveBody(self.space, b)
        self._added_shapes.clear()
        self._added_bodies.clear()
        self._handlers.clear()  # breaks the handler ↔ simulation cycle: the space is freed now

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- robot construction ----------------------------------------------------------------------
    def _robot_body(
        self, key: str, polys: Sequence[NDArray[np.float64]], ct: int, z: float, radius: float = 0.0
    ) -> Any:
        geom = tuple(tuple(map(tuple, p.tolist())) for p in polys)
        raw = self.scene.raw_body(
            ("robot", key, geom, radius),
            lambda: _RawBody([list(p) for p in geom], radius, self.scene.settings.robot_friction),
        )
        lib.cpBodySetType(raw.body, _DYNAMIC)
        lib.cpBodyInit(raw.body, 1.0, 1.0)
        lib.cpBodySetType(raw.body, _KINEMATIC)
        raw.set_contact(z, True, ct)
        self._add_body(raw.body)
        for sh in raw.shapes:
            self._add_shape(sh)
        return raw.body

    def _build_dot_robot(self) -> None:
        f = self.robot_f
        self.base = self._robot_body("dot", (), CT_ROBOT, ot.Z_ALL, radius=float(f[12]))
        lib.cpBodySetAngle(self.base, 0.0)
        lib.cpBodySetPosition(self.base, (float(f[0]), float(f[1])))
        lib.cpBodySetVelocity(self.base, (0.0, 0.0))

    def _build_kin_robot(self) -> None:
        f = self.robot_f
        self.radius, self.arm_len = float(f[16]), float(f[18])
        self.gw, self.gh, self.fh, self.fw = float(f[19]), float(f[20]), float(f[22]), float(f[23])
        arm, grip, left, _ = kin_robot_local(
            0.0, self.arm_len, self.gw, self.gh, 0.0, self.fh, self.fw
        )
        # Finger bodies have their origin at the finger centre (left/right made at zero gap).
        finger = left - np.array([self.fw / 2, 0.0])
        self.base = self._robot_body("base", (), CT_ROBOT, ot.Z_ALL, radius=self.radius)
        self.gripper = self._robot_body("gripper", (arm, grip), CT_ROBOT, ot.Z_SURFACE)
        self.finger_l = self._robot_body("finger_l", (finger,), CT_FINGER, ot.Z_SURFACE)
        self.finger_r = self._robot_body("finger_r", (finger,), CT_FINGER, ot.Z_SURFACE)
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
        fo = self.fw / 2
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
        for body, pos in (
            (self.base, (q[0], q[1])),
            (self.gripper, (gx, gy)),
            (self.finger_l, (lx, ly)),
            (self.finger_r, (rx, ry)),
        ):
            lib.cpBodySetAngle(body, th)
            lib.cpBodySetPosition(body, pos)
            lib.cpBodySetVelocity(body, (0.0, 0.0))
            lib.cpBodySetAngularVelocity(body, 0.0)
        if self.held >= 0:
            b = self.bodies[self.held]
            self._set_cog(b, *self._held_pose(q))
            lib.cpBodySetVelocity(b, (0.0, 0.0))
            lib.cpBodySetAngularVelocity(b, 0.0)

    @staticmethod
    def _set_cog(b: Any, cx: float, cy: float, th: float) -> None:
        """Place a body so that its centre of mass is at (cx, cy) with angle th."""
        cog = lib.cpBodyGetCenterOfGravity(b)
        ox, oy = _rot((cog.x, cog.y), th)
        lib.cpBodySetAngle(b, th)
        lib.cpBodySetPosition(b, (cx - ox, cy - oy))

    def _attach(self, i: int) -> None:
        """Record the rigid transform from the gripper to object i's centre of mass."""
        b = self.bodies[i]
        gx, gy, *_, c, s = self._kin_points(self.q)
        cog = lib.cpBodyLocalToWorld(b, lib.cpBodyGetCenterOfGravity(b))
        dx, dy = cog.x - gx, cog.y - gy
        self.held_rel = (c * dx + s * dy, -s * dx + c * dy, lib.cpBodyGetAngle(b) - self.q[2])
        self.held = i

    def _held_pose(self, q: Sequence[float]) -> tuple[float, float, float]:
        """World centre of mass and angle of the held object for configuration q."""
        gx, gy, *_, c, s = self._kin_points(q)
        u, v, dth = self.held_rel
        return gx + c * u - s * v, gy + s * u + c * v, q[2] + dth

    # -- contact callbacks -------------------------------------------------------------------------
    def _on_static(self, arbiter: Any, space: Any, data: Any) -> None:
        self.blocked = True

    def _on_finger(self, arbiter: Any, space: Any, data: Any) -> None:
        if not self._grasp_open:
            return
        arb = arbiter._arbiter
        pa, pb = ffi.new("cpShape **"), ffi.new("cpShape **")
        lib.cpArbiterGetShapes(arb, pa, pb)
        owner = self.shape_owner
        i = owner.get(
            int(ffi.cast("uintptr_t", pb[0])), owner.get(int(ffi.cast("uintptr_t", pa[0])), -1)
        )
        if i < 0:
            return
        gx, gy, *_, c, s = self._kin_points(self._q_step)
        n = lib.cpArbiterGetNormal(arb)
        if abs(n.x * c + n.y * s) > math.sin(GRASP_NORMAL_TOL):
            return
        body = self.bodies[i]
        cog = lib.cpBodyLocalToWorld(body, lib.cpBodyGetCenterOfGravity(body))
        if abs(-(cog.x - gx) * s + (cog.y - gy) * c) > self.gh / 2:
            return
        lo, hi = -1e-6, self.fw + 1e-6
        cps = lib.cpArbiterGetContactPointSet(arb)
        for k in range(cps.count):
            for p in (cps.points[k].pointA, cps.points[k].pointB):
                along = (p.x - gx) * c + (p.y - gy) * s
                if lo <= along <= hi:
                    self._candidates.add(i)
                    return

    # -- running -----------------------------------------------------------------------------------
    def _step(self) -> None:
        lib.cpSpaceStep(self.space, self.dt)

    def warm_start(self) -> None:
        """Prime the contact solver: one substep with the robot still, then every object is put
        back exactly as the state says. The contacts (and their impulses) found in that substep
        warm-start the first real substep, as they would in an uninterrupted simulation; without
        this, resting stacks creep a little at every action boundary."""
        dyn = [b for i, b in enumerate(self.bodies) if i != self.held]
        saved = [
            (
                lib.cpBodyGetAngle(b),
                lib.cpBodyGetPosition(b),
                lib.cpBodyGetVelocity(b),
                lib.cpBodyGetAngularVelocity(b),
            )
            for b in dyn
        ]
        self._step()
        for b, (a, p, v, w) in zip(dyn, saved):
            lib.cpBodySetAngle(b, a)
            lib.cpBodySetPosition(b, p)
            lib.cpBodySetVelocity(b, v)
            lib.cpBodySetAngularVelocity(b, w)
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
        x, y = float(self.robot_f[0]), float(self.robot_f[1])
        tx, ty = x + float(action[0]), y + float(action[1])
        self.robot_v = (0.0, 0.0)
        stopped = False
        last_v: tuple[float, float] | None = None
        for k in range(n):
            if stopped:
                self._step()
                continue
            rem = n - k
            nx, ny = x + (tx - x) / rem, y + (ty - y) / rem
            v = ((nx - x) / dt, (ny - y) / dt)
            if v != last_v:
                lib.cpBodySetVelocity(base, v)
                last_v = v
            self._step()
            if self.blocked:
                lib.cpBodySetPosition(base, (x, y))
                lib.cpBodySetVelocity(base, (0.0, 0.0))
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
            self._handlers.append(
                _Handler(
                    self,
                    lib.cpSpaceAddCollisionHandler(self.space, CT_FINGER, CT_DYNAMIC),
                    post=self._on_finger,
                )
            )
        bodies = (self.base, self.gripper, self.finger_l, self.finger_r)
        pts = self._kin_points(q)
        hold = self._held_pose(q) if self.held >= 0 else None
        self.vel = [(0.0, 0.0, 0.0)] * 5
        stopped = False
        last: list[Any] = [None] * 5
        for k in range(n):
            if stopped:
                self._step()
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
            nhold = None
            if hold is not None:
                nhold = self._held_pose(nq)
                vel.append(((nhold[0] - hold[0]) / dt, (nhold[1] - hold[1]) / dt, w))
                hb: tuple[Any, ...] = (*bodies, self.bodies[self.held])
            else:
                hb = bodies
            # Velocities change only when the robot turns or a target changes: set them lazily.
            for j, (body, v) in enumerate(zip(hb, vel)):
                if v != last[j]:
                    lib.cpBodySetVelocity(body, (v[0], v[1]))
                    lib.cpBodySetAngularVelocity(body, v[2])
                    last[j] = v
            self._q_step = nq
            self._step()
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
                    self.q = q
                    self._grasp(self._candidates.pop())
                    hold = self._held_pose(q)
                    target[4] = q[4]
                    last = [None] * 5
                else:  # more than one object between the fingers: abort and open
                    target[4] = self.gh
                self._grasp_open = False
                self._candidates.clear()
        self.q = q

    def _grasp(self, i: int) -> None:
        body = self.bodies[i]
        cog = lib.cpBodyGetCenterOfGravity(body)
        lib.cpBodySetType(body, _KINEMATIC)
        lib.cpBodySetCenterOfGravity(body, cog)
        self.raws[i].set_contact(float(self.zs[i]), True, CT_HELD)
        self._attach(i)

    def settle(self, max_substeps: int, check_every: int, speed_tol: float) -> int:
        """Step with the robot still until every object moves slower than ``speed_tol`` (m/s;
        spin below 10 × ``speed_tol`` rad/s), checked every ``check_every`` substeps; returns the
        substeps run."""
        self.vel = [(0.0, 0.0, 0.0)] * 5
        self.robot_v = (0.0, 0.0)
        dyn = [b for i, b in enumerate(self.bodies) if i != self.held]
        k = 0
        while k < max_substeps:
            for _ in range(min(check_every, max_substeps - k)):
                self._step()
                k += 1
            if all(_slow(b, speed_tol) for b in dyn):
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
            p, v = lib.cpBodyGetPosition(b), lib.cpBodyGetVelocity(b)
            th = wrap_angle(lib.cpBodyGetAngle(b))
            rows.append((p.x, p.y, th, v.x, v.y, lib.cpBodyGetAngularVelocity(b)))
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


def _slow(b: Any, tol: float) -> bool:
    v = lib.cpBodyGetVelocity(b)
    return bool(
        abs(v.x) < tol and abs(v.y) < tol and abs(lib.cpBodyGetAngularVelocity(b)) < 10 * tol
    )


def _rot(v: Any, th: float) -> tuple[float, float]:
    c, s = math.cos(th), math.sin(th)
    return c * v[0] - s * v[1], s * v[0] + c * v[1]
