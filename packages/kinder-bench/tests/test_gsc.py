"""Generative skill chaining: data, chained sampler, training (checkpoints, resume), agent.

One small model is trained per test session on StickButton2D-b1 (BP demonstrations): its
two-skill skeleton PickStick → StickPress (button on the table) makes random parameters fail
often (the stick must be grasped where the press can reach the button), while the other
instances give the one-skill RobotPress skeleton used to check that untouched objects are held.
"""

from __future__ import annotations

import csv
import dataclasses
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from kinder_bench.agents import make_agent
from kinder_bench.baselines.gsc.agent import (
    chain_steps,
    execute_chain,
    find_skeleton,
    random_params,
)
from kinder_bench.baselines.gsc.data import (
    load_transitions,
    save_transitions,
    transitions_from_records,
)
from kinder_bench.baselines.gsc.model import GSCModel
from kinder_bench.baselines.gsc.sampler import ChainStep, sample_chain
from kinder_bench.baselines.gsc.train import GSCTrainConfig, load_demonstrations, train_gsc
from kinder_bench.cli import app
from kinder_bench.demos.collection import CollectConfig, collect
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.training.checkpoints import latest_checkpoint, read_checkpoint
from kinder_core import make, make_object_centric
from kinder_gym.models import model_for

ENV = "kinder/StickButton2D-b1-v0"
#: The session model's budget: BP demos, perturbed executions per demo skill, steps.
TRAIN = {
    "demo_episodes": 40,
    "perturbations": 6,
    "steps": 1200,
    "hidden": 128,
    "depth": 3,
    "classifier_hidden": 128,
    "classifier_depth": 2,
}


@pytest.fixture(scope="session")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[GSCModel, Path]:
    out = tmp_path_factory.mktemp("gsc") / "model"
    config = GSCTrainConfig(ENV, str(out), checkpoint_every=400, **TRAIN)  # type: ignore[arg-type]
    model = train_gsc(config, show_progress=False)
    return model, out


@pytest.fixture(scope="module")
def tiny_transitions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Transitions of 3 BP demos (1 perturbation each), for the cheap training tests."""
    out = tmp_path_factory.mktemp("gsc_tiny")
    config = GSCTrainConfig(ENV, str(out), demo_episodes=3, perturbations=1, steps=1)
    train_gsc(config, show_progress=False)
    return out / "transitions.npz"


def _two_skill_instances(n: int) -> list[int]:
    env = make_object_centric(ENV)
    planning = model_for(env)
    seeds = []
    for seed in range(1000, 1400):
        x0, _ = env.reset(seed=seed)
        sk = find_skeleton(planning, x0, ["PickStick", "StickPress"], np.random.default_rng(0))
        if sk is not None and len(sk) == 2:
            seeds.append(seed)
        if len(seeds) == n:
            break
    return seeds


def test_collected_demos_become_labelled_transitions(tmp_path: Path) -> None:
    collect(
        CollectConfig(ENV, "bilevel_planning", episodes=2, seed=1000),
        tmp_path / "demos",
        executor="inline",
        progress=False,
    )
    records = load_demonstrations(tmp_path / "demos")
    assert len(records) == 2 and all(r.success and r.skills for r in records)
    env = make_object_centric(ENV)
    trs = transitions_from_records(records, env)
    ops = [t.operator for t in trs]
    assert ops == [lab.operator for r in records for lab in r.skills]
    assert set(ops) <= {"PickStick", "StickPress", "RobotPress"}
    assert all(t.success for t in trs)
    save_transitions(tmp_path / "t.npz", trs)
    back = load_transitions(tmp_path / "t.npz")
    assert [b.operator for b in back] == ops
    for a, b in zip(trs, back, strict=True):
        assert a.objects == b.objects and a.success == b.success
        np.testing.assert_array_equal(a.params, b.params)
        np.testing.assert_array_equal(a.start, b.start)
        np.testing.assert_array_equal(a.end, b.end)
    # A recorded skill whose end state is not its operator's effect is labelled a failure.
    label = records[0].skills[0]
    cut = dataclasses.replace(records[0], skills=[dataclasses.replace(label, end=label.start)])
    assert not transitions_from_records([cut], env)[0].success
    with pytest.raises(ValueError, match="skill labels"):
        transitions_from_records([dataclasses.replace(records[0], skills=[])], env)
    with pytest.raises(FileNotFoundError, match="neither"):
        load_demonstrations(tmp_path)


def test_skill_labelled_lerobot_dataset_is_a_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The demos fixture (a LeRobot v3 dataset of BP episodes on Obstruction2D-o1)."""
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf"))
    monkeypatch.setenv("HF_DATASETS_CACHE", str(tmp_path / "hf" / "datasets"))
    root = Path(__file__).parents[2] / "kinder-gym/tests/data/demos/Obstruction2D-o1"
    records = load_demonstrations(root)
    env = make_object_centric(records[0].env_id)
    trs = transitions_from_records(records, env)
    assert len(trs) == sum(len(r.skills) for r in records) > 0
    assert all(t.success for t in trs)  # BP's skills reached their operators' effects
    assert {t.operator for t in trs} <= {s.name for s in model_for(env).skills}


