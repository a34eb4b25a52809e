"""The evaluation runner: a standard way to run any agent on any env and keep every result.

A run is ``(env id, agent, agent arguments, seeds, episodes per seed, max steps)``, optionally with
Gaussian observation and action noise on the env (:class:`RunConfig`; the paper's robustness
experiment). Episode ``i`` of seed ``s`` resets the env with the ``i``-th draw of
``numpy.random.default_rng(s).integers(0, 2**31 - 1)``, so the episode instances depend only on
the seed and every method sees the same ones. The agent of that episode is seeded from
``SeedSequence([s, i])``; an episode therefore depends on nothing else, which makes results
independent of the executor, of the order episodes finish in, and of resuming.

Every finished episode is appended as one JSON line to ``<run_dir>/results.jsonl`` (see the README
for the schema) and ``<run_dir>/config.json`` records the runs and the package versions. When a
run ends, its summary rows (one per env × method, with the command and the settings that decide
whether it is at the paper's protocol) are written to ``<run_dir>/summary.csv``
(:func:`write_summary`), the file ``benchmarks/results/*_summary.csv`` keeps for good. Running
again with the same run directory skips the episodes already there. An exception in an episode
(agent or env) is recorded as a failed episode with its error.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import importlib
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import gymnasium
import numpy as np

from kinder_bench.agents import (
    Agent,
    agent_class,
    args_to_dict,
    identity_args,
    make_agent,
    make_args,
)
from kinder_bench.evaluation.envs import default_max_steps, make_env, resolve_env_id, short_id
from kinder_bench.evaluation.executors import execute
from kinder_bench.evaluation.metrics import aggregate
from kinder_bench.evaluation.protocol import PAPER_EPISODES, PAPER_MAX_STEPS, PAPER_SEEDS
from kinder_bench.evaluation.recording import VIDEO_FORMATS, write_video
from kinder_bench.evaluation.results import (
    CONFIG_FILE,
    RESULTS_FILE,
    SCHEMA_VERSION,
    append_record,
    environment_info,
    invocation,
    load_records,
    package_versions,
    write_json,
    write_text,
)
from kinder_bench.evaluation.subtasks import SubtaskTracker, tracker_for
from kinder_bench.evaluation.summary import CSV_FILE, csv_table, dedupe, run_commands, run_trainings
from kinder_core import NoisyAction, NoisyObservation, ObjectCentricEnv

#: Fields that are wall-clock measurements or describe the machine while the episode ran
#: (everything else in a record is deterministic).
TIMING_FIELDS = ("inference_time", "inference_cpu_time", "load_avg", "env_time", "finished_at")


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """One evaluation run: an agent with fixed arguments on one env, over several seeds."""

    env_id: str
    """A registered id (``kinder/Motion2D-p0-v0``; ``Motion2D-p0`` is accepted)."""
    agent: str = "random"
    """An agent name (``random``, ``mpc``, ...) or a ``module:Class`` entry point."""
    agent_args: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    """Overrides of the agent's ``Args`` defaults."""
    seeds: tuple[int, ...] = PAPER_SEEDS
    """Run seeds; each fixes its episodes' instances (the paper: 5 seeds)."""
    episodes: int = PAPER_EPISODES
    """Episodes per seed (the paper: 50)."""
    max_steps: int | None = None
    """Step budget per episode; None: the paper's budget for its eight benchmark envs
    (:data:`~kinder_bench.evaluation.protocol.PAPER_MAX_STEPS`), else the env's
    ``max_episode_steps``."""
    label: str | None = None
    """The method's name in reports; None: the agent name."""
    training: str = ""
    """The training budget of a learned agent's checkpoints, in words (``1M env steps``),
    recorded in ``config.json`` and the summary rows (a learned agent fills a paper cell only
    with the paper's budget; :mod:`kinder_bench.reporting.paper`); empty: not recorded."""
    obs_noise: float = 0.0
    """Std of the Gaussian noise added to every observation entry
    (:class:`kinder_core.NoisyObservation`, clipped to the observation bounds); 0: none. A run
    with noise is a variant (the paper's noise table), never a paper cell."""
    action_noise: float = 0.0
    """Std of the Gaussian noise added to every action entry before the env steps
    (:class:`kinder_core.NoisyAction`, clipped to the action bounds); 0: none."""


