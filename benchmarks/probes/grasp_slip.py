"""Slip of a held 2 cm cube and the step cost of Dynamic3D under different MuJoCo contact settings.

For each contact setting (friction cone, impratio) and seed: reset ``kinder/Shelf3D-o1-v0``, run
the Shelf3D model's Pick skill (parameters drawn as the planner would, up to 5 tries) until the
cube is held, then hold still (zero deltas, gripper closed) for 10 actions and ``--hold`` more,
and report how fast the cube moved relative to the pinch point over the latter (mm/s of simulated
time) and whether it is still held. Step cost is the mean CPU time of this process per ``env.step``
(µs per action; CPU rather than wall time, so that other jobs on a shared machine inflate it less)
over the hold and over ``--random`` seeded random actions on Shelf3D-o1 and SweepIntoDrawer3D-o5.
Settings are run alternately per seed so that machine load affects them alike.

Usage:
    python benchmarks/probes/grasp_slip.py [--seeds 1000-1004] [--hold 50] [--random 200]
        [--settings pyramidal:1 elliptic:10 ...] [--out benchmarks/results/grasp_slip.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from kinder_bench.evaluation.protocol import DEVELOPMENT_SEED
from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose, pinch_position
from kinder_gym.skills import SkillFailure, execute_skill

SHELF = "kinder/Shelf3D-o1-v0"
SWEEP = "kinder/SweepIntoDrawer3D-o5-v0"
#: Actions held before the slip is measured.
SETTLE = 10


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def _config(setting: str) -> dict[str, Any]:
    cone, impratio = setting.split(":")
    return {"cone": cone, "impratio": float(impratio)}


def slip(setting: str, seed: int, hold: int) -> dict[str, Any]:
    """Pick the cube, hold it, and measure its drift relative to the pinch point."""
    env = make_object_centric(SHELF, config=_config(setting))
    model = create_model(env)
    robot, cube = env.objects["robot"], env.objects["cube1"]  # type: ignore[attr-defined]
    state = env.reset(seed=seed)[0]
    op = next(o for o in model.ground_operators(state) if o.name == "Pick(robot, cube1)")
    rng = np.random.default_rng(seed)
    held = None
    for _ in range(5):
        gs = model.skill(op)
        try:
            out = execute_skill(gs.controller, state, gs.controller.sample_parameters(state, rng),
                                env.transition, 400)  # fmt: skip
        except SkillFailure:
            continue
        if "(Holding robot cube1)" in {str(a) for a in model.abstract(out.states[-1])}:
            held = out.states[-1]
            break
    rec: dict[str, Any] = {"setting": setting, "seed": seed}
    if held is None:
        rec["picked"] = False
        return rec
    rec["picked"] = True

    def offset(s: Any) -> np.ndarray:
        pinch = pinch_position(base_pose(s, robot), arm_joints(s, robot))
        return np.asarray(s[cube][:3]) - pinch

    action = np.zeros(env.action_space.shape, dtype=np.float32)
    action[10] = 1.0
    env.set_state(held)
    s = held
    for _ in range(SETTLE):  # the fingers finish closing and the arm comes to rest
        s = env.step(action)[0]
    start = offset(s)
    t0 = time.process_time()
    for _ in range(hold):
        s = env.step(action)[0]
    rec["hold_step_us"] = 1e6 * (time.process_time() - t0) / hold
    seconds = hold * env.config.substeps * env.config.timestep  # type: ignore[attr-defined]
    rec["slip_mm_per_s"] = 1e3 * float(np.linalg.norm(offset(s) - start)) / seconds
    rec["still_held"] = "(Holding robot cube1)" in {str(a) for a in model.abstract(s)}
    env.close()
    return rec


def step_cost(setting: str, env_id: str, seed: int, steps: int) -> float:
    """Mean µs per step of seeded random actions (resetting on termination)."""
    env = make_object_centric(env_id, config=_config(setting))
    env.reset(seed=seed)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    t0 = time.process_time()
    for a in actions:
        if env.step(a)[2]:
            env.reset()
    us = 1e6 * (time.process_time() - t0) / steps
    env.close()
    return us


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seeds",
        default=f"{DEVELOPMENT_SEED}-{DEVELOPMENT_SEED + 4}",
        help="env reset seeds (development seeds, never the evaluation instances)",
    )
    parser.add_argument("--hold", type=int, default=50, help="actions held still (0.1 s each)")
    parser.add_argument("--random", type=int, default=200, help="random actions per step-cost run")
    parser.add_argument("--settings", nargs="+", default=["pyramidal:1", "elliptic:10"])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    recs: list[dict[str, Any]] = []
    for seed in _seeds(args.seeds):
        for setting in args.settings:
            rec = slip(setting, seed, args.hold)
            for env_id in (SHELF, SWEEP):
                rec[f"random_step_us {env_id}"] = step_cost(setting, env_id, seed, args.random)
            print(json.dumps(rec), flush=True)
            recs.append(rec)
    print(
        "\n| cone:impratio | picked | still held | slip mm/s (median, max) | hold µs/step "
        "| random µs/step Shelf3D-o1 | random µs/step SweepIntoDrawer3D-o5 |"
    )
    print("|---|---|---|---|---|---|---|")
    for setting in args.settings:
        rs = [r for r in recs if r["setting"] == setting]
        held = [r for r in rs if r["picked"]]
        sl = [r["slip_mm_per_s"] for r in held]

        def med(key: str, rs: list[dict[str, Any]] = rs) -> float:
            return float(statistics.median(r[key] for r in rs if key in r))

        print(
            f"| {setting} | {len(held)}/{len(rs)} | {sum(r['still_held'] for r in held)}/"
            f"{len(held)} | {statistics.median(sl):.3f}, {max(sl):.3f} | "
            f"{med('hold_step_us'):.0f} | {med(f'random_step_us {SHELF}'):.0f} | "
            f"{med(f'random_step_us {SWEEP}'):.0f} |"
            if sl
            else f"| {setting} | 0/{len(rs)} | | | | | |"
        )
    if args.out:
        tmp = args.out.with_suffix(".tmp")
        tmp.write_text(json.dumps(recs, indent=1) + "\n")
        os.replace(tmp, args.out)


if __name__ == "__main__":
    main()
