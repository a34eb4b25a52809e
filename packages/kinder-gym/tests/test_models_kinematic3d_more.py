"""Obstruction3D, Packing3D and Table3D planning models (need the ``[3d]`` extra)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import ObjectCentricEnv, ObjectCentricState, make_object_centric
from kinder_gym.model import PlanningModel
from kinder_gym.models import create_model
from kinder_gym.models.kinematic3d.obstruction3d import grasp_poses
from kinder_gym.models.kinematic3d.tidybot import polygons_overlap
from kinder_gym.testing import check_planning_model


def names(atoms: frozenset[object]) -> set[str]:
    return {str(a) for a in atoms}


def run_chain(
    env: ObjectCentricEnv, model: PlanningModel, state: ObjectCentricState, steps: Sequence[str]
) -> ObjectCentricState:
    """Run the named ground operators' skills in turn, sampling parameters as the planner does;
    each must reach its operator's predicted abstract state within five samples."""
    rng = np.random.default_rng(0)
    assert model.env is env
    return check_planning_model(
        model,
        state,
        steps,
        rng,
        samples=5,
        retry_mispredictions=True,
        check_action_bounds=True,
        require_finished=False,
    )


# -- Obstruction3D ------------------------------------------------------------------------------


def test_obstruction3d_predicates_on_built_states() -> None:
    env = make_object_centric("kinder/Obstruction3D-o2-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert names(model.abstract(state)) == {
        "(HandEmpty robot)",
        "(Obstructed2 target_region)",
        "(Obstructing obstruction0 target_region)",
        "(Obstructing obstruction1 target_region)",
        "(OnTable target_block)",
    }
    assert names(model.goal(state)) == {
        "(HandEmpty robot)",
        "(OnRegion target_block target_region)",
    }
    # Move both obstructions off the region and put the block on it.
    moved = state.copy()
    moved.set(env.obstructions[0], "pose_x", 0.45)
    moved.set(env.obstructions[0], "pose_y", -0.35)
    moved.set(env.obstructions[1], "pose_x", 0.45)
    moved.set(env.obstructions[1], "pose_y", -0.25)
    region = moved[env.region]
    block = moved[env.block]
    block[0], block[1] = region[0], region[1]
    block[2] = region[2] + region[11] + block[11] + 0.002
    atoms = names(model.abstract(moved))
    assert atoms == {
        "(HandEmpty robot)",
        "(Obstructed0 target_region)",
        "(OnRegion target_block target_region)",
        "(OnTable obstruction0)",
        "(OnTable obstruction1)",
    }
    assert env.goal_reached(moved)
    # A held block is in no placement predicate.
    held = moved.copy()
    held.set(env.robot, "grasp_active", 1.0)
    held.set(env.block, "grasp_active", 1.0)
    atoms = names(model.abstract(held))
    assert "(Holding robot target_block)" in atoms
    assert "(HandEmpty robot)" not in atoms
    assert not any("target_block target_region" in a for a in atoms)


def test_obstruction3d_grounding() -> None:
    env = make_object_centric("kinder/Obstruction3D-o2-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert sorted(o.name for o in model.ground_operators(state)) == [
        "PickBlock(robot, target_block)",
        "PickObstruction1(robot, obstruction0, target_region)",
        "PickObstruction1(robot, obstruction1, target_region)",
        "PickObstruction2(robot, obstruction0, target_region)",
        "PickObstruction2(robot, obstruction1, target_region)",
        "PlaceOnRegion(robot, target_block, target_region)",
        "PlaceOnTable(robot, obstruction0)",
        "PlaceOnTable(robot, obstruction1)",
    ]
    assert "(:action PickObstruction2" in model.domain_pddl()


def test_obstruction3d_grasps_keep_the_pads_clear() -> None:
    # A 4 cm cube with a taller neighbour 5 mm away along +x: no grasp closes along x, and the
    # pinch point sits 28 mm above the cube's bottom so the pads (25 mm below it) clear the
    # support.
    cube = np.array([0.3, 0.0, 0.1, 0, 0, 0, 1, 0, -1, 0.02, 0.02, 0.02])
    wall = np.array([[0.325, -0.05], [0.345, -0.05], [0.345, 0.05], [0.325, 0.05]])
    poses = grasp_poses(cube, [(wall, 0.08, 0.2)], 0.0)
    assert poses
    for pos, _ in poses:
        assert pos[2] == pytest.approx(0.08 + 0.028)
    free = grasp_poses(cube, [], 0.0)
    assert len(free) > len(poses)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert polygons_overlap(square, square + 0.5, 0.0)
    assert not polygons_overlap(square, square + np.array([1.01, 0.0]), 0.0)
    assert polygons_overlap(square, square + np.array([1.01, 0.0]), 0.02)


