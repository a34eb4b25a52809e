"""PPO and SAC on Stable-Baselines3: training, checkpoints, resuming, the agents, errors.

Budgets are tiny (a few thousand env steps, small networks) so the file runs in about a minute
on two cores.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from kinder_bench.agents import agent_class, make_agent, make_args
from kinder_bench.baselines.rl import train as rl_train
from kinder_bench.baselines.rl.agents import check_compatible
from kinder_bench.baselines.rl.envs import make_rl_env
from kinder_bench.baselines.rl.train import PPOArgs, SACArgs, make_train_args, train
from kinder_bench.evaluation.envs import make_env
from kinder_bench.evaluation.metrics import aggregate
from kinder_bench.evaluation.runner import RunConfig, run_benchmark, with_run_seed
from kinder_bench.training.checkpoints import list_checkpoints, read_checkpoint

MOTION = "kinder/Motion2D-p0-v0"
IMPORTS = ("kinder_bench_toy",)
TINY_PPO = {"n_envs": 2, "n_steps": 256, "batch_size": 128, "n_epochs": 2, "hidden_size": 16}


def tiny_ppo(**kw: Any) -> PPOArgs:
    values: dict[str, Any] = {"env_id": MOTION, "log_every": 512, **TINY_PPO, **kw}
    return PPOArgs(**values)


class Interrupted(Exception):
    """Stands for a kill right after a checkpoint was written."""


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A PPO run on Motion2D-p0 interrupted after its 1024-step checkpoint, then resumed."""
    out = tmp_path_factory.mktemp("ppo") / "run"
    args = tiny_ppo(total_steps=2048, checkpoint_every=1024, keep_checkpoints=5)
    save = rl_train._save_checkpoint

    def save_then_die(*a: Any, **kw: Any) -> Path:
        path = save(*a, **kw)
        raise Interrupted(path)

    rl_train._save_checkpoint = save_then_die  # type: ignore[assignment]
    try:
        with pytest.raises(Interrupted):
            train("ppo", args, out, progress=False)
    finally:
        rl_train._save_checkpoint = save  # type: ignore[assignment]
    assert [s for s, _ in list_checkpoints(out)] == [1024]
    result = train("ppo", args, out, progress=False)
    assert result.resumed_from == 1024
    assert result.steps == 2048 and result.ran_steps == 1024
    return out


def test_training_checkpoints_and_resumes_to_the_same_step_count(ppo_run: Path) -> None:
    assert [s for s, _ in list_checkpoints(ppo_run)] == [1024, 2048]
    ckpt = read_checkpoint(list_checkpoints(ppo_run)[-1][1])
    assert ckpt.method == "ppo" and ckpt.info["env_id"] == MOTION and ckpt.step == 2048
    assert ckpt.info["obs_shape"] == [19]
    assert ckpt.args["env_id"] == MOTION and ckpt.args["hidden_size"] == 16
    rows = (ppo_run / "progress.csv").read_text().splitlines()
    steps = [int(r.split(",")[0]) for r in rows[1:]]
    assert steps == [512, 1024, 1536, 2048]  # the killed run logged up to 1024; resumed after
    config = json.loads((ppo_run / "config.json").read_text())
    assert config["algo"] == "ppo" and config["resolved"]["hidden_size"] == 16
    # Rerunning a finished run trains nothing.
    again = train("ppo", tiny_ppo(total_steps=2048, checkpoint_every=1024), ppo_run)
    assert again.ran_steps == 0 and again.steps == 2048


def test_training_is_deterministic(tmp_path: Path) -> None:
    args = tiny_ppo(total_steps=512)
    a = train("ppo", args, tmp_path / "a", progress=False)
    b = train("ppo", args, tmp_path / "b", progress=False)
    env = make_env(MOTION)
    obs, _ = env.reset(seed=3)
    acts = []
    for r in (a, b):
        agent = make_agent("ppo", env, {"checkpoint": str(r.checkpoint)}, seed=0)
        acts.append(agent.act(obs))
    np.testing.assert_array_equal(acts[0], acts[1])


def test_kept_checkpoints_survive_rotation_and_match_a_shorter_run(tmp_path: Path) -> None:
    """With a constant learning rate, the checkpoint kept at 1024 steps of a 2048-step run is the
    policy of a 1024-step run with the same seed and arguments."""
    args = tiny_ppo(anneal_lr=False, keep_steps=(1000,), checkpoint_every=512, keep_checkpoints=1)
    long = train("ppo", dataclasses.replace(args, total_steps=2048), tmp_path / "long", False)
    kept = [(s, read_checkpoint(p).kept) for s, p in list_checkpoints(long.out)]
    assert kept == [(1024, True), (2048, False)]
    short = train("ppo", dataclasses.replace(args, total_steps=1024), tmp_path / "short", False)
    env = make_env(MOTION)
    obs, _ = env.reset(seed=5)
    acts = [
        make_agent("ppo", env, {"checkpoint": str(path)}, seed=0).act(obs)
        for path in (long.out / "checkpoints" / "step_000001024", short.checkpoint)
    ]
    np.testing.assert_array_equal(acts[0], acts[1])
    assert make_train_args("ppo", {"keep_steps": "[300, 100]"}).keep_steps == (100, 300)