@dataclasses.dataclass(frozen=True)
class EpisodeTask:
    """Everything one episode needs (picklable: it travels to worker processes)."""

    run_id: str
    env_id: str
    agent: str
    agent_args: dict[str, Any]
    label: str
    max_steps: int
    seed: int
    episode: int
    env_seed: int
    agent_seed: int
    video_path: str | None = None
    imports: tuple[str, ...] = ()
    video_stride: int = 1
    """Record every this many steps (and the first and last frame)."""
    obs_noise: float = 0.0
    action_noise: float = 0.0

    @property
    def key(self) -> tuple[str, int, int]:
        return (self.run_id, self.seed, self.episode)


@dataclasses.dataclass
class BenchOutcome:
    """What :func:`run_benchmark` did."""

    run_dir: Path
    records: list[dict[str, Any]]
    """Every record of the run directory's runs (old and new), sorted."""
    num_ran: int
    num_skipped: int


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """The env seeds of a run seed's episodes (one draw each from ``default_rng(seed)``)."""
    rng = np.random.default_rng(seed)
    return [int(rng.integers(0, 2**31 - 1)) for _ in range(episodes)]


def agent_seed(seed: int, episode: int) -> int:
    """The agent's seed in episode ``episode`` of run seed ``seed``."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


def run_id(
    env_id: str,
    agent: str,
    agent_args: Mapping[str, Any],
    max_steps: int,
    obs_noise: float = 0.0,
    action_noise: float = 0.0,
) -> str:
    """A short stable hash of what determines a run's results (not its seeds or label). Noise
    enters only when there is some, so noise-free runs keep the ids they always had."""
    parts: list[Any] = [env_id, agent, dict(agent_args), max_steps]
    if obs_noise or action_noise:
        parts.append({"obs_noise": obs_noise, "action_noise": action_noise})
    blob = json.dumps(parts, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def check_noise(name: str, std: float) -> float:
    """A noise std as a float, or a ValueError naming it and what is expected."""
    try:
        value = float(std)
    except (TypeError, ValueError):
        raise ValueError(f"{name} {std!r}: expected a number >= 0 (a Gaussian std)") from None
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} {std!r}: expected a finite number >= 0 (a Gaussian std)")
    return value


def import_modules(modules: Sequence[str]) -> None:
    """Import modules that register extra envs or agents (``--import``)."""
    for m in modules:
        importlib.import_module(m)


@dataclasses.dataclass(frozen=True)
class ResolvedRun:
    """A :class:`RunConfig` with the id resolved and every default filled in."""

    run_id: str
    env_id: str
    agent: str
    agent_args: dict[str, Any]
    label: str
    seeds: tuple[int, ...]
    episodes: int
    max_steps: int
    training: str = ""
    obs_noise: float = 0.0
    action_noise: float = 0.0


def resolve_run(config: RunConfig) -> ResolvedRun:
    """Resolve the env id, the agent's full arguments and the step budget (errors early)."""
    env_id = resolve_env_id(config.env_id)
    cls = agent_class(config.agent)
    made = make_args(cls, config.agent_args)
    args = args_to_dict(made)
    max_steps = config.max_steps
    if max_steps is None:
        max_steps = PAPER_MAX_STEPS.get(env_id) or default_max_steps(env_id)
    if max_steps <= 0 or config.episodes <= 0 or not config.seeds:
        raise ValueError(
            f"A run needs max_steps > 0, episodes > 0 and at least one seed; got {config}"
        )
    obs_noise = check_noise("obs_noise", config.obs_noise)
    action_noise = check_noise("action_noise", config.action_noise)
    return ResolvedRun(
        run_id=run_id(
            env_id, config.agent, identity_args(made), max_steps, obs_noise, action_noise
        ),
        env_id=env_id,
        agent=config.agent,
        agent_args=args,
        label=config.label or config.agent,
        seeds=tuple(int(s) for s in config.seeds),
        episodes=int(config.episodes),
        max_steps=int(max_steps),
        training=config.training.strip(),
        obs_noise=obs_noise,
        action_noise=action_noise,
    )


