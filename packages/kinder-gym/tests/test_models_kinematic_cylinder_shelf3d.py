"""The KinematicCylinderShelf3D planning model (needs the ``[3d]`` extra)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_garden3d.kinematic3d.geometry import quat_to_matrix
from kinder_garden3d.kinematic3d.kinematic_cylinder_shelf3d import KinematicCylinderShelf3DEnv
from kinder_gym.models import create_model
from kinder_gym.models.kinematic3d.kinematic_cylinder_shelf3d import side_quat
from kinder_gym.testing import check_planning_model


def names(atoms: frozenset[object]) -> set[str]:
    return {str(a) for a in atoms}


def test_side_quat_levels_the_approach_along_the_heading() -> None:
    for heading in (0.0, 0.7, -2.0):
        rot = quat_to_matrix(side_quat(heading))
        assert rot[:, 2] == pytest.approx([math.cos(heading), math.sin(heading), 0.0], abs=1e-12)


def test_predicates_follow_the_env_goal() -> None:
    env = make_object_centric("kinder/KinematicCylinderShelf3D-o2-v0")
    assert isinstance(env, KinematicCylinderShelf3DEnv)
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    assert names(model.abstract(state)) == {
        "(HandEmpty robot)",
        "(OnFloor cylinder0)",
        "(OnFloor cylinder1)",
    }
    a, b = env.cylinders
    state[a][:3] = (2.0, 2.4, 0.02 + 0.2667 + 0.00635 + 0.10)  # standing on board 1
    state[b][:3] = (2.1, 2.4, 0.02 + 0.00635 + 0.075)  # standing on the bottom board
    assert names(model.abstract(state)) >= {"(OnShelf cylinder0)", "(OnShelf cylinder1)"}
    assert env.goal_reached(state)
    state[b][0] = 2.5  # outside the footprint
    assert "(OnFloor cylinder1)" in names(model.abstract(state))
    env.close()


def test_side_pick_and_place_reach_their_predictions_and_the_goal() -> None:
    env = make_object_centric("kinder/KinematicCylinderShelf3D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    state = check_planning_model(
        model,
        state,
        ["Pick(robot, cylinder0)", "Place(robot, cylinder0)"],
        np.random.default_rng(0),
        samples=10,
        retry_mispredictions=True,
        check_action_bounds=True,
        require_finished=False,
    )
    assert env.goal_reached(state)
    env.close()
