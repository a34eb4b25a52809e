"""Collecting demonstrations with any agent, in parallel, resumably; building datasets from them.

A collection is ``(env id, agent, agent arguments, seed, wanted successes, step budget)``
(:class:`CollectConfig`). Attempt ``i`` resets the env with the ``i``-th draw of
``default_rng(seed).integers(0, 2**31 - 1)`` and seeds the agent from ``SeedSequence([seed, i])``
(the runner's convention, :mod:`kinder_bench.evaluation.runner`), so every attempt depends only on
its index. Attempts run through the runner's executors
(:func:`kinder_bench.evaluation.executors.execute`) in batches sized from the success rate so far,
until ``episodes`` attempts succeeded or ``max_attempts`` were made. The kept episodes are **the
first ``episodes`` successes by attempt index**, so the result does not depend on the executor, the
number of workers or the finishing order.

Files in the collection directory:

* ``attempts.jsonl``: one line per finished attempt (index, env seed, success, steps, wall-clock
  seconds, error); appended atomically (:func:`kinder_bench.evaluation.results.append_record`).
  Running the same command again skips the attempts listed there (resume).
* ``episodes/attempt-<index>.npz``: each successful episode's :class:`EpisodeRecord`, written
  atomically (:mod:`kinder_gym.demos.store`), with skill labels for agents that expose
  ``last_skill`` (the bilevel planner: :class:`~kinder_bench.baselines.bilevel_planning.
  ExecutedSkill`).
* ``collect.json``: the configuration and the simulators' versions (a rerun with a different
  configuration, or with other simulator versions, whose transitions differ, is refused).

:func:`build_dataset` then writes the kept episodes, in attempt order, into a LeRobotDataset v3
(:class:`~kinder_gym.demos.lerobot_format.DemoWriter`), rendering the images from the recorded
states, so collection itself never renders. An interrupted build (Ctrl-C, an exception) still
closes the writer, so the dataset stays valid and the next build appends the missing episodes; a
build killed hard leaves an unreadable dataset, which the next build detects and rebuilds from the
episode files.

**Determinism caveat.** An attempt is deterministic except through wall-clock limits inside the
agent: the bilevel planner's ``planning_timeout``. The dataset specs
(:mod:`kinder_bench.demos.specs`) raise it far above the time a plan takes, so that the counted
limits (abstract plans, samples per step) decide, not the machine's speed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import sys
import time
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium

from kinder_bench.agents import agent_class, args_to_dict, make_agent, make_args
from kinder_bench.evaluation.envs import default_max_steps, make_env, resolve_env_id
from kinder_bench.evaluation.executors import execute
from kinder_bench.evaluation.protocol import PAPER_MAX_STEPS
from kinder_bench.evaluation.results import append_record, load_records, write_json
from kinder_bench.evaluation.runner import agent_seed, episode_seeds, import_modules
from kinder_gym.demos.record import SOURCES, EpisodeRecorder, package_versions
from kinder_gym.demos.store import load_record, save_record

ATTEMPTS_FILE = "attempts.jsonl"
EPISODES_DIR = "episodes"
CONFIG_FILE = "collect.json"
#: The simulators whose versions decide what a collected episode is: a collection resumes only on
#: the versions it started with (``collect.json`` records them).
SIMULATORS = ("pymunk", "pybullet", "mujoco")
#: Attempts one collection may make per wanted episode by default.
DEFAULT_ATTEMPTS_PER_EPISODE = 10


#: The default collection seed. Collection draws env instances exactly as the runner does
#: (``episode_seeds(seed, n)``), so a collection seed among the evaluation seeds (0-4) would train
#: on the very instances the benchmark evaluates; 1000 draws a disjoint set (checked by
#: :func:`evaluation_overlap` and the tests).
COLLECTION_SEED = 1000
#: The run seeds the benchmark evaluates with (``kinder bench run --seeds 0-4``).
EVALUATION_SEEDS = range(5)
#: The most episodes per evaluation seed the overlap check covers (the paper's 50).
EVALUATION_EPISODES = 50


def evaluation_overlap(seed: int, attempts: int) -> set[int]:
    """The env seeds that a collection with ``seed`` and ``attempts`` shares with evaluation.

    Evaluation covers :data:`EVALUATION_SEEDS` × :data:`EVALUATION_EPISODES`; an empty set means
    no training instance is an evaluation instance.
    """
    evaluated = {s for run in EVALUATION_SEEDS for s in episode_seeds(run, EVALUATION_EPISODES)}
    return evaluated.intersection(episode_seeds(seed, attempts))


@dataclasses.dataclass(frozen=True)
class CollectConfig:
    """What to collect."""

    env_id: str
    """A registered id (``Motion2D-p0`` is accepted)."""
    agent: str = "bilevel_planning"
    """The agent that produces the demonstrations (``bilevel_planning``, ``mpc``, a scripted
    ``module:Class`` agent, ...)."""
    agent_args: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    """Overrides of the agent's ``Args`` defaults."""
    episodes: int = 100
    """Successful episodes wanted."""
    seed: int = COLLECTION_SEED
    """The collection seed (fixes every attempt's env and agent seeds); keep it outside the
    evaluation seeds (see :data:`COLLECTION_SEED`)."""
    max_steps: int | None = None
    """Step budget per attempt; None: the paper's budget for its eight envs, else the env's."""
    max_attempts: int | None = None
    """Stop after this many attempts; None: ``10 × episodes``."""
    source: str | None = None
    """The records' source; None: ``bilevel_planning`` / ``mpc`` for those agents, else
    ``scripted``."""


