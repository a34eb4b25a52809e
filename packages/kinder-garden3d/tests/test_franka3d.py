"""FrankaPickPlace3D: the desk-mounted FR3 arm's Dynamic3D env (``dynamic3d/franka.py``).

The contract kit runs in ``test_dynamic3d_contract.py``; here: the reset layout of upstream's
task file, the mount pose as features, a scripted IK pick-and-place that reaches the goal, and
the task-file checks of the robot section.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core import ObjectCentricState
from kinder_garden3d.dynamic3d.env import Dynamic3DEnv
from kinder_garden3d.dynamic3d.franka import Franka3DEnv
from kinder_garden3d.dynamic3d.taskfile import TaskFileError, load_task, resolve_task_path
from kinder_garden3d.robot.fr3 import FR3_HOME, fr3_description
from kinder_garden3d.robot.ik import InverseKinematics

ENV_ID = "kinder/FrankaPickPlace3D-o1-v0"
TASK = "FrankaPickPlace3D/FrankaPickPlace3D-o1.json"
DOWN = (1.0, 0.0, 0.0, 0.0)  # (x, y, z, w): the gripper's approach axis points down


@pytest.fixture(scope="module")
def env() -> Any:
    env = kinder_core.make_object_centric(ENV_ID)
    yield env
    env.close()


def _arm(env: Any, state: ObjectCentricState) -> np.ndarray:
    robot = env.objects["robot"]
    return np.array([state.get(robot, f"pos_arm_joint{i}") for i in range(1, 8)])


def test_reset_follows_upstreams_task_file(env: Any) -> None:
    robot, cube, desk = env.objects["robot"], env.objects["cube1"], env.objects["desk_1"]
    assert isinstance(env, Franka3DEnv) and env.action_space.shape == (8,)
    for seed in range(1000, 1010):
        state, info = env.reset(seed=seed)
        assert info["success"] is False
        # The desk at (0.5, 0) facing +x, lifted by [0, 0.1] m; the mount in its region.
        assert state.get(desk, "x") == 0.5 and state.get(desk, "y") == 0.0
        lift = state.get(desk, "z")
        assert 0.0 <= lift <= 0.1
        assert 0.13 <= state.get(robot, "pos_base_x") <= 0.17
        assert -0.02 <= state.get(robot, "pos_base_y") <= 0.02
        assert state.get(robot, "pos_base_rot") == 0.0
        # The 5 cm cube rests on the desk top in its region (desk frame x 0.05-0.25, y -0.15-0).
        assert state.get(cube, "bb_x") == pytest.approx(0.05)
        assert state.get(cube, "z") == pytest.approx(0.75 + lift + 0.025, abs=2e-3)
        assert 0.55 <= state.get(cube, "x") <= 0.75 and -0.15 <= state.get(cube, "y") <= 0.0
        # The arm settled near the home pose with the gripper open.
        assert np.abs(_arm(env, state) - np.array(FR3_HOME)).max() < 0.06
        assert state.get(robot, "pos_gripper") == pytest.approx(0.0, abs=1e-3)
    mount = env.data.mocap_pos[env._mount]
    assert mount[2] == 0.75  # upstream's mount height: the desk's nominal height


def test_the_mount_pose_is_restored_from_features(env: Any) -> None:
    state, _ = env.reset(seed=1000)
    robot = env.objects["robot"]
    moved = state.copy()
    moved.set(robot, "pos_base_x", 0.2)
    moved.set(robot, "pos_base_rot", 0.3)
    bare = ObjectCentricState(moved.layout, moved.data.copy())  # features only, no sim_state
    env.set_state(bare)
    after, _, _, _, _ = env.step(np.zeros(8, dtype=np.float32))
    assert after.get(robot, "pos_base_x") == pytest.approx(0.2)
    assert after.get(robot, "pos_base_rot") == pytest.approx(0.3)
    link1 = env.data.xpos[env.model.body("robot_fr3_link1").id]
    assert link1 == pytest.approx([0.2, state.get(robot, "pos_base_y"), 0.75 + 0.333])


@pytest.mark.parametrize("seed", [1000, 1001])
def test_a_scripted_ik_pick_and_place_reaches_the_goal(env: Any, seed: int) -> None:
    """Top-down grasp of the cube, lift, carry to the goal region's centre, release."""
    state, _ = env.reset(seed=seed)
    robot, cube, desk = env.objects["robot"], env.objects["cube1"], env.objects["desk_1"]
    base = tuple(state.get(robot, f) for f in ("pos_base_x", "pos_base_y", "pos_base_rot"))
    ik = InverseKinematics(desc=fr3_description())
    terminated = False

    def solve(point: tuple[float, float, float], q0: np.ndarray) -> np.ndarray:
        result = ik.solve(point, DOWN, base_pose=base, base_z=0.75, initial_arm_joints=q0)
        assert result.success, point
        return result.arm_joints

    def go(target: np.ndarray, grip: float, hold: int = 3) -> None:
        nonlocal state, terminated
        for _ in range(100):
            delta = np.clip(target - _arm(env, state), -0.1, 0.1)
            state, _, terminated, _, _ = env.step(np.array([*delta, grip], dtype=np.float32))
            if np.abs(target - _arm(env, state)).max() < 0.01:
                break
        for _ in range(hold):
            state, _, terminated, _, _ = env.step(np.array([0.0] * 7 + [grip], dtype=np.float32))

    x, y, z = (state.get(cube, f) for f in ("x", "y", "z"))
    goal_x = state.get(desk, "x") + 0.05  # the goal region: desk frame x -0.05-0.15
    goal_y = 0.195  # y 0.12-0.27
    above = solve((x, y, z + 0.15), _arm(env, state))
    go(above, 0.0)
    grasp = solve((x, y, z), above)
    go(grasp, 0.0)
    go(_arm(env, state), 1.0, hold=8)  # close on the cube
    lift = solve((x, y, z + 0.15), grasp)
    go(lift, 1.0)
    assert state.get(cube, "z") > z + 0.1  # the cube came up with the gripper
    assert not terminated
    over = solve((goal_x, goal_y, z + 0.15), lift)
    go(over, 1.0)
    go(solve((goal_x, goal_y, z + 0.01), over), 1.0)
    go(_arm(env, state), 0.0, hold=8)  # release
    assert terminated and env.goal_reached(state)
    go(over, 0.0)  # back up: the cube stays, resting on the desk
    assert env.goal_reached(state)
    assert state.get(cube, "z") == pytest.approx(z, abs=1e-3)


