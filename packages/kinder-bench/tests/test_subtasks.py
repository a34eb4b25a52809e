"""Subtask milestones: the tracker, SweepIntoDrawer3D's milestones on real states, the runner's
record, the aggregation, the summary column and the results page's subtask table."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from kinder_bench.evaluation.metrics import Stat, aggregate, seed_metrics
from kinder_bench.evaluation.protocol import PAPER_MAX_STEPS
from kinder_bench.evaluation.runner import EpisodeTask, run_episode
from kinder_bench.evaluation.subtasks import Milestone, SubtaskTracker, family, tracker_for
from kinder_bench.evaluation.summary import csv_table, parse_subtasks_field
from kinder_bench.reporting.paper import Result, at_paper_protocol, results_from_csv
from kinder_bench.reporting.report import subtasks_table, write_report
from kinder_bench.reporting.results_doc import load_paper_subtasks, subtasks_markdown

SWEEP = "kinder/SweepIntoDrawer3D-o5-v0"
NAMES = ("open_drawer", "grasp_sweeper", "sweep_some", "sweep_all")


def test_the_tracker_keeps_the_first_step_each_milestone_held() -> None:
    tracker = SubtaskTracker(
        [Milestone("big", lambda x: x > 5), Milestone("even", lambda x: x % 2 == 0)]  # type: ignore[arg-type,operator]
    )
    for step, value in enumerate([1, 3, 6, 2, 7]):
        tracker.observe(value, step)  # type: ignore[arg-type]
    # "big" held at step 2 and not at step 3: reached once counts.
    assert tracker.result() == {"big": 2, "even": 2}
    never = SubtaskTracker([Milestone("never", lambda x: False)])
    never.observe(0, 0)  # type: ignore[arg-type]
    assert never.result() == {"never": None}
    with pytest.raises(ValueError, match="at least one milestone"):
        SubtaskTracker([])


def test_only_families_with_milestones_get_a_tracker() -> None:
    assert family(SWEEP) == family("SweepIntoDrawer3D-o5") == "SweepIntoDrawer3D"
    assert tracker_for("kinder/Motion2D-p0-v0", None) is None  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def sweep_env() -> Any:
    import kinder_core

    env = kinder_core.make(SWEEP)
    env.reset(seed=1000)
    yield env.unwrapped
    env.close()


def test_sweep_into_drawer_milestones_on_real_states(sweep_env: Any) -> None:
    from kinder_gym.models.dynamic3d import sweep_into_drawer3d as model
    from kinder_gym.models.dynamic3d.tidybot import arm_joints, base_pose

    env = sweep_env
    start = env.get_state()
    tracker = tracker_for(SWEEP, env)
    assert tracker is not None
    tests = {m.name: m.reached for m in tracker.milestones}
    assert tuple(tests) == NAMES
    assert not any(t(start) for t in tests.values()), "nothing is reached at the start"

    objs = env.objects
    opened = start.copy()
    opened.set(objs[model.DRAWER], "pos", model.OPEN_POS + 0.05)
    assert tests["open_drawer"](opened) and not tests["sweep_some"](opened)

    # Put the wiper's head on the pinch point and close the gripper on it.
    robot, wiper = objs["robot"], objs[model.WIPER]
    held = start.copy()
    pinch = model.pinch_pose(base_pose(held, robot), arm_joints(held, robot))[0]
    for f, v in zip(("x", "y", "z"), pinch - model.HEAD_CENTRE):
        held.set(wiper, f, float(v))
    for f, v in zip(("qw", "qx", "qy", "qz"), (1.0, 0.0, 0.0, 0.0)):
        held.set(wiper, f, v)
    held.set(robot, "pos_gripper", 0.5)
    assert tests["grasp_sweeper"](held)
    held.set(robot, "pos_gripper", 0.0)  # open fingers hold nothing
    assert not tests["grasp_sweeper"](held)

    # Cubes into the drawer's goal region, one and then all.
    t = env.goal.regions.transform(opened, model.GOAL_REGION)
    box = env.goal.regions.specs[model.GOAL_REGION].boxes[0]
    inside = t[:3, :3] @ ((box[:3] + box[3:]) / 2) + t[:3, 3]
    cubes = sorted((o for n, o in objs.items() if n.startswith(model.SCREW_PREFIX)), key=str)
    some = opened.copy()
    for f, v in zip(("x", "y", "z"), inside):
        some.set(cubes[0], f, float(v))
    assert tests["sweep_some"](some) and not tests["sweep_all"](some)
    everything = some.copy()
    for cube in cubes:
        for f, v in zip(("x", "y", "z"), inside):
            everything.set(cube, f, float(v))
    assert tests["sweep_all"](everything) and bool(env.goal_reached(everything))


def _task(env_id: str, max_steps: int) -> EpisodeTask:
    return EpisodeTask(
        run_id="r",
        env_id=env_id,
        agent="random",
        agent_args={},
        label="random",
        max_steps=max_steps,
        seed=1000,
        episode=0,
        env_seed=1000,
        agent_seed=0,
    )


def test_the_runner_records_subtasks_only_where_the_family_has_them() -> None:
    record = run_episode(_task(SWEEP, 3))
    assert record["error"] is None, record["traceback"]
    assert record["subtasks"] == dict.fromkeys(NAMES)
    assert "subtasks" not in run_episode(_task("kinder/Motion2D-p0-v0", 3))


def _rec(seed: int, episode: int, reached: dict[str, int | None] | None) -> dict[str, Any]:
    record = {
        "run_id": "r1",
        "env_id": SWEEP,
        "agent": "dp",
        "label": "dp",
        "agent_args": {},
        "max_steps": 1000,
        "seed": seed,
        "episode": episode,
        "success": reached is not None and reached["sweep_all"] is not None,
        "reward": -100.0,
        "steps": 100,
        "inference_time": 1.0,
        "env_time": 0.1,
        "error": None,
    }
    if reached is not None:
        record["subtasks"] = reached
    return record


def _reached(*names: str) -> dict[str, int | None]:
    return {n: (10 if n in names else None) for n in NAMES}


# Seed 0: 2 of 2 open, 1 of 2 grasp; seed 1: 1 of 2 open, none further.
RECORDS = [
    _rec(0, 0, _reached("open_drawer", "grasp_sweeper")),
    _rec(0, 1, _reached("open_drawer")),
    _rec(1, 0, _reached("open_drawer")),
    _rec(1, 1, _reached()),
]


def test_subtask_rates_aggregate_per_seed_then_across_seeds() -> None:
    s0 = seed_metrics([r for r in RECORDS if r["seed"] == 0])
    assert s0.subtasks == {"open_drawer": 1.0, "grasp_sweeper": 0.5, "sweep_some": 0.0,
                           "sweep_all": 0.0}  # fmt: skip
    (summary,) = aggregate(RECORDS)
    assert summary.subtasks["open_drawer"].mean == pytest.approx(0.75)
    assert summary.subtasks["open_drawer"].std == pytest.approx(np.std([1.0, 0.5], ddof=1))
    assert summary.subtasks["grasp_sweeper"].mean == pytest.approx(0.25)
    # One episode without the record (written before tracking existed): no rates at all.
    assert aggregate([*RECORDS[:3], _rec(1, 1, None)])[0].subtasks == {}


def test_the_summary_column_round_trips(tmp_path: Path) -> None:
    (summary,) = aggregate(RECORDS)
    path = tmp_path / "x_summary.csv"
    path.write_text(csv_table([summary], {"r1": "kinder bench run ..."}))
    (result,) = results_from_csv(path)
    assert set(result.subtasks) == set(NAMES)
    for name in NAMES:
        assert result.subtasks[name].mean == pytest.approx(summary.subtasks[name].mean)
    assert parse_subtasks_field("", 5) == {}
    with pytest.raises(ValueError, match="subtasks"):
        parse_subtasks_field('{"open_drawer": 0.5}', 5)


def test_the_report_prints_the_subtask_table(tmp_path: Path) -> None:
    table = subtasks_table(aggregate(RECORDS))
    assert "SweepIntoDrawer3D-o5" in table and "| dp | 0.75 ± 0.35 | 0.25 ± 0.35 |" in table
    assert subtasks_table(aggregate([_rec(0, 0, None)])) == ""
    from kinder_bench.evaluation.results import append_record

    (tmp_path / "run").mkdir()
    for r in RECORDS:
        append_record(tmp_path / "run" / "results.jsonl", r)
    md, paths = write_report([tmp_path / "run"], plot=False)
    assert "grasp_sweeper" in md and "grasp_sweeper" in paths["table"].read_text()


def _result(agent: str, label: str, seeds: tuple[int, ...], per_seed: int) -> Result:
    stat = Stat(0.5, 0.1, len(seeds))
    return Result(
        env_id=SWEEP,
        method=label,
        agent=agent,
        run_id=f"{label}-{len(seeds)}",
        success=stat,
        reward=stat,
        inference_time=stat,
        num_seeds=len(seeds),
        episodes=len(seeds) * per_seed,
        errors=0,
        command="kinder bench run ...",
        seeds=seeds,
        max_steps=PAPER_MAX_STEPS[SWEEP],
        agent_args={},
        training="",
        subtasks={n: Stat(0.5, 0.1, len(seeds)) for n in NAMES},
    )


def test_the_results_page_puts_ours_beside_the_papers_subtasks() -> None:
    paper = load_paper_subtasks()
    assert paper[(SWEEP, "dp")] == {"open_drawer": "0.87", "grasp_sweeper": "0.74",
                                    "sweep_some": "0.22", "sweep_all": "0.14"}  # fmt: skip
    empty = subtasks_markdown([])
    assert "| DP (paper) |  | n/r (0.87) | n/r (0.74) | n/r (0.22) | n/r (0.14) |" in empty
    # A variant (5 × 10) of DP fills no paper cell: it gets its own row, named by what differs.
    variant = _result("dp", "dp", (0, 1, 2, 3, 4), 10)
    md = subtasks_markdown([variant])
    assert "| DP (paper) |  | n/r (0.87)" in md
    assert "| DP · 5×10, training not recorded | 5 × 10 | 0.50 ± 0.10 |" in md
    # Only a run at the paper's protocol fills the paper's row (DP needs its training budget).
    protocol = dataclasses.replace(
        variant, episodes=250, training="paper preset, up to 5001 epochs"
    )
    assert at_paper_protocol(protocol)
    md = subtasks_markdown([protocol])
    assert "| DP (paper) | 5 × 50 | 0.50 ± 0.10 (0.87) | 0.50 ± 0.10 (0.74) |" in md
    assert "| DP ·" not in md
    with pytest.raises(ValueError, match="row 2"):
        load_paper_subtasks("env_id,baseline,a\nkinder/X-v0,dp,high\n")
    with pytest.raises(ValueError, match="header"):
        load_paper_subtasks("env,baseline,a\n")
