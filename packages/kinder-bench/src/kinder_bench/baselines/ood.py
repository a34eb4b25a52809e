"""The paper's out-of-distribution test for the imitation baselines (``kinder train ood``).

A policy trained on DynObstruction2D-o1 (one obstruction) is evaluated with the standard runner
on DynObstruction2D-o0, -o1, -o2 and -o3 (0–3 obstructions), all with the paper's 200-step budget.
The paper runs it for the imitation baselines that need no env-specific state (DP, VLA): DP's
inputs (the image and the robot state) exist in every variant. The agents pick features by name,
so a DPES policy also runs on o2 and o3 (it sees obstruction0 and not the extra ones) but not on
o0, which lacks obstruction0: those episodes are recorded as errors naming the missing features.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from kinder_bench.baselines.diffusion import checkpoint_training
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_bench.reporting.report import write_report
from kinder_bench.training.checkpoints import load_checkpoint

TRAIN_ENV = "kinder/DynObstruction2D-o1-v0"
OOD_ENVS = tuple(f"kinder/DynObstruction2D-o{n}-v0" for n in range(4))
OOD_MAX_STEPS = 200


def run_ood(
    checkpoint: Path | str,
    out: Path | str,
    agent: str = "dp",
    seeds: Sequence[int] = (0, 1, 2, 3, 4),
    episodes: int = 50,
    workers: int | None = None,
    executor: str = "process",
    progress: bool = True,
    device: str = "cpu",
) -> str:
    """Evaluate ``checkpoint`` on :data:`OOD_ENVS` into ``out``; returns the report table.
    Every run records the checkpoint's training budget (:func:`checkpoint_training`), so that
    the results page can tell a run at the paper's budget from a smaller one."""
    ckpt = load_checkpoint(checkpoint, ("dp", "dpes"))
    if ckpt.info.get("env_id") != TRAIN_ENV:
        raise ValueError(
            f"{ckpt.path} was trained on {ckpt.info.get('env_id')}; the OOD test expects a policy "
            f"trained on {TRAIN_ENV}"
        )
    runs = [
        RunConfig(
            env_id,
            agent,
            {"checkpoint": str(Path(checkpoint).resolve()), "device": device},
            seeds=tuple(seeds),
            episodes=episodes,
            max_steps=OOD_MAX_STEPS,
            training=checkpoint_training(ckpt),
        )
        for env_id in OOD_ENVS
    ]
    run_benchmark(runs, out, executor=executor, workers=workers, progress=progress)
    table, _ = write_report([out])
    return table
