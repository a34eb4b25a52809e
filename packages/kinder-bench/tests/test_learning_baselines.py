"""DP, DPES and MBRL: training, checkpoints, resume, evaluation through the runner, learning.

DP/DPES mechanics use kinder-gym's committed Motion2D-p0 demo fixture (3 episodes, 224×224
video); the learning checks use scripted demos of the toy env (``kinder_bench_demos``).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("torch")

import torch
from kinder_bench_demos import write_toy_dataset
from kinder_bench_toy import TOY_ID
from typer.testing import CliRunner

from kinder_bench.agents import make_agent
from kinder_bench.baselines.demo_data import read_dataset_spec
from kinder_bench.baselines.diffusion import (
    DiffusionTrainArgs,
    diffusion_config,
    paper_budget_steps,
    train_diffusion,
)
from kinder_bench.baselines.diffusion_presets import PAPER_EPOCHS
from kinder_bench.baselines.mbrl import MBRLTrainArgs, load_delta_model, train_mbrl
from kinder_bench.baselines.ood import run_ood
from kinder_bench.cli import app
from kinder_bench.evaluation.envs import make_env
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.training.checkpoints import CheckpointError, load_checkpoint, read_checkpoint

FIXTURE = Path(__file__).parents[2] / "kinder-gym" / "tests" / "data" / "demos" / "Motion2D-p0"
MOTION = "kinder/Motion2D-p0-v0"


@pytest.fixture(scope="module", autouse=True)
def _offline(tmp_path_factory: pytest.TempPathFactory) -> None:
    """No hub, HF caches in a temp dir, one torch thread (the CI machine has 2 cores)."""
    os.environ["HF_HUB_OFFLINE"] = "1"
    os.environ.setdefault("HF_HOME", str(tmp_path_factory.mktemp("hf")))
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def motion(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not FIXTURE.is_dir():
        pytest.skip(f"the demo fixture {FIXTURE} is not in this checkout")
    root = tmp_path_factory.mktemp("demos") / "Motion2D-p0"
    shutil.copytree(FIXTURE, root)
    return root


@pytest.fixture(scope="module")
def toy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """40 scripted toy episodes, states only."""
    return write_toy_dataset(tmp_path_factory.mktemp("toy") / "ds", 40, images=False)


@pytest.fixture(scope="module")
def toy_direct(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """60 toy episodes of constant-length steps straight at the target, states only."""
    return write_toy_dataset(tmp_path_factory.mktemp("toy") / "direct", 60, images=False, gain=None)


def _dp_args(dataset: Path, out: Path, steps: int, method: str = "dp") -> DiffusionTrainArgs:
    return DiffusionTrainArgs(
        dataset=dataset, out=out, method=method, steps=steps, preset="cpu", batch_size=4,
        save_every=2, log_every=1, seed=3,
    )  # fmt: skip


@pytest.fixture(scope="module")
def dp_run(motion: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dp") / "run"
    train_diffusion(_dp_args(motion, out, 3), progress=False)
    return out


def test_dataset_spec_of_the_fixture(motion: Path, tmp_path: Path) -> None:
    spec = read_dataset_spec(motion)
    assert spec.env_id == MOTION
    assert spec.state_names[0] == "robot.x" and spec.env_state_names[0] == "target_region.x"
    assert spec.cameras == ("render",) and spec.image_shape == (224, 224, 3)
    with pytest.raises(FileNotFoundError, match="not a LeRobot dataset"):
        read_dataset_spec(tmp_path)
    with pytest.raises(ValueError, match="holds demos of"):
        train_diffusion(
            DiffusionTrainArgs(dataset=motion, out=tmp_path / "x", env="StickButton2D-b1"),
            progress=False,
        )


def test_paper_budget_is_5001_epochs_of_full_batches(motion: Path) -> None:
    from kinder_gym.demos.lerobot_format import load_records

    lengths = [r.num_steps for r in load_records(motion)]
    # Every frame but the last 7 of an episode starts a sample; a shorter episode keeps one.
    starts = sum(max(1, n - 7) for n in lengths)
    assert paper_budget_steps(read_dataset_spec(motion), 4) == PAPER_EPOCHS * (starts // 4)
    assert paper_budget_steps(read_dataset_spec(motion), 10**6) == 0


def test_a_checkpoint_records_the_papers_budget_only_when_it_trained_it(motion: Path) -> None:
    from kinder_bench.baselines.diffusion import checkpoint_training
    from kinder_bench.reporting.paper import paper_settings
    from kinder_bench.training.checkpoints import Checkpoint

    paper_steps = paper_budget_steps(read_dataset_spec(motion), 64)

    def ckpt(step: int, dataset: Path, preset: str = "paper") -> Checkpoint:
        args = {"preset": preset, "batch_size": None}
        info = {"env_id": MOTION, "dataset": str(dataset)}
        return Checkpoint(Path("ckpt"), "dp", step, args, {}, False, info)

    assert (
        checkpoint_training(ckpt(paper_steps, motion)) == paper_settings("dp", MOTION)["training"]
    )
    short = f"{paper_steps - 1} steps × batch 64, preset paper"
    assert checkpoint_training(ckpt(paper_steps - 1, motion)) == short
    assert checkpoint_training(ckpt(9, motion, "cpu")) == "9 steps × batch 16, preset cpu"
    # The dataset is not where the trainer recorded it: the paper's budget cannot be checked.
    missing = motion.parent / "elsewhere"
    assert checkpoint_training(ckpt(paper_steps, missing)).endswith(
        "steps × batch 64, preset paper"
    )


def test_dp_checkpoints_logs_and_resumes_bit_identically(
    dp_run: Path, motion: Path, tmp_path: Path
) -> None:
    ckpts = sorted(p.name for p in (dp_run / "checkpoints").iterdir() if p.name.startswith("s"))
    assert ckpts == ["step_000000002", "step_000000003"]
    assert (dp_run / "checkpoints" / "latest").read_text().strip() == "step_000000003"
    rows = (dp_run / "progress.csv").read_text().splitlines()
    assert rows[0] == "step,loss,lr,samples_per_s,elapsed_s" and len(rows) == 4
    ckpt = read_checkpoint(dp_run / "checkpoints" / "step_000000003", ("dp",))
    assert ckpt.method == "dp" and ckpt.step == 3 and ckpt.info["env_id"] == MOTION
    assert ckpt.info["env_state_names"] == [] and ckpt.args["seed"] == 3
    assert ckpt.args["dataset"] == str(motion) and "kinder-bench" in ckpt.versions

    # Stop after 2 steps, then resume to 3: the same weights as the uninterrupted run.
    resumed = tmp_path / "resumed"
    train_diffusion(_dp_args(motion, resumed, 2), progress=False)
    train_diffusion(_dp_args(motion, resumed, 3), progress=False)
    a = torch.load(dp_run / "checkpoints/step_000000003/training_state.pt", weights_only=False)
    b = torch.load(resumed / "checkpoints/step_000000003/training_state.pt", weights_only=False)
    for key, value in a["policy"].items():
        torch.testing.assert_close(value, b["policy"][key], rtol=0, atol=0, msg=key)
    assert len((resumed / "progress.csv").read_text().splitlines()) == 4  # header + 3 rows
    with pytest.raises(ValueError, match="different"):
        train_diffusion(
            DiffusionTrainArgs(dataset=motion, out=resumed, method="dpes", preset="cpu"),
            progress=False,
        )


def test_dp_agent_in_the_runner(dp_run: Path, tmp_path: Path) -> None:
    run = RunConfig(MOTION, "dp", {"checkpoint": str(dp_run)}, seeds=(0,), episodes=1, max_steps=9)
    run_benchmark([run], tmp_path / "eval", executor="inline", progress=False)
    (record,) = [json.loads(line) for line in (tmp_path / "eval/results.jsonl").open()]
    assert record["error"] is None, record["traceback"]
    assert record["steps"] == 9 and record["inference_time"] > 0

    def episode(seed: int) -> list[np.ndarray]:
        env = make_env(MOTION)
        agent = make_agent("dp", env, {"checkpoint": str(dp_run)}, seed=seed)
        obs, info = env.reset(seed=5)
        agent.reset(obs, info)
        actions = []
        for _ in range(9):  # two chunks: 8 queued actions, then a new prediction
            actions.append(agent.act(obs))
            obs = env.step(actions[-1])[0]
        return actions

    np.testing.assert_array_equal(episode(1), episode(1))
    assert not np.array_equal(episode(1), episode(2))
    with pytest.raises(ValueError, match="'dp' checkpoint; use --agent dp"):
        make_agent("dpes", make_env(MOTION), {"checkpoint": str(dp_run)})
    with pytest.raises(ValueError, match="needs --arg checkpoint"):
        make_agent("dp", make_env(MOTION), {})
    with pytest.raises(ValueError, match="lacks"):  # another robot: features missing
        make_agent("dp", make_env("kinder/DynObstruction2D-o1-v0"), {"checkpoint": str(dp_run)})
    with pytest.raises(ValueError, match="expects a policy trained on"):
        run_ood(dp_run, tmp_path / "ood", episodes=1, seeds=(0,), executor="inline")


def test_ood_command_evaluates_every_variant(
    dp_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The OOD command on Motion2D (trained on p0, evaluated on p0 and p1: same robot, more
    passages) stands in for DynObstruction2D-o1 → o0..o3, which has no fixture dataset."""
    from kinder_bench.baselines import ood

    monkeypatch.setattr(ood, "TRAIN_ENV", MOTION)
    monkeypatch.setattr(ood, "OOD_ENVS", (MOTION, "kinder/Motion2D-p1-v0"))
    monkeypatch.setattr(ood, "OOD_MAX_STEPS", 3)
    table = run_ood(dp_run, tmp_path / "ood", episodes=1, seeds=(0,), executor="inline")
    assert "Motion2D-p0" in table and "Motion2D-p1" in table
    records = [json.loads(line) for line in (tmp_path / "ood/results.jsonl").open()]
    assert len(records) == 2 and all(r["error"] is None for r in records)
    # Each run records the checkpoint's budget: 3 steps of the cpu preset, not the paper's.
    config = json.loads((tmp_path / "ood/config.json").read_text())
    assert {run["training"] for run in config["runs"]} == {"3 steps × batch 4, preset cpu"}


