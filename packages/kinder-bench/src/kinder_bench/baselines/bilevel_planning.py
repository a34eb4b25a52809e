"""Bilevel planning (BP): search-then-sample task and motion planning on the env's own model.

The paper's strongest baseline (KinDER spec, baselines §2 and §8), as one self-contained module.
Planning from a state ``x0``:

1. Abstract ``x0`` with the env's :class:`~kinder_gym.model.PlanningModel` (predicates) and derive
   the goal atoms.
2. Enumerate abstract plans (sequences of ground operators) by heuristic search with hFF over all
   ground operators: A* (``g + h``, the upstream code) or greedy best-first (``h``, the paper's
   wording), see :mod:`kinder_bench.baselines.bilevel_search`. At most ``max_abstract_plans``
   plans are tried, within ``planning_timeout`` seconds for search and refinement together.
3. Refine each plan by depth-first backtracking over the skills' samplers: for step ``i``, draw up
   to ``samples_per_step`` parameter vectors (one for a skill without parameters: it is
   deterministic), roll the skill out with the env's own pure ``transition`` for at most
   ``max_skill_horizon`` steps, and accept the sample iff the reached state's abstraction equals
   the operator's predicted abstract state exactly; otherwise (or on
   :class:`~kinder_gym.skills.SkillFailure`) draw the next sample, and when all fail, backtrack to
   step ``i − 1``. A rollout that reaches the env's goal ends the plan early, and the last step
   must reach the env's goal (not just the goal atoms).
4. When every abstract plan (at most ``max_abstract_plans``) failed, refine the same plans again
   with fresh samples, up to ``refinement_rounds`` rounds in all (upstream: one round).
5. Episode limit: the agent plans with the steps left in the episode (its env's time limit minus
   the actions already taken) as a budget, and a skill sample whose rollout is cut off by that
   budget before the skill finishes (or reaches the goal) is rejected like a failed sample, so
   no plan longer than the episode's remaining steps is accepted (``respect_episode_limit``;
   upstream has no such check and returns plans that time out). Rollouts are never cut shorter
   than ``max_skill_horizon`` otherwise, so with steps to spare the search is unchanged.

The refined plan is a list of actions, executed from the agent's :meth:`act`. Execution is
monitored: the agent remembers the state each action was planned from and, when the observed
state differs (``divergence_atol``), plans again from the observed state (``max_replans`` times
per episode); it also plans again if the actions run out before the episode ends. The upstream
agent is open-loop (no monitoring). When planning fails, the call that planned (:meth:`reset` or
:meth:`act`) raises :class:`~kinder_bench.agents.base.AgentFailure`; the runner counts the time
of calls that raise, so the failed planning time is part of the episode's inference time.

Everything random comes from the agent's seeded RNG, so an episode's plan is reproducible as
long as no planning call reaches ``planning_timeout`` and no motion-planning query inside a skill
reaches its own time cap (``kinder_gym.motion_planning`` stops each RRT-Connect attempt after
``max_iterations`` or a ``timeout`` of 0.5–2 s). Both count the planner's clock. With the
paper's wall-clock seconds, where a call or an attempt is cut off depends on the machine's speed
and load: the same seed can then give a different plan (or none) on a busier machine; planning
KinematicShelf3D-o3 (development seed 1001, 600 s budget) three times in one process on a busy
machine, with the motion planners' caps on the wall clock, gave three different action sequences
(343, 342 and 326 actions). ``planning_clock="process"`` counts both in the agent process's CPU
seconds instead, which a busy machine does not shorten (a variant: not the paper's setting): the
same three plans then gave one action sequence (340 actions). For runs that must
reproduce exactly in any process, bound the planner by simulated env steps
(``max_model_steps``, counted over every skill rollout of the call) and lift the wall-clock
budget (``planning_timeout=inf``); an RRT-Connect attempt that reaches its time cap still
depends on the machine's speed.
"""

from __future__ import annotations

import dataclasses
import re
import time
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents import OMIT_DEFAULT_FROM_RUN_ID
from kinder_bench.agents.base import Agent, AgentFailure
from kinder_bench.baselines.bilevel_search import (
    HFF,
    SEARCH_ALGORITHMS,
    AbstractPlan,
    abstract_plans,
)
from kinder_core import ObjectCentricEnv, ObjectCentricState
from kinder_gym import motion_planning
from kinder_gym.concepts import GroundAtom
from kinder_gym.model import PlanningModel, abstract_match
from kinder_gym.models import model_for, use_model
from kinder_gym.operators import GroundOperator
from kinder_gym.skills import SkillFailure, execute_skill

FloatArray = NDArray[np.float64]

