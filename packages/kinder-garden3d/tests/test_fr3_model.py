"""The FR3 arm model: its chain is Franka's published kinematics, its MJCF agrees with the
pure-numpy forward kinematics, its servos hold and its gripper closes, and mink IK reaches the
poses a desk-mounted pick-and-place needs."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from kinder_garden3d.robot.description import (
    FINGER_STATE_MAX,
    finger_joint_positions,
    forward_kinematics,
    matrix_to_quat_xyzw,
)
from kinder_garden3d.robot.fr3 import (
    FR3_HOME,
    FR3_JOINT_LIMITS,
    fr3_description,
    fr3_mjcf,
)
from kinder_garden3d.robot.ik import InverseKinematics

DESC = fr3_description()
LOW = np.array([lo for lo, _ in FR3_JOINT_LIMITS])
HIGH = np.array([hi for _, hi in FR3_JOINT_LIMITS])

#: Franka's modified Denavit-Hartenberg table for the FR3 (a_{i-1}, d_i, alpha_{i-1}), and the
#: flange offset along link 7's z axis.
DH = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.316, math.pi / 2),
    (0.0825, 0.0, math.pi / 2),
    (-0.0825, 0.384, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.088, 0.0, math.pi / 2),
)
FLANGE_D = 0.107


def _dh_frames(base: tuple[float, float, float], q: np.ndarray, base_z: float) -> list[np.ndarray]:
    """World frames of links 1-7 and the flange from the DH table (independent of the model)."""

    def rot_x(a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])

    def rot_z(a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    def trans(x: float, y: float, z: float) -> np.ndarray:
        t = np.eye(4)
        t[:3, 3] = (x, y, z)
        return t

    t = trans(base[0], base[1], base_z) @ rot_z(base[2])
    frames = []
    for (a, d, alpha), qi in zip(DH, q, strict=True):
        t = t @ rot_x(alpha) @ trans(a, 0.0, 0.0) @ rot_z(float(qi)) @ trans(0.0, 0.0, d)
        frames.append(t)
    frames.append(t @ trans(0.0, 0.0, FLANGE_D))
    return frames


def test_chain_is_frankas_published_kinematics():
    rng = np.random.default_rng(1000)
    for _ in range(50):
        q = rng.uniform(LOW, HIGH)
        base = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-3, 3)))
        ours = forward_kinematics(base, q, base_z=0.75, desc=DESC)
        reference = _dh_frames(base, q, 0.75)
        names = [f"fr3_link{i}" for i in range(1, 8)] + ["flange"]
        for name, ref in zip(names, reference, strict=True):
            assert np.abs(ours[name] - ref).max() < 1e-12, name


def test_limits_home_and_description():
    low, high = DESC.arm_joint_limits
    assert np.array_equal(low, LOW) and np.array_equal(high, HIGH)
    assert DESC.retract == FR3_HOME
    assert np.all(np.array(FR3_HOME) >= LOW) and np.all(np.array(FR3_HOME) <= HIGH)
    # The home pose points the gripper straight down, in front of the mount.
    ee = forward_kinematics((0.0, 0.0, 0.0), FR3_HOME, desc=DESC)["pinch_site"]
    assert ee[2, 2] < -0.999
    assert 0.5 < ee[0, 3] < 0.6 and abs(ee[1, 3]) < 1e-6 and 0.45 < ee[2, 3] < 0.55
    with pytest.raises(ValueError, match="Expected 7 arm joints"):
        forward_kinematics((0.0, 0.0, 0.0), (0.0,), desc=DESC)


def test_mjcf_agrees_with_forward_kinematics():
    model = mujoco.MjModel.from_xml_string(fr3_mjcf(prefix="fr3_"))
    data = mujoco.MjData(model)
    assert model.nq == 9 and model.nu == 8  # 7 arm hinges + 2 pads; 7 servos + gripper
    qadr = {
        n: model.jnt_qposadr[model.joint("fr3_" + n).id]
        for n in (*DESC.arm_joint_names, *DESC.finger_joint_names)
    }
    rng = np.random.default_rng(1001)
    for _ in range(30):
        q = rng.uniform(LOW, HIGH)
        s = float(rng.uniform(0.0, FINGER_STATE_MAX))
        for name, value in zip(DESC.arm_joint_names, q, strict=True):
            data.qpos[qadr[name]] = value
        for name, value in zip(DESC.finger_joint_names, finger_joint_positions(s), strict=True):
            data.qpos[qadr[name]] = value
        mujoco.mj_kinematics(model, data)
        ours = forward_kinematics((0.0, 0.0, 0.0), q, finger_state=s, desc=DESC)
        for link in DESC.links:
            body = model.body("fr3_" + link.name).id
            assert np.abs(data.xpos[body] - ours[link.name][:3, 3]).max() < 1e-9, link.name
            xmat = data.xmat[body].reshape(3, 3)
            assert np.abs(xmat - ours[link.name][:3, :3]).max() < 1e-9, link.name
        for frame in DESC.frames:
            site = model.site("fr3_" + frame.name).id
            assert np.abs(data.site_xpos[site] - ours[frame.name][:3, 3]).max() < 1e-9


def test_servos_hold_home_under_gravity_and_the_gripper_closes():
    model = mujoco.MjModel.from_xml_string(fr3_mjcf())
    data = mujoco.MjData(model)
    arm = [model.jnt_qposadr[model.joint(n).id] for n in DESC.arm_joint_names]
    data.qpos[arm] = FR3_HOME
    data.ctrl[[model.actuator(f"arm_{i}").id for i in range(1, 8)]] = FR3_HOME
    data.ctrl[model.actuator("fingers_actuator").id] = 255.0
    mujoco.mj_step(model, data, nstep=1000)  # 2 s
    assert np.abs(data.qpos[arm] - np.array(FR3_HOME)).max() < 0.01
    left = data.qpos[model.jnt_qposadr[model.joint("left_finger_joint").id]]
    right = data.qpos[model.jnt_qposadr[model.joint("right_finger_joint").id]]
    assert left == pytest.approx(0.0425, abs=2e-3) and right == pytest.approx(left, abs=1e-3)
    # Servo targets outside the joint range are clipped to it (ctrlrange = joint range).
    assert model.actuator("arm_4").ctrlrange.tolist() == [-3.0421, -0.1518]
    assert model.actuator("arm_1").forcerange.tolist() == [-87.0, 87.0]
    assert model.actuator("arm_7").forcerange.tolist() == [-12.0, 12.0]
    # Upstream's joint dynamics (Menagerie's franka_fr3).
    dofs = [model.jnt_dofadr[model.joint(n).id] for n in DESC.arm_joint_names]
    assert model.dof_damping[dofs].tolist() == [0.21] * 7
    assert model.dof_armature[dofs].tolist() == [0.195] * 4 + [0.074] * 3
    assert model.dof_frictionloss[dofs].tolist() == [1.137] * 4 + [0.763, 0.44, 0.248]


def test_ik_round_trips_random_reachable_poses():
    ik = InverseKinematics(desc=DESC)
    rng = np.random.default_rng(1002)
    for _ in range(15):
        arm = rng.uniform(LOW + 0.1 * (HIGH - LOW), HIGH - 0.1 * (HIGH - LOW))
        base = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-3, 3)))
        target = forward_kinematics(base, arm, base_z=0.75, desc=DESC)["pinch_site"]
        # 0.2 mm: the posture regulariser leaves one of these poses at 0.13 mm after 300 steps.
        result = ik.solve(
            target[:3, 3],
            matrix_to_quat_xyzw(target[:3, :3]),
            base_pose=base,
            base_z=0.75,
            position_tolerance=2e-4,
        )
        assert result.success, (result.position_error, result.orientation_error)
        reached = forward_kinematics(base, result.arm_joints, base_z=0.75, desc=DESC)
        assert np.abs(reached["pinch_site"][:3, 3] - target[:3, 3]).max() < 2e-4
        assert np.abs(reached["pinch_site"][:3, :3] - target[:3, :3]).max() < 2e-3
        assert np.all(result.arm_joints >= LOW - 1e-9) and np.all(result.arm_joints <= HIGH + 1e-9)


def test_ik_reaches_top_down_grasps_over_the_desk_regions():
    """Upstream's FrankaPickPlace3D-o1 layout: the mount at (0.15, 0) on a 0.75 m desk centred at
    (0.5, 0); the cube region spans x 0.55-0.75, y -0.15-0 and the goal region x 0.45-0.65,
    y 0.12-0.27 (world frame). A top-down grasp of a 5 cm cube and a lift 0.15 m above it must be
    reachable everywhere in both regions, from the home pose."""
    ik = InverseKinematics(desc=DESC)
    down = (1.0, 0.0, 0.0, 0.0)  # x, y, z, w: approach axis pointing down
    base = (0.15, 0.0, 0.0)
    for xs, ys in (((0.55, 0.65, 0.75), (-0.15, -0.075, 0.0)), ((0.45, 0.55, 0.65), (0.12, 0.27))):
        for x in xs:
            for y in ys:
                for z in (0.775, 0.925):
                    result = ik.solve((x, y, z), down, base_pose=base, base_z=0.75)
                    assert result.success, ((x, y, z), result.position_error)
                    # The gripper stays above the desk top.
                    frames = forward_kinematics(base, result.arm_joints, base_z=0.75, desc=DESC)
                    assert frames["flange"][2, 3] > 0.75 + 0.1
