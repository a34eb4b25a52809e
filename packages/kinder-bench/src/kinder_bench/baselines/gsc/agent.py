"""The GSC agent: skeleton from BP's abstract search, parameters from the chained sampler, the
same skills as BP for execution, re-planning from the reached state when a skill fails.

Planning from a state ``x``:

1. Abstract ``x`` with the env's :class:`~kinder_gym.model.PlanningModel` and enumerate abstract
   plans with the bilevel planner's search (:func:`~kinder_bench.baselines.bilevel_search.
   abstract_plans`, A* with hFF by default); the skeleton is the first plan whose operators all
   have a trained model (GSC itself is given the skeleton; it does not search over skeletons).
2. Sample ``num_samples`` chains jointly (:func:`~kinder_bench.baselines.gsc.sampler.
   sample_chain`: γ-overlap score composition, ``x`` inpainted, objects the skeleton never names
   held fixed) and keep the top-ranked sample's parameters (product of the feasibility
   classifiers).

Execution is closed-loop *within* a skill and open-loop across skills, as in GSC: each step's
ground skill (``PlanningModel.skill``, the controller BP uses) is reset with the sampled
parameters on the live state and fed every observed state; when it terminates, the reached
state's abstraction is checked against the operator's predicted abstract state (BP's acceptance
rule). A skill that raises :class:`~kinder_gym.skills.SkillFailure`, runs past the model's
``max_skill_horizon``, or ends in the wrong abstract state triggers re-planning (new skeleton,
new samples) from the reached state, at most ``max_replans`` times per episode; so does running
out of skills before the episode ends. Everything happens inside one episode: the protocol's
single rollout (GSC's own evaluation retries its top-5 samples from a reset simulator).
With ``resample_each_skill``, the rest of the chain is also re-sampled after every successful
skill (receding horizon; off by default, as in GSC).

The runner counts sampling time as inference time (it happens in ``reset``/``act``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from numpy.typing import NDArray

from kinder_bench.agents.base import Agent, AgentFailure, needs_checkpoint
from kinder_bench.baselines.bilevel_search import HFF, SEARCH_ALGORITHMS, abstract_plans
from kinder_bench.baselines.gsc.model import MODEL_FILE, GSCModel
from kinder_bench.baselines.gsc.sampler import ChainSamples, ChainStep, sample_chain
from kinder_bench.training.checkpoints import find_checkpoint
from kinder_core import ObjectCentricState
from kinder_gym.concepts import GroundAtom
from kinder_gym.model import PlanningModel, abstract_match
from kinder_gym.models import model_for
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import Controller, SkillFailure, execute_skill

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class GSCArgs:
    """Arguments of the GSC agent."""

    checkpoint: str = ""
    """A ``kinder train gsc`` run directory (its newest checkpoint) or one checkpoint (required)."""
    num_samples: int = 40
    """Chains sampled jointly per plan (GSC: 40)."""
    steps: int = 50
    """Denoising steps (GSC: 256)."""
    gamma: float = 0.5
    """Forward/backward weight on every shared state (1: forward chaining, 0: backward)."""
    search: str = "astar"
    """Abstract search for the skeleton: ``astar`` or ``gbfs`` (as BP)."""
    max_abstract_plans: int = 10
    """Abstract plans looked at for one whose operators all have models."""
    max_replans: int = 5
    """Planning calls per episode after the first."""
    resample_each_skill: bool = False
    """Re-sample the rest of the chain from the reached state after every successful skill."""
    threads: int = 1
    """``torch.set_num_threads`` while sampling."""

    def __post_init__(self) -> None:
        checks = [
            (bool(self.checkpoint), "checkpoint is required (a `kinder train gsc` directory)"),
            (self.num_samples >= 1, "num_samples must be >= 1"),
            (self.steps >= 1, "steps must be >= 1"),
            (0.0 <= self.gamma <= 1.0, "gamma must be in [0, 1]"),
            (self.search in SEARCH_ALGORITHMS, f"search must be one of {SEARCH_ALGORITHMS}"),
            (self.max_abstract_plans >= 1, "max_abstract_plans must be >= 1"),
            (self.max_replans >= 0, "max_replans must be >= 0"),
            (self.threads >= 1, "threads must be >= 1"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"GSCArgs: {msg}, got {self}")


_CACHE: dict[tuple[str, float], GSCModel] = {}


def load_model(checkpoint: str | Path) -> GSCModel:
    """The model of a run directory (its newest checkpoint) or of one checkpoint directory
    (cached per checkpoint and modification time).

    Raises:
        FileNotFoundError: no checkpoint at ``checkpoint`` (train one with ``kinder train gsc``).
        CheckpointError: not a GSC checkpoint of this format.
    """
    path = find_checkpoint(checkpoint)
    file = path / MODEL_FILE
    key = (str(path.resolve()), file.stat().st_mtime if file.is_file() else 0.0)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = GSCModel.load(path).eval()
    return _CACHE[key]


def find_skeleton(
    planning: PlanningModel,
    x: ObjectCentricState,
    known: Sequence[str],
    rng: np.random.Generator,
    search: str = "astar",
    max_plans: int = 10,
) -> list[GroundOperator] | None:
    """The first abstract plan from ``x`` whose operators are all in ``known`` (None if none of
    the first ``max_plans`` is)."""
    s0 = planning.abstract(x)
    goal = planning.goal(x)
    ops = planning.ground_operators(x)
    heuristic = HFF(ops, goal, s0)
    for i, plan in enumerate(
        abstract_plans(s0, goal, ops, rng, search, max_plans, math.inf, heuristic=heuristic)
    ):
        if all(o.parent.name in known for o in plan.operators):
            return list(plan.operators)
        if i + 1 >= max_plans:
            break
    return None


def chain_steps(skeleton: Sequence[GroundOperator]) -> list[ChainStep]:
    """The sampler's view of a skeleton."""
    return [ChainStep(o.parent.name, tuple(ob.name for ob in o.objects)) for o in skeleton]


