"""The default Dynamic2D transition: upstream kindergarden 0.2.5's PD-controlled robot in pymunk.

Upstream (``kinder.envs.dynamic2d``) keeps one pymunk space alive through an episode. Each action
sets a target (the robot's pose plus the action's deltas, the arm and finger gap clipped to their
ranges) and runs ``sim_hz // control_hz`` control steps; every control step a PD controller (gains
``kp``/``kv``, integration step ``1 / control_hz``) sets the velocities of the robot's kinematic
bodies, which then move for ``sim_hz // control_hz`` physics steps of ``1 / sim_hz`` seconds (with
the defaults, 10 × 10 steps of 0.01 s: one second of simulated time per action). A contact of the
robot with a static body (walls, the table) puts the robot back where that control step began and
stops it; a closing finger touching a graspable object in the right way grasps it (the object
becomes kinematic and follows the gripper); opening the fingers releases it.

The velocity features are the bodies' velocities at the end of the action (the controller's last
command, zero after a wall contact), and they feed the controller at the next action.

Exact replay. A transition must be a function of the observed state, so :class:`PDSpace` builds a
fresh space from the state for every action, adding bodies and shapes exactly as upstream does
when it is reset from a state vector (``reset(options={"init_state": ...})``), then runs upstream's
action. Our transition therefore equals upstream's "reload the state, then step", bit for bit where
pymunk's operations are the same. Upstream's uninterrupted run also carries Chipmunk's hidden
state (cached contact impulses) from one action to the next, which its own state vector does not
hold; that is the replay noise the conformance tests measure and allow for.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pymunk
from pymunk.vec2d import Vec2d

from kinder_core import Object, ObjectCentricState
from kinder_core.state import FloatArray

# Collision types, as upstream numbers them.
CT_STATIC = 0
CT_DYNAMIC = 1
CT_ROBOT = 2
CT_FINGER = 3
CT_ARM = 4
CT_NON_GRASPABLE = 5


# -- SE(2) poses, computed with the same numpy operations as upstream's SE2Pose -----------------
Pose = tuple[float, float, float]


def wrap(theta: float) -> float:
    """An angle wrapped to [−π, π] (arctan2 of its sine and cosine, as upstream wraps)."""
    return float(np.clip(np.arctan2(np.sin(theta), np.cos(theta)), -np.pi, np.pi))


def compose(a: Pose, b: Pose) -> Pose:
    """Pose ``a * b`` (``b`` expressed in ``a``'s frame); the angle is wrapped."""
    c, s = np.cos(a[2]), np.sin(a[2])
    r = np.array([[c, -s], [s, c]]).dot((b[0], b[1]))
    return (float(a[0] + r[0]), float(a[1] + r[1]), wrap(a[2] + b[2]))


def inverse(a: Pose) -> Pose:
    c, s = np.cos(a[2]), np.sin(a[2])
    return (float(-a[0] * c - a[1] * s), float(a[0] * s - a[1] * c), -a[2])


def body_pose(b: pymunk.Body) -> Pose:
    p = b.position
    return (p.x, p.y, b.angle)


# -- the two-finger robot ------------------------------------------------------------------------
@dataclass(frozen=True)
class PDSettings:
    """Physics and controller constants of one family (upstream's names in comments)."""

    gravity: float  # gravity_y
    damping: float
    collision_slop: float = 0.001
    control_hz: int = 10
    sim_hz: int = 100
    kp_pos: float = 50.0
    kv_pos: float = 5.0
    kp_rot: float = 50.0
    kv_rot: float = 5.0
    finger_moving_threshold: float = 1e-3
    grasp_theta_tol: float = 0.1  # grasping_theta_thresh
    init_robot_pos: tuple[float, float] = (5.0, 5.0)  # where the robot's bodies are created
    # Robot parts whose contact with a static body reverts the robot (collision types).
    static_stops: tuple[int, ...] = (CT_ROBOT,)


class PDRobot:
    """Four kinematic bodies (base, gripper base with the arm, left and right finger), their
    pose at the start of the current control step, and the objects they hold."""

    def __init__(self, features: Sequence[float] | FloatArray, settings: PDSettings) -> None:
        f = [float(v) for v in features]
        self.radius, self.arm_max = f[16], f[18]
        self.gw, self.gh, self.fh, self.fw = f[19], f[20], f[22], f[23]
        self.settings = settings
        self.held: list[tuple[pymunk.Body, list[pymunk.Shape], Pose]] = []
        # Objects grasped during an action: id of the dynamic body -> its kinematic successor.
        self.grasped: dict[int, pymunk.Body] = {}
        self.closing = False
        self.opening = False
        x0, y0 = settings.init_robot_pos
        self.last_pos = Vec2d(x0, y0)
        self.last_angle = 0.0
        self.last_arm = self.radius
        self.last_gap = self.gh

        self.base = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.base_shape = pymunk.Circle(self.base, self.radius)
        self._robot_shape(self.base_shape, CT_ROBOT)
        self.base.angle = 0.0
        self.base.position = self.last_pos

        hw, hh = self.gw / 2, self.gh / 2
        self.gripper = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.gripper_shape = pymunk.Poly(self.gripper, [(-hw, hh), (-hw, -hh), (hw, -hh), (hw, hh)])
        self._robot_shape(self.gripper_shape, CT_ARM)
        half_arm = self.arm_max / 2
        self.arm_shape = pymunk.Poly(
            self.gripper,
            [(-half_arm, hw), (-half_arm, -hw), (half_arm, -hw), (half_arm, hw)],
            transform=pymunk.Transform(tx=-half_arm - hw, ty=0),
        )
        self._robot_shape(self.arm_shape, CT_ARM)
        gx, gy, gth = compose(body_pose(self.base), (self.last_arm, 0.0, 0.0))
        self.gripper.angle = gth
        self.gripper.position = (gx, gy)

        fw2, fh2 = self.fw / 2, self.fh / 2
        finger = [(-fw2, fh2), (-fw2, -fh2), (fw2, -fh2), (fw2, fh2)]
        self.finger_l = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.finger_l_shape = pymunk.Poly(self.finger_l, finger)
        self._robot_shape(self.finger_l_shape, CT_FINGER)
        self._put(self.finger_l, compose(body_pose(self.gripper), (fw2, self.last_gap / 2, 0.0)))
        self.finger_r = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.finger_r_shape = pymunk.Poly(self.finger_r, finger)
        # The right finger takes the arm's collision type so that only one finger grasps.
        self._robot_shape(self.finger_r_shape, CT_ARM)
        self._put(self.finger_r, compose(body_pose(self.gripper), (fw2, -self.last_gap / 2, 0.0)))

    @staticmethod
    def _robot_shape(shape: pymunk.Shape, ct: int) -> None:
        shape.friction = 1
        shape.collision_type = ct
        shape.density = 1.0

    @staticmethod
    def _put(body: pymunk.Body, pose: Pose) -> None:
        body.angle = pose[2]
        body.position = (pose[0], pose[1])

    def add_to(self, space: pymunk.Space) -> None:
        space.add(self.base, self.base_shape)
        space.add(self.gripper, self.gripper_shape, self.arm_shape)
        space.add(self.finger_l, self.finger_l_shape)
        space.add(self.finger_r, self.finger_r_shape)

    # -- measured configuration ----------------------------------------------------------------
    def arm(self) -> float:
        return compose(inverse(body_pose(self.base)), body_pose(self.gripper))[0]

    def finger_offsets(self) -> tuple[float, float]:
        """Left and right finger offsets across the gripper (left positive)."""
        g_inv = inverse(body_pose(self.gripper))
        return (
            compose(g_inv, body_pose(self.finger_l))[1],
            compose(g_inv, body_pose(self.finger_r))[1],
        )

    def gap(self) -> float:
        left, right = self.finger_offsets()
        return left - right

    # -- placing -------------------------------------------------------------------------------
    def set_from_state(self, f: Sequence[float] | FloatArray) -> None:
        """Place the bodies and set their velocities from the robot's features."""
        b = self.base
        b.angle = f[2]
        b.angular_velocity = f[5]
        b.position = (f[0], f[1])
        b.velocity = Vec2d(f[3], f[4])
        g = compose(body_pose(b), (f[17], 0.0, 0.0))
        self.gripper.angle = g[2]
        self.gripper.angular_velocity = f[8]
        self.gripper.position = (g[0], g[1])
        self.gripper.velocity = Vec2d(f[6], f[7])
        for body, side, k in ((self.finger_l, 1.0, 9), (self.finger_r, -1.0, 12)):
            p = compose(g, (self.fw / 2, side * f[21] / 2, 0.0))
            body.angle = p[2]
            body.angular_velocity = f[k + 2]
            body.position = (p[0], p[1])
            body.velocity = Vec2d(f[k], f[k + 1])
        self.remember()

    def remember(self) -> None:
        """Record the current configuration as the one a static contact returns to."""
        self.last_pos = Vec2d(self.base.position.x, self.base.position.y)
        self.last_angle = self.base.angle
        self.last_arm = self.arm()
        self.last_gap = self.gap()

    def revert(self) -> None:
        """Back to the remembered configuration, at rest (held objects follow)."""
        b = self.base
        b.angle = self.last_angle
        b.position = self.last_pos
        b.velocity = Vec2d(0.0, 0.0)
        b.angular_velocity = 0.0
        g = compose(body_pose(b), (self.last_arm, 0.0, 0.0))
        for body, pose in (
            (self.gripper, g),
            (self.finger_l, compose(g, (self.fw / 2, self.last_gap / 2, 0.0))),
            (self.finger_r, compose(g, (self.fw / 2, -self.last_gap / 2, 0.0))),
        ):
            body.angle = pose[2]
            body.position = (pose[0], pose[1])
            body.velocity = Vec2d(0.0, 0.0)
            body.angular_velocity = 0.0
        for obj_body, _, rel in self.held:
            p = compose(g, rel)
            obj_body.angle = p[2]
            obj_body.position = (p[0], p[1])
            obj_body.velocity = Vec2d(0.0, 0.0)
            obj_body.angular_velocity = 0.0

    def hold(self, body: pymunk.Body, shapes: list[pymunk.Shape]) -> None:
        """Attach a (kinematic) body at its current pose relative to the gripper."""
        rel = compose(inverse(body_pose(self.gripper)), body_pose(body))
        self.held.append((body, shapes, rel))

    def holds(self, body: pymunk.Body) -> bool:
        return any(b is body for b, _, _ in self.held)

    # -- control -------------------------------------------------------------------------------
    def command(self, target: Sequence[float] | FloatArray, dt: float) -> None:
        """One PD control step towards ``target`` = (x, y, θ, arm, gap): remember the current
        configuration and set every robot body's (and held object's) velocity."""
        st = self.settings
        kp, kv, kp_r, kv_r = st.kp_pos, st.kv_pos, st.kp_rot, st.kv_rot
        pos = Vec2d(self.base.position.x, self.base.position.y)
        vel = self.base.velocity
        th = self.base.angle
        w = self.base.angular_velocity
        normal = Vec2d(math.cos(th + math.pi / 2), math.sin(th + math.pi / 2))
        arm = self.arm()
        grip_vel = self.gripper.velocity
        left, right = self.finger_offsets()

        new_vel = vel + (kp * (Vec2d(target[0], target[1]) - pos) + kv * (Vec2d(0, 0) - vel)) * dt
        new_w = w + (kp_r * (target[2] - th) + kv_r * (0.0 - w)) * dt

        # Arm: a prismatic joint along the base's heading.
        arm_rate = (grip_vel - vel - normal * arm * w).rotated(-th).x
        arm_rate_next = arm_rate + (kp * (target[3] - arm) + kv * (0.0 - arm_rate)) * dt
        along = Vec2d(arm_rate_next, 0.0).rotated(th)
        grip_new = new_vel + normal * arm * new_w + along

        held_vels = []
        for obj_body, _, _ in self.held:
            rel = Vec2d(obj_body.position.x, obj_body.position.y) - pos
            held_vels.append(
                new_vel + rel.normalized().rotated(math.pi / 2) * rel.length * new_w + along
            )

        finger_vels = []
        for body, offset, tgt in (
            (self.finger_l, left, target[4] / 2),
            (self.finger_r, right, -target[4] / 2),
        ):
            rel = Vec2d(body.position.x, body.position.y) - pos
            tangent = rel.normalized().rotated(math.pi / 2)
            rate = (body.velocity - vel - tangent * rel.length * w).rotated(-th).y
            rate_next = rate + (kp * (tgt - offset) + kv * (0.0 - rate)) * dt
            finger_vels.append(
                new_vel + tangent * rel.length * new_w + Vec2d(arm_rate_next, rate_next).rotated(th)
            )

        self.remember()
        self.base.velocity = new_vel
        self.base.angular_velocity = new_w
        self.gripper.velocity = grip_new
        self.gripper.angular_velocity = new_w
        self.finger_l.velocity = finger_vels[0]
        self.finger_l.angular_velocity = new_w
        self.finger_r.velocity = finger_vels[1]
        self.finger_r.angular_velocity = new_w
        for (obj_body, _, _), v in zip(self.held, held_vels):
            obj_body.velocity = v
            obj_body.angular_velocity = self.gripper.angular_velocity

    def grasps(self, points: pymunk.ContactPointSet, target: pymunk.Body) -> bool:
        """Whether a finger contact grasps ``target``: the fingers are closing, the contact
        normal is within ``grasp_theta_tol`` of perpendicular to the gripper, the target's origin
        lies between the fingers and a contact point lies along the fingers."""
        if not self.closing:
            return False
        d = abs(self.gripper.angle - points.normal.angle)
        d = min(d, 2 * np.pi - d)
        if not abs(d - np.pi / 2) < self.settings.grasp_theta_tol:
            return False
        g_inv = inverse(body_pose(self.gripper))
        rel = compose(g_inv, (target.position.x, target.position.y, 0.0))
        if abs(rel[1]) > self.gh / 2:
            return False
        for pt in points.points:
            a = compose(g_inv, (pt.point_a.x, pt.point_a.y, 0.0))
            if abs(a[1]) < self.gh / 2 and 0 < a[0] < self.fw / 2:
                return True
        return False


class PDDot:
    """The dot robot: one kinematic disc under a PD controller on its position."""

    def __init__(self, features: Sequence[float] | FloatArray, settings: PDSettings) -> None:
        self.settings = settings
        self.held: list[tuple[pymunk.Body, list[pymunk.Shape], Pose]] = []
        self.grasped: dict[int, pymunk.Body] = {}
        x0, y0 = settings.init_robot_pos
        self.last_pos = Vec2d(x0, y0)
        self.base = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.base_shape = pymunk.Circle(self.base, float(features[12]))
        self.base_shape.friction = 1
        self.base_shape.collision_type = CT_ROBOT
        self.base_shape.density = 1.0
        self.base.position = self.last_pos

    def add_to(self, space: pymunk.Space) -> None:
        space.add(self.base, self.base_shape)

    def set_from_state(self, f: Sequence[float] | FloatArray) -> None:
        self.base.position = (f[0], f[1])
        self.base.velocity = Vec2d(f[3], f[4])
        self.remember()

    def remember(self) -> None:
        self.last_pos = Vec2d(self.base.position.x, self.base.position.y)

    def revert(self) -> None:
        self.base.position = self.last_pos
        self.base.velocity = Vec2d(0.0, 0.0)

    def command(self, target: Sequence[float], dt: float) -> None:
        st = self.settings
        pos = Vec2d(self.base.position.x, self.base.position.y)
        vel = self.base.velocity
        acc = st.kp_pos * (Vec2d(target[0], target[1]) - pos) + st.kv_pos * (Vec2d(0, 0) - vel)
        self.remember()
        self.base.velocity = vel + acc * dt


# -- what a space holds ------------------------------------------------------------------------
@dataclass
class BodySpec:
    """How one object enters the space: ``make`` adds its body and shapes to the space (placing
    them as upstream does) and returns the body, or None for objects upstream does not simulate.
    ``obj`` is None for the constant objects (walls, tables) that our states leave out."""

    name: str
    obj: Object | None
    make: Callable[[pymunk.Space, Any], pymunk.Body | None]
    # How upstream reads this object's angle back: "raw" (unwrapped), "wrap" (arctan2 wrap),
    # "once" (shifted by 2π once when outside [−π, π]) or "keep" (not read: the state's value).
    theta: str = "raw"


@dataclass
class PDSpace:
    """A pymunk space holding one full state, built in upstream's order."""

    settings: PDSettings
    robot_obj: Object
    robot_features: Sequence[float] | FloatArray
    specs: list[BodySpec]
    space: pymunk.Space = field(init=False)
    robot: Any = field(init=False)  # PDRobot, or PDDot for the dot robot
    bodies: dict[Object, pymunk.Body] = field(init=False)

    def __post_init__(self) -> None:
        st = self.settings
        space = pymunk.Space()
        space.gravity = 0, st.gravity
        space.damping = st.damping
        space.collision_slop = st.collision_slop
        self.is_dot = self.robot_obj.type.name == "dot_robot"
        robot: PDRobot | PDDot = (
            PDDot(self.robot_features, st) if self.is_dot else PDRobot(self.robot_features, st)
        )
        robot.add_to(space)
        if not self.is_dot:
            space.on_collision(CT_DYNAMIC, CT_FINGER, post_solve=_on_finger, data=robot)
        for ct in st.static_stops:
            space.on_collision(CT_STATIC, ct, pre_solve=_on_static, data=robot)
        self.space, self.robot = space, robot
        robot.set_from_state(self.robot_features)
        self.bodies = {}
        self._theta: dict[Object, str] = {}
        for spec in sorted(self.specs, key=lambda s: s.name):
            if spec.obj == self.robot_obj:
                continue
            body = spec.make(space, robot)
            if spec.obj is not None and body is not None:
                self.bodies[spec.obj] = body
                self._theta[spec.obj] = spec.theta

    def reindex(self) -> None:
        """As upstream after a reset from a state: reindex every body's shapes."""
        for body in list(self.space.bodies):
            self.space.reindex_shapes_for_body(body)

    def settle(self, seconds: float) -> None:
        """Let the objects settle with the robot still (upstream's reset stabilisation)."""
        dt = 1.0 / self.settings.sim_hz
        for _ in range(int(seconds * self.settings.sim_hz)):
            self.space.step(dt)

    def act(self, action: Sequence[float] | FloatArray) -> None:
        """One upstream action: PD control towards the commanded target, then grasp and release
        bookkeeping."""
        st, robot, space = self.settings, self.robot, self.space
        n = st.sim_hz // st.control_hz
        sim_dt, control_dt = 1.0 / st.sim_hz, 1.0 / st.control_hz
        if self.is_dot:
            p = robot.base.position
            dot_target = [p.x + float(action[0]), p.y + float(action[1])]
            for _ in range(n):
                robot.command(dot_target, control_dt)
                for _ in range(n):
                    space.step(sim_dt)
            return
        dx, dy, dth, darm, dgap = (float(a) for a in action)
        base = robot.base
        target = [
            base.position.x + dx,
            base.position.y + dy,
            base.angle + dth,
            max(min(robot.arm() + darm, robot.arm_max), robot.radius),
            0.0,
        ]
        gap = robot.gap()
        target[4] = max(min(gap + dgap, robot.gh), robot.fh * 2)
        robot.opening = target[4] - gap > st.finger_moving_threshold
        robot.closing = gap - target[4] > st.finger_moving_threshold
        for _ in range(n):
            robot.command(target, control_dt)
            for _ in range(n):
                space.step(sim_dt)
        if len(robot.held) > 1:  # two objects grasped at once: the grasp fails, fingers open
            robot.closing, robot.opening = False, True
        if robot.opening:
            robot.held = []
        robot.closing = robot.opening = False

    def write(self, state: ObjectCentricState) -> None:
        """Write the robot's and the objects' simulated features into ``state``."""
        robot = self.robot
        r = state[self.robot_obj]
        if self.is_dot:
            b = robot.base
            r[0], r[1], r[3], r[4] = b.position.x, b.position.y, b.velocity.x, b.velocity.y
        else:
            b, g, fl, fr = robot.base, robot.gripper, robot.finger_l, robot.finger_r
            r[0], r[1], r[2] = b.position.x, b.position.y, b.angle
            r[3], r[4], r[5] = b.velocity.x, b.velocity.y, b.angular_velocity
            r[6], r[7], r[8] = g.velocity.x, g.velocity.y, g.angular_velocity
            r[9], r[10], r[11] = fl.velocity.x, fl.velocity.y, fl.angular_velocity
            r[12], r[13], r[14] = fr.velocity.x, fr.velocity.y, fr.angular_velocity
            r[17] = robot.arm()
            r[21] = robot.gap()
        state[self.robot_obj] = r
        held_bodies = {id(hb) for hb, _, _ in robot.held}
        current = self._current
        for obj, body in self.bodies.items():
            body = current.get(obj, body)
            f = state[obj]
            f[0], f[1] = body.position.x, body.position.y
            mode = self._theta[obj]
            th = body.angle
            if mode == "wrap":
                f[2] = wrap(th)
            elif mode == "once":
                f[2] = th - 2 * np.pi if th > np.pi else th + 2 * np.pi if th < -np.pi else th
            elif mode == "raw":
                f[2] = th
            f[3], f[4], f[5] = body.velocity.x, body.velocity.y, body.angular_velocity
            f[7] = 1.0 if id(body) in held_bodies else 0.0
            state[obj] = f

    @property
    def _current(self) -> dict[Object, pymunk.Body]:
        """Objects grasped during the action live on as new kinematic bodies."""
        out: dict[Object, pymunk.Body] = {}
        for obj, body in self.bodies.items():
            new = self.robot.grasped.get(id(body))
            if new is not None:
                out[obj] = new
        return out


def _on_static(arbiter: pymunk.Arbiter, space: pymunk.Space, robot: PDRobot | PDDot) -> None:
    robot.revert()


def _on_finger(arbiter: pymunk.Arbiter, space: pymunk.Space, robot: PDRobot) -> None:
    body = arbiter.bodies[0]
    if not robot.grasps(arbiter.contact_point_set, body):
        return
    kin = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    kin.position = body.position
    kin.angle = body.angle
    shapes = list(body.shapes)
    copies: list[pymunk.Shape] = []
    for sh in shapes:
        c = sh.copy()
        c.body = kin
        copies.append(c)
    space.add(kin, *copies)
    robot.hold(kin, copies)
    space.remove(body, *shapes)
    robot.grasped[id(body)] = kin


# -- object builders, as upstream builds each kind of object -----------------------------------
def box_vertices(w: float, h: float) -> list[tuple[float, float]]:
    return [(-w / 2, -h / 2), (-w / 2, h / 2), (w / 2, h / 2), (w / 2, -h / 2)]


def static_rect(
    x: float, y: float, theta: float, w: float, h: float, angle_first: bool = True
) -> Callable[..., Any]:
    """A static rectangle: a kinematic body of the static collision type (placed angle first,
    or position first as DynPushT2D places its walls)."""

    def make(space: pymunk.Space, robot: PDRobot) -> pymunk.Body:
        b = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        sh = pymunk.Poly(b, box_vertices(w, h))
        sh.friction = 1.0
        sh.density = 1.0
        sh.mass = 1.0
        sh.elasticity = 0.99
        sh.collision_type = CT_STATIC
        space.add(b, sh)
        if angle_first:
            b.angle = theta
            b.position = x, y
        else:
            b.position = x, y
            b.angle = theta
        return b

    return make


def dynamic_rect(
    f: Sequence[float] | FloatArray, w: float, h: float, mass: float
) -> Callable[..., Any]:
    """A box: dynamic, or kinematic and held when its ``held`` feature is set."""
    x, y, th, vx, vy, om, held = (float(f[i]) for i in range(8) if i != 6)

    def make(space: pymunk.Space, robot: PDRobot) -> pymunk.Body:
        if held > 0.5:
            b = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            sh = pymunk.Poly(b, box_vertices(w, h))
            sh.friction = 1.0
            sh.density = 1.0
            sh.mass = mass
            sh.collision_type = CT_DYNAMIC
            space.add(b, sh)
            b.angle = th
            b.position = x, y
            robot.hold(b, [sh])
            return b
        moment = pymunk.moment_for_box(mass, (w, h))
        b = pymunk.Body()
        sh = pymunk.Poly(b, box_vertices(w, h))
        sh.friction = 1.0
        sh.density = 1.0
        sh.collision_type = CT_DYNAMIC
        sh.mass = mass
        b.moment = moment
        b.mass = mass
        space.add(b, sh)
        b.angle = th
        b.position = x, y
        b.velocity = vx, vy
        b.angular_velocity = om
        return b

    return make


def lshape_polys(
    w: float, l1: float, l2: float
) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """The two convex parts of an L-object with its outer corner at the origin: the arm along
    −x (length ``l1``) and the arm along −y (length ``l2``), both ``w`` thick."""
    return (
        [(0, 0), (-l1, 0), (-l1, -w), (0, -w)],
        [(-w, -l2), (0, -l2), (0, 0), (-w, 0)],
    )


def dynamic_lobject(
    f: Sequence[float] | FloatArray,
    w: float,
    l1: float,
    l2: float,
    mass: float,
    set_body_mass: bool = True,
    held_ct: int = CT_DYNAMIC,
) -> Callable[..., Any]:
    """An L-object (two convex parts of half the mass each): dynamic, or kinematic and held
    (with collision type ``held_ct``). ``set_body_mass``: DynPushPullHook2D also sets the body's
    mass and moment after making the shapes (DynScoopPour2D does not)."""
    x, y, th, vx, vy, om, held = (float(f[i]) for i in range(8) if i != 6)
    p1, p2 = lshape_polys(w, l1, l2)

    def make(space: pymunk.Space, robot: PDRobot) -> pymunk.Body:
        m1 = pymunk.moment_for_poly(mass / 2, p1)
        m2 = pymunk.moment_for_poly(mass / 2, p2)
        if held > 0.5:
            b = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        else:
            b = pymunk.Body(mass=mass, moment=m1 + m2)
        s1, s2 = pymunk.Poly(b, p1), pymunk.Poly(b, p2)
        for s in (s1, s2):
            s.friction = 1.0
            s.density = 1.0
            s.collision_type = held_ct if held > 0.5 else CT_DYNAMIC
            s.mass = mass / 2
        if held <= 0.5 and set_body_mass:
            b.moment = m1
            b.mass = mass
            b.moment = m2
            b.mass = mass
        space.add(b, s1, s2)
        b.angle = th
        b.position = x, y
        if held > 0.5:
            robot.hold(b, [s1, s2])
        else:
            b.velocity = vx, vy
            b.angular_velocity = om
        return b

    return make


def small_circle(f: Sequence[float] | FloatArray, radius: float, mass: float) -> Callable[..., Any]:
    """A small non-graspable disc (its angle is never set: upstream places discs unrotated)."""
    x, y, vx, vy, om = (float(f[i]) for i in (0, 1, 3, 4, 5))

    def make(space: pymunk.Space, robot: Any) -> pymunk.Body:
        b = pymunk.Body(mass, pymunk.moment_for_circle(mass, 0, radius))
        sh = pymunk.Circle(b, radius)
        sh.friction = 1.0
        sh.density = 1.0
        sh.collision_type = CT_NON_GRASPABLE
        sh.mass = mass
        space.add(b, sh)
        b.position = x, y
        b.velocity = vx, vy
        b.angular_velocity = om
        return b

    return make


def small_square(f: Sequence[float] | FloatArray, size: float, mass: float) -> Callable[..., Any]:
    """A small non-graspable square."""
    x, y, th, vx, vy, om = (float(f[i]) for i in range(6))
    vs = box_vertices(size, size)

    def make(space: pymunk.Space, robot: Any) -> pymunk.Body:
        b = pymunk.Body(mass, pymunk.moment_for_poly(mass, vs))
        sh = pymunk.Poly(b, vs)
        sh.friction = 1.0
        sh.density = 1.0
        sh.collision_type = CT_NON_GRASPABLE
        sh.mass = mass
        space.add(b, sh)
        b.angle = th
        b.position = x, y
        b.velocity = vx, vy
        b.angular_velocity = om
        return b

    return make


def tblock(
    f: Sequence[float] | FloatArray, w: float, lh: float, lv: float, mass: float
) -> Callable[..., Any]:
    """DynPushT2D's T block: a bar ``lh`` × ``w`` below the origin and a stem ``w`` × ``lv``
    below the bar. Its shapes have unit density, so pymunk takes its mass from the area."""
    x, y, th, vx, vy, om = (float(f[i]) for i in range(6))

    def make(space: pymunk.Space, robot: Any) -> pymunk.Body:
        moment = pymunk.moment_for_box(mass, (lh, w)) + pymunk.moment_for_box(mass, (w, lv))
        b = pymunk.Body(mass, moment)
        bar = [(-lh / 2, 0), (-lh / 2, -w), (lh / 2, -w), (lh / 2, 0)]
        stem = [(-w / 2, -w), (-w / 2, -w - lv), (w / 2, -w - lv), (w / 2, -w)]
        s1, s2 = pymunk.Poly(b, bar), pymunk.Poly(b, stem)
        s1.friction = 1.0
        s2.friction = 1.0
        s1.density = 1.0
        s2.density = 1.0
        s1.collision_type = CT_DYNAMIC
        s2.collision_type = CT_DYNAMIC
        space.add(b, s1, s2)
        b.angle = th
        b.position = (x, y)
        b.velocity = vx, vy
        b.angular_velocity = om
        return b

    return make


__all__ = [
    "BodySpec",
    "PDDot",
    "PDRobot",
    "PDSettings",
    "PDSpace",
    "dynamic_lobject",
    "dynamic_rect",
    "small_circle",
    "small_square",
    "static_rect",
    "tblock",
]
