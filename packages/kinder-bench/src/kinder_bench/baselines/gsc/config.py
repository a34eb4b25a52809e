"""The arguments of ``kinder train gsc`` (:class:`GSCTrainConfig`), apart from the trainer so
that the command line reads them without importing torch."""

from __future__ import annotations

import dataclasses
from typing import Any


@dataclasses.dataclass(frozen=True)
class GSCTrainConfig:
    """What ``kinder train gsc`` trains (every field is a command-line option)."""

    env_id: str
    """The env (short ids such as ``StickButton2D-b1`` are accepted)."""
    out: str
    """The output (checkpoint) directory."""
    dataset: str | None = None
    """A LeRobot dataset directory of skill-labelled demos; None: generate BP demos."""
    demo_episodes: int = 50
    """Successful BP demonstrations to collect when no dataset is given."""
    demo_seed: int = 1000
    """Collection seed of those demonstrations (keep it apart from the evaluation seeds)."""
    perturbations: int = 4
    """Perturbed executions per successful demo transition (classifier negatives)."""
    perturb_noise: float = 0.1
    """Std of the Gaussian parameter perturbation, as a fraction of each parameter's range."""
    perturb_uniform: float = 0.5
    """Fraction of perturbations drawn uniformly from the parameter space instead."""
    steps: int = 2000
    """Optimisation steps (each trains every skill's two networks on one minibatch)."""
    batch_size: int = 128
    lr: float = 1e-3
    hidden: int = 128
    """Width of the ε-network (the measured cells of ``benchmarks/results/gsc.md``)."""
    depth: int = 3
    """Residual blocks of the ε-network."""
    classifier_hidden: int = 256
    classifier_depth: int = 3
    checkpoint_every: int = 500
    log_every: int = 100
    seed: int = 0
    threads: int = 1
    """``torch.set_num_threads``."""
    keep: int = 2
    """Checkpoints to keep (older ones are deleted)."""

    def __post_init__(self) -> None:
        checks = [
            (self.demo_episodes >= 1, "demo_episodes must be >= 1"),
            (self.perturbations >= 0, "perturbations must be >= 0"),
            (self.perturb_noise >= 0, "perturb_noise must be >= 0"),
            (0 <= self.perturb_uniform <= 1, "perturb_uniform must be in [0, 1]"),
            (self.steps >= 1, "steps must be >= 1"),
            (self.batch_size >= 2, "batch_size must be >= 2"),
            (self.lr > 0, "lr must be > 0"),
            (self.hidden >= 1 and self.depth >= 1, "hidden and depth must be >= 1"),
            (self.checkpoint_every >= 1 and self.log_every >= 1, "intervals must be >= 1"),
            (self.threads >= 1, "threads must be >= 1"),
            (self.keep >= 1, "keep must be >= 1"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"GSCTrainConfig: {msg}, got {self}")

    def data_dict(self) -> dict[str, Any]:
        """The fields that decide the data and the networks (a resume must match them)."""
        d = dataclasses.asdict(self)
        for k in ("out", "steps", "checkpoint_every", "log_every", "threads", "keep"):
            d.pop(k)
        return d