def test_sampler_respects_the_inpainted_initial_state(trained: tuple[GSCModel, Path]) -> None:
    model, _ = trained
    env = make_object_centric(ENV)
    planning = model_for(env)
    seed = _two_skill_instances(1)[0]
    x0, _ = env.reset(seed=seed)
    s0 = env.box_space.vectorize(x0)
    sk = find_skeleton(planning, x0, list(model.skills), np.random.default_rng(0))
    assert sk is not None
    samples = sample_chain(model, s0, chain_steps(sk), num_samples=8, steps=20, seed=3)
    assert samples.states.shape == (8, 3, s0.shape[0])
    for b in range(8):
        assert np.array_equal(samples.states[b, 0], s0)  # exactly, not approximately
        for i in (1, 2):  # static features are copied exactly
            assert np.array_equal(samples.states[b, i][model.static], s0[model.static])
    for spec, p in zip((model.skills[o.parent.name] for o in sk), samples.params, strict=True):
        assert np.all(p >= spec.param_lo) and np.all(p <= spec.param_hi)
    # The stick is moved by the chain: its pose is sampled, not copied.
    stick = model.layout.object_dims("stick")
    moving = stick[~model.static[stick]]
    assert moving.size and not np.allclose(samples.states[:, 2][:, moving], s0[moving])
    # Deterministic for a seed.
    again = sample_chain(model, s0, chain_steps(sk), num_samples=8, steps=20, seed=3)
    np.testing.assert_array_equal(again.states, samples.states)
    assert np.array_equal(again.order, samples.order)


def test_objects_the_skeleton_never_names_are_held(trained: tuple[GSCModel, Path]) -> None:
    model, _ = trained
    env = make_object_centric(ENV)
    x0, _ = env.reset(seed=0)
    s0 = env.box_space.vectorize(x0)
    samples = sample_chain(
        model, s0, [ChainStep("RobotPress", ("robot", "button0"))], num_samples=4, steps=10
    )
    stick = model.layout.object_dims("stick")
    for b in range(4):
        assert np.array_equal(samples.states[b, 1][stick], s0[stick])
    with pytest.raises(ValueError, match="No trained model"):
        sample_chain(model, s0, [ChainStep("Fly", ("robot",))])
    with pytest.raises(ValueError, match="gamma"):
        sample_chain(
            model,
            s0,
            [ChainStep("PickStick", ("robot", "stick"))] * 2,
            gamma=[0.5, 0.5],
        )


