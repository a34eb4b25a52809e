"""``kinder demo``: the main job, a small real benchmark that finishes in about two minutes.

The bilevel planner (BP, the paper's strongest baseline) next to MPC and random on four of the
paper's benchmark envs, two 2D and two 3D (:data:`DEMO_ENVS`: Motion2D-p0, StickButton2D-b1,
BaseMotion3D, Shelf3D-o1). Each runs 2 seeds (0 and 1) of a few episodes with the paper's step
budget for the env, on a local pool of 2 processes. It prints the results table, records the first
episode of each seed as a GIF (every few steps, so a GIF has about 100 frames), and writes the
report (``table.md``, ``summary.csv``, ``success.png``, the paper comparison ``paper_table.md``
and the self-contained page ``report.html``) under the run directory. Rerunning resumes (and so
only rewrites the report). Nothing is downloaded.

Deviations from the paper's protocol, to fit the time budget (use ``kinder bench run`` for the
paper's): 2 seeds instead of 5 and 1–2 episodes per seed instead of 50, and MPC with a much
smaller search (:data:`DEMO_MPC_ARGS`: horizon 20 instead of 100, 5 rollouts instead of 10, 4
control points, a new solve every 5 steps instead of every step; on Shelf3D-o1, whose MuJoCo
steps cost milliseconds, horizon 10 with 3 rollouts, solved every 10 steps). The paper's figures
in the comparison are for its protocol.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import kinder_core
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.reporting.report import write_report


@dataclasses.dataclass(frozen=True)
class DemoEnv:
    """One env of the demo: its id, episodes per seed, MPC's arguments there and the step
    budget (None: the paper's for its envs, else the env's)."""

    env_id: str
    episodes: int
    mpc_args: Mapping[str, Any]
    max_steps: int | None = None


#: MPC's demo arguments (the paper's: horizon 100, 10 rollouts, 10 control points, every step).
DEMO_MPC_ARGS: dict[str, Any] = {
    "horizon": 20,
    "num_rollouts": 5,
    "num_control_points": 4,
    "replan_interval": 5,
}

#: The demo's envs: the paper's two Kinematic2D envs, its Kinematic3D BaseMotion3D and its
#: Dynamic3D Shelf3D-o1 (one episode per seed: a 500-step MuJoCo episode).
DEMO_ENVS: tuple[DemoEnv, ...] = (
    DemoEnv("kinder/Motion2D-p0-v0", 2, DEMO_MPC_ARGS),
    DemoEnv("kinder/StickButton2D-b1-v0", 2, DEMO_MPC_ARGS),
    DemoEnv("kinder/BaseMotion3D-v0", 2, DEMO_MPC_ARGS),
    DemoEnv(
        "kinder/Shelf3D-o1-v0",
        1,
        {**DEMO_MPC_ARGS, "horizon": 10, "num_rollouts": 3, "replan_interval": 10},
    ),
)
DEMO_AGENTS = ("bilevel_planning", "mpc", "random")
DEMO_SEEDS = (0, 1)
#: Frames per recorded episode, about (the stride is the step budget / this).
DEMO_FRAMES = 100
DEMO_NOTE = (
    "kinder demo: 2 seeds x 1-2 episodes (paper: 5 x 50) and MPC with a much smaller search "
    "than the paper's (kinder_bench.demo); the paper's figures are for its full protocol."
)


@dataclasses.dataclass
class DemoResult:
    """What the demo produced."""

    table: str
    files: list[Path]
    seconds: float
    html: Path | None


def demo_envs() -> list[DemoEnv]:
    """The demo's envs that are installed (3D ones need ``kinder-garden3d``)."""
    known = set(kinder_core.list_envs())
    envs = [e for e in DEMO_ENVS if e.env_id in known]
    if not envs:
        raise ValueError(
            "The demo needs the KinDERGarden environments; none of "
            f"{[e.env_id for e in DEMO_ENVS]} is registered (install kinder-garden2d)."
        )
    return envs


def demo_runs(envs: Sequence[DemoEnv], seeds: Sequence[int] = DEMO_SEEDS) -> list[RunConfig]:
    """The demo's runs: every agent of :data:`DEMO_AGENTS` on every env."""
    runs = []
    for env in envs:
        for agent in DEMO_AGENTS:
            args = dict(env.mpc_args) if agent == "mpc" else {}
            runs.append(
                RunConfig(env.env_id, agent, args, tuple(seeds), env.episodes, env.max_steps)
            )
    return runs


def run_demo(
    out: Path | str = "runs/demo",
    workers: int = 2,
    envs: Sequence[DemoEnv] | None = None,
    seeds: Sequence[int] = DEMO_SEEDS,
    imports: Sequence[str] = (),
    progress: bool = True,
) -> DemoResult:
    """Run the demo benchmark into ``out`` (resuming it if it is there) and write its report."""
    start = time.perf_counter()
    out = Path(out)
    envs = list(envs or demo_envs())
    runs = demo_runs(envs, seeds)
    outcome = run_benchmark(
        runs,
        out,
        executor="process",
        workers=workers,
        record="gif",
        record_episodes=1,
        record_frames=DEMO_FRAMES,
        imports=imports,
        progress=progress,
        command="kinder demo",
    )
    _, paths = write_report([out], out, paper=True, html=True, title="kinder demo", note=DEMO_NOTE)
    table = paths["table"].read_text()  # our table (the paper comparison is paper_table.md)
    videos = sorted(Path(r["video"]) for r in outcome.records if r.get("video"))
    return DemoResult(
        table, [*videos, *paths.values()], time.perf_counter() - start, paths.get("html")
    )
