"""Kinematic3D models (need the ``[3d]`` extra: kinder-garden3d)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("kinder_garden3d")

from kinder_core import make_object_centric
from kinder_gym.models import create_model
from kinder_gym.skills import execute_skill


def test_basemotion3d_predicates_and_skill() -> None:
    env = make_object_centric("kinder/BaseMotion3D-v0")
    model = create_model(env)
    state = env.reset(seed=3)[0]
    assert {str(a) for a in model.abstract(state)} == {"(NotAtTarget robot target)"}
    at = state.copy()
    at.set(env.robot, "pos_base_x", state.get(env.target, "x"))
    at.set(env.robot, "pos_base_y", state.get(env.target, "y"))
    assert {str(a) for a in model.abstract(at)} == {"(AtTarget robot target)"}
    op = model.ground_operators(state)[0]
    gs = model.skill(op)
    out = execute_skill(gs.controller, state, [], env.transition, 100, stop_on_goal=False)
    assert out.finished
    assert model.abstract(out.states[-1]) == op.apply(model.abstract(state))
    high = env.action_space.high
    assert all(np.all(np.abs(a) <= high + 1e-9) for a in out.actions)
