"""Why bilevel planning finds no plan: the skill failures and abstract mismatches of each episode.

Plans the first planning call of each episode of a development run seed (the runner's episode
seeds of ``--seed``, by default :data:`~kinder_bench.evaluation.protocol.DEVELOPMENT_SEED`: never
the evaluation seeds 0–4, whose episodes fill the results table; the BP agent's defaults and the
env's step limit) and, for the episodes where no plan is found, counts what the skill samples ran
into: each :class:`~kinder_gym.skills.SkillFailure` by controller and message (numbers stripped, so
messages that differ only in a coordinate count together), and the samples whose reached abstract
state differed from the operator's prediction.

    uv run python benchmarks/probes/bp_failure_causes.py kinder/DynObstruction2D-o1-v0 --episodes 50

Prints a markdown table: cause, how many failed episodes met it, and how many samples it cost.
"""

from __future__ import annotations

import argparse
import collections
import re
from typing import Any

import gymnasium

from kinder_bench.baselines import bilevel_planning as bp
from kinder_bench.evaluation.protocol import DEVELOPMENT_SEED
from kinder_bench.evaluation.runner import episode_seeds
from kinder_core import make_object_centric
from kinder_gym import skills


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("env_id")
    p.add_argument("--seed", type=int, default=DEVELOPMENT_SEED, help="a development run seed")
    p.add_argument("--episodes", type=int, default=50)
    a = p.parse_args()
    env = make_object_centric(a.env_id)
    max_steps = gymnasium.spec(a.env_id).max_episode_steps  # registered by make_object_centric
    current: collections.Counter[str] = collections.Counter()
    execute = skills.execute_skill

    def counting(controller: Any, *args: Any, **kwargs: Any) -> Any:
        try:
            return execute(controller, *args, **kwargs)
        except skills.SkillFailure as e:
            message = re.sub(r"-?\d+\.\d+", "#", str(e))
            current[f"{type(controller).__name__}: {message}"] += 1
            raise

    bp.execute_skill = counting  # the planner calls it through its module
    episodes: collections.Counter[str] = collections.Counter()
    samples: collections.Counter[str] = collections.Counter()
    solved = 0
    seeds = episode_seeds(a.seed, a.episodes)
    for s in seeds:
        current.clear()
        x0, _ = env.reset(seed=s)
        plan, stats = bp.plan_episode(
            env, x0, bp.BilevelPlanningArgs(), seed=s, max_steps=max_steps
        )
        if plan is not None:
            solved += 1
            continue
        causes = dict(current)
        if stats.abstract_mismatches:
            causes["reached abstract state differs from the prediction"] = stats.abstract_mismatches
        if stats.over_budget:
            causes["plan longer than the episode's step limit"] = stats.over_budget
        if stats.timed_out:
            causes["planning timeout"] = 1
        for cause, n in causes.items():
            episodes[cause] += 1
            samples[cause] += n
    print(f"{a.env_id}: the first planning call solved {solved} of {len(seeds)} episodes ", end="")
    print(f"(runner seed {a.seed})\n")
    print("| cause (failed episodes may meet several) | failed episodes | samples |")
    print("|---|---|---|")
    for cause, n in episodes.most_common():
        print(f"| {cause} | {n} | {samples[cause]} |")


if __name__ == "__main__":
    main()