def make_tasks(
    run: ResolvedRun,
    video_dir: Path | None = None,
    record: str | None = None,
    record_episodes: int | None = None,
    imports: tuple[str, ...] = (),
    record_frames: int | None = None,
) -> list[EpisodeTask]:
    """The episodes of a run (recording the first ``record_episodes`` of each seed, or all;
    with ``record_frames``, every ``ceil(max_steps / record_frames)``-th step)."""
    stride = 1 if record_frames is None else max(1, math.ceil(run.max_steps / record_frames))
    tasks = []
    for seed in run.seeds:
        for i, env_seed in enumerate(episode_seeds(seed, run.episodes)):
            video = None
            wanted = record_episodes is None or i < record_episodes
            if record and video_dir is not None and wanted:
                stem = f"{short_id(run.env_id)}__{run.label}__{run.run_id[:6]}"
                video = str(video_dir / f"{stem}__s{seed}_e{i}.{record}")
            tasks.append(
                EpisodeTask(
                    run_id=run.run_id,
                    env_id=run.env_id,
                    agent=run.agent,
                    agent_args=run.agent_args,
                    label=run.label,
                    max_steps=run.max_steps,
                    seed=seed,
                    episode=i,
                    env_seed=env_seed,
                    agent_seed=agent_seed(seed, i),
                    video_path=video,
                    imports=imports,
                    video_stride=stride,
                    obs_noise=run.obs_noise,
                    action_noise=run.action_noise,
                )
            )
    return tasks


# Envs are reused across the episodes a process runs (``reset(seed=...)`` fully re-seeds them).
_ENV_CACHE: dict[tuple[str, int, float, float], gymnasium.Env[Any, Any]] = {}


def _env_for(
    env_id: str, max_steps: int, obs_noise: float = 0.0, action_noise: float = 0.0
) -> gymnasium.Env[Any, Any]:
    """The episode's env: the id's Box view, inside the noise wrappers when the run has noise
    (their RNGs are seeded by each ``reset(seed=...)``, so an episode's noise is fixed too)."""
    key = (env_id, max_steps, obs_noise, action_noise)
    if key not in _ENV_CACHE:
        env = make_env(env_id, max_steps=max_steps, render_mode="rgb_array")
        if obs_noise:
            env = NoisyObservation(env, obs_noise)
        if action_noise:
            env = NoisyAction(env, action_noise)
        _ENV_CACHE[key] = env
    return _ENV_CACHE[key]