@dataclasses.dataclass(frozen=True)
class ResolvedCollect:
    env_id: str
    agent: str
    agent_args: dict[str, Any]
    episodes: int
    seed: int
    max_steps: int
    max_attempts: int
    source: str

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def resolve_collect(config: CollectConfig) -> ResolvedCollect:
    """Fill in the defaults and validate (errors early, in the parent process)."""
    env_id = resolve_env_id(config.env_id)
    cls = agent_class(config.agent)
    args = args_to_dict(make_args(cls, config.agent_args))
    max_steps = config.max_steps or PAPER_MAX_STEPS.get(env_id) or default_max_steps(env_id)
    source = config.source or (
        config.agent if config.agent in ("bilevel_planning", "mpc") else "scripted"
    )
    if source not in SOURCES:
        raise ValueError(f"source must be one of {SOURCES}, got {source!r}")
    if config.episodes <= 0 or max_steps <= 0:
        raise ValueError(f"episodes and max_steps must be > 0, got {config}")
    max_attempts = config.max_attempts or DEFAULT_ATTEMPTS_PER_EPISODE * config.episodes
    return ResolvedCollect(
        env_id=env_id,
        agent=config.agent,
        agent_args=args,
        episodes=int(config.episodes),
        seed=int(config.seed),
        max_steps=int(max_steps),
        max_attempts=int(max_attempts),
        source=source,
    )


@dataclasses.dataclass(frozen=True)
class AttemptTask:
    """One attempt (picklable: it travels to worker processes)."""

    env_id: str
    agent: str
    agent_args: dict[str, Any]
    source: str
    max_steps: int
    index: int
    env_seed: int
    agent_seed: int
    out_dir: str
    imports: tuple[str, ...] = ()


def episode_path(out_dir: Path | str, index: int) -> Path:
    """Where attempt ``index``'s episode file goes."""
    return Path(out_dir) / EPISODES_DIR / f"attempt-{index:06d}.npz"


_ENVS: dict[tuple[str, int], gymnasium.Env[Any, Any]] = {}


def run_attempt(task: AttemptTask) -> dict[str, Any]:
    """Run one attempt; save the episode when it succeeds. Never raises for errors inside the
    episode (they are reported in the returned line)."""
    from kinder_gym.demos.lerobot_format import env_task

    start = time.perf_counter()
    line: dict[str, Any] = {
        "index": task.index,
        "env_seed": task.env_seed,
        "agent_seed": task.agent_seed,
        "success": False,
        "steps": 0,
        "error": None,
        "file": None,
    }
    try:
        import_modules(task.imports)
        key = (task.env_id, task.max_steps)
        if key not in _ENVS:
            _ENVS[key] = make_env(task.env_id, max_steps=task.max_steps)
        env = _ENVS[key]
        agent = make_agent(task.agent, env, task.agent_args, seed=task.agent_seed)
        recorder = EpisodeRecorder(env, task.env_id, task.source)
        obs = recorder.reset(task.env_seed)
        agent.reset(obs, recorder.reset_info)
        current: tuple[int, int] | None = None
        while not recorder.done:
            action = agent.act(obs)
            skill = getattr(agent, "last_skill", None)
            if skill is not None and (skill.plan, skill.index) != current:
                current = (skill.plan, skill.index)
                recorder.begin_skill(
                    skill.operator.parent.name,
                    [o.name for o in skill.operator.objects],
                    skill.params,
                )
            obs, _, _, _, _ = recorder.step(action)
        record = recorder.finish(
            task=env_task(env),
            metadata={
                "agent": task.agent,
                "agent_args": task.agent_args,
                "attempt": task.index,
                "agent_seed": task.agent_seed,
                "max_steps": task.max_steps,
            },
        )
        line["steps"] = record.num_steps
        line["success"] = record.success
        if record.success:
            line["file"] = save_record(episode_path(task.out_dir, task.index), record).name
    except Exception as e:
        line["error"] = f"{type(e).__name__}: {e}"
        line["traceback"] = traceback.format_exc()[-2000:]
    line["seconds"] = time.perf_counter() - start
    return line