def test_obstruction3d_skills_reach_their_predictions() -> None:
    env = make_object_centric("kinder/Obstruction3D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    state = run_chain(
        env,
        model,
        state,
        [
            "PickObstruction1(robot, obstruction0, target_region)",
            "PlaceOnTable(robot, obstruction0)",
            "PickBlock(robot, target_block)",
            "PlaceOnRegion(robot, target_block, target_region)",
        ],
    )
    assert env.goal_reached(state)


# -- Packing3D ----------------------------------------------------------------------------------


def test_packing3d_predicates_and_grounding() -> None:
    env = make_object_centric("kinder/Packing3D-p2-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert names(model.abstract(state)) == {
        "(HandEmpty robot)",
        "(OnTablePlate part0)",
        "(OnTableTriangle part1)",
    }
    assert names(model.goal(state)) == {
        "(HandEmpty robot)",
        "(InRackPlate part0 rack)",
        "(InRackTriangle part1 rack)",
    }
    assert sorted(o.name for o in model.ground_operators(state)) == [
        "PickPlate(robot, part0)",
        "PickTriangle(robot, part1)",
        "PlacePlate(robot, part0, rack)",
        "PlaceTriangle(robot, part1, rack)",
    ]
    # A plate seated in the rack's −y end.
    seated = state.copy()
    rack = seated[env.rack]
    plate = seated[env.parts[0]]
    plate[0], plate[1] = rack[0], rack[1] - 0.08
    plate[2] = rack[2] - rack[11] + 0.01 + plate[11] + 0.002
    assert "(InRackPlate part0 rack)" in names(model.abstract(seated))


def test_packing3d_skills_reach_their_predictions() -> None:
    env = make_object_centric("kinder/Packing3D-p1-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    state = run_chain(
        env, model, state, ["PickTriangle(robot, part0)", "PlaceTriangle(robot, part0, rack)"]
    )
    assert env.goal_reached(state)


# -- Table3D ------------------------------------------------------------------------------------


def test_table3d_predicates_and_pick() -> None:
    env = make_object_centric("kinder/Table3D-o2-v0")
    model = create_model(env)
    state = env.reset(seed=0)[0]
    assert names(model.abstract(state)) == {
        "(HandEmpty robot)",
        "(OnTable cube0)",
        "(OnTable cube1)",
    }
    assert names(model.goal(state)) == {"(HoldingUp robot)"}
    assert sorted(o.name for o in model.ground_operators(state)) == [
        "Pick(robot, cube0)",
        "Pick(robot, cube1)",
    ]
    # Held but not high enough: Holding without HoldingUp.
    held = state.copy()
    held.set(env.robot, "grasp_active", 1.0)
    held.set(env.cubes[0], "grasp_active", 1.0)
    assert names(model.abstract(held)) == {"(Holding robot cube0)", "(OnTable cube1)"}
    held.set(env.cubes[0], "pose_z", 0.6)
    assert "(HoldingUp robot)" in names(model.abstract(held))
    state = run_chain(env, model, state, ["Pick(robot, cube0)"])
    assert env.goal_reached(state)


# -- the planner --------------------------------------------------------------------------------


def solves(env_id: str, seeds: Sequence[int]) -> None:
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_reaches_goal

    env = make_object_centric(env_id)
    for seed in seeds:
        reached, stats = plan_reaches_goal(env, seed, BilevelPlanningArgs(planning_timeout=60))
        assert reached, (env_id, seed, stats)


@pytest.mark.parametrize(
    "env_id",
    ["kinder/Obstruction3D-o1-v0", "kinder/Packing3D-p1-v0", "kinder/Table3D-o1-v0"],
)
def test_planner_solves_the_smallest_variant(env_id: str) -> None:
    pytest.importorskip("kinder_bench")
    solves(env_id, [0])


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_id",
    ["kinder/Obstruction3D-o4-v0", "kinder/Packing3D-p3-v0", "kinder/Table3D-o3-v0"],
)
def test_planner_solves_the_largest_variant(env_id: str) -> None:
    pytest.importorskip("kinder_bench")
    solves(env_id, [0, 1])