def test_max_wall_s_stops_at_an_update_boundary_and_resumes(tmp_path: Path) -> None:
    args = tiny_ppo(total_steps=4096, max_wall_s=1e-6, checkpoint_every=10_000)
    first = train("ppo", args, tmp_path, progress=False)
    # The deadline passes before the second rollout: one update's steps, checkpointed.
    assert first.steps == first.ran_steps == 512
    assert [s for s, _ in list_checkpoints(tmp_path)] == [512]
    done = train("ppo", dataclasses.replace(args, max_wall_s=None), tmp_path, progress=False)
    assert (done.resumed_from, done.steps) == (512, 4096)


def test_runner_evaluates_the_checkpoint(ppo_run: Path, tmp_path: Path) -> None:
    # No {seed} in the path: one policy for both seeds.
    runs = [RunConfig(MOTION, "ppo", {"checkpoint": str(ppo_run)}, seeds=(0, 1), episodes=2)]
    out = run_benchmark(runs, tmp_path, executor="inline", progress=False)
    assert len(out.records) == 4
    for rec in out.records:
        assert rec["error"] is None, rec["traceback"]
        assert rec["steps"] == 200 or rec["success"]
        assert rec["inference_time"] > 0
    # The agent acts deterministically and inside the action box.
    env = make_env(MOTION)
    obs, _ = env.reset(seed=0)
    a1 = make_agent("ppo", env, {"checkpoint": str(ppo_run)}, seed=1).act(obs)
    a2 = make_agent("ppo", env, {"checkpoint": str(ppo_run)}, seed=2).act(obs)
    np.testing.assert_array_equal(a1, a2)
    assert env.action_space.contains(a1.astype(np.float32))


def test_seed_template_selects_each_seeds_policy(tmp_path: Path) -> None:
    assert with_run_seed({"checkpoint": "runs/seed{seed}", "n": 3}, 4) == {
        "checkpoint": "runs/seed4",
        "n": 3,
    }


def test_sac_trains_checkpoints_its_replay_buffer_and_resumes(tmp_path: Path) -> None:
    values: dict[str, Any] = {
        "env_id": MOTION,
        "n_envs": 2,
        "hidden_size": 16,
        "buffer_size": 4096,
        "learning_starts": 256,
        "batch_size": 64,
        "log_every": 256,
    }
    first = train("sac", SACArgs(**values, total_steps=512), tmp_path, progress=False)
    assert first.steps == 512
    assert (first.checkpoint / "replay_buffer.pkl").is_file()
    ckpt = read_checkpoint(first.checkpoint, ("sac",))
    assert ckpt.step == 512 and ckpt.args["buffer_size"] == 4096 and ckpt.info["obs_shape"] == [19]
    second = train("sac", SACArgs(**values, total_steps=768), tmp_path, progress=False)
    assert second.resumed_from == 512 and second.steps == 768
    from kinder_bench.baselines.rl.train import KinderSAC

    model = KinderSAC.load(second.checkpoint / "model.zip", device="cpu")
    assert model.q_learning_rate == pytest.approx(1e-3)
    assert model.critic.optimizer.param_groups[0]["lr"] == pytest.approx(1e-3)
    assert model.actor.optimizer.param_groups[0]["lr"] == pytest.approx(3e-4)
    env = make_env(MOTION)
    obs, _ = env.reset(seed=0)
    action = make_agent("sac", env, {"checkpoint": str(tmp_path)}, seed=0).act(obs)
    assert env.action_space.contains(action.astype(np.float32))


def test_learned_policy_beats_random_on_a_tiny_env(tmp_path: Path) -> None:
    """BenchReachEasy (the toy reach task, target radius 0.3, 25 steps): 8k steps of PPO
    learn to head for the target; random succeeds in about 1 episode in 10."""
    from kinder_bench_toy import EASY_ID

    args = PPOArgs(
        env_id=EASY_ID,
        total_steps=8192,
        n_envs=4,
        n_steps=128,
        batch_size=128,
        n_epochs=5,
        hidden_size=32,
        num_layers=2,
        anneal_lr=False,
        learning_rate=1e-3,
    )
    result = train("ppo", args, tmp_path / "train", progress=False)
    ckpt = {"checkpoint": str(result.out)}
    runs = [
        RunConfig(EASY_ID, "random", seeds=(0,), episodes=30),
        RunConfig(EASY_ID, "ppo", ckpt, seeds=(0,), episodes=30),
    ]
    out = run_benchmark(runs, tmp_path / "eval", executor="inline", imports=IMPORTS, progress=False)
    sr = {s.method: s.success.mean for s in aggregate(out.records)}
    print(f"success rate on {EASY_ID} (30 episodes of 25 steps): {sr}")
    assert sr["ppo"] is not None and sr["random"] is not None
    assert sr["ppo"] >= sr["random"] + 0.5