def test_top_sample_beats_random_parameters(
    trained: tuple[GSCModel, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """On two-skill instances (PickStick → StickPress), executing the top-ranked sample open loop
    in the env model reaches the goal far more often than uniform random parameters."""
    model, _ = trained
    torch.set_num_threads(1)
    env = make_object_centric(ENV)
    planning = model_for(env)
    seeds = _two_skill_instances(30)
    gsc = rand = 0
    for seed in seeds:
        x0, _ = env.reset(seed=seed)
        sk = find_skeleton(planning, x0, list(model.skills), np.random.default_rng(seed))
        assert sk is not None and len(sk) == 2
        samples = sample_chain(
            model, env.box_space.vectorize(x0), chain_steps(sk), 40, 50, 0.5, seed=seed
        )
        gsc += execute_chain(planning, x0, sk, samples.best_params())[0]
        params = random_params(planning, sk, np.random.default_rng(seed))
        rand += execute_chain(planning, x0, sk, params)[0]
    n = len(seeds)
    with capsys.disabled():
        print(f"\nGSC top sample {gsc}/{n} vs random parameters {rand}/{n} ({ENV})")
    assert gsc >= rand + 0.2 * n
    assert gsc >= 1.5 * rand


def test_checkpoint_round_trip_and_resume(tiny_transitions: Path, tmp_path: Path) -> None:
    def config(out: Path) -> GSCTrainConfig:
        out.mkdir(exist_ok=True)
        shutil.copy(tiny_transitions, out / "transitions.npz")
        return GSCTrainConfig(
            ENV,
            str(out),
            demo_episodes=3,
            perturbations=1,
            steps=12,
            checkpoint_every=5,
            log_every=4,
            hidden=32,
            depth=1,
            classifier_hidden=16,
        )

    full = train_gsc(config(tmp_path / "a"), show_progress=False)

    class Stop(Exception):
        pass

    def stop_at_7(step: int) -> None:
        if step == 7:
            raise Stop

    with pytest.raises(Stop):
        train_gsc(config(tmp_path / "b"), show_progress=False, on_step=stop_at_7)
    ckpt = latest_checkpoint(tmp_path / "b")
    assert ckpt == tmp_path / "b" / "checkpoints" / "step_000000005"
    st = torch.load(ckpt / "train_state.pt", weights_only=True)
    assert st["step"] == 5  # the last checkpoint before the interruption
    meta = read_checkpoint(ckpt, ("gsc",))
    assert meta.step == 5 and meta.info["env_id"] == ENV and meta.args["hidden"] == 32
    resumed = train_gsc(config(tmp_path / "b"), show_progress=False)
    for key, value in full.score_nets.state_dict().items():
        torch.testing.assert_close(resumed.score_nets.state_dict()[key], value)
    for key, value in full.classifiers.state_dict().items():
        torch.testing.assert_close(resumed.classifiers.state_dict()[key], value)
    # The saved model round-trips.
    loaded = GSCModel.load(tmp_path / "b")
    assert loaded.meta() == resumed.meta()
    for key, value in resumed.score_nets.state_dict().items():
        torch.testing.assert_close(loaded.score_nets.state_dict()[key], value)
    steps = [int(r["step"]) for r in _rows(tmp_path / "b" / "progress.csv")]
    assert steps == sorted(steps) and steps[-1] == 12
    # Other data settings in the same directory are refused.
    with pytest.raises(ValueError, match="other settings"):
        train_gsc(
            GSCTrainConfig(ENV, str(tmp_path / "b"), demo_episodes=4, steps=12),
            show_progress=False,
        )


def _rows(path: Path) -> list[dict[str, Any]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def test_cli_train_gsc(tiny_transitions: Path, tmp_path: Path) -> None:
    out = tmp_path / "cli"
    out.mkdir()
    shutil.copy(tiny_transitions, out / "transitions.npz")
    args = ["train", "gsc", "--env", "StickButton2D-b1", "--out", str(out), "--steps", "3"]
    args += ["--demo-episodes", "3", "--perturbations", "1", "--hidden", "16", "--depth", "1"]
    result = CliRunner().invoke(app, [*args, "--no-progress"])
    assert result.exit_code == 0, result.output
    ckpt = latest_checkpoint(out)
    assert ckpt is not None and ckpt.name == "step_000000003"
    assert (ckpt / "model.pt").is_file() and (out / "summary.json").is_file()
    assert f"--agent gsc --arg checkpoint={out}" in result.output
    bad = CliRunner().invoke(app, ["train", "gsc", "--env", "Nope2D", "--out", str(tmp_path)])
    assert bad.exit_code != 0


def test_agent_runs_through_the_runner(trained: tuple[GSCModel, Path], tmp_path: Path) -> None:
    _, ckpt = trained
    args = {"checkpoint": str(ckpt), "num_samples": 16, "steps": 20}
    outcome = run_benchmark(
        [RunConfig("StickButton2D-b1", "gsc", args, seeds=(0,), episodes=3)],
        tmp_path / "run",
        executor="inline",
        progress=False,
    )
    assert len(outcome.records) == 3
    for rec in outcome.records:
        assert rec["error_in"] in (None, "agent"), rec["traceback"]
        assert rec["inference_time"] > 0
    assert any(r["success"] for r in outcome.records)
    # The agent alone: a clear error without a checkpoint or with the wrong env.
    with pytest.raises(ValueError, match="checkpoint"):
        make_agent("gsc", make(ENV), {})
    with pytest.raises(ValueError, match="trained on"):
        make_agent("gsc", make("kinder/StickButton2D-b3-v0"), {"checkpoint": str(ckpt)})
