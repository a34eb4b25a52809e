"""The shared robot model: URDF and MJCF generated from one description agree, and IK works."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pybullet as pb
import pytest

from kinder_garden3d.robot.description import (
    FINGER_STATE_MAX,
    RETRACT,
    finger_joint_positions,
    forward_kinematics,
    gripper_opening,
    matrix_to_quat_xyzw,
    quat_xyzw_to_matrix,
    robot_description,
)
from kinder_garden3d.robot.ik import InverseKinematics
from kinder_garden3d.robot.mjcf import finger_ctrl, to_mjcf
from kinder_garden3d.robot.urdf import to_urdf, urdf_path

DESC = robot_description()


def _random_config(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    lo, hi = DESC.arm_joint_limits
    lo = np.where(np.isfinite(lo), lo, -math.pi)
    hi = np.where(np.isfinite(hi), hi, math.pi)
    base = rng.uniform([-3.0, -3.0, -math.pi], [3.0, 3.0, math.pi])
    return base, rng.uniform(lo, hi), float(rng.uniform(0.0, FINGER_STATE_MAX))


@pytest.fixture(scope="module")
def bullet():
    cid = pb.connect(pb.DIRECT)
    robot = pb.loadURDF(str(urdf_path()), useFixedBase=True, physicsClientId=cid)
    links, joints = {}, {}
    for i in range(pb.getNumJoints(robot, physicsClientId=cid)):
        info = pb.getJointInfo(robot, i, physicsClientId=cid)
        links[info[12].decode()] = i
        joints[info[1].decode()] = i
    yield cid, robot, links, joints
    pb.disconnect(physicsClientId=cid)


def test_fk_urdf_and_mjcf_agree_at_random_configurations(bullet):
    cid, robot, links, joints = bullet
    model = mujoco.MjModel.from_xml_string(to_mjcf())
    data = mujoco.MjData(model)
    qadr = {
        n: model.jnt_qposadr[model.joint(n).id]
        for n in (*DESC.base_joint_names, *DESC.arm_joint_names, *DESC.finger_joint_names)
    }
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(25):
        base, arm, fingers = _random_config(rng)
        reference = forward_kinematics(tuple(base), arm, fingers)
        values = dict(zip(DESC.base_joint_names, base, strict=True))
        values.update(zip(DESC.arm_joint_names, arm, strict=True))
        values.update(zip(DESC.finger_joint_names, finger_joint_positions(fingers), strict=True))
        for name, value in values.items():
            data.qpos[qadr[name]] = value
        mujoco.mj_kinematics(model, data)
        pb.resetBasePositionAndOrientation(
            robot,
            [base[0], base[1], 0.0],
            [0.0, 0.0, math.sin(base[2] / 2), math.cos(base[2] / 2)],
            physicsClientId=cid,
        )
        for name in (*DESC.arm_joint_names, *DESC.finger_joint_names):
            pb.resetJointState(robot, joints[name], values[name], physicsClientId=cid)
        for link in DESC.links:
            ref = reference[link.name]
            body = model.body(link.name).id
            mj_rot = data.xmat[body].reshape(3, 3)
            worst = max(worst, np.abs(data.xpos[body] - ref[:3, 3]).max())
            worst = max(worst, np.abs(mj_rot - ref[:3, :3]).max())
            if link.parent is None:
                pos, quat = pb.getBasePositionAndOrientation(robot, physicsClientId=cid)
            else:
                state = pb.getLinkState(
                    robot, links[link.name], computeForwardKinematics=True, physicsClientId=cid
                )
                pos, quat = state[4], state[5]
            # URDF (pybullet) against MJCF (MuJoCo) directly.
            worst = max(worst, np.abs(np.array(pos) - data.xpos[body]).max())
            worst = max(worst, np.abs(quat_xyzw_to_matrix(quat) - mj_rot).max())
        for frame in DESC.frames:
            site = model.site(frame.name).id
            worst = max(worst, np.abs(data.site_xpos[site] - reference[frame.name][:3, 3]).max())
    assert worst < 1e-6, f"FK disagreement {worst:.3g}"


def test_mjcf_exposes_the_dynamic3d_interface():
    model = mujoco.MjModel.from_xml_string(to_mjcf(prefix="robot_"))
    actuators = {model.actuator(i).name for i in range(model.nu)}
    assert {"robot_base_x", "robot_base_y", "robot_base_th", "robot_fingers_actuator"} <= actuators
    assert {f"robot_arm_{i}" for i in range(1, 8)} <= actuators
    assert model.actuator("robot_arm_1").ctrlrange.tolist() == [-200.0, 200.0]
    assert model.actuator("robot_arm_7").ctrlrange.tolist() == [-100.0, 100.0]
    for name in ("robot_pinch_site", "robot_flange", "robot_arm_base"):
        model.site(name)
    for name in ("robot_base", "robot_wrist"):
        model.camera(name)
    assert model.camera("robot_base").fovy[0] == pytest.approx(52.2)
    assert model.body("robot_base_link").mass[0] == pytest.approx(60.0)
    fixed = mujoco.MjModel.from_xml_string(to_mjcf(free_base=False))
    assert fixed.nq == 9 and fixed.nu == 8


def test_position_servo_variant_holds_the_retract_pose_under_gravity():
    model = mujoco.MjModel.from_xml_string(to_mjcf(free_base=False, arm_actuators="position"))
    data = mujoco.MjData(model)
    arm = [model.jnt_qposadr[model.joint(n).id] for n in DESC.arm_joint_names]
    data.qpos[arm] = RETRACT
    for i in range(7):
        data.ctrl[model.actuator(f"arm_{i + 1}").id] = RETRACT[i]
    mujoco.mj_step(model, data, nstep=2000)  # 1 s
    assert np.abs(data.qpos[arm] - np.array(RETRACT)).max() < 0.05
    with pytest.raises(ValueError, match="arm_actuators"):
        to_mjcf(arm_actuators="velocity")  # type: ignore[arg-type]


def test_torque_motors_with_pd_and_gravity_compensation_track_a_target():
    model = mujoco.MjModel.from_xml_string(to_mjcf(free_base=False))
    data = mujoco.MjData(model)
    arm_q = [model.jnt_qposadr[model.joint(n).id] for n in DESC.arm_joint_names]
    arm_v = [model.jnt_dofadr[model.joint(n).id] for n in DESC.arm_joint_names]
    acts = [model.actuator(f"arm_{i + 1}").id for i in range(7)]
    kp = np.array([200.0] * 4 + [100.0] * 3)
    kd = np.array([30.0] * 4 + [15.0] * 3)
    data.qpos[arm_q] = RETRACT
    target = np.array(RETRACT) + np.array([0.3, 0.2, 0.0, 0.3, 0.0, 0.2, 0.0])
    for _ in range(4000):  # 2 s at 0.5 ms
        q, qd = data.qpos[arm_q], data.qvel[arm_v]
        data.ctrl[acts] = kp * (target - q) - kd * qd + data.qfrc_bias[arm_v]
        mujoco.mj_step(model, data)
    assert np.abs(data.qpos[arm_q] - target).max() < 0.02


def test_base_camera_matches_tidybot_euler():
    model = mujoco.MjModel.from_xml_string(to_mjcf())
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ref_xml = (
        '<mujoco><worldbody><camera name="c" pos="0.2525 0 0.335" '
        'euler="0 -0.7853981633974483 -1.5707963267948966"/></worldbody></mujoco>'
    )
    ref_model = mujoco.MjModel.from_xml_string(ref_xml)
    ref = mujoco.MjData(ref_model)
    mujoco.mj_kinematics(ref_model, ref)
    cam = model.camera("base").id
    assert np.allclose(data.cam_xmat[cam], ref.cam_xmat[0], atol=1e-12)
    assert np.allclose(data.cam_xpos[cam], ref.cam_xpos[0], atol=1e-12)


def test_gripper_motors_and_finger_mapping():
    assert gripper_opening(0.0) == pytest.approx(0.085)
    assert gripper_opening(FINGER_STATE_MAX) == pytest.approx(0.0)
    assert finger_joint_positions(-1.0) == (0.0, 0.0)
    assert finger_ctrl(FINGER_STATE_MAX) == 255.0 and finger_ctrl(0.0) == 0.0
    # The finger servo in MuJoCo closes the pads when commanded 255.
    model = mujoco.MjModel.from_xml_string(to_mjcf(free_base=False))
    data = mujoco.MjData(model)
    model.opt.gravity[:] = 0.0
    data.ctrl[model.actuator("fingers_actuator").id] = 255.0
    mujoco.mj_step(model, data, nstep=4000)
    left = data.qpos[model.jnt_qposadr[model.joint("left_finger_joint").id]]
    right = data.qpos[model.jnt_qposadr[model.joint("right_finger_joint").id]]
    assert left == pytest.approx(0.0425, abs=2e-3) and right == pytest.approx(left, abs=1e-3)


def test_urdf_is_well_formed_and_matches_the_description():
    root = ET.fromstring(to_urdf())
    assert [link.get("name") for link in root.findall("link")] == [lk.name for lk in DESC.links]
    limits = {
        j.get("name"): j.find("limit") for j in root.findall("joint") if j.get("type") == "revolute"
    }
    assert float(limits["joint_2"].get("upper")) == pytest.approx(2.2497)
    assert urdf_path().read_text() == to_urdf()


def test_retract_pose_points_the_gripper_down():
    ee = forward_kinematics((0.0, 0.0, 0.0), RETRACT)["pinch_site"]
    assert ee[2, 2] < -0.95  # approach axis points down
    assert 0.2 < ee[0, 3] < 0.35 and 0.5 < ee[2, 3] < 0.7


@pytest.mark.parametrize("free_base", [False, True])
def test_ik_round_trips_random_reachable_poses(free_base):
    ik = InverseKinematics(free_base=free_base)
    rng = np.random.default_rng(3)
    lo, hi = DESC.arm_joint_limits
    lo = np.where(np.isfinite(lo), lo, -math.pi)
    hi = np.where(np.isfinite(hi), hi, math.pi)
    for _ in range(15):
        arm = rng.uniform(0.8 * lo, 0.8 * hi)
        base = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-3, 3)))
        target = forward_kinematics(base, arm, base_z=-0.4)["pinch_site"]
        quat = matrix_to_quat_xyzw(target[:3, :3])
        result = ik.solve(
            target[:3, 3], quat, base_pose=base if not free_base else (0.0, 0.0, 0.0), base_z=-0.4
        )
        assert result.success, (result.position_error, result.orientation_error)
        reached = forward_kinematics(result.base_pose, result.arm_joints, base_z=-0.4)
        assert np.abs(reached["pinch_site"][:3, 3] - target[:3, 3]).max() < 2e-4
        assert np.abs(reached["pinch_site"][:3, :3] - target[:3, :3]).max() < 2e-3
        low, high = DESC.arm_joint_limits
        assert np.all(result.arm_joints >= low - 1e-9) and np.all(result.arm_joints <= high + 1e-9)


def test_ik_reports_unreachable_targets():
    ik = InverseKinematics()
    result = ik.solve((5.0, 0.0, 0.5), (1.0, 0.0, 0.0, 0.0), restarts=1)
    assert not result.success and result.position_error > 1.0


def test_ik_rejects_bad_input():
    ik = InverseKinematics()
    with pytest.raises(ValueError, match="unit quaternion"):
        ik.solve((0.3, 0.0, 0.5), (1.0, 1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="shape"):
        ik.solve((0.3, 0.0), (1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="7 entries"):
        ik.solve((0.3, 0.0, 0.5), (1.0, 0.0, 0.0, 0.0), initial_arm_joints=(0.0,))


def test_description_lookups_name_the_valid_choices():
    with pytest.raises(ValueError, match="expected one of"):
        DESC.link("elbow")
    with pytest.raises(ValueError, match="Expected 7 arm joints"):
        forward_kinematics((0.0, 0.0, 0.0), (0.0,))