def test_mismatched_checkpoints_are_clear_errors(ppo_run: Path, toy_id: str) -> None:
    import kinder_bench_toy  # noqa: F401  (registers the toy id)

    toy = make_env(toy_id)
    with pytest.raises(ValueError, match=r"trained on kinder/Motion2D-p0-v0.*BenchReach"):
        make_agent("ppo", toy, {"checkpoint": str(ppo_run)})
    motion = make_env(MOTION)
    with pytest.raises(ValueError, match=r"holds a ppo policy.*--agent ppo"):
        make_agent("sac", motion, {"checkpoint": str(ppo_run)})
    meta = read_checkpoint(list_checkpoints(ppo_run)[-1][1]).info
    with pytest.raises(ValueError, match=r"observations of shape \(20,\).*\(19,\)"):
        check_compatible({**meta, "obs_shape": [20]}, motion, ppo_run)
    with pytest.raises(ValueError, match="action bounds"):
        check_compatible({**meta, "action_high": [1.0] * 5}, motion, ppo_run)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        make_args(agent_class("ppo"), {"checkpoint": str(ppo_run / "missing")})
    with pytest.raises(FileNotFoundError, match="holds no checkpoint"):
        make_args(agent_class("ppo"), {"checkpoint": str(ppo_run / "checkpoints")})
    with pytest.raises(ValueError, match="need --arg checkpoint"):
        make_args(agent_class("sac"), {})


def test_bad_training_arguments_are_clear_errors(ppo_run: Path) -> None:
    with pytest.raises(ValueError, match=r"other arguments.*seed"):
        train("ppo", tiny_ppo(total_steps=2048, seed=1), ppo_run)
    with pytest.raises(ValueError, match="BaseMotion3D shaping"):
        make_rl_env(MOTION, 10, reward="dense")
    with pytest.raises(ValueError, match="keep_steps must all be > 0"):
        make_train_args("ppo", {"keep_steps": "[0]"})
    with pytest.raises(ValueError, match="max_wall_s must be > 0"):
        make_train_args("ppo", {"max_wall_s": "-1"})
    with pytest.raises(ValueError, match="vec_env must be one of"):
        make_train_args("ppo", {"vec_env": "threads"})
    with pytest.raises(ValueError, match=r"Unknown ppo argument.*buffer_size"):
        make_train_args("ppo", {"buffer_size": "10"})
    with pytest.raises(ValueError, match="needs PPOArgs"):
        train("ppo", SACArgs(), ppo_run)
    args = make_train_args("sac", {"n_envs": "4", "hidden_size": "none", "q_lr": "2e-3"})
    assert dataclasses.astuple(args) == dataclasses.astuple(
        SACArgs(n_envs=4, hidden_size=None, q_lr=2e-3)
    )


def test_dense_reward_rewards_progress_towards_the_target() -> None:
    pytest.importorskip("kinder_garden3d")
    env = make_rl_env("kinder/BaseMotion3D-v0", 100, reward="dense")
    obs, _ = env.reset(seed=0)
    target = obs[19:21]
    toward = np.zeros(11, dtype=np.float32)
    toward[:2] = np.clip(target / 0.8, -1.0, 1.0)  # halfway (at most 0.4 m per axis)
    _, r_toward, *_ = env.step(toward)
    _, r_away, *_ = env.step(-toward)
    assert r_toward > -1.0 > r_away  # the env's −1 plus positive / negative progress
    sparse = make_rl_env("kinder/BaseMotion3D-v0", 100)
    sparse.reset(seed=0)
    assert sparse.step(toward)[1] == -1.0


def test_kinder_train_command(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from kinder_bench.cli import app

    cmd = ["train", "ppo", "--env", "Motion2D-p0", "--steps", "256", "--out", str(tmp_path)]
    tiny = ["--n-envs", "1", "--no-progress", "--hp", "n_steps=256", "--hp", "batch_size=256"]
    tiny += ["--hp", "n_epochs=1", "--hp", "hidden_size=8"]
    result = CliRunner().invoke(app, cmd + tiny)
    assert result.exit_code == 0, result.output
    assert "--agent ppo --arg checkpoint=" in result.output
    assert [s for s, _ in list_checkpoints(tmp_path)] == [256]
    again = CliRunner().invoke(app, cmd + tiny)
    assert again.exit_code == 0 and "already trained (256 steps)" in again.output
    bad = CliRunner().invoke(app, [*cmd, "--hp", "hidden_size"])
    assert bad.exit_code == 2 and "expected KEY=VALUE" in bad.output
    bad = CliRunner().invoke(app, [*cmd, "--hp", "nope=1"])
    assert bad.exit_code == 2 and "Unknown ppo argument" in bad.output
