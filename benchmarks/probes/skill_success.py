"""How often the dynamic planning models' skills reach their operators' predictions.

A planner-free check of the skills (no search, no time budget, so machine load does not change
it), for comparing physics settings or skill constants. For each env reset seed (development
seeds, :data:`~kinder_bench.evaluation.protocol.DEVELOPMENT_SEED` on by default, so that no skill is
tuned on an instance the evaluation uses) the operators run in a fixed order, each with up to 3
parameter samples from its own sampler:

* ``shelf``: Pick then Place of every cube in turn (Shelf3D-oN); a step counts when the
  abstract state afterwards equals the operator's prediction.
* ``sweep``: OpenDrawer, PickWiper, then up to 6 Sweep passes, each aimed at the first screw not
  yet in the drawer (SweepIntoDrawer3D-o5); a pass counts when its target ends in the drawer and
  no screw is lost (a pass that loses one is undone, as the planner would reject it).
* ``toss``: Topple, then Pick and Drop of every cube in turn (Tossing3D-oN); a step counts as
  for ``shelf``.
* ``cupboard``: Pick then Place of every cube, then PickRod then PlaceRod of every rod
  (SortClutteredBlocks3D-o12, the cupboard variant); a step counts as for ``shelf``; no step
  limit (the actions are counted: the whole task needs more than its 1000).
* ``pour``: Pick then Place of every cube in turn (ScoopPour3D-oN: cube by cube with the
  gripper); a step counts as for ``shelf``, a cube already in the green bin is skipped.
* ``pickplace``: greedy passes over the objects not yet at their goal: Pick, then the one other
  operator on that object (Place, Drop); an object whose Pick, or whose place after it, fails
  all its samples waits for the next pass, and a place after which no Pick works is drawn
  again, as the planner would backtrack; an object that reached its goal with another one (a
  neighbour carried along) is skipped (SortClutteredBlocks3D bins and bowls); no step limit
  (the actions are counted, to size a variant's step budget). A model that moves the objects
  with a tool (SweepSimple3D: PickWiper, then Sweep of each block) takes the tool once, then
  runs the one operator on each object in the same passes, up to the model's
  ``max_skill_horizon`` actions a run (a sweep takes more than the carrying skills' 400).
* ``scoop``: GraspScoop, then ScoopAndPour within what is left of the episode's step limit
  (DynScoopPour2D-oN), one parameter sample each, so its counts are single-sample rates.

Usage:
    python benchmarks/probes/skill_success.py shelf --env kinder/Shelf3D-o4-v0 --seeds 1000-1005
    python benchmarks/probes/skill_success.py sweep --seeds 1000-1019 [--contacts pyramidal:1]
    python benchmarks/probes/skill_success.py toss --env kinder/Tossing3D-o2-v0 --seeds 1000-1009
    python benchmarks/probes/skill_success.py scoop --env kinder/DynScoopPour2D-o10-v0 \\
        --seeds 1000-1029
    python benchmarks/probes/skill_success.py cupboard --seeds 1000-1009
    python benchmarks/probes/skill_success.py pour --env kinder/ScoopPour3D-o10-v0 --seeds 1000-1011
    python benchmarks/probes/skill_success.py pickplace \\
        --env kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins-v0

A step counts as the planner counts it (``abstract_match``): the predicted abstract state, or
one with extra atoms of the model's monotone predicates. ``--verbose`` prints a line per skill
run on stderr (long measurements). Prints one JSON object: successes and tries per skill, the
actions of the successful runs, the screws in the drawer at the end (sweep), the episodes whose
env goal was reached and each episode's actions (the successful skill runs only, as a plan
executes them).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from kinder_bench.evaluation.protocol import DEVELOPMENT_SEED
from kinder_bench.evaluation.results import write_json
from kinder_core import ObjectCentricState, make_object_centric
from kinder_gym.model import abstract_match
from kinder_gym.models import create_model
from kinder_gym.skills import SkillFailure, execute_skill

TRIES = 3
MAX_STEPS = 400


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "model", choices=("shelf", "sweep", "toss", "scoop", "cupboard", "pour", "pickplace")
    )
    parser.add_argument("--env", help="env id (default: Shelf3D-o1 or SweepIntoDrawer3D-o5)")
    parser.add_argument(
        "--seeds",
        default=f"{DEVELOPMENT_SEED}-{DEVELOPMENT_SEED + 9}",
        help="env reset seeds (development seeds: never tune on the evaluation instances)",
    )
    parser.add_argument("--contacts", help="cone:impratio, e.g. pyramidal:1 (default: the env's)")
    parser.add_argument("--out", type=Path, help="also write the JSON object to this file")
    parser.add_argument(
        "--verbose", action="store_true", help="one line per skill run on stderr (long runs)"
    )
    args = parser.parse_args(argv)
    default = {
        "shelf": "kinder/Shelf3D-o1-v0",
        "sweep": "kinder/SweepIntoDrawer3D-o5-v0",
        "toss": "kinder/Tossing3D-o1-v0",
        "scoop": "kinder/DynScoopPour2D-o10-v0",
        "cupboard": "kinder/SortClutteredBlocks3D-o12-sort_the_blocks_into_the_cupboard-v0",
        "pour": "kinder/ScoopPour3D-o10-v0",
        "pickplace": "kinder/SortClutteredBlocks3D-o20-sort_the_cluttered_blocks_into_bins-v0",
    }[args.model]
    kwargs: dict[str, Any] = {}
    if args.contacts:
        cone, impratio = args.contacts.split(":")
        kwargs["config"] = {"cone": cone, "impratio": float(impratio)}
    env = make_object_centric(args.env or default, **kwargs)
    model = create_model(env)
    stats: dict[str, Any] = {
        "env": args.env or default,
        "seeds": args.seeds,
        "contacts": args.contacts or "default",
    }
    steps = 0
    in_drawer = 0
    episode_actions: list[int] = []
    episode_solved: list[bool] = []

    def count(skill: str, ok: bool) -> None:
        done, tried = stats.get(skill, (0, 0))
        stats[skill] = (done + ok, tried + 1)

    def atoms(s: ObjectCentricState) -> set[str]:
        return {str(a) for a in model.abstract(s)}

    def run(
        name: str,
        skill: str,
        state: ObjectCentricState,
        rng: np.random.Generator,
        tries: int = TRIES,
        max_steps: int = MAX_STEPS,
    ) -> ObjectCentricState | None:
        nonlocal steps
        op = ops[name]
        want_atoms = op.apply(model.abstract(state))
        want = {str(a) for a in want_atoms}
        target = name.split(", ")[-1].rstrip(")")
        for _ in range(tries):
            gs = model.skill(op)
            params = gs.controller.sample_parameters(state, rng)
            started = time.perf_counter()
            try:
                out = execute_skill(gs.controller, state, params, env.transition, max_steps,
                                    stop_on_goal=False)  # fmt: skip
            except SkillFailure as failure:
                count(skill, False)
                if args.verbose:
                    print(f"{name}: failed ({failure}) in {time.perf_counter() - started:.1f} s",
                          file=sys.stderr, flush=True)  # fmt: skip
                continue
            reached = model.abstract(out.states[-1])
            after = {str(a) for a in reached}
            if args.model == "sweep" and skill == "Sweep":
                # monotone: other screws may drop in too, none may be lost
                ok = f"(InDrawer {target})" in after and not any("(Lost" in a for a in after)
            else:  # as the planner accepts it: exact, or extra monotone atoms
                ok = out.finished and abstract_match(model, reached, want_atoms)
            count(skill, ok)
            if args.verbose:
                print(f"{name}: {'ok' if ok else 'missed ' + str(sorted(after ^ want))[:200]}, "
                      f"{len(out.actions)} actions in {time.perf_counter() - started:.1f} s",
                      file=sys.stderr, flush=True)  # fmt: skip
            if ok:
                steps += len(out.actions)
                return out.states[-1]
        return None

    for seed in _seeds(args.seeds):
        steps_before = steps
        state: ObjectCentricState | None = env.reset(seed=seed)[0]
        rng = np.random.default_rng(seed)
        assert state is not None
        ops = {o.name: o for o in model.ground_operators(state)}
        if args.model == "shelf":
            for cube in sorted(n for n in env.objects if n.startswith("cube")):  # type: ignore[attr-defined]
                for name, skill in ((f"Pick(robot, {cube})", "Pick"),
                                    (f"Place(robot, {cube}, cupboard_1)", "Place")):  # fmt: skip
                    state = run(name, skill, state, rng) if state is not None else None
        elif args.model == "cupboard":
            names = sorted(n for n in env.objects if "_cube" in n or "_cuboid" in n)  # type: ignore[attr-defined]
            for obj in sorted(names, key=lambda n: ("_cuboid" in n, n)):  # cubes first
                kind = "Rod" if "_cuboid" in obj else ""
                pick, place = f"Pick{kind}", f"Place{kind}"
                for name, skill in ((f"{pick}(robot, {obj})", pick),
                                    (f"{place}(robot, {obj}, cupboard_0)", place)):  # fmt: skip
                    state = run(name, skill, state, rng) if state is not None else None
        elif args.model == "pour":
            for cube in sorted(n for n in env.objects if n.startswith("cube_")):  # type: ignore[attr-defined]
                if state is not None and f"(InTarget {cube})" not in atoms(state):
                    for name in (f"Pick(robot, {cube})", f"Place(robot, {cube})"):
                        skill = name.split("(")[0]
                        state = run(name, skill, state, rng) if state is not None else None
        elif args.model == "pickplace":
            assert state is not None
            goal = {str(a) for a in model.goal(state)}
            objs = sorted(n.split(", ")[1].rstrip(")") for n in ops if n.startswith("Pick("))
            horizon = MAX_STEPS
            # Each object's operators: Pick, then the place; with a tool (no Pick of an object:
            # SweepSimple3D), the tool's pick once, then the one operator on each object.
            moves = {
                o: (f"Pick(robot, {o})",
                    next(n for n in ops if not n.startswith("Pick(") and f", {o})" in n))
                for o in objs
            }  # fmt: skip
            if not objs:
                objs = sorted({a.strip("()").split()[-1] for a in goal})
                tool_pick = next(n for n in ops if n.startswith("Pick")
                                 and n.split(", ")[-1].rstrip(")") not in objs)  # fmt: skip
                tool = tool_pick.split(", ")[-1].rstrip(")")
                use = next(n.split("(")[0] for n in ops if f"(robot, {tool}, " in n)
                moves = {o: (f"{use}(robot, {tool}, {o})",) for o in objs}
                horizon = model.max_skill_horizon  # a sweep is longer than MAX_STEPS
                state = run(tool_pick, tool_pick.split("(")[0], state, rng, max_steps=horizon)
            pending = list(objs)
            # (state before the last place, the place's name, its action count): a place
            # after which no pick works is drawn again, as the planner would backtrack.
            last: tuple[ObjectCentricState, str, int] | None = None
            redraws = 0
            while pending and state is not None:
                progress = False
                for obj in list(pending):
                    if {a for a in goal if obj in a.strip("()").split()} <= atoms(state):
                        pending.remove(obj)  # let down in the goal area with another object
                        progress = True
                        continue
                    start = steps
                    *firsts, place = moves[obj]
                    picked: ObjectCentricState | None = state
                    for name in firsts:
                        if picked is not None:
                            picked = run(name, name.split("(")[0], picked, rng)
                    if picked is None:
                        continue
                    before = steps
                    placed = run(place, place.split("(")[0], picked, rng, max_steps=horizon)
                    if placed is None:  # every place failed: undo the pick, try it again later
                        steps = start
                        continue
                    state, last = placed, (picked, place, steps - before)
                    if {a for a in goal if obj in a.strip("()").split()} <= atoms(state):
                        pending.remove(obj)
                        progress = True
                if not progress and last is not None and redraws < TRIES * len(objs):
                    picked, place, n = last
                    redraws += 1
                    before = steps
                    redo = run(place, place.split("(")[0], picked, rng, max_steps=horizon)
                    if redo is not None:  # the new place replaces the old one
                        last = (picked, place, steps - before)
                        steps -= n
                        state = redo
                    continue
                if not progress:
                    break
        elif args.model == "scoop":
            limit = env.spec.max_episode_steps if env.spec is not None else 1000
            before = steps
            state = run("GraspScoop(robot, hook)", "GraspScoop", state, rng, 1, limit)
            if state is not None:
                left = limit - (steps - before)
                state = run("ScoopAndPour(robot, hook)", "ScoopAndPour", state, rng, 1, left)
        elif args.model == "toss":
            steps_ = [("Topple(robot, cuboid_barrier)", "Topple")]
            for cube in sorted(n for n in env.objects if n.startswith("cube_")):  # type: ignore[attr-defined]
                steps_ += [(f"Pick(robot, {cube})", "Pick"),
                           (f"Drop(robot, {cube}, bin_0, cuboid_barrier)", "Drop")]  # fmt: skip
            for name, skill in steps_:
                state = run(name, skill, state, rng) if state is not None else None
        else:
            for prefix in ("OpenDrawer", "PickWiper"):
                name = next(n for n in ops if n.startswith(prefix))
                state = run(name, prefix, state, rng) if state is not None else None
            for _ in range(6):
                if state is None:
                    break
                have = atoms(state)
                left = [n for n in ops if n.startswith("Sweep")
                        and f"(InDrawer {n.split(', ')[-1].rstrip(')')})" not in have]  # fmt: skip
                if not left:
                    break
                state = run(left[0], "Sweep", state, rng, tries=1) or state
            if state is not None:
                in_drawer += sum(a.startswith("(InDrawer") for a in atoms(state))
        episode_solved.append(state is not None and bool(env.goal_reached(state)))
        episode_actions.append(steps - steps_before)
    stats.update({"success_actions": steps, "solved": sum(episode_solved)})
    stats.update({"episode_actions": episode_actions, "episode_solved": episode_solved})
    if args.model == "sweep":
        stats["screws_in_drawer"] = in_drawer
    print(json.dumps(stats))
    if args.out is not None:
        write_json(args.out, stats)


if __name__ == "__main__":
    main()
