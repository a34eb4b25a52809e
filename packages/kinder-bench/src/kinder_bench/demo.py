"""``kinder demo``: a small, real benchmark that finishes in about a minute on two cores.

Random and MPC on fast Kinematic2D envs, two seeds of a few episodes each with a short step
budget; it prints the results table and writes GIFs of the first episode of each seed. MPC runs
with a shorter horizon than the paper's (see :data:`DEMO_MPC_ARGS`) to fit the time budget; use
``kinder bench run`` for the paper's protocol.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import kinder_core
from kinder_bench.report import write_report
from kinder_bench.runner import RunConfig, run_benchmark

#: Preferred demo envs (the paper's Kinematic2D benchmark envs).
DEMO_ENVS = ("kinder/Motion2D-p0-v0", "kinder/StickButton2D-b1-v0")
DEMO_SEEDS = (0, 1)
DEMO_EPISODES = 2
DEMO_MAX_STEPS = 100
DEMO_MPC_ARGS: dict[str, object] = {"horizon": 50}


@dataclasses.dataclass
class DemoResult:
    """What the demo produced."""

    table: str
    files: list[Path]
    seconds: float


def demo_envs(count: int = 2) -> list[str]:
    """The demo's envs: :data:`DEMO_ENVS` where registered, topped up with other Kinematic2D ids."""
    available = kinder_core.list_envs("Kinematic2D")
    if not available:
        raise ValueError(
            "The demo needs Kinematic2D environments; none is registered (install kinder-garden2d)."
        )
    preferred = [e for e in DEMO_ENVS if e in available]
    return (preferred + [e for e in available if e not in preferred])[:count]


def run_demo(
    out: Path | str = "runs/demo",
    workers: int = 2,
    envs: Sequence[str] | None = None,
    seeds: Sequence[int] = DEMO_SEEDS,
    episodes: int = DEMO_EPISODES,
    max_steps: int = DEMO_MAX_STEPS,
    imports: Sequence[str] = (),
    progress: bool = True,
) -> DemoResult:
    """Run the demo benchmark into ``out`` (resuming it if it is there) and write its report."""
    start = time.perf_counter()
    out = Path(out)
    runs = [
        RunConfig(env, agent, args, tuple(seeds), episodes, max_steps)
        for env in (envs or demo_envs())
        for agent, args in (("random", {}), ("mpc", DEMO_MPC_ARGS))
    ]
    outcome = run_benchmark(
        runs,
        out,
        executor="process",
        workers=workers,
        record="gif",
        record_episodes=1,
        imports=imports,
        progress=progress,
    )
    table, paths = write_report([out], out)
    videos = sorted(Path(r["video"]) for r in outcome.records if r.get("video"))
    return DemoResult(table, [*videos, *paths.values()], time.perf_counter() - start)
