"""``--vec-env batched``: the batched Kinematic2D env as an SB3 ``VecEnv``.

It must hand SB3 exactly what ``DummyVecEnv`` of the training env stack hands it (same seeds,
same actions), pass through SB3's ``VecCheckNan`` and ``VecNormalize``, and train PPO.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecCheckNan, VecEnv, VecNormalize

from kinder_bench.baselines.rl.batched import BatchedVecEnv
from kinder_bench.baselines.rl.envs import make_rl_env
from kinder_bench.baselines.rl.train import make_train_args, make_venv, resolve
from kinder_garden2d.kinematic2d.motion2d import Motion2DConfig


def _same_infos(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert set(x) == set(y), (sorted(x), sorted(y))
        for key in x:
            if key == "terminal_observation":
                assert x[key].dtype == y[key].dtype and np.array_equal(x[key], y[key])
            elif key == "episode":
                assert {k: v for k, v in x[key].items() if k != "t"} == {
                    k: v for k, v in y[key].items() if k != "t"
                }
            else:
                assert x[key] == y[key], key


@pytest.mark.parametrize(
    "env_id", ["kinder/Obstruction2D-o1-v0", "kinder/StickButton2D-b2-v0", "kinder/Motion2D-p1-v0"]
)
def test_batched_vec_env_equals_dummy_vec_env(env_id: str) -> None:
    n, max_steps = 4, 25
    batched = BatchedVecEnv(env_id, n, max_steps)
    dummy = DummyVecEnv([lambda: make_rl_env(env_id, max_steps)] * n)
    assert batched.observation_space == dummy.observation_space
    assert batched.action_space == dummy.action_space
    batched.seed(1900)
    dummy.seed(1900)
    obs_b, obs_d = batched.reset(), dummy.reset()
    assert obs_b.dtype == obs_d.dtype and np.array_equal(obs_b, obs_d)
    assert batched.reset_infos == dummy.reset_infos
    rng = np.random.default_rng(1900)
    ended = 0
    for t in range(70):
        if t % 4 == 0:
            actions = rng.uniform(-1.0, 1.0, (n, 5)).astype(np.float32)
        ob, rb, db, ib = batched.step(actions)
        od, rd, dd, idd = dummy.step(actions)
        assert ob.dtype == od.dtype and np.array_equal(ob, od), f"step {t}: observations"
        assert rb.dtype == rd.dtype and np.array_equal(rb, rd), f"step {t}: rewards"
        assert np.array_equal(db, dd), f"step {t}: dones"
        _same_infos(ib, idd)
        ended += int(db.sum())
    assert ended >= n  # every sub-env hit its limit at least once
    batched.close()
    dummy.close()


def test_passes_sb3_wrappers_and_seeding() -> None:
    env = VecNormalize(
        VecCheckNan(BatchedVecEnv("kinder/Motion2D-p0-v0", 8, 20), raise_exception=True)
    )
    env.seed(2100)
    first = env.reset()
    assert first.shape == (8, 19)
    for _ in range(45):
        obs, rewards, dones, infos = env.step(np.zeros((8, 5), dtype=np.float32))
        assert obs.shape == (8, 19) and rewards.shape == (8,) and dones.shape == (8,)
    assert all("episode" in i for i in infos) or not dones.any()
    raw = BatchedVecEnv("kinder/Motion2D-p0-v0", 2, 20)
    raw.seed(2100)
    again = raw.reset()
    single = make_rl_env("kinder/Motion2D-p0-v0", 20)
    assert np.array_equal(again[1], single.reset(seed=2101)[0])
    assert raw.get_attr("num_passages") == [0, 0]
    assert raw.env_is_wrapped(VecEnv) == [False, False]  # type: ignore[arg-type]
    frames = raw.env_method("render", indices=[1])
    assert frames[0].ndim == 3
    with pytest.raises(AttributeError, match="share one single env"):
        raw.set_attr("num_passages", 2)


def test_batched_refuses_other_envs_and_dense_reward() -> None:
    with pytest.raises(ValueError, match="has none"):
        BatchedVecEnv("kinder/DynObstruction2D-o1-v0", 2, 10)
    args = make_train_args(
        "ppo", {"env_id": "Motion2D-p0", "vec_env": "batched", "reward": "dense"}
    )
    with pytest.raises(ValueError, match="sparse"):
        make_venv("ppo", args, resolve("ppo", args))
    with pytest.raises(ValueError, match="vec_env must be one of"):
        make_train_args("ppo", {"env_id": "Motion2D-p0", "vec_env": "threads"})


@pytest.mark.slow
def test_ppo_learns_a_toy_variant_with_the_batched_env() -> None:
    """A toy Motion2D-p0: the robot starts 0.3-0.4 left of the target region, at its height,
    with 30-step episodes. PPO (a small MLP, 24k steps on 32 batched sub-envs) learns to drive
    into the region: its deterministic success rate beats the random policy's by 0.5."""
    config = Motion2DConfig(
        robot_init_x=(1.85, 1.9), robot_init_y=(1.05, 1.15), target_init_y=(1.0, 1.05)
    )

    def make(n: int) -> BatchedVecEnv:
        return BatchedVecEnv("kinder/Motion2D-p0-v0", n, 30, config=config)

    model = PPO(
        "MlpPolicy",
        make(32),
        n_steps=64,
        batch_size=256,
        n_epochs=5,
        learning_rate=1e-3,
        policy_kwargs={"net_arch": [32, 32]},
        seed=2200,
        device="cpu",
    )
    model.learn(24_576)

    def success_rate(act: Any) -> float:
        env = make(64)
        env.seed(2300)
        obs = env.reset()
        successes = episodes = 0
        for _ in range(60):
            obs, _, dones, infos = env.step(act(obs))
            for d, i in zip(dones, infos):
                episodes += int(d)
                successes += int(d and i["is_success"])
        return successes / episodes

    rng = np.random.default_rng(2300)
    random = success_rate(lambda obs: rng.uniform(-1, 1, (64, 5)).astype(np.float32))
    learned = success_rate(lambda obs: model.predict(obs, deterministic=True)[0])
    assert learned > random + 0.5, (learned, random)
