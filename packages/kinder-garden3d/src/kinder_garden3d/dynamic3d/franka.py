"""The Dynamic3D environment of the desk-mounted Franka FR3 arm (task files with
``"robot": {"model": "fr3", ...}``)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import mujoco
import numpy as np
from gymnasium import spaces

from kinder_core import Object, ObjectCentricStateSpace
from kinder_core.state import FloatArray, StateLayout
from kinder_garden3d.dynamic3d.env import (
    _FINGER_TRAVEL,
    Dynamic3DConfig,
    Dynamic3DEnv,
    _PlacementFailure,
)
from kinder_garden3d.dynamic3d.geometry import Array, quat_yaw, yaw_quat
from kinder_garden3d.dynamic3d.object_types import ALL_TYPES, FR3_ROBOT_TYPE
from kinder_garden3d.dynamic3d.scene import ROBOT_PREFIX
from kinder_garden3d.dynamic3d.taskfile import ROBOT
from kinder_garden3d.robot.description import RobotDescription
from kinder_garden3d.robot.fr3 import FR3_HOME, fr3_description

#: Contact settings of upstream kindergarden 0.2.5's FR3 scenes (MuJoCo's defaults: its FR3
#: model sets neither, unlike its TidyBot model).
FRANKA_CONFIG_DEFAULTS: dict[str, Any] = {"cone": "pyramidal", "impratio": 1.0}
_MOUNT_BODY = ROBOT_PREFIX + "fr3_link0"


class Franka3DEnv(Dynamic3DEnv):
    """A desk-mounted Franka FR3 arm in a MuJoCo scene described by a task file.

    ## Description
    The Dynamic3D tasks of upstream kindergarden 0.2.5's fixed-base arm (FrankaPickPlace3D)
    run in this class: the same task files, scene assembly, placement, goals, rendering and
    state handling as every Dynamic3D task (`Dynamic3DEnv`), with a different robot: a Franka
    Research 3 7-DoF arm (joint position servos, upstream's gains) with a Robotiq 2F-85-style
    two-finger gripper, bolted on the task's `robot.mount_surface` table. The arm's kinematics
    are Franka's published values and its shapes are primitives (`robot/fr3.py`). Physics:
    MuJoCo 3.3, 0.5 ms steps, 200 steps per action (0.1 s, 10 Hz control), MuJoCo's default
    pyramidal friction cone and `impratio = 1` (as upstream's FR3 scenes), `multiccd` as every
    Dynamic3D task.

    ## Observation Space
    All objects sorted by name, each with its type's features. Movable objects (16):
    `x, y, z, qw, qx, qy, qz, vx, vy, vz, wx, wy, wz, bb_x, bb_y, bb_z`; fixtures (7):
    `x, y, z, qw, qx, qy, qz`. The robot (19): `pos_base_x, pos_base_y, pos_base_rot` (the
    mount's pose, fixed during an episode), `pos_arm_joint1..7, pos_gripper,
    vel_arm_joint1..7, vel_gripper` (gripper: finger closure in [0, 1], 0 = open). Quaternions
    are ordered (w, x, y, z). Object names, order and sizes match upstream kindergarden 0.2.5.
    The full MuJoCo state travels with each state as `sim_state`, so `set_state(s); step(a)`
    reproduces a step exactly.

    ## Action Space
    An 8-D float32 Box: Δarm joints 1–7 in ±0.1 rad and a gripper command in [0, 1] (0 = open,
    1 = closed), as upstream. The arm's position servos get the current joint positions plus
    the deltas (clipped to the joint range by the servos' control range; kp = 4500, 4500, 3500,
    3500, 2000, 2000, 2000, kv = kp / 10, torques limited to 87 / 12 N m; no gravity
    compensation, as upstream); the gripper servo gets `command × 255`.

    ## Reward
    −1 on every step.

    ## Starting State
    Fixtures, the robot's mount and objects are placed by the task's initial-state predicates
    as in every Dynamic3D task; the mount sits at the top height of its table (the table's
    nominal `height`, as upstream's `mount_height`). The arm starts in upstream's home pose
    (0, 0, 0, −1.57079, 0, 1.57079, −0.7853) rad with the gripper open; ten all-zero actions
    then let the scene settle (the arm sags a little under gravity, as upstream's).

    ## Episode End
    Terminates when the task's goal predicates hold (`on`: the object's centre lies in the
    region's box in the region's frame). Each task file sets `max_episode_steps` (1000 unless
    stated).

    ## Arguments
    `task`: a bundled task (`"FrankaPickPlace3D/FrankaPickPlace3D-o1.json"`) or a path to any
    task file whose robot is `fr3`. `num_objects`: the task's count (tasks with a `count`
    section). `config`: a `Dynamic3DConfig` (or a dict of its fields; unset fields take
    `FRANKA_CONFIG_DEFAULTS`, then the dataclass defaults). `render_mode`: `"rgb_array"` or None.

    ## Deviations
    * The arm is built from capsules and cylinders around Franka's published kinematic chain
      (link frames agree with upstream's `fr3.xml` to 1e-15), not from Franka's meshes; joint
      damping, armature and friction loss are upstream's.
    * The gripper is the project's 2F-85 stand-in (two prismatic pads, 85 mm stroke, a pad
      servo force-limited to 235 N), not the four-bar linkage with a ±5 N tendon actuator.
      `pos_gripper`/`vel_gripper` are the measured finger closure and its rate (upstream
      reports the command `ctrl / 255` and the driver joint's rate).
    * The lab backdrop ("lab2") is a plain floor; the desk is a box top on four box legs.
    * `Dynamic3DConfig(arm_control="held_torque")` is for the mobile manipulator's torque
      motors only and is rejected here.

    ## References
    KinDER (RSS 2026); upstream kindergarden 0.2.5 (`Franka3DEnv`); Franka Research 3
    datasheet; MuJoCo.

    ## Version History
    * v0: initial release.
    """

    robot_model: ClassVar[str] = "fr3"

    def __init__(
        self,
        task: str = "FrankaPickPlace3D/FrankaPickPlace3D-o1.json",
        num_objects: int | None = None,
        config: Dynamic3DConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = "rgb_array",
    ) -> None:
        if config is None:
            config = Dynamic3DConfig(**FRANKA_CONFIG_DEFAULTS)
        elif isinstance(config, Mapping):
            try:
                config = Dynamic3DConfig(**{**FRANKA_CONFIG_DEFAULTS, **config})
            except TypeError as e:
                raise ValueError(f"Franka3DEnv: bad config {config!r}: {e}") from None
        if config.arm_control != "pd":
            raise ValueError(
                f"Franka3DEnv: arm_control must be 'pd' (the FR3's joint position servos), got "
                f"{config.arm_control!r}"
            )
        super().__init__(task, num_objects, config, render_mode)
        if not any(entity == ROBOT for _, entity, _ in self.task.initial_state):
            raise ValueError(
                f"{self.task.file}: the fr3 arm needs an initial-state predicate placing 'robot' "
                f"(its mount region)"
            )
        if self.task.arm_velocity_targets:
            raise ValueError(
                f"{self.task.file}: arm_velocity_targets is for the mobile manipulator's torque "
                f"motors; the fr3 arm takes joint deltas only"
            )
        self.observation_space = ObjectCentricStateSpace((*ALL_TYPES, FR3_ROBOT_TYPE))

    # -- setup ----------------------------------------------------------------------------------
    def _robot_description(self) -> RobotDescription:
        return fr3_description()

    def _setup_objects(self) -> None:
        super()._setup_objects()
        self.objects[ROBOT] = Object(ROBOT, FR3_ROBOT_TYPE)
        self._layout = StateLayout.of(self.objects.values())

    def _setup_robot_indices(
        self,
        add: Callable[[Object, str, int, float], None],
        jq: Callable[[str], int],
        jv: Callable[[str], int],
    ) -> None:
        """Arm and gripper as the mobile manipulator's; the mount's x, y from its mocap
        position (its yaw is converted in :meth:`_features` / :meth:`_write_features`)."""
        m = self.model
        nq = m.nq
        desc = fr3_description()
        robot = self.objects[ROBOT]
        self._mount = int(m.body_mocapid[m.body(_MOUNT_BODY).id])
        self._mount_height = float(
            self.scene.fixtures[str(self.task.robot_mount)].frames["top"][2, 3]
        )
        off_mp = nq + m.nv
        add(robot, "pos_base_x", off_mp + 3 * self._mount, 1.0)
        add(robot, "pos_base_y", off_mp + 3 * self._mount + 1, 1.0)
        self._rot_index = self._layout.index(robot, "pos_base_rot")
        arm_names = [ROBOT_PREFIX + n for n in desc.arm_joint_names]
        left, right = (ROBOT_PREFIX + n for n in desc.finger_joint_names)
        for i, jn in enumerate(arm_names):
            add(robot, f"pos_arm_joint{i + 1}", jq(jn), 1.0)
            add(robot, f"vel_arm_joint{i + 1}", nq + jv(jn), 1.0)
        add(robot, "pos_gripper", jq(left), 1.0 / _FINGER_TRAVEL)
        add(robot, "vel_gripper", nq + jv(left), 1.0 / _FINGER_TRAVEL)
        self._q_base = np.zeros(0, dtype=np.intp)
        self._q_arm = np.array([jq(n) for n in arm_names])
        self._q_fingers = np.array([jq(left), jq(right)])
        self._v_fingers = np.array([jv(left), jv(right)])

    def _setup_actions(self) -> None:
        cfg, m = self.config, self.model
        self._act_base = np.zeros(0, dtype=np.intp)
        self._act_arm = np.array([m.actuator(f"{ROBOT_PREFIX}arm_{i}").id for i in range(1, 8)])
        self._act_grip = m.actuator(f"{ROBOT_PREFIX}fingers_actuator").id
        low = [-cfg.max_arm_delta] * 7 + [0.0]
        high = [cfg.max_arm_delta] * 7 + [1.0]
        self.action_space = spaces.Box(
            np.array(low, dtype=np.float32), np.array(high, dtype=np.float32), dtype=np.float32
        )
        self._zero_action = np.zeros(len(low))

    # -- state <-> simulator --------------------------------------------------------------------
    def _features(self) -> FloatArray:
        data = super()._features()
        data[self._rot_index] = quat_yaw(self.data.mocap_quat[self._mount])
        return data

    def _write_features(self, data: FloatArray) -> None:
        super()._write_features(data)
        self.data.mocap_pos[self._mount, 2] = self._mount_height
        self.data.mocap_quat[self._mount] = yaw_quat(float(data[self._rot_index]))

    # -- dynamics -------------------------------------------------------------------------------
    def _apply(self, action: FloatArray) -> None:
        d = self.data
        d.ctrl[self._act_arm] = d.qpos[self._q_arm] + action[0:7]
        d.ctrl[self._act_grip] = action[7] * 255.0

    # -- reset ----------------------------------------------------------------------------------
    def _place_all(self, rng: np.random.Generator) -> None:
        m, d = self.model, self.data
        self._cache = None  # MjData no longer holds any state handed out
        mujoco.mj_resetData(m, d)
        d.qpos[self._q_arm] = FR3_HOME
        d.mocap_pos[self._mount] = (-80.0, -80.0, self._mount_height)  # parked until placed
        d.mocap_quat[self._mount] = yaw_quat(0.0)
        self._fixture_boxes: list[tuple[str, Array, Array]] = []
        for name, spec in self.task.fixtures.items():
            if spec.pos is not None:
                self._fixture_boxes.append((name, *self._fixture_aabb(name)))
        for _, entity, region in self.task.initial_state:
            if entity == ROBOT:
                self._place_robot(rng, region)
            elif entity in self.task.fixtures:
                self._place_fixture(rng, entity, region)
            else:
                self._place_object(rng, entity, region)
        d.ctrl[self._act_arm] = d.qpos[self._q_arm]

    def _place_robot(self, rng: np.random.Generator, region: str | None) -> None:
        """Place the mount in ``region`` at the mount height (its table may overlap it, as
        upstream's, so only collisions with objects count)."""
        if region is None:
            raise _PlacementFailure("the fr3 arm's mount needs a region")
        d = self.data
        for _ in range(self.config.max_placement_tries):
            point, yaw = self._region_sample(rng, region)
            d.mocap_pos[self._mount] = (point[0], point[1], self._mount_height)
            d.mocap_quat[self._mount] = yaw_quat(yaw)
            if not self._collides(ROBOT, ignore_fixtures=True):
                return
        raise _PlacementFailure(f"could not place the robot in region {region!r}")