def test_dpes_normalises_the_environment_state(motion: Path) -> None:
    """lerobot leaves ``observation.environment_state`` unnormalised unless the normalisation
    mapping names ENV (the trap); DPES's config names it."""
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.policies.diffusion.processor_diffusion import make_diffusion_pre_post_processors

    cfg = diffusion_config(motion, "dpes", "cpu")
    assert "observation.environment_state" in cfg.input_features
    assert cfg.normalization_mapping["ENV"].value == "MIN_MAX"
    stats = LeRobotDatasetMetadata("kinder/Motion2D-p0", root=motion).stats
    env_stats = stats["observation.environment_state"]
    lo, hi = np.asarray(env_stats["min"]), np.asarray(env_stats["max"])
    raw = torch.as_tensor((lo + hi) / 2 + 0.25 * (hi - lo), dtype=torch.float32)
    batch = {
        "observation.state": torch.as_tensor(stats["observation.state"]["max"]).float(),
        "observation.environment_state": raw,
        "observation.images.render": torch.zeros(3, 224, 224),
    }
    pre, _ = make_diffusion_pre_post_processors(cfg, stats)
    out = pre(dict(batch))["observation.environment_state"][0]
    varying = torch.as_tensor(hi > lo)
    torch.testing.assert_close(out[varying], torch.full_like(out[varying], 0.5))
    # The trap: without the ENV entry the same input passes through unchanged.
    del cfg.normalization_mapping["ENV"]
    pre_raw, _ = make_diffusion_pre_post_processors(cfg, stats)
    torch.testing.assert_close(pre_raw(dict(batch))["observation.environment_state"][0], raw)


