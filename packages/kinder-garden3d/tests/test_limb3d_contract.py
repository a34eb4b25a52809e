"""LimbRepositioning3D: every id passes the kinder-core test kit, and the task's mechanics hold
(upstream's spaces, the weld, the goal test, the reset distribution)."""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core.testing import check_cross_process_determinism, check_kinder_env
from kinder_garden3d.limb3d.env import (
    TORSO_TO_LIMB,
    VARIANTS,
    LimbRepositioning3DConfig,
    LimbRepositioning3DEnv,
    wrapped_joint_distance,
)
from kinder_garden3d.limb3d.limbs import LIMB_NAMES, LIMBS

LIMB_IDS = [i for i in kinder_core.list_envs("Dynamic3D") if "LimbRepositioning3D" in i]

#: Upstream 0.2.5's features (kinder/envs/dynamic3d/limb_object_types.py), in vector order.
UPSTREAM_ROBOT = [
    "pos_base_x",
    "pos_base_y",
    "pos_base_rot",
    *(f"joint_{i}" for i in range(1, 8)),
    *(f"joint_vel_{i}" for i in range(1, 8)),
]
UPSTREAM_LIMB = [
    *(f"joint_{i}" for i in range(1, 7)),
    *(f"joint_vel_{i}" for i in range(1, 7)),
    *(f"goal_joint_{i}" for i in range(1, 7)),
]

UPSTREAM_FIXTURE = ["pose_x", "pose_y", "pose_z", "pose_qx", "pose_qy", "pose_qz", "pose_qw"]

#: Variants whose grasp IK does not reach the seed-1000 draw within 0.1 mm.
IK_MISS_AT_1000 = {"wheelchair-left-leg", "wheelchair-right-leg"}


def test_ids_and_step_limit():
    assert sorted(LIMB_IDS) == sorted(
        f"kinder/LimbRepositioning3D-{scene}-{side}-{limb}-v0"
        for scene in ("isolated", "human", "wheelchair", "bed")
        for side in ("left", "right")
        for limb in ("arm", "leg")
    )
    for env_id in LIMB_IDS:
        assert kinder_core.make(env_id).spec.max_episode_steps == 2400


@pytest.mark.parametrize("env_id", LIMB_IDS)
def test_kinder_test_kit(env_id):
    check_kinder_env(env_id)


@pytest.mark.parametrize("env_id", LIMB_IDS)
def test_spaces_are_upstreams(env_id):
    env = kinder_core.make(env_id)
    try:
        box = env.get_wrapper_attr("box")
        furnished = "wheelchair" in env_id or "bed" in env_id
        assert [(o.name, o.type.name, list(o.type.features)) for o in box.objects] == [
            ("robot", "Limb3DRobot", UPSTREAM_ROBOT),
            ("limb", "Limb3DLimb", UPSTREAM_LIMB),
        ] + ([("fixture", "Limb3DFixture", UPSTREAM_FIXTURE)] if furnished else [])
        assert env.observation_space.shape == ((42,) if furnished else (35,))
        assert np.all(np.isinf(env.observation_space.low))
        assert env.action_space.shape == (7,) and env.action_space.dtype == np.float32
        assert np.all(env.action_space.low == -1.0) and np.all(env.action_space.high == 1.0)
    finally:
        env.close()


def test_cross_process_determinism():
    check_cross_process_determinism("kinder/LimbRepositioning3D-isolated-left-leg-v0")


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_reset_grasps_the_limb_and_the_weld_holds(variant):
    env = LimbRepositioning3DEnv(variant)
    try:
        state, _ = env.reset(seed=1000)
        v = VARIANTS[variant]
        limb = state[env.limb]
        lo, hi = env.limb_joint_limits()
        nominal = np.array(v.init_joints)
        assert np.all(limb[:6] >= np.maximum(nominal - 0.26, lo))
        assert np.all(limb[:6] <= np.minimum(nominal + 0.26, hi))
        assert np.array_equal(limb[12:18], v.goal_joints)
        assert np.array_equal(state[env.robot][:3], v.robot_base)

        def grasp_error() -> float:
            gp, gq = env.grasp_frame_pose()
            tool_p, _ = pb.multiplyTransforms(gp, gq, *env._grasp_tf)
            return float(np.linalg.norm(np.array(tool_p) - env._scene.ee_pose()[0]))

        env._load(state)
        # The documented IK misses (env docstring, Deviations) include seed 1000 of these.
        assert grasp_error() < (0.16 if variant in IK_MISS_AT_1000 else 1e-4)
        rng = np.random.default_rng(1000)
        for _ in range(100):
            state, *_ = env.step(rng.uniform(-1.0, 1.0, 7))
        env._load(state)
        assert grasp_error() < 5e-3
        assert not np.allclose(state[env.limb][:6], limb[:6])  # the torques moved the limb
    finally:
        env.close()


def test_goal_test_wraps_the_continuous_joints():
    env = LimbRepositioning3DEnv("isolated-right-arm")
    try:
        state, _ = env.reset(seed=1001)
        goal = np.array(VARIANTS["isolated-right-arm"].goal_joints)
        near = state.copy()
        near[env.limb][:6] = goal + np.array([0.05, 0.0, 0.0, 0.0, 0.0, 2.0 * math.pi])
        far = state.copy()
        far[env.limb][:6] = goal + np.array([0.05, 0.06, 0.0, 0.0, 0.0, 0.0])
        assert env.goal_reached(near) and not env.goal_reached(far)
        assert wrapped_joint_distance(goal, goal + 2.0 * math.pi) == pytest.approx(0.0, abs=1e-9)
    finally:
        env.close()