@dataclasses.dataclass
class CollectOutcome:
    """What :func:`collect` left in the collection directory."""

    config: ResolvedCollect
    attempts: list[dict[str, Any]]
    """Every finished attempt, by index."""
    kept: list[dict[str, Any]]
    """The kept attempts: the first ``episodes`` successes by index."""
    ran: int
    """Attempts run by this call."""
    seconds: float
    """Wall-clock seconds of this call."""

    @property
    def complete(self) -> bool:
        return len(self.kept) >= self.config.episodes

    @property
    def attempted_for_kept(self) -> int:
        """Attempts up to and including the last kept one (the kept/attempted denominator)."""
        if not self.kept:
            return len(self.attempts)
        last = self.kept[-1]["index"]
        return sum(1 for a in self.attempts if a["index"] <= last)


def read_attempts(out_dir: Path | str) -> list[dict[str, Any]]:
    """The finished attempts of a collection directory, by index (one line per index)."""
    by_index = {int(a["index"]): a for a in load_records(Path(out_dir) / ATTEMPTS_FILE)}
    return [by_index[i] for i in sorted(by_index)]


def kept_attempts(attempts: Sequence[Mapping[str, Any]], episodes: int) -> list[dict[str, Any]]:
    """The first ``episodes`` successful attempts by index, counting only an unbroken prefix of
    indices (a success after a missing index is not kept until the gap is run)."""
    kept: list[dict[str, Any]] = []
    for expected, a in enumerate(attempts):
        if int(a["index"]) != expected or len(kept) >= episodes:
            break
        if a["success"]:
            kept.append(dict(a))
    return kept


def _check_config(out_dir: Path, config: ResolvedCollect) -> None:
    path = out_dir / CONFIG_FILE
    new = config.to_json()
    simulators = package_versions(SIMULATORS)
    if path.exists():
        old = json.loads(path.read_text())
        same = {k: old.get(k) for k in new if k not in ("episodes", "max_attempts")}
        if same != {k: v for k, v in new.items() if k not in ("episodes", "max_attempts")}:
            raise ValueError(
                f"{path}: this directory holds a different collection ({old}); use another "
                f"directory or the same configuration (only episodes/max_attempts may change)"
            )
        # A collection started before the versions were recorded cannot be checked.
        if old.get("simulators", simulators) != simulators:
            raise ValueError(
                f"{path}: this directory's episodes were collected with {old['simulators']}, "
                f"this environment has {simulators}, whose transitions differ; move the "
                f"directory aside (or use another) to collect again"
            )
    write_json(path, {**new, "simulators": simulators})


def _progress(total: int, enabled: bool, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit="ep",
        disable=not enabled,
        file=sys.stderr,
        dynamic_ncols=True,
    )


def collect(
    config: CollectConfig,
    out_dir: Path | str,
    executor: str = "process",
    workers: int | None = None,
    imports: Sequence[str] = (),
    progress: bool = True,
) -> CollectOutcome:
    """Collect (or resume collecting) until ``config.episodes`` successes are kept or
    ``max_attempts`` attempts were made (module docstring)."""
    started = time.perf_counter()
    imports = tuple(imports)
    import_modules(imports)
    resolved = resolve_collect(config)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _check_config(out, resolved)
    seeds = episode_seeds(resolved.seed, resolved.max_attempts)
    attempts = read_attempts(out)
    ran = 0
    bar = _progress(resolved.episodes, progress, f"collect {resolved.env_id}")
    bar.update(min(len(kept_attempts(attempts, resolved.episodes)), resolved.episodes))
    try:
        while True:
            kept = kept_attempts(attempts, resolved.episodes)
            done = {int(a["index"]) for a in attempts}
            needed = resolved.episodes - len(kept)
            if needed <= 0:
                break
            # Indices not yet run below the frontier (gaps of an interrupted run), then new ones.
            frontier = (max(done) + 1) if done else 0
            gaps = [i for i in range(frontier) if i not in done]
            successes = sum(1 for a in attempts if a["success"])
            rate = successes / len(attempts) if attempts else 1.0
            batch = max(1, math.ceil(needed / max(rate, 0.05)))
            fresh = list(range(frontier, min(frontier + batch, resolved.max_attempts)))
            indices = gaps or fresh  # fill the gaps first: they may already suffice
            if not indices:
                break  # the attempt budget is spent
            tasks = [
                AttemptTask(
                    env_id=resolved.env_id,
                    agent=resolved.agent,
                    agent_args=resolved.agent_args,
                    source=resolved.source,
                    max_steps=resolved.max_steps,
                    index=i,
                    env_seed=seeds[i],
                    agent_seed=agent_seed(resolved.seed, i),
                    out_dir=str(out),
                    imports=imports,
                )
                for i in indices
            ]
            # The batch is sized from the success rate so far; once it has given enough kept
            # episodes the rest is cancelled (a process pool lets its running attempts finish
            # unrecorded: indices past the last kept one are never kept).
            results = execute(run_attempt, tasks, executor, workers)
            try:
                for line in results:
                    append_record(out / ATTEMPTS_FILE, line)
                    attempts.append(line)
                    ran += 1
                    attempts.sort(key=lambda a: int(a["index"]))
                    now_kept = len(kept_attempts(attempts, resolved.episodes))
                    bar.update(max(0, min(now_kept, resolved.episodes) - bar.n))
                    tried = len(attempts)
                    ok = sum(1 for a in attempts if a["success"])
                    bar.set_postfix(kept=f"{ok}/{tried}", refresh=False)
                    if now_kept >= resolved.episodes:
                        break
            finally:
                close = getattr(results, "close", None)  # a generator: ends the executor now
                if close is not None:
                    close()
    finally:
        bar.close()
    attempts = read_attempts(out)
    return CollectOutcome(
        config=resolved,
        attempts=attempts,
        kept=kept_attempts(attempts, resolved.episodes),
        ran=ran,
        seconds=time.perf_counter() - started,
    )


