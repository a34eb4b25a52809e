"""The runner: episode instances, determinism, resume, crash records, executors, recording."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from kinder_bench_toy import CRASH_THINK

from kinder_bench.evaluation.results import CONFIG_FILE, RESULTS_FILE, append_record, load_records
from kinder_bench.evaluation.runner import (
    TIMING_FIELDS,
    RunConfig,
    agent_seed,
    episode_seeds,
    resolve_run,
    run_benchmark,
)
from kinder_bench.evaluation.summary import CSV_FILE
from kinder_bench.reporting.paper import paper_settings, protocol_deviations, results_from_csv

IMPORTS = ("kinder_bench_toy",)


def _runs(toy_id: str, seeds: tuple[int, ...] = (0, 1), episodes: int = 3) -> list[RunConfig]:
    return [
        RunConfig(toy_id, "random", {}, seeds, episodes),
        RunConfig(toy_id, "mpc", {"horizon": 15, "num_rollouts": 5}, seeds, episodes),
    ]


def _strip(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Records without wall-clock fields (what must match across runs and executors)."""
    return [{k: v for k, v in r.items() if k not in TIMING_FIELDS} for r in records]


def _bench(runs: list[RunConfig], run_dir: Path, **kw: Any) -> Any:
    kw.setdefault("executor", "inline")
    return run_benchmark(runs, run_dir, imports=IMPORTS, progress=False, **kw)


def test_episode_seeds_follow_the_protocol() -> None:
    rng = np.random.default_rng(7)
    expected = [int(rng.integers(0, 2**31 - 1)) for _ in range(5)]
    assert episode_seeds(7, 5) == expected
    assert episode_seeds(7, 3) == expected[:3]  # more episodes extend, never reshuffle
    assert agent_seed(0, 1) != agent_seed(1, 0)


def test_same_instances_for_every_method(toy_id: str, tmp_path: Path) -> None:
    out = _bench(_runs(toy_id), tmp_path)
    by_agent: dict[str, list[tuple[int, int, int]]] = {}
    for r in out.records:
        by_agent.setdefault(r["agent"], []).append((r["seed"], r["episode"], r["env_seed"]))
    assert by_agent["random"] == by_agent["mpc"]
    assert len(by_agent["random"]) == 6


def test_results_are_deterministic(toy_id: str, tmp_path: Path) -> None:
    a = _bench(_runs(toy_id), tmp_path / "a")
    b = _bench(_runs(toy_id), tmp_path / "b")
    assert _strip(a.records) == _strip(b.records)
    assert any(r["success"] for r in a.records)  # MPC solves some: the comparison has content
    assert not all(r["success"] for r in a.records)


def test_records_have_the_schema(toy_id: str, tmp_path: Path) -> None:
    out = _bench(_runs(toy_id, seeds=(0,), episodes=1), tmp_path)
    lines = (tmp_path / RESULTS_FILE).read_text().splitlines()
    assert len(lines) == 2
    rec = json.loads(lines[1])
    for key in (
        "schema",
        "run_id",
        "env_id",
        "agent",
        "agent_args",
        "label",
        "max_steps",
        "seed",
        "episode",
        "env_seed",
        "agent_seed",
        "success",
        "reward",
        "steps",
        "inference_time",
        "inference_cpu_time",
        "load_avg",
        "env_time",
        "error",
        "error_in",
        "traceback",
        "video",
        "versions",
        "finished_at",
    ):
        assert key in rec, key
    mpc = next(r for r in out.records if r["agent"] == "mpc")
    assert mpc["agent_args"]["horizon"] == 15 and mpc["agent_args"]["noise_fraction"] == 1.0
    assert mpc["max_steps"] == 40  # the env's registered budget
    assert "numpy" in rec["versions"] and "kinder-bench" in rec["versions"]
    # The simulator under the env is recorded too (pymunk comes with kinder-garden2d).
    assert rec["versions"]["pymunk"] == metadata.version("pymunk")
    # The agent's CPU time and the machine's load say how busy the machine was.
    assert rec["inference_cpu_time"] >= 0.0
    assert rec["load_avg"] is None or rec["load_avg"] >= 0.0
    config = json.loads((tmp_path / CONFIG_FILE).read_text())
    assert {r["agent"] for r in config["runs"]} == {"random", "mpc"}
    assert config["imports"] == list(IMPORTS)
    assert "versions" in config


def test_rerun_skips_finished_episodes(toy_id: str, tmp_path: Path) -> None:
    first = _bench(_runs(toy_id), tmp_path)
    again = _bench(_runs(toy_id), tmp_path)
    assert (first.num_ran, again.num_ran, again.num_skipped) == (12, 0, 12)
    more = _bench(_runs(toy_id, seeds=(0, 1, 2)), tmp_path)  # one more seed: only it runs
    assert more.num_ran == 6
    assert len(load_records(tmp_path)) == 18


