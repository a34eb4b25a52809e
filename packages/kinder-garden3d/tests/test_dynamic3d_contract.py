"""Every Dynamic3D id is registered and passes the kinder-core test kit; importing stays light.

The default run checks one id per family; ``-m slow`` runs every check on every id.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core.testing import CHECKS, check_cross_process_determinism, check_kinder_env
from kinder_garden3d.dynamic3d.env import Dynamic3DEnv
from kinder_garden3d.dynamic3d.taskfile import resolve_task_path

#: The MuJoCo Dynamic3D ids (LimbRepositioning3D, pybullet, has its own test file).
DYNAMIC3D_IDS = [i for i in kinder_core.list_envs("Dynamic3D") if "LimbRepositioning3D" not in i]

_REARRANGE = [
    "o1-put_the_boxed_drink_behind_the_bowl",
    "o1-put_the_boxed_drink_in_front_of_the_bowl",
    "o1-put_the_boxed_drink_next_to_the_bowl",
    "o1-put_the_boxed_drink_on_the_left_side_of_the_bowl",
    "o1-put_the_boxed_drink_on_the_right_side_of_the_bowl",
    "o2-put_the_boxed_drink_and_the_can_next_to_the_bowl",
    "o2-put_the_boxed_drink_in_front_of_and_the_can_behind_the_bowl",
    "o2-put_the_boxed_drink_on_the_left_and_the_can_on_the_right_side_of_the_bowl",
    "o2-put_the_can_in_front_of_and_the_boxed_drink_behind_the_bowl",
    "o2-put_the_can_on_the_left_and_the_boxed_drink_on_the_right_side_of_the_bowl",
]
_SORT = [
    "o4-sort_the_cluttered_blocks_into_bins",
    "o20-sort_the_cluttered_blocks_into_bins",
    "o20-sort_the_cluttered_blocks_into_bowls",
    "o12-sort_the_blocks_into_the_cupboard",
]
_SWEEP = [
    *(f"o{n}-sweep_the_blocks_to_the_left_side_of_the_kitchen_island" for n in (1, 5, 10, 50)),
    "o50-sweep_the_blocks_to_the_right_side_of_the_kitchen_island",
    "o50-sweep_the_blocks_to_the_right_side_of_the_kitchen_counter",
]
EXPECTED_IDS = [
    *(f"kinder/Shelf3D-o{n}-v0" for n in (1, 2, 3, 4, 6, 8)),
    *(f"kinder/ConstrainedCupboard3D-o{n}-v0" for n in range(1, 7)),
    *(f"kinder/Rearrange3D-{v}-v0" for v in _REARRANGE),
    *(f"kinder/SortClutteredBlocks3D-{v}-v0" for v in _SORT),
    *(f"kinder/SweepSimple3D-{v}-v0" for v in _SWEEP),
    "kinder/SweepIntoDrawer3D-o5-v0",
    *(f"kinder/ScoopPour3D-o{n}-v0" for n in (10, 20, 30, 40, 50, 100)),
    "kinder/BalanceBeam3D-o3-v0",
    "kinder/Tossing3D-o1-v0",
    "kinder/Tossing3D-o2-v0",
    *(f"kinder/Dynamo3D-o{n}-v0" for n in (1, 3, 12)),
    "kinder/FrankaPickPlace3D-o1-v0",
    "kinder/PickPlace3D-o1-v0",
]

#: One id per family for the default run (every id under ``-m slow``).
DEFAULT_IDS = [
    "kinder/Shelf3D-o1-v0",
    "kinder/ConstrainedCupboard3D-o1-v0",
    "kinder/Rearrange3D-o1-put_the_boxed_drink_behind_the_bowl-v0",
    "kinder/SortClutteredBlocks3D-o4-sort_the_cluttered_blocks_into_bins-v0",
    "kinder/SweepSimple3D-o1-sweep_the_blocks_to_the_left_side_of_the_kitchen_island-v0",
    "kinder/SweepIntoDrawer3D-o5-v0",
    "kinder/ScoopPour3D-o10-v0",
    "kinder/BalanceBeam3D-o3-v0",
    "kinder/Tossing3D-o1-v0",
    "kinder/Dynamo3D-o1-v0",
    "kinder/FrankaPickPlace3D-o1-v0",
    "kinder/PickPlace3D-o1-v0",
]


def test_all_ids_are_registered():
    assert sorted(DYNAMIC3D_IDS) == sorted(EXPECTED_IDS)
    families = {i.split("/")[1].split("-")[0] for i in DEFAULT_IDS}
    assert families == set(kinder_core.families("Dynamic3D")) - {"LimbRepositioning3D"}


@pytest.mark.parametrize("env_id", DEFAULT_IDS)
def test_kinder_test_kit_one_id_per_family(env_id):
    check_kinder_env(env_id)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", EXPECTED_IDS)
@pytest.mark.parametrize("check", list(CHECKS))
def test_kinder_test_kit_every_id(env_id, check):
    CHECKS[check](env_id)


def test_cross_process_determinism():
    check_cross_process_determinism("kinder/Shelf3D-o2-v0")


@pytest.mark.slow
@pytest.mark.parametrize("env_id", DEFAULT_IDS)
def test_cross_process_determinism_per_family(env_id):
    check_cross_process_determinism(env_id)


def test_box_view_matches_the_spec_example():
    """Shelf3D-o1: cube1 (16) + cupboard_1 (7) + robot (22) = 45, sorted by name."""
    env = kinder_core.make("kinder/Shelf3D-o1-v0")
    try:
        box = env.get_wrapper_attr("box")
        assert box.shape == (45,)
        names = box.feature_names
        assert (
            names[0] == "cube1.x"
            and names[16] == "cupboard_1.x"
            and names[23] == "robot.pos_base_x"
        )
        assert names[3:7] == ["cube1.qw", "cube1.qx", "cube1.qy", "cube1.qz"]
        assert env.action_space.shape == (11,)
        assert env.spec is not None and env.spec.max_episode_steps == 1000
    finally:
        env.close()


def test_tossing_is_11d_and_velocity_targets_give_18d(tmp_path):
    env = kinder_core.make_object_centric("kinder/Tossing3D-o1-v0")
    try:
        assert env.action_space.shape == (11,)  # as upstream kindergarden 0.2.5
        assert env.objects["cuboid_barrier"].type.name == "Dynamic3DMovable"
        path = resolve_task_path(env.task.file)[0]
    finally:
        env.close()
    task = json.loads(path.read_text())
    task["arm_velocity_targets"] = True
    custom = tmp_path / "Tossing3D-velocities.json"
    custom.write_text(json.dumps(task))
    env = Dynamic3DEnv(str(custom), num_objects=1)
    try:
        assert env.action_space.shape == (18,)
        assert np.all(env.action_space.low[11:] == -10.0)
        assert np.all(env.action_space.high[11:] == 10.0)
    finally:
        env.close()


def test_importing_the_package_imports_no_simulator():
    code = (
        "import os, sys; import kinder_garden3d, kinder_core; "
        "ids = kinder_core.list_envs('Dynamic3D'); "
        "assert len([i for i in ids if 'LimbRepositioning3D' not in i]) == 47; "
        "assert 'mujoco' not in sys.modules, 'mujoco imported'; "
        "assert 'MUJOCO_GL' not in os.environ, 'MUJOCO_GL set'"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)


def test_render_cameras_include_the_robot_cameras():
    env = kinder_core.make_object_centric("kinder/Shelf3D-o1-v0")
    try:
        env.reset(seed=0)
        frames = env.render_cameras()  # type: ignore[attr-defined]
        assert {"task_view", "robot_base", "robot_wrist"} <= set(frames)
        for name, frame in frames.items():
            assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8, name
            assert frame.std() > 0, f"{name} is blank"
    finally:
        env.close()