def test_reset_distribution_covers_the_noise_box():
    env = LimbRepositioning3DEnv("isolated-left-leg", LimbRepositioning3DConfig(ik_iterations=1))
    try:
        draws = np.array([env.reset(seed=s)[0][env.limb][:6] for s in range(1000, 1040)])
    finally:
        env.close()
    nominal = np.array(VARIANTS["isolated-left-leg"].init_joints)
    lo, hi = (np.array(v) for v in LIMBS["left-leg"].limits_rad)
    low, high = np.maximum(nominal - 0.26, lo), np.minimum(nominal + 0.26, hi)
    assert np.all(draws >= low) and np.all(draws <= high)
    # Forty uniform draws span most of each joint's interval.
    assert np.all(draws.max(axis=0) - draws.min(axis=0) > 0.7 * (high - low))


def test_bad_configuration_and_variant_are_rejected():
    with pytest.raises(ValueError, match="Unknown variant"):
        LimbRepositioning3DEnv("isolated-left-tail")
    with pytest.raises(ValueError, match="torque_limit"):
        LimbRepositioning3DConfig(torque_limit=0.0)


def test_stable_baselines3_env_checker():
    sb3_env_util = pytest.importorskip("stable_baselines3.common.env_checker")
    env = kinder_core.make("kinder/LimbRepositioning3D-isolated-right-arm-v0")
    try:
        sb3_env_util.check_env(env, warn=True, skip_render_check=True)
    finally:
        env.close()


@pytest.mark.parametrize("limb", ["right-arm", "left-leg"])
def test_human_scene_resets_keep_the_limb_out_of_the_body(limb):
    env = LimbRepositioning3DEnv(f"human-{limb}")
    try:
        env.reset(seed=1000)
        assert len(env._obstacles) == 5  # torso, head, three other limbs
        tol = env.config.init_max_penetration
        nominal = np.array(VARIANTS[f"human-{limb}"].init_joints)
        assert env.limb_penetration(nominal) == 0.0
        for seed in range(1000, 1010):
            state, _ = env.reset(seed=seed)
            assert env.limb_penetration(state[env.limb][:6]) > -tol
        # Swinging the limb 1 rad about the ball joint's y axis drives it into the body.
        into_body = nominal.copy()
        into_body[1] += -1.0 if limb == "right-arm" else 1.0
        assert env.limb_penetration(into_body) < -0.1
    finally:
        env.close()


@pytest.mark.parametrize(
    ("variant", "fixture_pos"),
    [("wheelchair-left-leg", (0.0, 0.0, 0.0)), ("bed-right-arm", (0.0, 0.0, 0.35))],
)
def test_furnished_scenes_seat_the_person_and_observe_the_fixture(variant, fixture_pos):
    env = LimbRepositioning3DEnv(variant)
    try:
        state, _ = env.reset(seed=1000)
        assert env.fixture is not None
        assert list(state[env.fixture]) == [*fixture_pos, 0.0, 0.0, 0.0, 1.0]
        # torso, head, three other limbs, and the furniture
        assert len(env._obstacles) == 6
        v = VARIANTS[variant]
        cid = env._client()
        # The other limbs hold the scene's resting posture (seated: hips flexed 1.3 rad).
        others = env._obstacles[2:5]
        rest = [r for name, r in zip(LIMB_NAMES, v.resting) if name != v.limb]
        for body, joints in zip(others, rest):
            got = [pb.getJointState(body, j, physicsClientId=cid)[0] for j in env._limb_joints]
            assert got == pytest.approx(joints)
        # The limb's anchor is the torso composed with the attachment offset.
        tp, tq = env.torso_pose()
        anchor, _ = pb.multiplyTransforms(tp, tq, TORSO_TO_LIMB[v.limb], [0, 0, 0, 1])
        assert anchor == pytest.approx(v.limb_base_pos, abs=1e-12)
        tol = env.config.init_max_penetration
        for seed in range(1000, 1005):
            state, _ = env.reset(seed=seed)
            assert env.limb_penetration(state[env.limb][:6]) > -tol
        # The fixture is constant along an episode.
        for _ in range(3):
            state, *_ = env.step(np.ones(7, dtype=np.float32))
        assert list(state[env.fixture]) == [*fixture_pos, 0.0, 0.0, 0.0, 1.0]
    finally:
        env.close()


def test_furniture_is_an_obstacle_of_the_limb():
    env = LimbRepositioning3DEnv("wheelchair-left-leg")
    try:
        env.reset(seed=1000)
        furniture = env._obstacles[-1]
        cid = env._client()
        nominal = np.array(VARIANTS["wheelchair-left-leg"].init_joints)
        env._set_limb(cid, nominal)
        assert env._distance(cid, furniture) > 0.0
        # Extending the hip drives the thigh down through the seat.
        into_seat = nominal.copy()
        into_seat[0] += 0.8
        assert env.limb_penetration(into_seat) < -0.05
    finally:
        env.close()


def test_bed_leg_resets_perturb_only_the_hip_abduction():
    env = LimbRepositioning3DEnv("bed-left-leg")
    try:
        nominal = np.array(VARIANTS["bed-left-leg"].init_joints)
        draws = np.array([env.reset(seed=s)[0][env.limb][:6] for s in range(1000, 1006)])
    finally:
        env.close()
    fixed = [0, 2, 3, 4, 5]
    assert np.array_equal(draws[:, fixed], np.tile(nominal[fixed], (6, 1)))
    assert np.all(np.abs(draws[:, 1] - nominal[1]) <= 0.26) and np.ptp(draws[:, 1]) > 0.01