def test_resume_after_interrupt_loses_nothing_and_repeats_nothing(
    toy_id: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs = [RunConfig(toy_id, "kinder_bench_toy:InterruptingAgent", {}, (0, 1), 3)]
    flag = tmp_path / "interrupt"
    flag.touch()
    monkeypatch.setenv("KINDER_BENCH_TEST_INTERRUPT", str(flag))
    with pytest.raises(KeyboardInterrupt):
        _bench(runs, tmp_path / "run")
    partial = load_records(tmp_path / "run")
    assert [(r["seed"], r["episode"]) for r in partial] == [(0, 0), (0, 1)]
    # A write cut short by the interruption leaves half a line; resuming must cope.
    with open(tmp_path / "run" / RESULTS_FILE, "a") as f:
        f.write('{"run_id": "trunc')
    flag.unlink()
    resumed = _bench(runs, tmp_path / "run")
    assert resumed.num_ran == 4 and resumed.num_skipped == 2
    keys = [(r["seed"], r["episode"]) for r in load_records(tmp_path / "run")]
    assert sorted(keys) == [(s, e) for s in (0, 1) for e in range(3)]  # each exactly once
    reference = _bench(runs, tmp_path / "reference")
    assert _strip(resumed.records) == _strip(reference.records)


def _start_slow_run(toy_id: str, run_dir: Path, episodes: int) -> subprocess.Popen[bytes]:
    """`kinder bench run` of the slow toy agent (2 seeds, 2 pool workers) in its own session."""
    cmd = [
        sys.executable, "-m", "kinder_bench", "bench", "run", "--env", toy_id,
        "--agent", "kinder_bench_toy:SlowAgent", "--seeds", "0-1", "--episodes", str(episodes),
        "--out", str(run_dir), "--workers", "2", "--no-progress", "--no-report",
        "--import", "kinder_bench_toy",
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.Popen(
        cmd, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )


def _wait_for_records(proc: subprocess.Popen[bytes], run_dir: Path, count: int) -> None:
    """Until the run has written ``count`` records (or ended)."""
    results = run_dir / RESULTS_FILE
    while proc.poll() is None and (not results.exists() or results.read_text().count("\n") < count):
        time.sleep(0.05)


def test_resume_after_killing_the_whole_process_group(toy_id: str, tmp_path: Path) -> None:
    # The hardest interruption: SIGKILL to the CLI and its pool workers in the middle of a run.
    run_dir = tmp_path / "run"
    proc = _start_slow_run(toy_id, run_dir, 6)
    try:
        _wait_for_records(proc, run_dir, 3)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read() if proc.stderr else ""
    before = load_records(run_dir)
    assert 3 <= len(before) < 12
    runs = [RunConfig(toy_id, "kinder_bench_toy:SlowAgent", {}, (0, 1), 6)]
    resumed = _bench(runs, run_dir, executor="process", workers=2)
    assert resumed.num_ran == 12 - len(before)
    keys = [(r["seed"], r["episode"]) for r in load_records(run_dir)]
    assert sorted(keys) == [(s, e) for s in (0, 1) for e in range(6)]


def _alive_children(parent: int, marker: str) -> list[int]:
    """Live (not zombie) processes whose parent is ``parent`` and whose command line has
    ``marker``, from /proc."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if int(ppid) == parent and state != "Z" and marker in cmdline:
            found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a Linux parent-death signal")
def test_killing_the_run_alone_ends_its_pool_workers(toy_id: str, tmp_path: Path) -> None:
    # `kill <pid>` of a run (not of its process group) must not leave its workers planning on.
    run_dir = tmp_path / "run"
    proc = _start_slow_run(toy_id, run_dir, 20)
    try:
        _wait_for_records(proc, run_dir, 1)
        workers = _alive_children(proc.pid, "--multiprocessing-fork")
        assert proc.poll() is None and len(workers) == 2, workers
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 20.0
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(_alive(w) for w in workers)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_agent_crash_is_recorded_as_a_failure(toy_id: str, tmp_path: Path) -> None:
    runs = [RunConfig(toy_id, "kinder_bench_toy:CrashingAgent", {}, (0,), 6)]
    out = _bench(runs, tmp_path)
    crashed = [r for r in out.records if r["error"]]
    assert len(out.records) == 6
    assert crashed and len(crashed) < 6
    for r in crashed:
        assert r["env_seed"] % 2 == 1
        assert r["success"] is False and r["steps"] == 2 and r["error_in"] == "agent"
        assert r["error"] == "ValueError: boom" and "boom" in r["traceback"]
        # The time of the call that raised is counted (a sleep lasts at least its duration).
        assert r["inference_time"] >= CRASH_THINK
        # A sleeping agent spends wall-clock time, not CPU time.
        assert r["inference_cpu_time"] < r["inference_time"]


def test_unknown_env_and_agent_fail_before_running(toy_id: str, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="BenchReach"):
        _bench([RunConfig("kinder/BenchRaech-v0")], tmp_path)
    with pytest.raises(ValueError, match="Unknown agent"):
        _bench([RunConfig(toy_id, "nope")], tmp_path)
    assert not (tmp_path / RESULTS_FILE).exists()


def test_process_pool_equals_inline(toy_id: str, tmp_path: Path) -> None:
    inline = _bench(_runs(toy_id), tmp_path / "inline")
    pool = _bench(_runs(toy_id), tmp_path / "pool", executor="process", workers=2)
    assert _strip(pool.records) == _strip(inline.records)


def test_ray_equals_inline(toy_id: str, tmp_path: Path) -> None:
    pytest.importorskip("ray")
    inline = _bench(_runs(toy_id), tmp_path / "inline")
    ray_out = _bench(_runs(toy_id), tmp_path / "ray", executor="ray", workers=2)
    assert _strip(ray_out.records) == _strip(inline.records)


def test_recording_writes_gifs(toy_id: str, tmp_path: Path) -> None:
    import imageio.v3 as iio

    runs = [RunConfig(toy_id, "mpc", {"horizon": 15}, (0, 1), 2)]
    out = _bench(runs, tmp_path, record="gif", record_episodes=1)
    videos = [r["video"] for r in out.records if r["video"]]
    assert len(videos) == 2  # the first episode of each seed
    rec = next(r for r in out.records if r["video"])
    frames = iio.imread(rec["video"])
    # GIF writers merge identical consecutive frames, so there are at most steps + 1 of them.
    assert 2 <= frames.shape[0] <= rec["steps"] + 1
    assert frames.shape[1:3] == (32, 32)


def test_append_record_writes_whole_lines(tmp_path: Path) -> None:
    path = tmp_path / RESULTS_FILE
    for i in range(3):
        append_record(path, {"i": i, "x": [1.5, None]})
    assert path.read_text().count("\n") == 3
    assert [r["i"] for r in load_records(path)] == [0, 1, 2]
    with pytest.raises(ValueError):
        append_record(path, {"bad": float("nan")})  # never writes invalid JSON
    assert len(load_records(path)) == 3


def test_default_step_budget_follows_the_paper(toy_id: str) -> None:
    from kinder_bench.evaluation.envs import default_max_steps
    from kinder_bench.evaluation.runner import resolve_run

    assert resolve_run(RunConfig("Motion2D-p0")).max_steps == 200  # the paper's budget
    registered = default_max_steps("kinder/Motion2D-p1-v0")
    assert resolve_run(RunConfig("Motion2D-p1")).max_steps == registered
    assert resolve_run(RunConfig(toy_id, max_steps=7)).max_steps == 7


def test_a_run_under_noise_is_seeded_recorded_and_keeps_noise_free_ids(
    toy_id: str, tmp_path: Path
) -> None:
    clean = RunConfig(toy_id, "mpc", {"horizon": 15, "num_rollouts": 5}, (0,), 3)
    noisy = dataclasses.replace(clean, obs_noise=0.05, action_noise=0.02)
    a = _bench([clean, noisy], tmp_path / "a")
    b = _bench([noisy], tmp_path / "b")
    by_noise = {(r["obs_noise"], r["action_noise"]): r for r in a.records}
    assert set(by_noise) == {(0.0, 0.0), (0.05, 0.02)}
    assert by_noise[(0.0, 0.0)]["run_id"] != by_noise[(0.05, 0.02)]["run_id"]
    # The same seed gives the same noisy episode in another run directory (another process).
    assert _strip(b.records) == _strip([r for r in a.records if r["obs_noise"]])
    # The noise changes the episodes (same instances, different trajectories).
    clean_rewards = [r["reward"] for r in a.records if not r["obs_noise"]]
    assert clean_rewards != [r["reward"] for r in b.records]
    # The summary rows say so, and the report names the run by its noise.
    row = next(r for r in results_from_csv(tmp_path / "a" / CSV_FILE) if r.obs_noise)
    assert (row.obs_noise, row.action_noise) == (0.05, 0.02)
    assert {"obs noise 0.05", "action noise 0.02"} <= set(protocol_deviations(row))
    # Noise-free runs keep the ids they had before noise existed (BP at the paper's settings
    # on Motion2D-p0, as in benchmarks/results/bp_conforming_summary.csv).
    paper_bp = {
        k: v
        for k, v in paper_settings("bilevel_planning", "kinder/Motion2D-p0-v0").items()
        if k not in ("max_steps", "training")
    }
    assert resolve_run(RunConfig("Motion2D-p0", "bilevel_planning", paper_bp)).run_id == (
        "3182dd1fd35c"
    )


@pytest.mark.parametrize("std", [-0.1, float("nan"), float("inf")])
def test_bad_noise_is_refused_before_running(toy_id: str, tmp_path: Path, std: float) -> None:
    with pytest.raises(ValueError, match=r"obs_noise .*expected a finite number >= 0"):
        _bench([RunConfig(toy_id, "random", {}, (0,), 1, obs_noise=std)], tmp_path)
    assert not (tmp_path / RESULTS_FILE).exists()