#: The clocks ``planning_timeout`` can count (``BilevelPlanningArgs.planning_clock``).
PLANNING_CLOCKS = {"wall": time.perf_counter, "process": time.process_time}


@dataclasses.dataclass(frozen=True)
class BilevelPlanningArgs:
    """Arguments of the bilevel planning baseline.

    Defaults: the paper's configuration (A*, 10 abstract plans, 3 samples per step, 60 s), plus
    execution monitoring and 3 refinement rounds (upstream: none and 1).
    """

    search: str = "astar"
    """Abstract search: ``astar`` (priority g + hFF; upstream code) or ``gbfs`` (priority hFF)."""
    max_abstract_plans: int = 10
    """Abstract plans refined before giving up (also: expansions allowed per abstract state)."""
    samples_per_step: int = 3
    """Parameter samples tried per plan step before backtracking."""
    max_skill_horizon: int = 0
    """Most env steps per skill execution; 0: the env model's own default."""
    planning_timeout: float = 60.0
    """Seconds for one planning call (abstract search and refinement together), on
    ``planning_clock``; ``inf`` for no time limit."""
    planning_clock: str = dataclasses.field(
        default="wall", metadata={OMIT_DEFAULT_FROM_RUN_ID: True}
    )
    """What ``planning_timeout`` counts: ``wall`` (wall-clock seconds, as the paper) or
    ``process`` (the agent process's CPU seconds). On a machine shared by other jobs a
    wall-clock budget buys less search the busier the machine is; a CPU-time budget buys the
    same search at any load (a variant: not the paper's setting)."""
    max_model_steps: int = 0
    """Simulated env steps one planning call may spend on skill rollouts: once they are spent,
    no further rollout starts and the call gives up like a timed-out one; 0: no limit. Unlike
    ``planning_timeout`` it does not depend on the machine, so the episodes it cuts off
    reproduce exactly."""
    replan_on_divergence: bool = True
    """Plan again when the observed state is not the state the next action was planned from."""
    divergence_atol: float = 1e-6
    """Absolute tolerance on every feature when comparing observed and planned states."""
    max_replans: int = 5
    """Planning calls per episode after the first (divergence or plan exhausted)."""
    refinement_rounds: int = 3
    """Rounds of refinement over the abstract plans found (each with fresh samples); 1 is the
    upstream behaviour (each abstract plan is refined once)."""
    respect_episode_limit: bool = True
    """Reject plans with more actions than the episode has steps left (the env's time limit);
    False: the upstream behaviour (no step budget)."""

    def __post_init__(self) -> None:
        checks = [
            (self.search in SEARCH_ALGORITHMS, f"search must be one of {SEARCH_ALGORITHMS}"),
            (self.max_abstract_plans >= 1, "max_abstract_plans must be >= 1"),
            (self.samples_per_step >= 1, "samples_per_step must be >= 1"),
            (self.max_skill_horizon >= 0, "max_skill_horizon must be >= 0"),
            (self.planning_timeout > 0, "planning_timeout must be > 0"),
            (
                self.planning_clock in PLANNING_CLOCKS,
                f"planning_clock must be one of {tuple(PLANNING_CLOCKS)}",
            ),
            (self.max_model_steps >= 0, "max_model_steps must be >= 0 (0: no limit)"),
            (self.divergence_atol >= 0, "divergence_atol must be >= 0"),
            (self.max_replans >= 0, "max_replans must be >= 0"),
            (self.refinement_rounds >= 1, "refinement_rounds must be >= 1"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"BilevelPlanningArgs: {msg}, got {self}")


@dataclasses.dataclass
class RefinedPlan:
    """A refined plan: ``states[t]`` is the state ``actions[t]`` is taken in
    (``len(states) == len(actions) + 1``), and the abstract plan it refines."""

    states: list[ObjectCentricState]
    actions: list[FloatArray]
    abstract_plan: AbstractPlan
    skills: list[tuple[str, FloatArray, int]]
    """Per executed skill: (ground operator name, parameters, number of actions)."""
    skill_operators: list[GroundOperator] = dataclasses.field(default_factory=list)
    """The ground operator of each entry of :attr:`skills` (same order)."""

    def skill_index(self, t: int) -> int:
        """Which entry of :attr:`skills` produced ``actions[t]``."""
        end = 0
        for i, (_, _, n) in enumerate(self.skills):
            end += n
            if t < end:
                return i
        raise IndexError(f"action {t} is beyond the plan's {end} actions")


@dataclasses.dataclass(frozen=True)
class ExecutedSkill:
    """The skill that produced the agent's latest action (for skill-labelled demonstrations)."""

    plan: int
    """Which plan of the episode (0: the first; re-planning starts a new one)."""
    index: int
    """The skill's position in that plan."""
    operator: GroundOperator
    params: FloatArray


@dataclasses.dataclass
class PlanningStats:
    """Counters of one planning call (for analysis and tests)."""

    abstract_plans: int = 0
    refinement_retries: int = 0
    skill_samples: int = 0
    skill_failures: int = 0
    abstract_mismatches: int = 0
    model_steps: int = 0
    over_budget: int = 0
    """Skill samples rejected because the plan would exceed the step budget."""
    time: float = 0.0
    timed_out: bool = False


class _Timeout(Exception):
    pass


class BilevelPlanner:
    """Search-then-sample over a :class:`~kinder_gym.model.PlanningModel` (module docstring)."""

    def __init__(self, model: PlanningModel, args: BilevelPlanningArgs) -> None:
        self.model = model
        self.args = args
        self._clock = PLANNING_CLOCKS[args.planning_clock]
        self.horizon = args.max_skill_horizon or model.max_skill_horizon
        self.stats = PlanningStats()
        self._max_steps: int | None = None

    def plan(
        self, x0: ObjectCentricState, rng: np.random.Generator, max_steps: int | None = None
    ) -> RefinedPlan | None:
        """A refined plan from ``x0`` with at most ``max_steps`` actions (None: no limit), or None
        when none was found in time."""
        if max_steps is not None and max_steps < 0:
            raise ValueError(f"max_steps must be >= 0 or None, got {max_steps}")
        self.stats = PlanningStats()
        self._max_steps = max_steps
        start = time.perf_counter()
        deadline = self._clock() + self.args.planning_timeout
        try:
            # The skills' motion planners cap their attempts with the planner's own clock.
            with motion_planning.timeouts_counted_by(self._clock):
                return self._plan(x0, rng, deadline)
        finally:
            self.stats.time = time.perf_counter() - start

    def _plan(
        self, x0: ObjectCentricState, rng: np.random.Generator, deadline: float
    ) -> RefinedPlan | None:
        model, args = self.model, self.args
        s0 = model.abstract(x0)
        goal = model.goal(x0)
        ops = model.ground_operators(x0)
        heuristic = HFF(ops, goal, s0)
        plans = abstract_plans(
            s0,
            goal,
            ops,
            rng,
            args.search,
            args.max_abstract_plans,
            deadline,
            heuristic=heuristic,
            clock=self._clock,
        )
        tried: list[AbstractPlan] = []
        for plan in plans:
            self.stats.abstract_plans += 1
            tried.append(plan)
            try:
                refined = self._refine(plan, x0, rng, deadline)
            except _Timeout:
                self.stats.timed_out = True
                return None
            if refined is not None:
                return refined
            if self.stats.abstract_plans >= args.max_abstract_plans:
                break
        # Further rounds over the same abstract plans with fresh samples.
        for _ in range(args.refinement_rounds - 1):
            for plan in tried:
                self.stats.refinement_retries += 1
                try:
                    refined = self._refine(plan, x0, rng, deadline)
                except _Timeout:
                    self.stats.timed_out = True
                    return None
                if refined is not None:
                    return refined
        if self._clock() > deadline:
            self.stats.timed_out = True
        return None

    def _refine(
        self,
        plan: AbstractPlan,
        x0: ObjectCentricState,
        rng: np.random.Generator,
        deadline: float,
    ) -> RefinedPlan | None:
        states: list[ObjectCentricState] = [x0]
        actions: list[FloatArray] = []
        skills: list[tuple[str, FloatArray, int]] = []
        used: list[GroundOperator] = []
        ops = list(plan.operators)
        if not ops:
            return (
                RefinedPlan(states, actions, plan, skills)
                if self.model.env.goal_reached(x0)
                else None
            )
        if self._refine_from(ops, plan.states[0], x0, rng, deadline, states, actions, skills, used):
            return RefinedPlan(states, actions, plan, skills, used)
        return None

    def _over_step_budget(self) -> bool:
        limit = self.args.max_model_steps
        return 0 < limit <= self.stats.model_steps

    def _accept(self, reached: frozenset[GroundAtom], expected: frozenset[GroundAtom]) -> bool:
        return abstract_match(self.model, reached, expected)

    def _refine_from(
        self,
        ops: list[GroundOperator],
        atoms: frozenset[GroundAtom],
        x: ObjectCentricState,
        rng: np.random.Generator,
        deadline: float,
        states: list[ObjectCentricState],
        actions: list[FloatArray],
        skills: list[tuple[str, FloatArray, int]],
        used: list[GroundOperator],
    ) -> bool:
        """Depth-first refinement of ``ops`` from ``x`` (abstracting to ``atoms``); appends the
        segments on success."""
        model = self.model
        op = ops[0]
        expected = op.apply(atoms)
        gs = model.skill(op)
        deterministic = gs.controller.params_space.shape == (0,)
        # Steps the rest of the plan may take; the rollout is cut there (never below the
        # horizon when the budget allows it, so the search is unchanged with steps to spare).
        budget = None if self._max_steps is None else self._max_steps - len(actions)
        horizon = self.horizon if budget is None else min(self.horizon, budget)
        for _ in range(1 if deterministic else self.args.samples_per_step):
            if self._clock() > deadline or self._over_step_budget():
                raise _Timeout
            gs = model.skill(op)  # a fresh controller per sample
            self.stats.skill_samples += 1
            try:
                params = gs.controller.sample_parameters(x, rng)
                rollout = execute_skill(
                    gs.controller,
                    x,
                    params,
                    model.env.transition,
                    horizon,
                    deadline=deadline,
                    clock=self._clock,
                )
            except SkillFailure:
                self.stats.skill_failures += 1
                continue
            self.stats.model_steps += len(rollout.actions)
            if rollout.timed_out:
                raise _Timeout
            if (
                horizon < self.horizon
                and len(rollout.actions) >= horizon
                and not (rollout.finished or rollout.terminated)
            ):
                self.stats.over_budget += 1  # cut off by the episode's step budget
                continue
            x_next = rollout.states[-1]
            done = rollout.terminated
            rest: list[GroundOperator] = []
            reached = expected
            if not done:
                reached = model.abstract(x_next)
                if not self._accept(reached, expected):
                    self.stats.abstract_mismatches += 1
                    continue
                # Steps whose effects already hold (monotone atoms achieved early) are skipped.
                rest = _drop_noops(ops[1:], reached)
                if not rest and not model.env.goal_reached(x_next):
                    continue
                done = not rest
            n_states, n_actions, n_skills = len(states), len(actions), len(skills)
            states.extend(rollout.states[1:])
            actions.extend(rollout.actions)
            skills.append((op.name, np.asarray(params, dtype=np.float64), len(rollout.actions)))
            used.append(op)
            if done or self._refine_from(
                rest, reached, x_next, rng, deadline, states, actions, skills, used
            ):
                return True
            del states[n_states:], actions[n_actions:], skills[n_skills:], used[n_skills:]
        return False


def _drop_noops(
    ops: Sequence[GroundOperator], atoms: frozenset[GroundAtom]
) -> list[GroundOperator]:
    """``ops`` without the steps that would not change the abstract state where they occur."""
    out = []
    for o in ops:
        nxt = o.apply(atoms)
        if nxt != atoms:
            out.append(o)
            atoms = nxt
    return out


_FAMILY_RE = re.compile(r"^(?:kinder/)?(?P<family>[A-Za-z0-9]+)(?:-.+?)?(?:-v\d+)?$")


class BilevelPlanningAgent(Agent[BilevelPlanningArgs]):
    """Bilevel planning with execution monitoring (see the module docstring)."""

    name = "bilevel_planning"
    Args = BilevelPlanningArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs a planning model for the env's family (``kinder_gym.models.MODELS``)."""
        del args
        from kinder_gym.models import MODELS

        m = _FAMILY_RE.match(env_id)
        family = m.group("family") if m else env_id
        if family in MODELS:
            return None
        return f"needs a planning model for the {family} family (kinder_gym.models)"

    def __init__(self, env: gymnasium.Env[Any, Any], args: BilevelPlanningArgs, seed: int) -> None:
        super().__init__(env, args, seed)
        self.planning_model = model_for(self.model)
        self.planner = BilevelPlanner(self.planning_model, args)
        self._plan: RefinedPlan | None = None
        self._failure: str | None = None
        self._t = 0
        self._steps_taken = 0
        self.replans = 0
        self.replans_ran_out = 0
        """Re-plans because the plan's actions ran out before the episode ended (the rest of
        :attr:`replans` were for a diverged state)."""
        self.history: list[PlanningStats] = []
        self.last_skill: ExecutedSkill | None = None
        """The skill that produced the latest action :meth:`act` returned."""

    def reset(self, obs: Any, info: dict[str, Any]) -> None:
        self.replans = 0
        self.replans_ran_out = 0
        self.history = []
        self.last_skill = None
        self._plan = None
        self._failure = None
        self._steps_taken = 0
        self._replan(self.observed_state(obs), first=True)

    def _replan(
        self, state: ObjectCentricState, first: bool = False, ran_out: bool = False
    ) -> None:
        """Plan from ``state`` (``ran_out``: because the plan's actions ran out); raise
        AgentFailure (and remember why) when that fails."""
        if not first:
            if self.replans >= self.args.max_replans:
                self._failure = (
                    f"{self.name}: plan diverged or ran out and the re-planning budget "
                    f"({self.args.max_replans}) is spent"
                )
                raise AgentFailure(self._failure)
            self.replans += 1
            self.replans_ran_out += ran_out
        plan = self.planner.plan(state, self.rng, self.steps_left())
        self.history.append(self.planner.stats)
        if plan is None or not plan.actions:
            s = self.planner.stats
            self._failure = (
                f"{self.name}: no plan found ({s.abstract_plans} abstract plan(s), "
                f"{s.skill_samples} skill samples, {s.time:.1f} s"
                f"{', timed out' if s.timed_out else ''})"
            )
            raise AgentFailure(self._failure)
        self._plan = plan
        self._t = 0

    def steps_left(self) -> int | None:
        """Steps left in the episode (the env's time limit minus the actions taken), or None
        when the env has no limit or ``respect_episode_limit`` is off."""
        spec = self.env.spec
        limit = None if spec is None else spec.max_episode_steps
        if not self.args.respect_episode_limit or limit is None:
            return None
        return max(0, int(limit) - self._steps_taken)

    def act(self, obs: Any) -> FloatArray:
        if self._failure is not None:
            raise AgentFailure(self._failure)
        if self._plan is None:
            raise AgentFailure(f"{self.name}: act() before reset()")
        state = self.observed_state(obs)
        plan = self._plan
        ran_out = self._t >= len(plan.actions)
        stale = ran_out or (
            self.args.replan_on_divergence
            and not _close(state, plan.states[self._t], self.args.divergence_atol)
        )
        if stale:
            self._replan(state, ran_out=ran_out)
        plan = self._plan
        action = plan.actions[self._t]
        i = plan.skill_index(self._t)
        self.last_skill = ExecutedSkill(
            len(self.history) - 1, i, plan.skill_operators[i], plan.skills[i][1]
        )
        self._t += 1
        self._steps_taken += 1
        return self.clip(action)

    def episode_info(self) -> dict[str, Any]:
        """The episode's planning calls and re-plans: ``replans`` in all, ``replans_ran_out``
        of them because the plan's actions ran out (the others: the observed state left the
        plan). Upstream's agent never re-plans (``max_replans=0``)."""
        return {
            "planning_calls": len(self.history),
            "replans": self.replans,
            "replans_ran_out": self.replans_ran_out,
        }

    @property
    def plan_(self) -> RefinedPlan | None:
        """The plan being executed."""
        return self._plan


def _close(a: ObjectCentricState, b: ObjectCentricState, atol: float) -> bool:
    if a.objects != b.objects:
        return False
    return bool(np.all(np.abs(a.data - b.data) <= atol))


def plan_episode(
    env: ObjectCentricEnv,
    state: ObjectCentricState,
    args: BilevelPlanningArgs | None = None,
    seed: int = 0,
    max_steps: int | None = None,
) -> tuple[RefinedPlan | None, PlanningStats]:
    """Plan once from ``state`` on ``env``'s model, with at most ``max_steps`` actions (a
    convenience for scripts and tests)."""
    planner = BilevelPlanner(model_for(env), args or BilevelPlanningArgs())
    plan = planner.plan(state, np.random.default_rng(seed), max_steps)
    return plan, planner.stats


def plan_reaches_goal(
    env: ObjectCentricEnv,
    seed: int,
    args: BilevelPlanningArgs | None = None,
    max_steps: int | None = None,
) -> tuple[bool, PlanningStats]:
    """Reset ``env`` with ``seed``, plan once (seeded alike, at most ``max_steps`` actions) and
    replay the plan through ``env.transition``: whether a plan was found and reaches the env's
    goal (for tests)."""
    x0, _ = env.reset(seed=seed)
    plan, stats = plan_episode(env, x0, args, seed=seed, max_steps=max_steps)
    if plan is None:
        return False, stats
    state, terminated = x0, False
    for action in plan.actions:
        state, _, terminated = env.transition(state, action)
    return terminated, stats


__all__: Sequence[str] = [
    "BilevelPlanner",
    "BilevelPlanningAgent",
    "BilevelPlanningArgs",
    "ExecutedSkill",
    "PlanningStats",
    "RefinedPlan",
    "abstract_match",
    "model_for",
    "plan_episode",
    "plan_reaches_goal",
    "use_model",
]