def kept_files(out_dir: Path | str, episodes: int | None = None) -> list[Path]:
    """The episode files of the kept attempts, in attempt order."""
    out = Path(out_dir)
    config = json.loads((out / CONFIG_FILE).read_text())
    wanted = int(config["episodes"]) if episodes is None else episodes
    return [out / EPISODES_DIR / a["file"] for a in kept_attempts(read_attempts(out), wanted)]


def build_dataset(
    out_dir: Path | str,
    dataset_dir: Path | str,
    images: bool = True,
    progress: bool = True,
    episodes: int | None = None,
) -> int:
    """Write the kept episodes of a collection into a LeRobotDataset v3 at ``dataset_dir``
    (module docstring); resumes a partly built dataset whose episodes are a prefix of the kept
    ones, and rebuilds one that is not (or is corrupt). Returns the number of episodes."""
    from kinder_gym.demos.lerobot_format import (
        DatasetError,
        DemoWriter,
        check_dataset,
        episode_summaries,
        read_kinder_meta,
    )

    out = Path(out_dir)
    config = json.loads((out / CONFIG_FILE).read_text())
    files = kept_files(out, episodes)
    dataset = Path(dataset_dir)
    done = 0
    if dataset.exists():
        try:
            check_dataset(dataset)
            meta = read_kinder_meta(dataset)
            have = [int(e["metadata"].get("attempt", -1)) for e in episode_summaries(dataset)]
            want = [int(f.stem.split("-")[1]) for f in files]
            if meta["env_id"] != config["env_id"] or have != want[: len(have)]:
                raise DatasetError(f"{dataset}: holds other episodes than {out}")
            if bool(meta["cameras"]) != images:
                raise DatasetError(f"{dataset}: built with images={not images}")
            done = len(have)
        except DatasetError as e:
            print(f"rebuilding {dataset}: {e}", file=sys.stderr)
            shutil.rmtree(dataset)
    bar = _progress(len(files), progress, f"build {config['env_id']}")
    bar.update(done)
    started = time.perf_counter()
    written = frames = 0
    try:
        if done < len(files):
            with DemoWriter(dataset, config["env_id"], images=images) as writer:
                for path in files[done:]:
                    record = load_record(path)
                    writer.add(record)
                    written += 1
                    frames += record.num_steps
                    bar.update(1)
    finally:
        bar.close()
        if written:
            _log_build(out, written, frames, time.perf_counter() - started, images)
    return len(files)


BUILD_LOG = "build.jsonl"


def _log_build(out: Path, episodes: int, frames: int, seconds: float, images: bool) -> None:
    """Append the write speed of one build call to ``<collection>/build.jsonl``."""
    append_record(
        out / BUILD_LOG,
        {"episodes": episodes, "frames": frames, "seconds": seconds, "images": images},
    )


__all__ = [
    "ATTEMPTS_FILE",
    "COLLECTION_SEED",
    "EVALUATION_SEEDS",
    "AttemptTask",
    "CollectConfig",
    "CollectOutcome",
    "build_dataset",
    "collect",
    "episode_path",
    "evaluation_overlap",
    "kept_attempts",
    "kept_files",
    "read_attempts",
    "resolve_collect",
    "run_attempt",
]
