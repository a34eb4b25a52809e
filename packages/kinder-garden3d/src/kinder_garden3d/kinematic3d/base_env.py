"""Shared mechanics of the Kinematic3D families ("teleport and check", environments.md §4.1).

The defaults follow upstream kindergarden 0.2.5's pybullet environments. One step:

1. The 10 motion deltas (clipped to ±``max_action_mag``) are added to the base pose and joints;
   the base is clipped to the world bounds, the yaw wrapped to [−π, π) and the limited joints
   clipped to ``arm_joint_limits`` (the Kinova URDF's). Continuous joints are not wrapped
   unless ``wrap_joints`` is set.
2. The motion is swept in ``ceil(max|Δ| / max_collision_check_step)`` increments (only the
   endpoint when the step is ``None``). At each increment the robot, the held object and what a
   held container carries are moved; the motion is reverted when the arm touches itself
   (``check_self_collisions``), the arm (and, with ``check_base_collisions``, the base chassis)
   or the held object comes within ``collision_distance`` of a collidable object other than the
   held object and its contents.
3. The gripper command runs: close → grasp when exactly one movable object is within
   ``collision_distance`` of the grasp marker (a 2 × 2 × 7 cm box at the tool frame), closing
   the fingers until they touch it; open → release when the held object is within
   ``min_placement_dist`` of a surface, otherwise keep holding. Opening with nothing held does
   nothing.

A held container (all half extents > 0.04) carries every movable object whose centre lies
strictly inside its half extents along the world axes. Reward −1 per step; ``terminated`` when
the goal holds. The end-effector pose (``ee_pose``) and the grasp transform features are in the
tool frame (see :data:`kinder_garden3d.kinematic3d.scene.TOOL_OFFSET`); with nothing held the
seven grasp-transform features are 0.

Kept deviations from upstream (bugs there): a held surface object (Transport3D's box) is never
its own support, so it cannot be released in mid-air; BaseMotion3D's target keeps its height
when a state is loaded.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pybullet as pb
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace
from kinder_core.state import FloatArray
from kinder_garden3d.kinematic3d.geometry import (
    Part,
    cuboid_parts,
    triangle_parts,
)
from kinder_garden3d.kinematic3d.object_types import (
    ALL_TYPES,
    CUBOID_TYPE,
    FIXTURE_TYPE,
    POINT_TYPE,
    ROBOT_TYPE,
    SOLID,
    TRIANGLE_TYPE,
    robot_action_space,
)
from kinder_garden3d.kinematic3d.scene import BodySpec, PyBulletScene
from kinder_garden3d.robot.description import FINGER_STATE_MAX, RETRACT

Array = NDArray[np.float64]
Rgba = tuple[float, float, float, float]

PURPLE: Rgba = (128 / 255, 0.0, 128 / 255, 1.0)
RED: Rgba = (0.85, 0.1, 0.1, 1.0)
BLUE: Rgba = (0.2, 0.35, 0.85, 1.0)
YELLOW: Rgba = (0.95, 0.8, 0.15, 1.0)
WOOD: Rgba = (0.76, 0.6, 0.42, 1.0)
GREY: Rgba = (0.6, 0.6, 0.62, 1.0)
FLOOR: Rgba = (0.86, 0.86, 0.84, 1.0)

# Robot feature slices.
_CONFIG = slice(0, 10)
_FINGER = 10
_GRASP = 11
_TF = slice(12, 19)
#: Upstream writes all seven grasp-transform features as 0 while nothing is held.
_NO_GRASP_TF = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: Limits of the arm joints in the Kinova Gen3 URDF that upstream's pybullet robot loads (±rad;
#: ``None`` = continuous). They are wider than the user guide's ranges that the shared robot
#: model (and Dynamic3D) uses.
KINOVA_URDF_JOINT_LIMITS: tuple[float | None, ...] = (None, 2.41, None, 2.66, None, 2.23, None)
#: Observed object types that are solid bodies (collide, may support others).
SOLID_TYPES = (CUBOID_TYPE, TRIANGLE_TYPE, FIXTURE_TYPE)
#: A held object with every half extent above this carries the objects inside it.
CONTAINER_MIN_HALF_EXTENT = 0.04


@dataclass(frozen=True)
class Kinematic3DConfig:
    """Settings shared by every Kinematic3D family (families extend it with their own fields).

    Attributes:
        max_action_mag: Bound of the 10 motion deltas (m or rad per step).
        max_collision_check_step: Sweep resolution in configuration space; ``None`` checks only
            the endpoint of each motion.
        base_z: Height of the robot base frame in the world.
        home_base_pose: Initial (x, y, yaw) of the base.
        home_joints: Initial arm joints (the Kinova retract pose).
        world_bounds: (x_min, x_max, y_min, y_max) for the base position.
        min_placement_dist: Largest distance (m) from a held object to a surface for a release to
            be accepted (any direction, as upstream).
        collision_distance: Bodies closer than this (m) collide in motion and grasp checks;
            touching counts, as in upstream's pybullet_helpers (1e-6).
        collision_tolerance: Penetration depth (m) beyond which :meth:`penetrations` reports a
            pair (the validity test of initial states and of planners' configurations).
        finger_close_step: Finger-state increment while closing on an object.
        arm_joint_limits: Symmetric limit of each arm joint (rad; ``None`` = continuous).
        wrap_joints: Wrap the continuous arm joints into [−π, π) after each motion (upstream
            leaves them unbounded; off by default).
        check_base_collisions: Also check the base chassis against the objects (upstream does
            only in BaseMotion3D).
        check_self_collisions: Reject motions that bring non-neighbouring arm links (or the
            fingers and the arm) into contact, as upstream does.
        max_reset_tries: Rejection-sampling budget of a reset before it raises.
        image_width, image_height: Size of rendered frames.
        camera_target, camera_distance, camera_yaw, camera_pitch: The overview orbit camera.
    """

    max_action_mag: float = 0.4
    max_collision_check_step: float | None = None
    base_z: float = 0.0
    home_base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    home_joints: tuple[float, ...] = RETRACT
    world_bounds: tuple[float, float, float, float] = (-10.0, 10.0, -10.0, 10.0)
    min_placement_dist: float = 0.005
    collision_distance: float = 1e-6
    collision_tolerance: float = 1e-4
    finger_close_step: float = 0.01
    arm_joint_limits: tuple[float | None, ...] = KINOVA_URDF_JOINT_LIMITS
    wrap_joints: bool = False
    check_base_collisions: bool = False
    check_self_collisions: bool = True
    max_reset_tries: int = 1000
    image_width: int = 640
    image_height: int = 360
    camera_target: tuple[float, float, float] = (0.0, 0.0, 0.3)
    camera_distance: float = 2.0
    camera_yaw: float = 50.0
    camera_pitch: float = -30.0

    def __post_init__(self) -> None:
        if not self.max_action_mag > 0:
            raise ValueError(f"max_action_mag must be > 0, got {self.max_action_mag}")
        step = self.max_collision_check_step
        if step is not None and not step > 0:
            raise ValueError(f"max_collision_check_step must be > 0 or None, got {step}")
        if len(self.home_joints) != 7:
            raise ValueError(f"home_joints needs 7 values, got {len(self.home_joints)}")
        x0, x1, y0, y1 = self.world_bounds
        if not (x0 < x1 and y0 < y1):
            raise ValueError(
                f"world_bounds must be (x_min, x_max, y_min, y_max) with min < max, got "
                f"{self.world_bounds}"
            )
        if len(self.arm_joint_limits) != 7:
            raise ValueError(f"arm_joint_limits needs 7 values, got {len(self.arm_joint_limits)}")
        if self.max_reset_tries < 1:
            raise ValueError(f"max_reset_tries must be >= 1, got {self.max_reset_tries}")


@dataclass(frozen=True)
class ConstantBody:
    """A static object that is not part of the observation (tables, floors)."""

    spec: BodySpec
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    surface: bool = True


@dataclass
class _SyncCache:
    """What the pybullet scene holds: the last state loaded whole (``layout``, ``data``) and
    each observed object's features when its body was last built and posed (``rows``), all
    valid for scene connection ``generation``."""

    generation: int = -1
    layout: Any = None
    data: Array = field(default_factory=lambda: np.zeros(0))
    rows: dict[str, Array] = field(default_factory=dict)


class ResetError(RuntimeError):
    """A reset could not find a valid initial state within the try budget."""


class Kinematic3DEnv(ObjectCentricEnv):
    """Base class of the Kinematic3D families (see the module docstring for the mechanics).

    Families implement ``_sample_initial_state``, ``goal_reached``, :meth:`box_objects`, and
    declare their objects' roles through :meth:`movable_names`, :meth:`surface_names`,
    :meth:`object_color` and :meth:`constant_bodies`.
    """

    def __init__(self, config: Kinematic3DConfig, render_mode: str | None = "rgb_array") -> None:
        super().__init__(render_mode=render_mode)
        self.config = config
        self.robot = Object("robot", ROBOT_TYPE)
        self.action_space = robot_action_space(config.max_action_mag)
        self.observation_space = ObjectCentricStateSpace(ALL_TYPES)
        limits = [math.inf if v is None else float(v) for v in config.arm_joint_limits]
        self._joint_high = np.array(limits)
        self._joint_low = -self._joint_high
        self._continuous = ~np.isfinite(self._joint_low)
        self._scene = PyBulletScene(config.base_z)
        self._sync_cache = _SyncCache()
        self._constants: dict[str, ConstantBody] = dict(self.constant_bodies())

    # -- family hooks ---------------------------------------------------------------------------
    def constant_bodies(self) -> dict[str, ConstantBody]:
        """Static bodies that are not observed (default: none)."""
        return {}

    def movable_names(self, state: ObjectCentricState) -> list[str]:
        """Names of the objects the robot may grasp."""
        return []

    def surface_names(self, state: ObjectCentricState) -> list[str]:
        """Names of the objects (observed or constant) a held object may be released onto."""
        return [n for n, c in self._constants.items() if c.surface]

    def object_color(self, obj: Object) -> Rgba:
        """Display colour of an observed object."""
        return GREY

    def object_parts(self, state: ObjectCentricState, obj: Object) -> list[Part]:
        """Convex parts of an observed object, from its features."""
        f = state[obj]
        if obj.type == CUBOID_TYPE:
            return cuboid_parts(float(f[8]), f[9:12])
        if obj.type == TRIANGLE_TYPE:
            return triangle_parts(float(f[8]), float(f[9]), float(f[10]), float(f[11]))
        raise ValueError(f"Object {obj!r} of type {obj.type.name!r} has no solid shape")

    def extra_motion_collision(
        self, state: ObjectCentricState, held: Object, pos: Array, quat: Array
    ) -> bool:
        """An extra test of the held object at world pose (pos, quat) against the others, run at
        every sweep increment (default: none)."""
        return False

    # -- bounds ---------------------------------------------------------------------------------
    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        x0, x1, y0, y1 = self.config.world_bounds
        reach = 2.0  # an arm's length (plus a held object) past the base bounds
        bounds: dict[str, tuple[float, float]] = {
            "pose_x": (x0 - reach, x1 + reach),
            "pose_y": (y0 - reach, y1 + reach),
            "pose_z": (-3.0, 3.0),
            "x": (x0 - reach, x1 + reach),
            "y": (y0 - reach, y1 + reach),
            "z": (-3.0, 3.0),
            "half_extent_x": (0.0, 2.0),
            "half_extent_y": (0.0, 2.0),
            "half_extent_z": (0.0, 2.0),
            "side_a": (0.0, 2.0),
            "side_b": (0.0, 2.0),
            "depth": (0.0, 2.0),
            "Kinematic3DRobot.grasp_tf_x": (-1.0, 1.0),
            "Kinematic3DRobot.grasp_tf_y": (-1.0, 1.0),
            "Kinematic3DRobot.grasp_tf_z": (-1.0, 1.0),
            "Kinematic3DRobot.pos_base_x": (x0, x1),
            "Kinematic3DRobot.pos_base_y": (y0, y1),
            "Kinematic3DRobot.pos_base_rot": (-math.pi, math.pi),
            "Kinematic3DRobot.finger_state": (0.0, FINGER_STATE_MAX),
            "Kinematic3DRobot.grasp_active": (0.0, 1.0),
            "grasp_active": (0.0, 1.0),
            "object_type": (-1.0, 1.0),
            "triangle_type": (0.0, 1.0),
        }
        for i in range(7):
            lo, hi = self._joint_low[i], self._joint_high[i]
            if not np.isfinite(lo):
                if not self.config.wrap_joints:
                    continue  # unbounded, as upstream
                lo, hi = -math.pi, math.pi
            bounds[f"Kinematic3DRobot.joint_{i + 1}"] = (float(lo), float(hi))
        for q in ("qx", "qy", "qz", "qw"):
            bounds[f"pose_{q}"] = (-1.0, 1.0)
            bounds[f"Kinematic3DRobot.grasp_tf_{q}"] = (-1.0, 1.0)
        return bounds

    # -- helpers for families -------------------------------------------------------------------
    def robot_features(self) -> list[float]:
        """The robot's initial 19 features (home pose, open gripper, nothing held)."""
        return [
            *self.config.home_base_pose,
            *self.config.home_joints,
            0.0,
            0.0,
            *_NO_GRASP_TF,
        ]

    @staticmethod
    def cuboid_features(
        pos: tuple[float, float, float] | Array,
        half: tuple[float, float, float] | Array,
        object_type: float = SOLID,
        yaw: float = 0.0,
    ) -> list[float]:
        """12 cuboid features for an upright cuboid with the given yaw."""
        return [
            *(float(v) for v in pos),
            0.0,
            0.0,
            math.sin(yaw / 2.0),
            math.cos(yaw / 2.0),
            0.0,
            object_type,
            *(float(v) for v in half),
        ]

    def held_object(self, state: ObjectCentricState) -> Object | None:
        """The object currently grasped, if any."""
        if state.get(self.robot, "grasp_active") < 0.5:
            return None
        for obj in state.objects:
            if obj.type in (CUBOID_TYPE, TRIANGLE_TYPE) and state[obj][7] > 0.5:
                return obj
        return None

    def contents(self, state: ObjectCentricState, container: Object | None) -> list[Object]:
        """Movable objects whose centre lies inside a held container."""
        if container is None or container.type != CUBOID_TYPE:
            return []
        f = state[container]
        half = f[9:12]
        if not np.all(half > CONTAINER_MIN_HALF_EXTENT):
            return []
        inside = []
        for name in self.movable_names(state):
            obj = state.get_object_from_name(name)
            if obj == container:
                continue
            # Upstream compares centres along the world axes (the container's own rotation is
            # ignored), strictly inside the half extents.
            if np.all(np.abs(state[obj][:3] - f[:3]) < half):
                inside.append(obj)
        return inside

    def ee_pose(self, state: ObjectCentricState) -> tuple[Array, Array]:
        """World pose (position, quaternion xyzw) of the end effector in ``state``."""
        self._sync(state)
        return self._scene.ee_pose()

    def pinch_pose(self, state: ObjectCentricState) -> tuple[Array, Array]:
        """World pose of the pinch point between the pads (the IK solver's ``pinch_site``;
        ``TOOL_OFFSET`` − ``PINCH_OFFSET`` = −2.5 cm from the end effector along its z axis)."""
        self._sync(state)
        return self._scene.pinch_pose()

    def penetrations(
        self, state: ObjectCentricState, moving: Collection[str] | None = None
    ) -> list[tuple[str, str]]:
        """Pairs of bodies that interpenetrate deeper than ``collision_tolerance`` in ``state``.

        Covers the robot against every collidable object and every pair of collidable objects
        (observed and constant). A valid initial state has none. With ``moving`` (names; the
        robot is ``"robot"``), only the pairs with exactly one member in it are checked, those
        a motion planner moving these bodies must test, and the rest are left out; the pairs
        reported are the same as those of the full check that have one member in ``moving``.
        """
        self._sync(state)
        scene, tol = self._scene, self.config.collision_tolerance
        names = [n for n, c in self._constants.items() if c.spec.collide]
        names += [o.name for o in state if o.type in SOLID_TYPES]
        bodies = {n: scene.body(n) for n in names}

        def checked(a: str, b: str) -> bool:
            return moving is None or ((a in moving) != (b in moving))

        found = [
            ("robot", n)
            for n, b in bodies.items()
            if checked("robot", n) and scene.collides(scene.robot, [b], tol)
        ]
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if checked(a, b) and scene.collides(bodies[a], [bodies[b]], tol):
                    found.append((a, b))
        return found

    def self_collision(self, state: ObjectCentricState) -> bool:
        """Whether the robot's arm touches itself in ``state`` (the pairs the env checks when
        ``check_self_collisions`` is set)."""
        self._sync(state)
        return self._scene.self_collides(self.config.collision_distance)

    def support_gap(self, state: ObjectCentricState, name: str) -> float:
        """The smallest gap between object ``name`` and a surface below it (+inf if none within
        ``min_placement_dist``)."""
        self._sync(state)
        scene, gap = self._scene, self.config.min_placement_dist
        body = scene.body(name)
        gaps = [
            scene.support_gap(body, scene.body(s), gap)
            for s in self.surface_names(state)
            if s != name
        ]
        return min(gaps, default=math.inf)

    # -- scene synchronisation ------------------------------------------------------------------
    def _sync(self, state: ObjectCentricState, force: bool = False) -> None:
        """Load ``state`` into the pybullet scene (skipped when it already holds it).

        An object whose features equal those it was last loaded with keeps its body and pose
        (a motion planner's states differ from each other only in the robot and what it
        carries): its body is a function of its features (``object_parts``, ``object_color``).
        ``force`` (after a step has moved bodies itself) poses every object again.
        """
        scene, cache = self._scene, self._sync_cache
        scene_client = scene.client  # connects if needed
        del scene_client
        if (
            not force
            and cache.generation == scene.generation
            and cache.layout is state.layout
            and np.array_equal(cache.data, state.data)
        ):
            return
        rows = cache.rows
        if cache.generation != scene.generation:
            rows.clear()
            for name, const in self._constants.items():
                scene.ensure_body(name, const.spec)
                scene.set_pose(name, list(const.pos), list(const.quat))
        keep = set(self._constants)
        for obj in state.objects:
            f = state[obj]
            if obj == self.robot:
                scene.set_robot(f[_CONFIG], float(f[_FINGER]))
                continue
            keep.add(obj.name)
            last = rows.get(obj.name)
            if not force and last is not None and np.array_equal(last, f):
                continue
            rows[obj.name] = f.copy()
            if obj.type == POINT_TYPE:
                spec = BodySpec((), self.object_color(obj), collide=False, sphere_radius=0.05)
                scene.ensure_body(obj.name, spec)
                scene.set_pose(obj.name, f[:3], [0.0, 0.0, 0.0, 1.0])
            else:
                spec = BodySpec(tuple(self.object_parts(state, obj)), self.object_color(obj))
                scene.ensure_body(obj.name, spec)
                scene.set_pose(obj.name, f[:3], f[3:7])
        scene.remove_except(keep)
        for name in [n for n in rows if n not in keep]:
            del rows[name]
        cache.generation = scene.generation
        cache.layout = state.layout
        cache.data = state.data.copy()

    def _collidable(self, state: ObjectCentricState, exclude: set[str]) -> list[int]:
        bodies = [
            self._scene.body(n)
            for n, c in self._constants.items()
            if c.spec.collide and n not in exclude
        ]
        bodies += [
            self._scene.body(o.name)
            for o in state
            if o.type in SOLID_TYPES and o.name not in exclude
        ]
        return bodies

    # -- the transition -------------------------------------------------------------------------
    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        cfg = self.config
        self._sync(state)
        robot = state[self.robot]
        q0 = robot[_CONFIG].copy()
        q1 = q0 + np.clip(action[:10], -cfg.max_action_mag, cfg.max_action_mag)
        x0, x1, y0, y1 = cfg.world_bounds
        q1[0] = min(max(q1[0], x0), x1)
        q1[1] = min(max(q1[1], y0), y1)
        q1[3:10] = np.clip(q1[3:10], self._joint_low, self._joint_high)

        held = self.held_object(state)
        carried = self.contents(state, held)
        exclude = {o.name for o in carried}
        if held is not None:
            exclude.add(held.name)
        obstacles = self._collidable(state, exclude)
        grasp_tf = (robot[_TF][:3].copy(), robot[_TF][3:].copy())

        if np.any(q1 != q0):
            if not self._sweep_collides(state, q0, q1, held, grasp_tf, obstacles):
                self._commit_motion(state, q1, held, carried, grasp_tf)
            self._sync(state, force=True)  # the sweep left the scene at some increment

        command = float(action[10])
        if command < -0.5 and held is None:
            self._try_grasp(state)
            self._sync(state, force=True)  # closing moved the fingers in the scene
        elif command > 0.5 and held is not None:
            # Opening with nothing held changes nothing (as upstream).
            self._try_release(state, held, carried)
            self._sync(state)
        return state

    def _held_world_pose(self, grasp_tf: tuple[Array, Array]) -> tuple[Array, Array]:
        ee_p, ee_q = self._scene.ee_pose()
        return _pb_compose(ee_p, ee_q, grasp_tf[0], grasp_tf[1])

    def _sweep_collides(
        self,
        state: ObjectCentricState,
        q0: Array,
        q1: Array,
        held: Object | None,
        grasp_tf: tuple[Array, Array],
        obstacles: list[int],
    ) -> bool:
        step = self.config.max_collision_check_step
        n = 1 if step is None else max(1, math.ceil(float(np.max(np.abs(q1 - q0))) / step))
        cfg, scene = self.config, self._scene
        dist = cfg.collision_distance
        held_body = scene.body(held.name) if held is not None else -1
        # The endpoint first: a colliding endpoint (the common case) ends the check at once.
        for i in (n, *range(1, n)):
            scene.set_robot(q0 + (q1 - q0) * (i / n))
            if cfg.check_self_collisions and scene.self_collides(dist):
                return True
            if scene.arm_near(obstacles, dist, include_base=cfg.check_base_collisions):
                return True
            if held is not None:
                pos, quat = self._held_world_pose(grasp_tf)
                scene.set_pose(held.name, pos, quat)
                if any(scene.near(held_body, b, dist) for b in obstacles):
                    return True
                if self.extra_motion_collision(state, held, pos, quat):
                    return True
        return False

    def _commit_motion(
        self,
        state: ObjectCentricState,
        q1: Array,
        held: Object | None,
        carried: list[Object],
        grasp_tf: tuple[Array, Array],
    ) -> None:
        robot = state[self.robot]
        q0 = robot[_CONFIG].copy()
        q = q1.copy()
        q[2] = _wrap(q[2])
        if self.config.wrap_joints:
            q[3:10][self._continuous] = [_wrap(v) for v in q[3:10][self._continuous]]
        robot[_CONFIG] = q
        if held is None:
            return
        # As upstream: each carried object keeps its transform in the end-effector frame.
        self._scene.set_robot(q0)
        ee_inv = _pb_invert(*self._scene.ee_pose())
        in_ee = [_pb_compose(*ee_inv, state[obj][:3], state[obj][3:7]) for obj in carried]
        self._scene.set_robot(q1)
        state[held][:3], state[held][3:7] = self._held_world_pose(grasp_tf)
        ee_p, ee_q = self._scene.ee_pose()
        for obj, (p, qq) in zip(carried, in_ee, strict=True):
            state[obj][:3], state[obj][3:7] = _pb_compose(ee_p, ee_q, p, qq)

    def _try_grasp(self, state: ObjectCentricState) -> None:
        """Grasp the one movable object within reach of the grasp marker, as upstream does.

        The fingers close in ``finger_close_step`` increments until the arm or the fingers
        touch the object (or the fingers are within one increment of closed); the grasp is
        undone if the robot then collides with anything else (or with itself).
        """
        scene, cfg = self._scene, self.config
        dist = cfg.collision_distance
        robot = state[self.robot]
        scene.place_marker()
        movable = [state.get_object_from_name(n) for n in self.movable_names(state)]
        touching = scene.marker_touching([scene.body(o.name) for o in movable], dist)
        if len(touching) != 1:
            return
        obj = next(o for o in movable if scene.body(o.name) == touching[0])
        body = touching[0]
        start = float(robot[_FINGER])
        s = start
        while not scene.arm_near([body], dist):
            if s >= FINGER_STATE_MAX - cfg.finger_close_step:
                break
            s += cfg.finger_close_step
            scene.set_robot(robot[_CONFIG], s)
        others = self._collidable(state, {obj.name})
        # Upstream checks the arm (never the base) here.
        if (cfg.check_self_collisions and scene.self_collides(dist)) or scene.arm_near(
            others, dist
        ):
            scene.set_robot(robot[_CONFIG], start)
            return
        ee_p, ee_q = scene.ee_pose()
        tf_p, tf_q = _pb_compose(*_pb_invert(ee_p, ee_q), state[obj][:3], state[obj][3:7])
        robot[_FINGER] = s
        robot[_GRASP] = 1.0
        robot[_TF] = [*tf_p, *tf_q]
        state[obj][7] = 1.0

    def _try_release(self, state: ObjectCentricState, held: Object, carried: list[Object]) -> None:
        scene, gap = self._scene, self.config.min_placement_dist
        body = scene.body(held.name)
        # A held surface never supports itself (upstream's check lets a held box or block
        # release anywhere because pybullet finds a body within any distance of itself).
        surfaces = [n for n in self.surface_names(state) if n != held.name]
        if not any(scene.near(body, scene.body(n), gap) for n in surfaces):
            return
        robot = state[self.robot]
        robot[_FINGER] = 0.0
        robot[_GRASP] = 0.0
        robot[_TF] = _NO_GRASP_TF
        state[held][7] = 0.0

    # -- rendering ------------------------------------------------------------------------------
    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        cfg = self.config
        self._sync(state)
        return self._scene.capture_orbit(
            cfg.camera_target,
            cfg.camera_distance,
            cfg.camera_yaw,
            cfg.camera_pitch,
            cfg.image_width,
            cfg.image_height,
        )

    def render_cameras(
        self, state: ObjectCentricState | None = None
    ) -> dict[str, NDArray[np.uint8]]:
        """Images from the ``overview``, ``base`` and ``wrist`` cameras (live state by default)."""
        if state is None:
            state = self.get_state()
        cfg = self.config
        images = {"overview": self._render_state(state)}
        for name in ("base", "wrist"):
            eye, target, up, fovy = self._scene.robot_camera(name)
            images[name] = self._scene.capture(
                eye, target, up, fovy, cfg.image_width, cfg.image_height
            )
        return images

    def close(self) -> None:
        """Release the pybullet client."""
        self._scene.close()
        super().close()

    # -- sampling helpers -----------------------------------------------------------------------
    def _reset_error(self, what: str) -> ResetError:
        return ResetError(
            f"{type(self).__name__}: could not sample {what} in {self.config.max_reset_tries} "
            f"tries; relax the configuration (fewer objects or larger regions)"
        )


def _pb_compose(p1: Array, q1: Array, p2: Array, q2: Array) -> tuple[Array, Array]:
    """``(p1, q1) ∘ (p2, q2)`` with pybullet's ``multiplyTransforms``, which upstream uses for the
    grasp transform and held objects (it computes in single precision and returns the rotation's
    quaternion in Bullet's sign convention; matching it keeps our features equal to upstream's)."""
    a, b = [float(v) for v in p1], [float(v) for v in q1]
    p, q = pb.multiplyTransforms(a, b, [float(v) for v in p2], [float(v) for v in q2])
    return np.array(p, dtype=np.float64), np.array(q, dtype=np.float64)


def _pb_invert(p: Array, q: Array) -> tuple[Array, Array]:
    """The inverse transform with pybullet's ``invertTransform`` (see :func:`_pb_compose`)."""
    ip, iq = pb.invertTransform([float(v) for v in p], [float(v) for v in q])
    return np.array(ip, dtype=np.float64), np.array(iq, dtype=np.float64)


def _wrap(angle: float) -> float:
    """Wrap an angle into [-pi, pi)."""
    return float((angle + math.pi) % (2.0 * math.pi) - math.pi)
