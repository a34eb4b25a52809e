"""Every Kinematic3D id passes the kinder-core test kit; registration stays light."""

from __future__ import annotations

import subprocess
import sys

import gymnasium
import numpy as np
import pybullet as pb
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core.testing import (
    check_cross_process_determinism,
    check_kinder_env,
    check_vector_consistency,
)

KINEMATIC3D_IDS = kinder_core.list_envs("Kinematic3D")

EXPECTED_BOX_SIZES = {
    "kinder/BaseMotion3D-v0": 22,
    **{f"kinder/Obstruction3D-o{n}-v0": 43 + 12 * n for n in range(5)},
    **{f"kinder/Packing3D-p{n}-v0": 31 + 12 * n for n in (1, 2, 3)},
    **{f"kinder/Table3D-o{n}-v0": 31 + 12 * n for n in (1, 2, 3)},
    **{f"kinder/Transport3D-o{n}-v0": 43 + 12 * n for n in (1, 2)},
    **{f"kinder/KinematicShelf3D-o{n}-v0": 26 + 12 * n for n in (1, 2, 3, 5, 10)},
    **{f"kinder/KinematicCylinderShelf3D-o{n}-v0": 26 + 12 * n for n in (1, 2, 3)},
    **{f"kinder/PrplLab3D-o{n}-v0": 26 + 12 * n for n in (1, 2)},
}


def test_all_ids_are_registered():
    assert sorted(KINEMATIC3D_IDS) == sorted(EXPECTED_BOX_SIZES)


@pytest.mark.parametrize("env_id", KINEMATIC3D_IDS)
def test_kinder_test_kit(env_id):
    check_kinder_env(env_id)


@pytest.mark.parametrize("env_id", KINEMATIC3D_IDS)
def test_box_view_size_and_spaces(env_id):
    env = kinder_core.make(env_id)
    try:
        assert env.observation_space.shape == (EXPECTED_BOX_SIZES[env_id],)
        assert env.action_space.shape == (11,) and env.action_space.dtype == np.float32
        assert env.action_space.low[10] == -1.0 and env.action_space.high[10] == 1.0
        obs, _ = env.reset(seed=0)
        assert obs.shape == (EXPECTED_BOX_SIZES[env_id],) and obs.dtype == np.float64
        assert env.get_wrapper_attr("box").feature_names[:3] == [
            "robot.pos_base_x",
            "robot.pos_base_y",
            "robot.pos_base_rot",
        ]
    finally:
        env.close()


def test_action_magnitudes_follow_the_spec():
    mags = {
        "kinder/BaseMotion3D-v0": 0.4,
        "kinder/Table3D-o1-v0": 0.4,
        "kinder/Obstruction3D-o1-v0": 0.2,
        "kinder/Packing3D-p1-v0": 0.2,
        "kinder/Transport3D-o1-v0": 0.2,
        "kinder/KinematicShelf3D-o1-v0": 0.2,
        "kinder/KinematicCylinderShelf3D-o1-v0": 0.2,
        "kinder/PrplLab3D-o1-v0": 0.4,
    }
    for env_id, mag in mags.items():
        env = kinder_core.make_object_centric(env_id)
        assert np.allclose(env.action_space.high[:10], mag), env_id
        env.close()


@pytest.mark.parametrize("env_id", ["kinder/Obstruction3D-o2-v0", "kinder/Transport3D-o2-v0"])
def test_cross_process_determinism(env_id):
    check_cross_process_determinism(env_id)


@pytest.mark.slow
@pytest.mark.parametrize("env_id", KINEMATIC3D_IDS)
def test_cross_process_determinism_every_id(env_id):
    check_cross_process_determinism(env_id)


@pytest.mark.parametrize(
    "env_id",
    [
        "kinder/BaseMotion3D-v0",
        "kinder/Obstruction3D-o1-v0",
        "kinder/Packing3D-p2-v0",
        "kinder/Table3D-o2-v0",
        "kinder/Transport3D-o1-v0",
    ],
)
def test_sync_and_async_vector_envs_agree(env_id):
    check_vector_consistency(env_id)


def test_importing_the_package_loads_no_simulator():
    code = (
        "import sys, kinder_garden3d, kinder_core; "
        "assert 'pybullet' not in sys.modules and 'mujoco' not in sys.modules; "
        "print(len(kinder_core.list_envs('Kinematic3D')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "24"


def test_each_env_has_a_private_client_and_close_releases_it():
    a = kinder_core.make_object_centric("kinder/Obstruction3D-o2-v0")
    b = kinder_core.make_object_centric("kinder/Obstruction3D-o2-v0")
    a.reset(seed=1)
    b.reset(seed=2)
    ca, cb = a._scene.client, b._scene.client
    assert ca != cb
    # Interleaved stepping equals stepping each env alone.
    actions = [a.action_space.sample() for _ in range(10)]
    inter = []
    for act in actions:
        inter.append((a.step(act)[0], b.step(act)[0]))
    a.close()
    assert not pb.getConnectionInfo(ca)["isConnected"]
    assert pb.getConnectionInfo(cb)["isConnected"]
    b.close()
    for seed, index in ((1, 0), (2, 1)):
        solo = kinder_core.make_object_centric("kinder/Obstruction3D-o2-v0")
        solo.reset(seed=seed)
        for act, pair in zip(actions, inter, strict=True):
            assert solo.step(act)[0] == pair[index]
        solo.close()


def test_a_closed_env_reconnects_when_used_again():
    env = kinder_core.make_object_centric("kinder/Table3D-o1-v0")
    env.reset(seed=0)
    state = env.get_state()
    act = np.array([0.1, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], dtype=np.float32)
    before = env.transition(state, act)[0]
    env.close()
    env.close()  # idempotent
    assert env.transition(state, act)[0] == before
    env.close()


def test_render_cameras_are_headless_images():
    env = kinder_core.make_object_centric("kinder/Table3D-o1-v0")
    env.reset(seed=0)
    images = env.render_cameras()
    assert set(images) == {"overview", "base", "wrist"}
    for name, img in images.items():
        assert img.shape == (360, 640, 3) and img.dtype == np.uint8, name
        assert img.std() > 0, name
    assert np.array_equal(images["overview"], env.render())
    env.close()


def test_gymnasium_make_gives_the_box_view():
    env = gymnasium.make("kinder/BaseMotion3D-v0")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (22,)
    assert env.spec is not None and env.spec.max_episode_steps == 200
    env.close()


@pytest.mark.parametrize(
    "env_id",
    [
        "kinder/KinematicShelf3D-o2-v0",
        "kinder/KinematicCylinderShelf3D-o2-v0",
        "kinder/PrplLab3D-o2-v0",
    ],
)
def test_upstream_extra_families_draw_vector_envs_and_processes_alike(env_id):
    check_vector_consistency(env_id)
    check_cross_process_determinism(env_id)
