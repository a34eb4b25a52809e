"""The conformance kit against fixtures written here from the toy env (standing in for upstream)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import kinder_core
from kinder_core.conformance import (
    check_resets,
    check_seeded_resets,
    check_transitions,
    compare_resets,
    fixture_name,
    ks_critical,
    ks_statistic,
    load_fixture,
)


def _write_fixture(path: Path, env_id: str, num_seeds: int = 60, steps: int = 8) -> dict[str, Any]:
    """Record ``env_id`` in the fixture format (tools/conformance/README.md), as the upstream
    worker does: exact float64 states, per-step deltas."""
    env = kinder_core.make(env_id)
    names = list(env.unwrapped.box_space.feature_names)
    vecs = np.array([env.reset(seed=s)[0] for s in range(num_seeds)])
    const = np.all(vecs == vecs[0], axis=0)
    rng = np.random.default_rng(1000)
    trajectories = []
    for seed in (0, 1):
        state, _ = env.reset(seed=seed)
        init, actions, deltas, rewards, terms = state.copy(), [], [], [], []
        for _ in range(steps):
            a = rng.uniform(-0.1, 0.1, 2)
            nxt, r, term, _, _ = env.step(a)
            actions.append(a.tolist())
            deltas.append([[int(i), float(nxt[i])] for i in np.flatnonzero(nxt != state)])
            rewards.append(float(r))
            terms.append(bool(term))
            state = nxt
            if term:
                break
        trajectories.append(
            {"name": f"random-{seed}", "kind": "random", "seed": seed,
             "init_state": init.tolist(), "actions": actions, "deltas": deltas,
             "rewards": rewards, "terminated": terms}
        )  # fmt: skip
    raw = {
        "format": 1,
        "env_id": env_id,
        "upstream": "toy",
        "feature_names": names,
        "action_low": [-0.1, -0.1],
        "action_high": [0.1, 0.1],
        "resets": {
            "num_seeds": num_seeds,
            "seeds": [0, 1, 2],
            "vectors": vecs[:3].tolist(),
            "constants": {n: float(vecs[0, i]) for i, n in enumerate(names) if const[i]},
            "samples": {n: vecs[:, i].tolist() for i, n in enumerate(names) if not const[i]},
            "min": vecs.min(0).tolist(),
            "max": vecs.max(0).tolist(),
            "mean": vecs.mean(0).tolist(),
            "std": vecs.std(0).tolist(),
        },
        "trajectories": trajectories,
    }
    path.write_text(json.dumps(raw))
    return raw


def test_fixture_name() -> None:
    assert fixture_name("kinder/StickButton2D-b1-v0") == "StickButton2D-b1.json"
    assert fixture_name("kinder/PushPullHook2D-v0") == "PushPullHook2D.json"
    with pytest.raises(ValueError, match="not a KinDER id"):
        fixture_name("StickButton2D")


def test_identical_env_conforms(tmp_path: Path, toy_id: str) -> None:
    path = tmp_path / "toy.json"
    _write_fixture(path, toy_id)
    fx = load_fixture(path)
    env = kinder_core.make(toy_id)
    reports = check_transitions(env, fx, atol=1e-12)
    assert [r.ok for r in reports] == [True, True]
    assert max(r.max_error for r in reports) == 0.0
    seeded = check_seeded_resets(env, fx)
    assert (seeded.matched, seeded.total) == (3, 3)
    dist = check_resets(env, fx)
    assert dist.ok, dist.failures
    assert {f.kind for f in dist.features} == {"constant", "sampled"}


def test_divergence_is_located(tmp_path: Path, toy_id: str) -> None:
    path = tmp_path / "toy.json"
    _write_fixture(path, toy_id)
    leaky = kinder_core.make("kinder/LeakyToyReach-v0")
    report = check_transitions(leaky, load_fixture(path), atol=1e-9)[0]
    assert not report.ok and report.first_divergence is not None
    assert (report.first_divergence.step, report.first_divergence.feature) == (0, "pebble0.x")
    assert report.first_divergence.error == pytest.approx(1e-3)


def test_reward_and_termination_are_compared(tmp_path: Path, toy_id: str) -> None:
    path = tmp_path / "toy.json"
    raw = _write_fixture(path, toy_id)
    raw["trajectories"][0]["rewards"][2] = 0.0
    raw["trajectories"][1]["terminated"][3] = True
    path.write_text(json.dumps(raw))
    r0, r1 = check_transitions(kinder_core.make(toy_id), load_fixture(path), atol=1e-9)
    assert r0.first_divergence is not None and r1.first_divergence is not None
    assert (r0.first_divergence.what, r0.first_divergence.step) == ("reward", 2)
    assert (r1.first_divergence.what, r1.first_divergence.step) == ("terminated", 3)


def test_distribution_mismatches_are_named(tmp_path: Path, toy_id: str) -> None:
    path = tmp_path / "toy.json"
    _write_fixture(path, toy_id)
    fx = load_fixture(path)
    ours = kinder_core.conformance.sample_resets(kinder_core.make(toy_id), range(1000, 1060))
    shifted = ours.copy()
    shifted[:, 0] = 0.5 * shifted[:, 0]  # robot.x over half upstream's range
    shifted[:, 2] = 2.0  # robot.speed: upstream's constant is 1.0
    bad = {f.name: f for f in compare_resets(shifted, fx).failures}
    assert set(bad) == {"robot.x", "robot.speed"}
    assert bad["robot.speed"].kind == "constant" and "constant 1.0" in bad["robot.speed"].detail
    assert "range" in bad["robot.x"].detail
    with pytest.raises(ValueError, match="expected \\(num_seeds, 10\\)"):
        compare_resets(ours[:, :3], fx)


def test_ks_statistic() -> None:
    rng = np.random.default_rng(1000)
    a, b = rng.uniform(0, 1, 300), rng.uniform(0, 1, 300)
    assert ks_statistic(a, a) == 0.0
    assert ks_statistic(a, a + 2.0) == 1.0
    assert ks_statistic(a, b) < ks_critical(300, 300, 1e-3)
    assert ks_statistic(a, 0.7 * b) > ks_critical(300, 300, 1e-3)
    with pytest.raises(ValueError, match="alpha"):
        ks_critical(10, 10, 1.5)


def test_load_fixture_rejects_another_format(tmp_path: Path) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"format": 99}))
    with pytest.raises(ValueError, match="fixture format 99; expected 1"):
        load_fixture(path)
