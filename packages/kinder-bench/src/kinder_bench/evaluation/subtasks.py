"""Subtask milestones: how far an episode of a multi-stage task got, not only whether it ended.

The paper breaks SweepIntoDrawer3D's success down into four subtasks (its Table "Subtask success
rate ... in the SweepIntoDrawer3D environment": open drawer, grasp sweeper, sweep some objects,
sweep all objects). The runner tracks the milestones of an env family here on the *true* state
(under observation noise too) after ``reset`` and after every step, and writes the first step at
which each was reached (``None``: never) into the episode's record as ``subtasks``. A milestone
counts once reached, whatever happens later (a drawer pushed shut again still was opened).

SweepIntoDrawer3D's milestones are the concepts of its planning model
(:mod:`kinder_gym.models.dynamic3d.sweep_into_drawer3d`), so "reached" means what the planner's
abstract state means; the paper does not define its thresholds:

* ``open_drawer``: the working drawer is slid out more than ``OPEN_POS`` (12 cm, far enough that
  cubes pushed off the island's top land inside it);
* ``grasp_sweeper``: the gripper is closed on something and its pinch point is within 5 cm of the
  wiper's head (``Holding(robot, wiper)``);
* ``sweep_some``: at least one cube is in the drawer (the env's own goal atom);
* ``sweep_all``: every cube is in the drawer at once, the env's goal (an episode that succeeds).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from kinder_bench.evaluation.envs import short_id
from kinder_core import ObjectCentricEnv, ObjectCentricState


@dataclasses.dataclass(frozen=True)
class Milestone:
    """A named test on the true state."""

    name: str
    reached: Callable[[ObjectCentricState], bool]


class SubtaskTracker:
    """The first step at which each milestone held, over one episode."""

    def __init__(self, milestones: Sequence[Milestone]) -> None:
        if not milestones:
            raise ValueError("SubtaskTracker needs at least one milestone")
        self.milestones = tuple(milestones)
        self._first: dict[str, int | None] = {m.name: None for m in self.milestones}

    def observe(self, state: ObjectCentricState, step: int) -> None:
        """Test the milestones not reached yet on the state after ``step`` steps."""
        for m in self.milestones:
            if self._first[m.name] is None and m.reached(state):
                self._first[m.name] = step

    def result(self) -> dict[str, int | None]:
        """Milestone name → the first step it held (``None``: never), in milestone order."""
        return dict(self._first)


SUBTASK_NAMES: dict[str, tuple[str, ...]] = {
    "SweepIntoDrawer3D": ("open_drawer", "grasp_sweeper", "sweep_some", "sweep_all"),
}
"""Env family → its milestone names in order (reports use them without building an env)."""

Test = Callable[[ObjectCentricState], bool]


def sweep_into_drawer3d(env: ObjectCentricEnv) -> tuple[Test, ...]:
    """SweepIntoDrawer3D's four subtask tests, in the order of :data:`SUBTASK_NAMES` (see the
    module docstring)."""
    from kinder_gym.models.dynamic3d import sweep_into_drawer3d as model

    objects: Mapping[str, Any] = env.objects  # type: ignore[attr-defined]
    robot, drawer, wiper = objects["robot"], objects[model.DRAWER], objects[model.WIPER]
    atoms: Callable[[ObjectCentricState], dict[str, bool]] = env.goal_atoms  # type: ignore[attr-defined]

    def open_drawer(state: ObjectCentricState) -> bool:
        return bool(state.get(drawer, "pos") > model.OPEN_POS)

    def grasp_sweeper(state: ObjectCentricState) -> bool:
        return model.holds_wiper(state, robot, wiper)

    def sweep_some(state: ObjectCentricState) -> bool:
        return any(atoms(state).values())

    def sweep_all(state: ObjectCentricState) -> bool:
        return bool(env.goal_reached(state))

    return (open_drawer, grasp_sweeper, sweep_some, sweep_all)


MILESTONE_TESTS: dict[str, Callable[[ObjectCentricEnv], tuple[Test, ...]]] = {
    "SweepIntoDrawer3D": sweep_into_drawer3d,
}
"""Env family → the factory of its milestone tests (built from the env, which names the
objects), one per name of :data:`SUBTASK_NAMES`, in that order."""


def family(env_id: str) -> str:
    """``kinder/SweepIntoDrawer3D-o5-v0`` (or ``SweepIntoDrawer3D-o5``) → ``SweepIntoDrawer3D``."""
    return short_id(env_id).split("-")[0]


def in_order(env_id: str, names: Iterable[str]) -> list[str]:
    """Milestone ``names`` in their family's order (records keep them as JSON objects, whose
    keys may come back sorted); names the family does not declare go last, sorted."""
    declared = SUBTASK_NAMES.get(family(env_id), ())
    names = set(names)
    return [n for n in declared if n in names] + sorted(names - set(declared))


def tracker_for(env_id: str, env: ObjectCentricEnv) -> SubtaskTracker | None:
    """A fresh tracker for an episode of ``env_id`` (``None``: the family has no milestones)."""
    fam = family(env_id)
    make = MILESTONE_TESTS.get(fam)
    if make is None:
        return None
    names = SUBTASK_NAMES[fam]
    return SubtaskTracker([Milestone(n, t) for n, t in zip(names, make(env), strict=True)])


__all__ = [
    "MILESTONE_TESTS",
    "SUBTASK_NAMES",
    "Milestone",
    "SubtaskTracker",
    "family",
    "in_order",
    "sweep_into_drawer3d",
    "tracker_for",
]
