"""The PrplLab3D planning model (needs the ``[3d]`` extra)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_garden3d.kinematic3d.prpl_lab3d import PrplLab3DEnv
from kinder_gym.models import create_model
from kinder_gym.testing import check_planning_model


def names(atoms: frozenset[object]) -> set[str]:
    return {str(a) for a in atoms}


def test_predicates_and_goal_on_built_states() -> None:
    env = make_object_centric("kinder/PrplLab3D-o2-v0")
    assert isinstance(env, PrplLab3DEnv)
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    assert names(model.abstract(state)) == {
        "(HandEmpty robot)",
        "(OnFloor cube0)",
        "(OnFloor cube1)",
    }
    assert names(model.goal(state)) == {"(HandEmpty robot)", "(Raised cube0)", "(Raised cube1)"}
    state[env.cubes[1]][2] = 0.78
    assert "(Raised cube1)" in names(model.abstract(state))
    env.close()


def test_pick_and_raise_reach_their_predictions_and_the_goal() -> None:
    env = make_object_centric("kinder/PrplLab3D-o1-v0")
    model = create_model(env)
    state = env.reset(seed=1000)[0]
    state = check_planning_model(
        model,
        state,
        ["Pick(robot, cube0)", "Raise(robot, cube0)"],
        np.random.default_rng(0),
        samples=8,
        retry_mispredictions=True,
        check_action_bounds=True,
        require_finished=False,
    )
    assert env.goal_reached(state)
    env.close()
