"""The Dynamic3D environment: one MuJoCo env class for every task file (environments.md §5)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from kinder_core import Object, ObjectCentricEnv, ObjectCentricState, ObjectCentricStateSpace
from kinder_core.state import FloatArray, StateLayout
from kinder_garden3d.dynamic3d.assets import STATIC_COLLIDER_TYPES
from kinder_garden3d.dynamic3d.geometry import Array, quat_yaw, quats_to_matrices, yaw_quat
from kinder_garden3d.dynamic3d.object_types import (
    ALL_TYPES,
    DRAWER_TYPE,
    FIXTURE_TYPE,
    MOVABLE_TYPE,
    ROBOT_TYPE,
    SEESAW_TYPE,
    STATIC_COLLIDER_TYPE,
)
from kinder_garden3d.dynamic3d.predicates import GoalEvaluator, Regions
from kinder_garden3d.dynamic3d.scene import (
    ARM_KD,
    ARM_KP,
    FRICTION_CONES,
    ROBOT_PREFIX,
    Scene,
    build_scene,
)
from kinder_garden3d.dynamic3d.taskfile import GROUND, ROBOT, TaskSpec, load_task
from kinder_garden3d.robot.description import (
    GRIPPER_STROKE,
    RobotDescription,
    robot_description,
)
from kinder_garden3d.robot.mjcf import ARM_TORQUE_LIMITS

# Headless rendering: EGL unless the user chose a backend (osmesa, glfw) before importing.
# PyOpenGL must agree; set it here too in case OpenGL is imported before MuJoCo's own GL setup.
os.environ.setdefault("MUJOCO_GL", "egl")
if os.environ["MUJOCO_GL"] in ("egl", "osmesa"):
    os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
import mujoco

_SIM_STATE_SPEC = int(
    mujoco.mjtState.mjSTATE_FULLPHYSICS
    | mujoco.mjtState.mjSTATE_MOCAP_POS
    | mujoco.mjtState.mjSTATE_MOCAP_QUAT
    | mujoco.mjtState.mjSTATE_WARMSTART
)
_FINGER_TRAVEL = GRIPPER_STROKE / 2.0  # slide of one finger pad from open to closed
_PENETRATION_TOL = 1e-4
#: The arm's configuration at reset: upstream kindergarden 0.2.5's TidyBot retract pose,
#: (0, -20, 180, -146, 0, -50, 90) degrees (joint 3 at +pi, where the shared robot model's
#: ``RETRACT`` has the same pose with -pi and rounded joints 2, 4 and 6).
HOME_ARM: tuple[float, ...] = tuple(
    math.radians(a) for a in (0.0, -20.0, 180.0, -146.0, 0.0, -50.0, 90.0)
)


@dataclass(frozen=True)
class Dynamic3DConfig:
    """Physical and sampling constants shared by every Dynamic3D task.

    Attributes:
        timestep: MuJoCo physics step (s): upstream's 0.5 ms. ``timestep=0.001, substeps=100``
            keeps 0.1 s per action at about half the cost, but a falling object then moves
            twice as far into what it hits per step (on MuJoCo 3.3 a 1 cm cube dropped 20 cm
            into ScoopPour3D's bin crossed its 2 cm floor in 1 of 100 resets); off by default.
        substeps: Physics steps per action (200 × 0.5 ms = 0.1 s, i.e. 10 Hz control).
        settle_actions: All-zero actions applied at reset before the first observation.
        max_base_delta: Bound of the base deltas (m for x, y; rad for yaw).
        max_arm_delta: Bound of the arm joint deltas (rad).
        max_arm_velocity_target: Bound of the 7 joint-velocity targets of 18-D tasks (rad/s).
        cone: MuJoCo friction cone, ``"elliptic"`` (default, as the upstream robot models:
            Menagerie's TidyBot and Gen3 + 2F-85) or ``"pyramidal"`` (MuJoCo's default, used
            before the contact update).
        impratio: Ratio of frictional to normal constraint impedance (10 as upstream's robot
            models; MuJoCo's default is 1). With the elliptic cone and 10, a 2 cm cube held
            in the gripper no longer creeps out of the pads.
        arm_control: ``"pd"`` (default): the arm's PD (``Kp (q* − q) − Kd q̇``, clipped) runs in
            MuJoCo position actuators at every physics step, with MuJoCo's ``gravcomp``.
            ``"held_torque"``: upstream kindergarden 0.2.5's controller: the torque
            ``Kp Δq − Kd q̇ + qfrc_bias`` (Coriolis and gravity), clipped to the motor limits, is
            computed once from the state at the start of the action and held for all its
            physics steps (motors, no ``gravcomp``).
        image_width, image_height: Rendered frame size for every camera.
        max_placement_tries: Pose samples per entity before a layout attempt is abandoned.
        max_reset_tries: Layout attempts per reset before a RuntimeError.
        placement_gap: Height (m) above its support at which an object is released.
        default_robot_region: (xmin, ymin, xmax, ymax) for the robot base when the task does
            not place it (any yaw).
        task_options: Names of entries of the task file's ``options`` section to apply (each
            a documented alternative to the default scene, off by default; see Deviations for
            the bundled ones). An option the task does not offer is an error.
    """

    timestep: float = 0.0005
    substeps: int = 200
    settle_actions: int = 10
    max_base_delta: float = 0.1
    max_arm_delta: float = 0.1
    max_arm_velocity_target: float = 10.0
    cone: str = "elliptic"
    impratio: float = 10.0
    arm_control: str = "pd"
    image_width: int = 640
    image_height: int = 480
    max_placement_tries: int = 500
    max_reset_tries: int = 20
    placement_gap: float = 0.001
    default_robot_region: tuple[float, float, float, float] = (-1.0, -1.0, 1.0, 1.0)
    task_options: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        options: object = self.task_options  # a config dict may hold any value here
        if not (isinstance(options, (list, tuple)) and all(isinstance(o, str) for o in options)):
            raise ValueError(
                f"Dynamic3DConfig.task_options must be a sequence of option names, got {options!r}"
            )
        object.__setattr__(self, "task_options", tuple(options))  # a list from a config dict
        positive = ("timestep", "max_base_delta", "max_arm_delta", "max_arm_velocity_target",
                    "impratio")  # fmt: skip
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"Dynamic3DConfig.{name} must be > 0, got {getattr(self, name)}")
        for name in ("substeps", "image_width", "image_height", "max_placement_tries",
                     "max_reset_tries"):  # fmt: skip
            if not getattr(self, name) >= 1:
                raise ValueError(f"Dynamic3DConfig.{name} must be >= 1, got {getattr(self, name)}")
        if self.cone not in FRICTION_CONES:
            raise ValueError(
                f"Dynamic3DConfig.cone must be one of {sorted(FRICTION_CONES)}, got {self.cone!r}"
            )
        if self.arm_control not in ("pd", "held_torque"):
            raise ValueError(
                f"Dynamic3DConfig.arm_control must be 'pd' or 'held_torque', got "
                f"{self.arm_control!r}"
            )
        if self.settle_actions < 0 or self.placement_gap < 0:
            raise ValueError("Dynamic3DConfig.settle_actions and placement_gap must be >= 0")
        x0, y0, x1, y1 = self.default_robot_region
        if not (x0 <= x1 and y0 <= y1):
            raise ValueError(
                f"default_robot_region must be (xmin, ymin, xmax, ymax), got "
                f"{self.default_robot_region}"
            )


class _PlacementFailure(Exception):
    pass


class Dynamic3DEnv(ObjectCentricEnv):
    """A TidyBot++-style mobile manipulator in a MuJoCo scene described by a task file.

    ## Description
    Every Dynamic3D task (Shelf3D, ConstrainedCupboard3D, Rearrange3D, SortClutteredBlocks3D,
    SweepSimple3D, SweepIntoDrawer3D, ScoopPour3D, BalanceBeam3D, Tossing3D, Dynamo3D) runs in
    this one class; tasks differ only in their task files (`tasks/<Family>/*.json`: fixtures,
    objects, regions, cameras, initial-state and goal predicates). The robot has a holonomic
    base (position servo), a 7-DoF Kinova Gen3 arm (joint PD torque control with gravity
    compensation) and a two-finger Robotiq 2F-85-style gripper. Physics: MuJoCo 3.3 (upstream's
    `mujoco~=3.3.0`), 0.5 ms steps, 200 steps per action (0.1 s of simulated time, 10 Hz
    control), elliptic friction cones with `impratio = 10` (the contact settings of upstream's
    robot models) and MuJoCo's `multiccd` (several contact points between convex shapes: our
    cylinder stand-ins, the can, stand still on a table as upstream's mesh can does, where
    MuJoCo 3.3's one point lets them rock). Every fixture and object
    is built from primitive shapes.

    ## Observation Space
    All objects sorted by name, each with its type's features. Movable objects (16):
    `x, y, z, qw, qx, qy, qz, vx, vy, vz, wx, wy, wz, bb_x, bb_y, bb_z` (pose of the bounding
    box centre, world-frame linear and angular velocity, full bounding-box size). A seesaw adds
    `hinge_pos, hinge_vel` (18). Fixtures (7): `x, y, z, qw, qx, qy, qz` (the footprint centre on
    the floor); fixed obstacles (`fixed_box`, used by no bundled task) add `bb_x, bb_y, bb_z`.
    Drawers (1): `pos` of the slide (0 = closed; constant 0 for drawers welded shut; a state
    built from features alone has its drawers at rest). The robot (22): `pos_base_x,
    pos_base_y, pos_base_rot, pos_arm_joint1..7, pos_gripper, vel_base_x, vel_base_y,
    vel_base_rot, vel_arm_joint1..7, vel_gripper` (gripper: finger closure in [0, 1], 0 = open).
    Quaternions are ordered (w, x, y, z). Object names, order and sizes match upstream
    kindergarden 0.2.5 for every id except BalanceBeam3D (see Deviations).
    The full MuJoCo state (qpos, qvel, warm start, mocap poses, time) travels with each state
    as `sim_state`, so `set_state(s); step(a)` reproduces a step exactly.

    ## Action Space
    An 11-D float32 Box: Δbase x, y (m) and yaw (rad) in ±0.1, Δarm joints 1–7 in ±0.1 rad,
    and a gripper command in [0, 1] (0 = open, 1 = closed). Targets are the current joint
    positions plus the deltas: the base tracks them with position servos; the arm with
    `Kp (q* − q) − Kd q̇` + gravity compensation (Kp = 200, 200, 200, 200, 100, 100, 100;
    Kd = 30, 30, 30, 30, 15, 15, 15; clipped to 200/100 N m); the gripper servo gets
    `command × 255`. Every bundled task is 11-D (as upstream kindergarden 0.2.5, Tossing3D
    included). A task file with `arm_velocity_targets` takes 18-D actions: the 11 above plus 7
    absolute joint-velocity targets q̇* in ±10 rad/s, giving `Kp (q* − q) + Kd (q̇* − q̇)` (the
    spec's older Tossing3D action).

    ## Reward
    −1 on every step.

    ## Starting State
    Fixtures and objects are placed by the task's initial-state predicates (`on`/`in` a
    region): a box of the region is drawn, then a point and a yaw in it, with rejection of
    colliding poses (bounded tries, then a RuntimeError). The robot is placed by its own
    predicate, or uniformly in x, y ∈ [−1, 1] with any yaw; its arm starts in upstream's retract
    pose (0, −20, 180, −146, 0, −50, 90)° (`HOME_ARM`) and the gripper open. A region box's z
    range is a drop height: fixtures are placed at it (upstream draws a floor fixture's height
    in [0, 0.1] m) and objects are released from it above their support. Ten all-zero actions
    then let the scene settle; layouts whose settled state already satisfies the goal (or has an
    object below the floor) are resampled.

    ## Episode End
    Terminates when the task's goal predicates hold (`on`/`in`: the object's centre, or the
    robot base, lies in the region's box in the region's frame; `balanced`: the seesaw's hinge
    angle is within the tolerance; combined with `and`/`or`). Each task file sets
    `max_episode_steps` (1000 unless stated).

    ## Arguments
    `task`: a bundled task (`"Shelf3D/Shelf3D.json"`, or a family name with a single file) or a
    path to any task file. `num_objects`: the task's count (tasks with a `count` section).
    `config`: a `Dynamic3DConfig` (or a dict of its fields). `render_mode`: `"rgb_array"` or
    None.

    ## Deviations
    * Assets are primitive stand-ins (no RoboCasa/MimicLabs meshes, no lab backdrop); the robot
      is the project's primitive-shape TidyBot++ model. Sizes follow environments.md §5.
    * The arm PD runs inside MuJoCo (position actuators with kv) at every physics step and
      gravity compensation is MuJoCo's `gravcomp` (gravity only; the spec's `qfrc_bias` also
      holds Coriolis terms, and the compensation is not included in the torque clip). Upstream
      computes `Kp Δq − Kd q̇ + qfrc_bias` once per action and holds that torque for the whole
      0.1 s, on arm joints with passive damping 50/25 N m s/rad and no armature:
      `Dynamic3DConfig(arm_control="held_torque")` does exactly that (one-step arm error against
      recorded upstream steps 5e-4 rad median, against 0.03 rad with the default;
      `tests/test_conformance_dynamic3d.py`). The default stays `"pd"` until the planning
      models' skills are re-tuned for the slower, damped arm.
    * `pos_gripper`/`vel_gripper` are the measured finger closure and its rate (upstream
      reports the command `ctrl / 255`). Drawers also report `vel`; seesaws report their hinge.
    * Joint-velocity targets are bounded (±10 rad/s) instead of unbounded, so that actions can
      be clipped and checked.
    * Every task starts with its goal unsatisfied; BalanceBeam3D's goal also requires the blocks
      on the beam (as in upstream 0.2.5).
    * Kitchen drawers slide only where a task lists them (`working_drawers`; SweepIntoDrawer3D's
      upper middle drawer); the others are welded shut but observed (with `pos` always 0, so
      the observation has upstream's layout).
    * BalanceBeam3D's seesaw is observed with its hinge (`hinge_pos, hinge_vel`: 88 values
      against upstream's 86). Upstream observes the seesaw as a plain movable object, whose
      pose does not give the beam's angle; the `balanced` goal is a function of the
      observation here, and `set_state` must be able to restore the beam, so the two features
      stay.
    * The robot's `base` camera is oriented with the spec's MuJoCo euler angles
      (0, −45°, −90°) when the scene is assembled.
    * Kept option, off by default: `Dynamic3DConfig(task_options=("flat_wiper",))` gives the
      SweepSimple3D tasks their earlier scene (a flat T wiper with a 3 cm head, 1 cm cubes, the
      wiper's yaw in ±20°, o1's regions for every variant, the goal box without upstream's 5 cm
      margin). The default is upstream's: an upright wiper and 2 cm cubes (the task files' notes).
    * Kept option, off by default: `Dynamic3DConfig(task_options=("half_size_objects",))`
      gives SortClutteredBlocks3D-o12 its earlier objects (2 cm cubes, 35 cm rods: upstream's
      half-extent sizes read as full extents), which the planning model's rod skills need. The
      default is upstream's: 4 cm cubes and 70 cm rods.

    ## References
    KinDER (RSS 2026), environments.md §5; TidyBot++ (CoRL 2024); MuJoCo.

    ## Version History
    * v0: initial release.
    * v0 (upstream conformance): Shelf3D and SweepIntoDrawer3D draw upstream kindergarden
      0.2.5's regions, sizes and masses (each task file's notes say which); the arm starts in
      upstream's retract pose (joint 3 at +π, joints 2, 4, 6 at −20°, −146°, −50°; it was the
      robot model's rounded `RETRACT` with joint 3 at −π). Checked against recorded upstream
      resets by `tests/test_conformance_dynamic3d.py`.
    * v0 (upstream conformance): SweepSimple3D draws upstream's scene: an upright wiper (a
      30 × 2 × 4 cm head and a 30 cm handle; o50 a 40 cm head and a 1 m handle) and 2 cm cubes
      dropped from up to 10 cm, the wiper's yaw in ±45°, o50's own regions, upstream's goal
      margin; the earlier scene is the `flat_wiper` task option.
    * v0 (upstream conformance): SortClutteredBlocks3D-o12 has upstream's 4 cm cubes and 70 cm
      rods and its goal heights (the earlier objects are the `half_size_objects` task option);
      o20 into bowls has upstream's table turned 90°, 16 cm bowls dropped at any yaw into its
      10 cm table squares (the goals) and 2 cm blocks of 0.1 kg.
    * v0 (contact update): elliptic friction cones and `impratio = 10` as upstream's robot
      models (MuJoCo's pyramidal cone and 1 before; `Dynamic3DConfig(cone="pyramidal",
      impratio=1)` restores them). A held 2 cm cube slipped about 0.9 mm/s out of the pads
      before and 0.05 mm/s now (`benchmarks/probes/grasp_slip.py`).
    * v0 (spaces update): observation and action spaces match upstream kindergarden 0.2.5 id by
      id (object names, order and feature lists; `benchmarks/results/upstream_spaces.json`):
      the kitchen scene adds the upper cooking-area cupboard and the left corner unit and
      observes all ten drawers (`pos` only, named `<fixture>_drawer_s<level>c<cell>`);
      Tossing3D is 11-D with a movable `cuboid_barrier`; objects are renamed as upstream
      (SweepIntoDrawer3D's screws `cube_i`, Dynamo3D's `obstacle_chair[_i]` with 11 chairs in
      o12, SortClutteredBlocks3D's `cube1..N`, BalanceBeam3D's `large_block`,
      `small_block_1/2`); SortClutteredBlocks3D-o12 follows upstream's cupboard layout.
    """

    #: The task files' ``robot.model`` this class simulates.
    robot_model: ClassVar[str] = "tidybot"

    def __init__(
        self,
        task: str,
        num_objects: int | None = None,
        config: Dynamic3DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        super().__init__(render_mode=render_mode)
        if config is None:
            config = Dynamic3DConfig()
        elif isinstance(config, Mapping):  # e.g. from gymnasium.make(..., config={...})
            try:
                config = Dynamic3DConfig(**config)
            except TypeError as e:
                raise ValueError(f"Dynamic3DEnv: bad config {config!r}: {e}") from None
        self.config = config
        cfg = self.config
        self.task: TaskSpec = load_task(task, num_objects, cfg.task_options)
        if self.task.robot != self.robot_model:
            raise ValueError(
                f"{self.task.file}: the task's robot is {self.task.robot!r} but "
                f"{type(self).__name__} simulates {self.robot_model!r} (tasks of the 'fr3' arm "
                f"run in kinder_garden3d.dynamic3d.franka.Franka3DEnv)"
            )
        self._held_torque = cfg.arm_control == "held_torque"
        self.scene: Scene = build_scene(
            self.task,
            (cfg.image_width, cfg.image_height),
            timestep=cfg.timestep,
            arm_motors=self._held_torque,
            cone=cfg.cone,
            impratio=cfg.impratio,
        )
        self.model = mujoco.MjModel.from_xml_string(self.scene.xml)
        self.data = mujoco.MjData(self.model)
        self._velocity_targets = self.task.arm_velocity_targets
        self._setup_objects()
        self._setup_indices()
        self._setup_actions()
        self.observation_space = ObjectCentricStateSpace(ALL_TYPES)
        self.regions = Regions(self.scene.regions, self.task.regions, self._layout)
        self.goal = GoalEvaluator(self.task.goal, self.regions, self._layout)
        self._renderers: dict[tuple[int, int], Any] = {}
        self._scene_option = mujoco.MjvOption()
        self._scene_option.geomgroup[:4] = 1  # the robot's collision shapes (group 3) are visible
        self._cache: tuple[FloatArray, FloatArray] | None = None
        self._update_metadata()

    # -- setup ----------------------------------------------------------------------------------
    def _setup_objects(self) -> None:
        task = self.task
        objs: dict[str, Object] = {ROBOT: Object(ROBOT, ROBOT_TYPE)}
        for name, spec in task.fixtures.items():
            kind = STATIC_COLLIDER_TYPE if spec.kind in STATIC_COLLIDER_TYPES else FIXTURE_TYPE
            objs[name] = Object(name, kind)
        for fixture in self.scene.fixtures.values():  # working and welded drawers alike
            for drawer in [d.name for d in fixture.drawers] + fixture.welded_drawers:
                objs[drawer] = Object(drawer, DRAWER_TYPE)
        for name in task.objects:
            kind = SEESAW_TYPE if name in self.scene.seesaws else MOVABLE_TYPE
            objs[name] = Object(name, kind)
        self.objects: dict[str, Object] = objs
        self._layout = StateLayout.of(objs.values())

    def _setup_indices(self) -> None:
        """Gather/scatter tables between MjData and the flat feature vector.

        The simulator vector is ``[qpos, qvel, mocap_pos, mocap_quat]``; feature ``k`` equals
        ``sim[src[k]] * scale[k]`` (then angular velocities are rotated to the world frame), and
        constant features (bounding boxes) come from ``self._const``.
        """
        m, lay = self.model, self._layout
        nq, nv = m.nq, m.nv
        off_mp, off_mq = nq + nv, nq + nv + 3 * m.nmocap
        dst: list[int] = []
        src: list[int] = []
        scale: list[float] = []
        const = np.zeros(lay.size)

        def jq(name: str) -> int:
            return int(m.jnt_qposadr[m.joint(name).id])

        def jv(name: str) -> int:
            return int(m.jnt_dofadr[m.joint(name).id])

        def add(obj: Object, feature: str, index: int, s: float = 1.0) -> None:
            dst.append(lay.index(obj, feature))
            src.append(index)
            scale.append(s)

        self._setup_robot_indices(add, jq, jv)

        for name in self.task.fixtures:
            obj = self.objects[name]
            mid = int(m.body_mocapid[m.body(name).id])
            for k, f in enumerate(("x", "y", "z")):
                add(obj, f, off_mp + 3 * mid + k)
            for k, f in enumerate(("qw", "qx", "qy", "qz")):
                add(obj, f, off_mq + 4 * mid + k)
            if obj.type is STATIC_COLLIDER_TYPE:
                lo, hi = self.scene.fixtures[name].aabb
                for k, f in enumerate(("bb_x", "bb_y", "bb_z")):
                    const[lay.index(obj, f)] = hi[k] - lo[k]
        for drawer, (_, joint) in self.scene.drawers.items():
            obj = self.objects[drawer]
            add(obj, "pos", jq(joint))  # welded drawers keep their constant 0
        # Slide velocities are not observed (as upstream): states from features are at rest.
        self._v_drawers = np.array([jv(j) for _, j in self.scene.drawers.values()], dtype=int)

        free_q, free_v, ang_dst = [], [], []
        for name in self.task.objects:
            obj = self.objects[name]
            qa, va = jq(f"{name}_joint"), jv(f"{name}_joint")
            for k, f in enumerate(("x", "y", "z", "qw", "qx", "qy", "qz")):
                add(obj, f, qa + k)
            for k, f in enumerate(("vx", "vy", "vz", "wx", "wy", "wz")):
                add(obj, f, nq + va + k)
            bb = self.scene.objects[name].bbox
            for k, f in enumerate(("bb_x", "bb_y", "bb_z")):
                const[lay.index(obj, f)] = bb[k]
            if name in self.scene.seesaws:
                hinge = self.scene.seesaws[name]
                add(obj, "hinge_pos", jq(hinge))
                add(obj, "hinge_vel", nq + jv(hinge))
            free_q.append(qa)
            free_v.append(va)
            ang_dst.append([lay.index(obj, f) for f in ("wx", "wy", "wz")])
        self._dst = np.array(dst, dtype=np.intp)
        self._src = np.array(src, dtype=np.intp)
        self._scale = np.array(scale)
        self._const = const
        self._free_quat = np.array([[q + 3 + k for k in range(4)] for q in free_q], dtype=np.intp)
        self._free_ang = np.array([[v + 3 + k for k in range(3)] for v in free_v], dtype=np.intp)
        self._ang_dst = np.array(ang_dst, dtype=np.intp).reshape(-1, 3)
        self._sim_size = int(mujoco.mj_stateSize(m, _SIM_STATE_SPEC))
        self._sim_buf = np.empty(nq + nv + 7 * m.nmocap)

        # Bodies of each entity (a root body and its descendants), for placement checks.
        parent = m.body_parentid
        roots = {n: m.body(n).id for n in [*self.task.fixtures, *self.task.objects]}
        roots[ROBOT] = m.body(ROBOT_PREFIX + self._robot_description().links[0].name).id
        self._entity_bodies: dict[str, NDArray[np.bool_]] = {}
        for name, root in roots.items():
            mask = np.zeros(m.nbody, dtype=bool)
            for b in range(m.nbody):
                a = b
                while a > 0 and a != root:
                    a = int(parent[a])
                mask[b] = a == root
            self._entity_bodies[name] = mask
        self._fixture_body = np.zeros(m.nbody, dtype=bool)
        for name in self.task.fixtures:
            self._fixture_body |= self._entity_bodies[name]
        self._floor_geom = int(m.geom("floor").id)

    def _robot_description(self) -> RobotDescription:
        """The robot model this env simulates (the mobile manipulator here)."""
        return robot_description()

    def _setup_robot_indices(
        self,
        add: Callable[[Object, str, int, float], None],
        jq: Callable[[str], int],
        jv: Callable[[str], int],
    ) -> None:
        """The robot's rows of the gather/scatter tables (``add(obj, feature, sim index,
        scale)``; ``jq``/``jv``: a joint's qpos/qvel address), and its joint addresses."""
        nq = self.model.nq
        desc = self._robot_description()
        robot = self.objects[ROBOT]
        base_names = [ROBOT_PREFIX + n for n in desc.base_joint_names]
        arm_names = [ROBOT_PREFIX + n for n in desc.arm_joint_names]
        left, right = (ROBOT_PREFIX + n for n in desc.finger_joint_names)
        for feat, jn in zip(("x", "y", "rot"), base_names, strict=True):
            add(robot, f"pos_base_{feat}", jq(jn), 1.0)
            add(robot, f"vel_base_{feat}", nq + jv(jn), 1.0)
        for i, jn in enumerate(arm_names):
            add(robot, f"pos_arm_joint{i + 1}", jq(jn), 1.0)
            add(robot, f"vel_arm_joint{i + 1}", nq + jv(jn), 1.0)
        add(robot, "pos_gripper", jq(left), 1.0 / _FINGER_TRAVEL)
        add(robot, "vel_gripper", nq + jv(left), 1.0 / _FINGER_TRAVEL)
        self._q_base = np.array([jq(n) for n in base_names])
        self._q_arm = np.array([jq(n) for n in arm_names])
        self._q_fingers = np.array([jq(left), jq(right)])
        self._v_fingers = np.array([jv(left), jv(right)])

    def _setup_actions(self) -> None:
        cfg, m = self.config, self.model
        self._act_base = np.array([m.actuator(f"{ROBOT_PREFIX}base_{k}").id for k in "xy"]
                                  + [m.actuator(f"{ROBOT_PREFIX}base_th").id])  # fmt: skip
        self._act_arm = np.array([m.actuator(f"{ROBOT_PREFIX}arm_{i}").id for i in range(1, 8)])
        self._act_grip = m.actuator(f"{ROBOT_PREFIX}fingers_actuator").id
        self._kd_over_kp = np.array(ARM_KD) / np.array(ARM_KP)
        self._kp = np.array(ARM_KP)
        self._kd = np.array(ARM_KD)
        self._torque_limit = np.array(ARM_TORQUE_LIMITS)
        arm_joints = [ROBOT_PREFIX + n for n in robot_description().arm_joint_names]
        self._v_arm = np.array([int(m.jnt_dofadr[m.joint(n).id]) for n in arm_joints])
        low = [-cfg.max_base_delta] * 3 + [-cfg.max_arm_delta] * 7 + [0.0]
        high = [cfg.max_base_delta] * 3 + [cfg.max_arm_delta] * 7 + [1.0]
        if self._velocity_targets:
            low += [-cfg.max_arm_velocity_target] * 7
            high += [cfg.max_arm_velocity_target] * 7
        self.action_space = spaces.Box(
            np.array(low, dtype=np.float32), np.array(high, dtype=np.float32), dtype=np.float32
        )
        self._zero_action = np.zeros(len(low))

    def _update_metadata(self) -> None:
        t = self.task
        family_id = f"{t.family} ({t.file}" + (f", num_objects={t.count})" if t.count else ")")
        self.metadata["summary"] = f"{t.description} {t.instruction}".strip()
        self.metadata["description"] = (
            f"**Task** {family_id}: {t.description}\n\n"
            + (f"**Instruction:** {t.instruction}\n\n" if t.instruction else "")
            + self.metadata["description"]
        )
        starts = "; ".join(f"{p} {e} {r}" for p, e, r in t.initial_state) or "none"
        self.metadata["starting_state"] = (
            f"Initial-state predicates: {starts}.\n\n" + self.metadata["starting_state"]
        )
        self.metadata["episode_end"] = (
            f"Goal: `{_goal_text(t.goal)}`. Step budget {t.max_episode_steps}.\n\n"
            + self.metadata["episode_end"]
        )
        if t.notes:
            self.metadata["deviations"] = self.metadata["deviations"] + f"\n* Task notes: {t.notes}"

    # -- state <-> simulator --------------------------------------------------------------------
    def _sim_vector(self) -> FloatArray:
        d, m = self.data, self.model
        nq, nv = m.nq, m.nv
        buf = self._sim_buf
        buf[:nq] = d.qpos
        buf[nq : nq + nv] = d.qvel
        buf[nq + nv : nq + nv + 3 * m.nmocap] = d.mocap_pos.ravel()
        buf[nq + nv + 3 * m.nmocap :] = d.mocap_quat.ravel()
        return buf

    def _features(self) -> FloatArray:
        """The feature vector of the simulator's current state."""
        data: FloatArray = self._const.copy()
        data[self._dst] = self._sim_vector()[self._src] * self._scale
        if len(self._ang_dst):
            q = self.data.qpos[self._free_quat]
            w_local = self.data.qvel[self._free_ang]
            data[self._ang_dst] = np.einsum("nij,nj->ni", quats_to_matrices(q), w_local)
        return data

    def _write_features(self, data: FloatArray) -> None:
        """Set qpos, qvel and mocap poses from features (the right finger mirrors the left,
        drawers are at rest); the warm start is cleared."""
        m, d = self.model, self.data
        nq, nv = m.nq, m.nv
        sim = self._sim_vector().copy()
        sim[self._src] = data[self._dst] / self._scale
        if len(self._ang_dst):
            q = sim[self._free_quat]
            w_world = data[self._ang_dst]
            sim[nq + self._free_ang] = np.einsum("nji,nj->ni", quats_to_matrices(q), w_world)
        d.qpos[:] = sim[:nq]
        d.qvel[:] = sim[nq : nq + nv]
        d.qpos[self._q_fingers[1]] = d.qpos[self._q_fingers[0]]
        d.qvel[self._v_fingers[1]] = d.qvel[self._v_fingers[0]]
        d.qvel[self._v_drawers] = 0.0
        d.mocap_pos[:] = sim[nq + nv : nq + nv + 3 * m.nmocap].reshape(-1, 3)
        d.mocap_quat[:] = sim[nq + nv + 3 * m.nmocap :].reshape(-1, 4)
        d.qacc_warmstart[:] = 0.0
        d.time = 0.0

    def _load(self, state: ObjectCentricState) -> None:
        """Make MjData hold ``state``: its ``sim_state`` when it agrees with the features, else
        the features (features always win)."""
        sim = state.sim_state
        if sim is not None and self._cache is not None:
            cached_data, cached_sim = self._cache
            if np.array_equal(state.data, cached_data) and np.array_equal(sim, cached_sim):
                return
        self.data.xfrc_applied[:] = 0.0  # the env never applies external forces
        self.data.qfrc_applied[:] = 0.0
        if sim is not None and sim.shape == (self._sim_size,):
            mujoco.mj_setState(self.model, self.data, sim, _SIM_STATE_SPEC)
            if np.array_equal(self._features(), state.data):
                self._cache = (state.data.copy(), sim.copy())
                return
        self._write_features(state.data)
        self._cache = None

    def _extract(self) -> ObjectCentricState:
        """The simulator's current state as an object-centric state (with ``sim_state``)."""
        data = self._features()
        sim = np.empty(self._sim_size)
        mujoco.mj_getState(self.model, self.data, sim, _SIM_STATE_SPEC)
        self._cache = (data, sim)
        return ObjectCentricState(self._layout, data, sim.copy())

    # -- dynamics -------------------------------------------------------------------------------
    def _transition(self, state: ObjectCentricState, action: FloatArray) -> ObjectCentricState:
        self._load(state)
        self._apply(action)
        mujoco.mj_step(self.model, self.data, self.config.substeps)
        return self._extract()

    def _apply(self, action: FloatArray) -> None:
        d = self.data
        ctrl = d.ctrl
        ctrl[self._act_base] = d.qpos[self._q_base] + action[0:3]
        if self._held_torque:
            # Upstream's controller: one torque from the state at the start of the action.
            mujoco.mj_forward(self.model, d)
            qdot = d.qvel[self._v_arm]
            damping = (
                self._kd * (action[11:18] - qdot) if self._velocity_targets else -self._kd * qdot
            )
            torque = self._kp * action[3:10] + damping + d.qfrc_bias[self._v_arm]
            ctrl[self._act_arm] = np.clip(torque, -self._torque_limit, self._torque_limit)
            ctrl[self._act_grip] = action[10] * 255.0
            return
        arm = d.qpos[self._q_arm] + action[3:10]
        if self._velocity_targets:
            # Kp (q* - q) + Kd (v* - v) == Kp ((q* + Kd/Kp v*) - q) - Kd v: one PD actuator.
            arm = arm + self._kd_over_kp * action[11:18]
        ctrl[self._act_arm] = arm
        ctrl[self._act_grip] = action[10] * 255.0

    def goal_reached(self, state: ObjectCentricState) -> bool:
        """Whether the task's goal expression holds in ``state`` (features only)."""
        return self.goal(state)

    def goals_reached(self, data: FloatArray, layout: StateLayout) -> NDArray[np.bool_]:
        """:meth:`goal_reached` of every row of ``data``, in whole-array numpy
        (:meth:`GoalEvaluator.many`, which :meth:`goal_reached` runs on one row). Rows in another
        layout of the env's objects are reordered into the env's first."""
        data = np.asarray(data, dtype=np.float64)
        if layout is not self._layout:
            columns = np.arange(layout.size)
            order = [columns[layout.slice_of(o)] for o in self._layout.objects]
            data = data[:, np.concatenate(order)]
        return self.goal.many(data)

    # -- reset ----------------------------------------------------------------------------------
    def _sample_initial_state(self, rng: np.random.Generator) -> ObjectCentricState:
        cfg = self.config
        problem = ""
        for _ in range(cfg.max_reset_tries):
            try:
                self._place_all(rng)
            except _PlacementFailure as e:
                problem = str(e)
                continue
            state = self._extract()
            for _ in range(cfg.settle_actions):
                state = self._transition(state, self._zero_action)
            if self.goal_reached(state):
                problem = "the settled layout already satisfied the goal"
                continue
            # The height of each object's bounding-box centre (a wiper's frame may be its
            # bottom face): below the floor means it fell through while settling.
            z = [
                state.get(self.objects[n], "z")
                - self.scene.objects[n].bottom
                + self.scene.objects[n].bbox[2] / 2.0
                for n in self.task.objects
            ]
            if z and min(z) < 0.0:
                problem = "an object fell below the floor while settling"
                continue
            return state
        raise RuntimeError(
            f"{self.env_name} ({self.task.file}): no valid initial state in "
            f"{cfg.max_reset_tries} layout attempts; last problem: {problem}"
        )

    def _place_all(self, rng: np.random.Generator) -> None:
        m, d = self.model, self.data
        self._cache = None  # MjData no longer holds any state handed out
        mujoco.mj_resetData(m, d)
        d.qpos[self._q_arm] = HOME_ARM
        d.qpos[self._q_base] = (-80.0, -80.0, 0.0)  # parked until the robot is placed
        self._fixture_boxes: list[tuple[str, Array, Array]] = []
        for name, spec in self.task.fixtures.items():
            if spec.pos is not None:
                self._fixture_boxes.append((name, *self._fixture_aabb(name)))
        robot_placed = False
        for _, entity, region in self.task.initial_state:
            if entity == ROBOT:
                self._place_robot(rng, region)
                robot_placed = True
            elif entity in self.task.fixtures:
                self._place_fixture(rng, entity, region)
            else:
                self._place_object(rng, entity, region)
        if not robot_placed:
            self._place_robot(rng, None)
        d.ctrl[self._act_base] = d.qpos[self._q_base]
        d.ctrl[self._act_arm] = d.qpos[self._q_arm]

    def _region_sample(self, rng: np.random.Generator, region: str) -> tuple[Array, float]:
        """A point (bottom height as z) and a yaw drawn from ``region``, in world coordinates."""
        spec = self.task.regions[region]
        k = int(rng.integers(len(spec.boxes)))
        box = spec.boxes[k]
        local = rng.uniform(box[:3], box[3:])
        yaw = float(rng.uniform(spec.yaws[k, 0], spec.yaws[k, 1]))
        frame = self.regions.transform(ObjectCentricState(self._layout, self._features()), region)
        world = frame[:3, :3] @ local + frame[:3, 3]
        heading = math.atan2(frame[1, 0], frame[0, 0])
        return world, heading + yaw

    def _collides(
        self, entity: str, ignore_fixtures: bool = False, ignore_floor: bool = False
    ) -> bool:
        """Whether ``entity`` penetrates another body (``ignore_floor``: not counting the
        floor plane)."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        n = d.ncon
        if n == 0:
            return False
        geoms = d.contact.geom[:n]
        deep = d.contact.dist[:n] < -_PENETRATION_TOL
        bodies = m.geom_bodyid[geoms]
        mask = self._entity_bodies[entity]
        mine = mask[bodies]
        hit = deep & (mine[:, 0] ^ mine[:, 1])
        other = np.where(mine[:, 0], bodies[:, 1], bodies[:, 0])
        if ignore_fixtures:
            hit &= ~self._fixture_body[other]
        if ignore_floor:
            hit &= ~np.any(geoms == self._floor_geom, axis=1)
        return bool(hit.any())

    def _place_object(self, rng: np.random.Generator, name: str, region: str) -> None:
        d = self.data
        qa = int(self.model.jnt_qposadr[self.model.joint(f"{name}_joint").id])
        centre = self.task.regions[region].drop == "centre"
        lift = 0.0 if centre else self.scene.objects[name].bottom + self.config.placement_gap
        for _ in range(self.config.max_placement_tries):
            point, yaw = self._region_sample(rng, region)
            point[2] += lift
            d.qpos[qa : qa + 3] = point
            d.qpos[qa + 3 : qa + 7] = yaw_quat(yaw)
            if not self._collides(name, ignore_floor=centre):
                return
        raise _PlacementFailure(f"could not place {name!r} in region {region!r} without collisions")

    def _qpos_of(self, name: str) -> Array:
        """The free joint's position coordinates (x, y, z) of object ``name``."""
        qa = int(self.model.jnt_qposadr[self.model.joint(f"{name}_joint").id])
        return np.array(self.data.qpos[qa : qa + 3])

    def _fixture_aabb(self, name: str) -> tuple[Array, Array]:
        mid = int(self.model.body_mocapid[self.model.body(name).id])
        pos, quat = self.data.mocap_pos[mid], self.data.mocap_quat[mid]
        lo, hi = self.scene.fixtures[name].aabb
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])  # fmt: skip
        world = corners @ quats_to_matrices(quat[None])[0].T + pos
        return world.min(axis=0), world.max(axis=0)

    def _place_fixture(self, rng: np.random.Generator, name: str, region: str) -> None:
        d = self.data
        mid = int(self.model.body_mocapid[self.model.body(name).id])
        for _ in range(self.config.max_placement_tries):
            point, yaw = self._region_sample(rng, region)
            d.mocap_pos[mid] = point
            d.mocap_quat[mid] = yaw_quat(yaw)
            lo, hi = self._fixture_aabb(name)
            overlap = any(
                np.all(lo < h - 1e-3) and np.all(hi > lw + 1e-3) for _, lw, h in self._fixture_boxes
            )
            if not overlap and not self._collides(name, ignore_fixtures=True):
                self._fixture_boxes.append((name, lo, hi))
                return
        raise _PlacementFailure(f"could not place fixture {name!r} in region {region!r}")

    def _place_robot(self, rng: np.random.Generator, region: str | None) -> None:
        """Place the base in ``region``, or (``None``) anywhere in the default robot region at
        any yaw and at least the task's ``robot_clearance`` from every object on the ground."""
        d = self.data
        on_ground = [
            self._qpos_of(entity)[:2]
            for _, entity, where in self.task.initial_state
            if entity in self.task.objects and self.task.regions[where].target == GROUND
        ]
        clearance = self.task.robot_clearance
        for _ in range(self.config.max_placement_tries):
            if region is None:
                x0, y0, x1, y1 = self.config.default_robot_region
                x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
                yaw = float(rng.uniform(-math.pi, math.pi))
                if any(math.hypot(x - p[0], y - p[1]) < clearance for p in on_ground):
                    continue
            else:
                point, yaw = self._region_sample(rng, region)
                x, y = point[0], point[1]
            d.qpos[self._q_base] = (x, y, yaw)
            if not self._collides(ROBOT):
                return
        raise _PlacementFailure(f"could not place the robot in region {region or 'default'!r}")

    # -- rendering ------------------------------------------------------------------------------
    @property
    def camera_names(self) -> list[str]:
        """Every camera: the task's, then the robot's base and wrist cameras."""
        return list(self.scene.cameras)

    def _renderer(self) -> Any:
        key = (self.config.image_height, self.config.image_width)
        if key not in self._renderers:
            try:
                self._renderers[key] = mujoco.Renderer(self.model, *key)
            except Exception as e:  # the GL backend is chosen by MUJOCO_GL
                raise RuntimeError(
                    f"{self.env_name}: could not create a MuJoCo renderer with "
                    f"MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} ({e}); headless machines need "
                    f"MUJOCO_GL=egl (libEGL) or MUJOCO_GL=osmesa (libOSMesa) set before mujoco is "
                    f"imported"
                ) from e
            # The first frame of a fresh GL context can differ in a few pixels from later ones;
            # render one and discard it so that equal states always give equal frames.
            renderer = self._renderers[key]
            mujoco.mj_kinematics(self.model, self.data)
            mujoco.mj_camlight(self.model, self.data)
            renderer.update_scene(self.data, camera="task_view", scene_option=self._scene_option)
            renderer.render()
        return self._renderers[key]

    def _render_camera(self, state: ObjectCentricState, camera: str) -> NDArray[np.uint8]:
        self._load(state)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        renderer = self._renderer()
        renderer.update_scene(self.data, camera=camera, scene_option=self._scene_option)
        frame: NDArray[np.uint8] = renderer.render().copy()
        return frame

    def _render_state(self, state: ObjectCentricState) -> NDArray[np.uint8]:
        return self._render_camera(state, "task_view")

    def render_cameras(
        self, state: ObjectCentricState | None = None
    ) -> dict[str, NDArray[np.uint8]]:
        """A frame from every camera (task cameras, ``robot_base``, ``robot_wrist``) of ``state``
        (default: the live state), keyed by camera name."""
        if state is None:
            state = self.get_state()
        return {name: self._render_camera(state, name) for name in self.scene.cameras}

    def close(self) -> None:
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
        super().close()

    def feature_bounds(self) -> dict[str, tuple[float, float]]:
        """Generous finite bounds (the world is a few metres across; quaternions are unit)."""
        big, pos = 1000.0, 100.0
        bounds = {f: (-pos, pos) for f in ("x", "y", "z", "pos_base_x", "pos_base_y")}
        bounds.update({f: (-1.0, 1.0) for f in ("qw", "qx", "qy", "qz")})
        bounds.update({f: (0.0, 10.0) for f in ("bb_x", "bb_y", "bb_z")})
        vel = ["vx", "vy", "vz", "wx", "wy", "wz", "hinge_vel", "vel_gripper",
               "vel_base_x", "vel_base_y", "vel_base_rot"]  # fmt: skip
        vel += [f"vel_arm_joint{i}" for i in range(1, 8)]
        bounds.update({f: (-big, big) for f in vel})
        bounds.update({f"pos_arm_joint{i}": (-big, big) for i in range(1, 8)})
        bounds.update({"pos_base_rot": (-big, big), "pos_gripper": (-0.5, 1.5)})
        bounds.update({"pos": (-1.0, 2.0), "hinge_pos": (-math.pi, math.pi)})
        return bounds

    # -- helpers for users and tests ------------------------------------------------------------
    def goal_atoms(self, state: ObjectCentricState) -> dict[str, bool]:
        """The truth of every atom of the goal in ``state``."""
        return self.goal.atoms(state)

    def base_yaw(self, state: ObjectCentricState, name: str) -> float:
        """The heading of an object or fixture (rad)."""
        obj = self.objects[name]
        return quat_yaw(np.array([state.get(obj, f) for f in ("qw", "qx", "qy", "qz")]))


def _goal_text(goal: Any) -> str:
    if goal[0] in ("and", "or"):
        inner = f" {goal[0]} ".join(_goal_text(g) for g in goal[1])
        return f"({inner})" if len(goal[1]) > 1 else inner
    if goal[0] == "balanced":
        return f"balanced({goal[1]}, {goal[2]:g}°)"
    return f"{goal[0]}({goal[1]}, {goal[2]})"