def test_dp_refuses_a_dataset_without_images(toy: Path) -> None:
    with pytest.raises(ValueError, match="DP needs camera images"):
        diffusion_config(toy, "dp", "cpu")


def _success(run_dir: Path, agent: str) -> float:
    records = [json.loads(line) for line in (run_dir / "results.jsonl").open()]
    mine = [r for r in records if r["agent"] == agent]
    assert all(r["error"] is None for r in mine), [r["traceback"] for r in mine]
    return float(np.mean([r["success"] for r in mine]))


def test_dpes_learns_the_toy_task_far_above_random(toy_direct: Path, tmp_path: Path) -> None:
    """A task learnable in a CPU-minute: reach a target whose position is in the environment
    state. DPES (state-only: the toy has no cameras in this dataset) is trained for 300 steps of
    batch 64 (the cpu preset, lr 1e-3), then evaluated on 20 episodes with random actions as the
    reference. Measured here: DPES 15/20, random 1/20."""
    out = tmp_path / "dpes"
    train_diffusion(
        DiffusionTrainArgs(
            dataset=toy_direct, out=out, method="dpes", preset="cpu", steps=300, batch_size=64,
            lr=1e-3, warmup_steps=20, save_every=300, log_every=100,
        ),
        progress=False,
    )  # fmt: skip
    ckpt = load_checkpoint(out, ("dpes",))
    assert ckpt.step == 300 and ckpt.args["method"] == "dpes" and ckpt.info["env_state_names"]
    with pytest.raises(CheckpointError, match=r"holds a dpes policy.*not mbrl"):
        make_agent("mbrl", make_env(TOY_ID), {"checkpoint": str(out)})
    runs = [
        RunConfig(TOY_ID, "dpes", {"checkpoint": str(out)}, seeds=(0,), episodes=20, max_steps=40),
        RunConfig(TOY_ID, "random", seeds=(0,), episodes=20, max_steps=40),
    ]
    run_benchmark(runs, tmp_path / "eval", executor="inline", progress=False)
    dpes, random = _success(tmp_path / "eval", "dpes"), _success(tmp_path / "eval", "random")
    print(f"toy success rate: dpes {dpes:.2f}, random {random:.2f}")
    assert dpes >= random + 0.4, (dpes, random)


