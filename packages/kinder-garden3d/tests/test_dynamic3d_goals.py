"""The Dynamic3D goal check on many states at once (``goals_reached``) gives the single-state
check's verdict (``goal_reached``) on every row, for one id of every MuJoCo Dynamic3D family
(LimbRepositioning3D runs on pybullet and has its own check)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium
import numpy as np
import pytest

import kinder_core
import kinder_garden3d  # noqa: F401  (registers the ids)
from kinder_core import ObjectCentricState
from kinder_core.state import StateLayout
from kinder_garden3d.dynamic3d.env import Dynamic3DEnv
from kinder_garden3d.dynamic3d.taskfile import ROBOT


def _one_per_family() -> list[str]:
    first: dict[str, str] = {}
    for env_id in kinder_core.list_envs("Dynamic3D"):
        if "LimbRepositioning3D" in env_id:  # pybullet, with its own goal check
            continue
        first.setdefault(env_id.split("/")[1].split("-")[0], env_id)
    return sorted(first.values())


def _atoms(goal: Any) -> Iterator[tuple[Any, ...]]:
    if goal[0] in ("and", "or"):
        for child in goal[1]:
            yield from _atoms(child)
    else:
        yield tuple(goal)


def _perturbed(env: Dynamic3DEnv, state: ObjectCentricState, rng: np.random.Generator) -> Any:
    """``state`` with the goal's drawers and hinges moved a little, each goal entity put at a
    random point of (or just beyond) one of its region's boxes, and balance angles drawn
    around their tolerance: a mix of both verdicts."""
    x = state.copy()
    layout = x.layout
    for frame in env.regions.frames.values():
        if frame.drawer is not None:
            i = layout.index(layout.object_named(frame.drawer), "pos")
            x.data[i] += rng.uniform(-0.05, 0.05)
        if frame.hinge is not None:
            i = layout.index(layout.object_named(frame.target), "hinge_pos")
            x.data[i] = rng.uniform(-0.3, 0.3)
    for atom in _atoms(env.task.goal):
        if atom[0] == "balanced":
            i = layout.index(layout.object_named(atom[1]), "hinge_pos")
            x.data[i] = np.radians(atom[2]) * rng.uniform(-1.3, 1.3)
            continue
        entity, region = atom[1], atom[2]
        boxes = env.regions.specs[region].boxes
        box = boxes[rng.integers(len(boxes))]
        centre, half = (box[:3] + box[3:]) / 2, (box[3:] - box[:3]) / 2
        local = centre + half * rng.uniform(-1.08, 1.08, 3)
        t = env.regions.transform(x, region)
        world = t[:3, :3] @ local + t[:3, 3]
        obj = layout.object_named(entity)
        if entity == ROBOT:
            x.data[layout.index(obj, "pos_base_x")] = world[0]
            x.data[layout.index(obj, "pos_base_y")] = world[1]
        else:
            for name, value in zip(("x", "y", "z"), world):
                x.data[layout.index(obj, name)] = value
    return x.data


@pytest.mark.parametrize("env_id", _one_per_family())
def test_goals_reached_matches_goal_reached(env_id: str) -> None:
    env = gymnasium.make(env_id).unwrapped
    assert isinstance(env, Dynamic3DEnv)
    rng = np.random.default_rng(1000)
    rows = []
    for seed in (1000, 1001):
        state, _ = env.reset(seed=seed)
        rows += [_perturbed(env, state, rng) for _ in range(200)]
    data = np.array(rows)
    layout = state.layout
    single = np.array([env.goal_reached(ObjectCentricState(layout, r)) for r in data])
    assert 0.02 < single.mean() < 0.98, f"{env_id}: the states do not mix both verdicts"
    np.testing.assert_array_equal(env.goals_reached(data, layout), single)
    assert env.goals_reached(data[:1], layout)[0] == single[0]
    env.close()


def test_goals_reached_reorders_rows_of_another_layout() -> None:
    """Rows whose objects are in another order get the verdicts of the env's own order."""
    env = gymnasium.make("kinder/SweepIntoDrawer3D-o5-v0").unwrapped
    rng = np.random.default_rng(1002)
    state, _ = env.reset(seed=1000)
    layout = state.layout
    data = np.array([_perturbed(env, state, rng) for _ in range(100)])
    other = StateLayout(tuple(reversed(layout.objects)))
    columns = np.arange(layout.size)
    reordered = data[:, np.concatenate([columns[layout.slice_of(o)] for o in other.objects])]
    expected = env.goals_reached(data, layout)
    assert 0 < expected.mean() < 1
    np.testing.assert_array_equal(env.goals_reached(reordered, other), expected)
    env.close()