def with_run_seed(agent_args: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """Agent arguments with ``{seed}`` in string values replaced by the run seed.

    This lets one run evaluate per-seed trained policies (``checkpoint=runs/ppo/seed{seed}``):
    the run id hashes the template, so every seed's results form one method in the report.
    """
    return {
        k: v.replace("{seed}", str(seed)) if isinstance(v, str) else v
        for k, v in agent_args.items()
    }


def run_episode(task: EpisodeTask) -> dict[str, Any]:
    """Run one episode and return its record; never raises for errors inside the episode."""
    record: dict[str, Any] = {
        "schema": SCHEMA_VERSION,
        "run_id": task.run_id,
        "env_id": task.env_id,
        "agent": task.agent,
        "agent_args": task.agent_args,
        "label": task.label,
        "max_steps": task.max_steps,
        "seed": task.seed,
        "episode": task.episode,
        "env_seed": task.env_seed,
        "agent_seed": task.agent_seed,
        "obs_noise": task.obs_noise,
        "action_noise": task.action_noise,
    }
    success, steps, total_reward = False, 0, 0.0
    inference_time = inference_cpu = env_time = 0.0
    error: str | None = None
    error_in: str | None = None
    trace: str | None = None
    frames: list[Any] | None = [] if task.video_path else None
    phase = "setup"
    agent: Agent[Any] | None = None
    subtasks: SubtaskTracker | None = None
    try:
        import_modules(task.imports)
        env = _env_for(task.env_id, task.max_steps, task.obs_noise, task.action_noise)
        # Milestones are tested on the true state, beneath any noise wrapper.
        oc_env = cast(ObjectCentricEnv, env.unwrapped)
        subtasks = tracker_for(task.env_id, oc_env)
        phase = "agent"
        agent_args = with_run_seed(task.agent_args, task.seed)
        agent = make_agent(task.agent, env, agent_args, seed=task.agent_seed)
        phase = "env"
        t0 = time.perf_counter()
        obs, info = env.reset(seed=task.env_seed)
        env_time += time.perf_counter() - t0
        if subtasks is not None:
            subtasks.observe(oc_env.get_state(), steps)
        if frames is not None:
            frames.append(env.render())
        phase = "agent"
        # Agent time is counted in `finally`, so a call that raises (e.g. a planner giving up
        # after its budget) still reports the time it spent.
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            agent.reset(obs, info)
        finally:
            inference_time += time.perf_counter() - t0
            inference_cpu += time.process_time() - c0
        while steps < task.max_steps:
            phase = "agent"
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                action = agent.act(obs)
            finally:
                inference_time += time.perf_counter() - t0
                inference_cpu += time.process_time() - c0
            phase = "env"
            t0 = time.perf_counter()
            obs, r, terminated, truncated, info = env.step(action)
            env_time += time.perf_counter() - t0
            steps += 1
            total_reward += float(r)
            if subtasks is not None:
                subtasks.observe(oc_env.get_state(), steps)
            last = terminated or truncated or steps >= task.max_steps
            if frames is not None and (steps % task.video_stride == 0 or last):
                frames.append(env.render())
            if terminated:
                success = True
                break
            if truncated:
                break
    except Exception as e:
        error = f"{type(e).__name__}: {e}"
        error_in = phase
        trace = traceback.format_exc()[-4000:]
    if agent is not None:
        try:
            agent_info = agent.episode_info()
            if agent_info:
                json.dumps(agent_info, allow_nan=False)  # must survive the JSON line
                record["agent_info"] = agent_info
        except Exception as e:  # the agent's report must not lose the episode's result
            record["agent_info_error"] = f"{type(e).__name__}: {e}"
    if subtasks is not None:
        record["subtasks"] = subtasks.result()
    reward: float | None = total_reward
    if not np.isfinite(total_reward):  # would not survive JSON, and is an env bug anyway
        success, reward = False, None
        error, error_in = f"ValueError: the env's rewards sum to {total_reward}", "env"
    video = None
    if frames and task.video_path:
        try:
            video = str(write_video(task.video_path, frames))
        except Exception as e:  # a failed video must not lose the episode's result
            record["video_error"] = f"{type(e).__name__}: {e}"
    record.update(
        success=success,
        reward=reward,
        steps=steps,
        inference_time=inference_time,
        # The agent's CPU time beside its wall-clock time, and the machine's load: a planner
        # with a wall-clock budget (BP's planning_timeout) solves less on a busy machine, and
        # these say how busy it was.
        inference_cpu_time=inference_cpu,
        load_avg=_load_avg(),
        env_time=env_time,
        error=error,
        error_in=error_in,
        traceback=trace,
        video=video,
        versions=package_versions(),
        finished_at=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    )
    return record


def _load_avg() -> float | None:
    """The machine's 1-minute load average (runnable processes; None where the OS has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def sort_key(record: Mapping[str, Any]) -> tuple[Any, ...]:
    """Records in a stable order: by env, label, run, seed, episode."""
    return (record["env_id"], record["label"], record["run_id"], record["seed"], record["episode"])


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc="episodes",
        unit="ep",
        disable=not enabled or total == 0,
        file=sys.stderr,
        dynamic_ncols=True,
    )


def run_benchmark(
    runs: Sequence[RunConfig],
    run_dir: Path | str,
    executor: str = "process",
    workers: int | None = None,
    address: str | None = None,
    record: str | None = None,
    record_episodes: int | None = 1,
    imports: Sequence[str] = (),
    progress: bool = True,
    command: str | None = None,
    record_frames: int | None = None,
) -> BenchOutcome:
    """Run (or resume) every episode of ``runs``, appending results to ``run_dir``.

    Args:
        runs: The runs; their episodes all go to one executor.
        run_dir: Where ``results.jsonl``, ``config.json`` and ``videos/`` live; episodes already
            in ``results.jsonl`` are skipped.
        executor: ``"process"`` (a local process pool), ``"inline"`` or ``"ray"``.
        workers: Processes (or local Ray CPUs); default: the CPUs available.
        address: A Ray cluster address (``--executor ray``); default: start a local instance.
        record: ``"gif"`` or ``"mp4"`` to record episodes to ``run_dir/videos``.
        record_episodes: Record the first this many episodes of each seed (None: all).
        record_frames: Record about this many frames of an episode at most: every
            ``ceil(max_steps / record_frames)``-th step, and the first and last frame (long
            episodes make shorter, faster videos and cost less rendering). None: every step.
        imports: Modules imported first, here and in every worker (to register envs or agents).
        progress: Show a progress bar.
        command: The command to record in ``config.json`` for these runs (reports show it);
            default: this process's command line
            (:func:`~kinder_bench.evaluation.results.invocation`).
    """
    if record_frames is not None and record_frames < 1:
        raise ValueError(f"record_frames must be >= 1 or None, got {record_frames}")
    if record is not None and record not in VIDEO_FORMATS:
        raise ValueError(f"record must be one of {VIDEO_FORMATS} or None, got {record!r}")
    run_dir = Path(run_dir)
    imports = tuple(imports)
    import_modules(imports)
    resolved = [resolve_run(c) for c in runs]
    run_dir.mkdir(parents=True, exist_ok=True)
    results_path = run_dir / RESULTS_FILE
    existing = load_records(results_path)
    done = {(r["run_id"], r["seed"], r["episode"]) for r in existing}
    tasks = [
        t
        for run in resolved
        for t in make_tasks(
            run, run_dir / "videos", record, record_episodes, imports, record_frames
        )
    ]
    pending = [t for t in tasks if t.key not in done]
    _write_config(run_dir, resolved, imports, command or invocation())

    bar = _progress(len(pending), progress)
    successes = 0
    new = []
    try:
        for rec in execute(run_episode, pending, executor, workers, address):
            append_record(results_path, rec)
            new.append(rec)
            successes += bool(rec["success"])
            bar.update(1)
            bar.set_postfix(success=f"{successes}/{len(new)}", refresh=False)
    finally:
        bar.close()
    write_summary(run_dir)
    wanted = {t.key for t in tasks}
    records = [r for r in existing + new if (r["run_id"], r["seed"], r["episode"]) in wanted]
    return BenchOutcome(
        run_dir=run_dir,
        records=sorted(records, key=sort_key),
        num_ran=len(new),
        num_skipped=len(tasks) - len(pending),
    )


def write_summary(run_dir: Path | str) -> Path | None:
    """Write ``summary.csv`` (the report's summary rows, with each run's command) for every
    episode of a run directory; None when it has no episodes yet."""
    run_dir = Path(run_dir)
    records = dedupe(load_records(run_dir / RESULTS_FILE))
    if not records:
        return None
    text = csv_table(aggregate(records), run_commands([run_dir]), run_trainings([run_dir]))
    return write_text(run_dir / CSV_FILE, text)


def _write_config(
    run_dir: Path, runs: Sequence[ResolvedRun], imports: tuple[str, ...], command: str
) -> None:
    path = run_dir / CONFIG_FILE
    merged: dict[str, Any] = {}
    if path.exists():
        old = json.loads(path.read_text())
        merged = {r["run_id"]: r for r in old.get("runs", [])}
    for run in runs:
        entry = dataclasses.asdict(run)
        entry["command"] = command  # the latest command that ran (or resumed) this run
        if run.run_id in merged:  # a rerun may add seeds or episodes to a run
            old_seeds = merged[run.run_id]["seeds"]
            entry["seeds"] = sorted({*old_seeds, *run.seeds})
            entry["episodes"] = max(merged[run.run_id]["episodes"], run.episodes)
        merged[run.run_id] = entry
    write_json(
        path,
        {
            "schema": SCHEMA_VERSION,
            "runs": list(merged.values()),
            "imports": list(imports),
            **environment_info(),
        },
    )