def test_mbrl_model_beats_constant_and_resumes(toy: Path, tmp_path: Path) -> None:
    out = tmp_path / "mbrl"
    args = MBRLTrainArgs(dataset=toy, out=out, epochs=40, batch_size=64, save_every=20)
    train_mbrl(args, progress=False)
    ev = json.loads((out / "eval.json").read_text())
    assert ev["count_1"] > 0 and ev["count_10"] > 0
    assert ev["model_l2_1"] < 0.2 * ev["const_l2_1"]
    assert ev["model_l2_10"] < 0.2 * ev["const_l2_10"]
    model, ckpt = load_delta_model(out)
    assert ckpt.info["env_id"] == TOY_ID and ckpt.method == "mbrl" and ckpt.step == 40
    assert bool(model.constant[model.names.index("target.radius")])

    # Stop after 20 epochs, resume to 40: the same model as the uninterrupted run.
    resumed = tmp_path / "resumed"
    train_mbrl(MBRLTrainArgs(dataset=toy, out=resumed, epochs=20, batch_size=64, save_every=20),
               progress=False)  # fmt: skip
    train_mbrl(MBRLTrainArgs(dataset=toy, out=resumed, epochs=40, batch_size=64, save_every=20),
               progress=False)  # fmt: skip
    other, _ = load_delta_model(resumed)
    for key, value in model.weights.items():
        np.testing.assert_array_equal(value, other.weights[key])

    # The MPC on the learned model reaches the toy goal far more often than random actions.
    runs = [
        RunConfig(TOY_ID, "mbrl", {"checkpoint": str(out), "horizon": 20}, seeds=(0,),
                  episodes=10, max_steps=40),
        RunConfig(TOY_ID, "random", seeds=(0,), episodes=10, max_steps=40),
    ]  # fmt: skip
    run_benchmark(runs, tmp_path / "eval", executor="inline", progress=False)
    mbrl, random = _success(tmp_path / "eval", "mbrl"), _success(tmp_path / "eval", "random")
    assert mbrl >= random + 0.5, (mbrl, random)


def test_train_cli_mbrl(toy: Path, tmp_path: Path) -> None:
    out = tmp_path / "cli"
    result = CliRunner().invoke(
        app, ["train", "mbrl", "--dataset", str(toy), "--out", str(out), "--epochs", "2",
              "--save-every", "1", "--no-progress"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "held-out 1-step open-loop error" in result.output
    assert [p.name for p in sorted((out / "checkpoints").glob("step_*"))] == [
        "step_000000001",
        "step_000000002",
    ]
    bad = CliRunner().invoke(app, ["train", "dp", "--dataset", str(tmp_path), "--out", str(out)])
    assert bad.exit_code == 2 and "not a LeRobot dataset" in bad.output


def test_learned_agents_say_they_need_a_checkpoint() -> None:
    from kinder_bench.agents import unavailable_reason

    for name in ("dp", "dpes", "mbrl", "gsc", "ppo", "sac"):
        reason = unavailable_reason(name, "kinder/Motion2D-p0-v0", {})
        assert reason is not None and "checkpoint" in reason and "kinder train" in reason
    for name in ("dp", "dpes", "mbrl", "gsc"):  # these check the checkpoint when loading it
        assert unavailable_reason(name, "kinder/Motion2D-p0-v0", {"checkpoint": "x"}) is None
    missing = unavailable_reason("ppo", "kinder/Motion2D-p0-v0", {"checkpoint": "/nonexistent"})
    assert missing is not None and "/nonexistent" in missing