def _task_json() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(resolve_task_path(TASK)[0].read_text())
    return data


def _write(tmp_path: Path, data: dict[str, Any]) -> str:
    path = tmp_path / "FrankaPickPlace3D-custom.json"
    path.write_text(json.dumps(data))
    return str(path)


def test_the_robot_section_is_validated(tmp_path: Path) -> None:
    task = load_task(TASK)
    assert task.robot == "fr3" and task.robot_mount == "desk_1"
    bad_model = _task_json()
    bad_model["robot"]["model"] = "panda"
    with pytest.raises(TaskFileError, match=r"robot\.model: must be one of"):
        load_task(_write(tmp_path, bad_model))
    bad_mount = _task_json()
    bad_mount["robot"]["mount_surface"] = "cube1"
    with pytest.raises(TaskFileError, match="mounted on a table fixture; got 'cube1'"):
        load_task(_write(tmp_path, bad_mount))
    tidybot_mount = _task_json()
    tidybot_mount["robot"]["model"] = "tidybot"
    with pytest.raises(TaskFileError, match="only the fixed-base 'fr3' robot has a mount"):
        load_task(_write(tmp_path, tidybot_mount))


def test_each_env_class_rejects_the_other_robot(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="the task's robot is 'fr3' but Dynamic3DEnv"):
        Dynamic3DEnv(TASK)
    with pytest.raises(ValueError, match="the task's robot is 'tidybot' but Franka3DEnv"):
        Franka3DEnv("Shelf3D/Shelf3D.json", num_objects=1)
    with pytest.raises(ValueError, match="arm_control must be 'pd'"):
        Franka3DEnv(TASK, config={"arm_control": "held_torque"})
    unplaced = _task_json()
    unplaced["initial_state"] = [p for p in unplaced["initial_state"] if p[1] != "robot"]
    with pytest.raises(ValueError, match="needs an initial-state predicate placing 'robot'"):
        Franka3DEnv(_write(tmp_path, unplaced))
    velocities = _task_json()
    velocities["arm_velocity_targets"] = True
    with pytest.raises(ValueError, match="the fr3 arm takes joint deltas only"):
        Franka3DEnv(_write(tmp_path, velocities))


def test_config_defaults_are_upstreams_contact_settings() -> None:
    env = Franka3DEnv(TASK, config={"substeps": 50})
    try:
        assert env.config.cone == "pyramidal" and env.config.impratio == 1.0
        assert env.config.substeps == 50
        assert env.camera_names == ["task_view"]
        frame = env.render_cameras(env.reset(seed=1000)[0])["task_view"]
        assert frame.shape == (480, 640, 3) and frame.std() > 5.0
    finally:
        env.close()