def execute_chain(
    planning: PlanningModel,
    x0: ObjectCentricState,
    skeleton: Sequence[GroundOperator],
    params: Sequence[FloatArray],
) -> tuple[bool, int]:
    """Execute ``params`` along ``skeleton`` open loop in the env model from ``x0``: whether the
    env's goal was reached, and how many skills succeeded before it or before a failure."""
    env = planning.env
    x = x0
    for i, (op, p) in enumerate(zip(skeleton, params, strict=True)):
        gs = planning.skill(op)
        expected = op.apply(planning.abstract(x))
        try:
            rollout = execute_skill(gs.controller, x, p, env.transition, planning.max_skill_horizon)
        except SkillFailure:
            return False, i
        x = rollout.states[-1]
        if rollout.terminated:
            return True, i + 1
        if not rollout.finished or not abstract_match(planning, planning.abstract(x), expected):
            return False, i
    return env.goal_reached(x), len(skeleton)


@dataclasses.dataclass
class _Active:
    op: GroundOperator
    controller: Controller
    expected: frozenset[GroundAtom]
    steps: int = 0


class GSCAgent(Agent[GSCArgs]):
    """Generative skill chaining (see the module docstring)."""

    name = "gsc"
    Args = GSCArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs the env family's planning model (the skeletons and skills) and a checkpoint."""
        from kinder_bench.baselines.bilevel_planning import BilevelPlanningAgent

        return BilevelPlanningAgent.unavailable(args, env_id) or needs_checkpoint(args, "gsc")

    def __init__(self, env: gymnasium.Env[Any, Any], args: GSCArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        self.gsc = load_model(args.checkpoint)
        model = self.model
        env_id = model.spec.id if model.spec is not None else None
        if env_id is not None and env_id != self.gsc.env_id:
            raise ValueError(
                f"The GSC checkpoint {args.checkpoint} was trained on {self.gsc.env_id}, not "
                f"{env_id}"
            )
        self.planning: PlanningModel = model_for(model)
        self.replans = 0
        self.sample_seconds: list[float] = []
        self.last_samples: ChainSamples | None = None
        self._queue: list[tuple[GroundOperator, FloatArray]] = []
        self._active: _Active | None = None
        self._failure: str | None = None

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.replans = 0
        self.sample_seconds = []
        self._failure = None
        self._active = None
        self._plan(self.observed_state(obs), first=True)

    def _plan(self, x: ObjectCentricState, first: bool = False, why: str = "") -> None:
        if not first:
            if self.replans >= self.args.max_replans:
                self._failure = (
                    f"gsc: {why}; the re-planning budget ({self.args.max_replans}) is spent"
                )
                raise AgentFailure(self._failure)
            self.replans += 1
        skeleton = find_skeleton(
            self.planning,
            x,
            list(self.gsc.skills),
            self.rng,
            self.args.search,
            self.args.max_abstract_plans,
        )
        if skeleton is None:
            self._failure = (
                f"gsc: no abstract plan found, or none of the first "
                f"{self.args.max_abstract_plans} uses only operators with a trained model "
                f"({sorted(self.gsc.skills)})"
            )
            raise AgentFailure(self._failure)
        if not skeleton:
            self._queue = []
            return
        torch.set_num_threads(self.args.threads)
        start = time.perf_counter()
        samples = sample_chain(
            self.gsc,
            self.model.box_space.vectorize(x),
            chain_steps(skeleton),
            self.args.num_samples,
            self.args.steps,
            self.args.gamma,
            seed=int(self.rng.integers(0, 2**31 - 1)),
        )
        self.sample_seconds.append(time.perf_counter() - start)
        self.last_samples = samples
        self._queue = list(zip(skeleton, samples.best_params(), strict=True))

    def _start_next(self, x: ObjectCentricState) -> None:
        """Start the next queued skill on ``x`` (re-planning on failure or an empty queue)."""
        while True:
            if not self._queue:
                self._plan(x, why="the plan ran out before the goal was reached")
                if not self._queue:
                    raise AgentFailure("gsc: the abstract plan is empty, the goal is not reached")
                continue
            op, params = self._queue.pop(0)
            controller = self.planning.skill(op).controller
            expected = op.apply(self.planning.abstract(x))
            try:
                if not controller.initiable(x):
                    raise SkillFailure(f"{op.name} is not initiable")
                controller.reset(x, params)
            except SkillFailure as e:
                self._plan(x, why=f"skill {op.name} failed to start ({e})")
                continue
            self._active = _Active(op, controller, expected)
            return

    def act(self, obs: Any) -> FloatArray:
        if self._failure is not None:
            raise AgentFailure(self._failure)
        x = self.observed_state(obs)
        for _ in range(self.args.max_replans + 64):
            active = self._active
            if active is None:
                self._start_next(x)
                continue
            if active.steps:
                active.controller.observe(x)
            if active.controller.terminated():
                self._active = None
                reached = self.planning.abstract(x)
                if not abstract_match(self.planning, reached, active.expected):
                    self._plan(x, why=f"skill {active.op.name} ended in the wrong abstract state")
                elif self.args.resample_each_skill and self._queue:
                    self._plan(x, first=True)
                continue
            if active.steps >= self.planning.max_skill_horizon:
                self._active = None
                self._plan(x, why=f"skill {active.op.name} ran past its step budget")
                continue
            try:
                action = active.controller.step()
            except SkillFailure as e:
                self._active = None
                self._plan(x, why=f"skill {active.op.name} failed ({e})")
                continue
            active.steps += 1
            return self.clip(action)
        raise AgentFailure("gsc: skills keep ending without emitting an action")


def random_params(
    planning: PlanningModel, skeleton: Sequence[GroundOperator], rng: np.random.Generator
) -> list[FloatArray]:
    """Uniform parameters from each step's controller parameter space (the random-parameter
    reference of the tests and the benchmark script)."""
    out = []
    for op in skeleton:
        space = planning.skill(op).controller.params_space
        out.append(rng.uniform(space.low.astype(np.float64), space.high.astype(np.float64)))
    return out


__all__ = [
    "GSCAgent",
    "GSCArgs",
    "chain_steps",
    "execute_chain",
    "find_skeleton",
    "load_model",
    "random_params",
]
