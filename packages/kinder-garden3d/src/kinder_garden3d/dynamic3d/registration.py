"""Registration of every Dynamic3D task file's ids (JSON only: MuJoCo is not imported).

Each file under ``tasks/<Family>/`` registers ``kinder/<Family>-<variant>-v0`` for every entry of
its ``variants`` (or one id named after the file stem when it has none). The kwargs are the task
file and, for counted tasks, ``num_objects``. Each id gets its own step limit: the variant's
``max_episode_steps``, else the file's, else 1000. The entry point follows the file's robot
(``robot.model``): the mobile manipulator's ``Dynamic3DEnv`` or the FR3 arm's ``Franka3DEnv``.
"""

from __future__ import annotations

from typing import Any

from kinder_core.registration import register_family
from kinder_garden3d.dynamic3d.taskfile import variant_table

ENTRY_POINT = "kinder_garden3d.dynamic3d.env:Dynamic3DEnv"
#: The env class of each robot model a task file may name.
ENTRY_POINTS = {"tidybot": ENTRY_POINT, "fr3": "kinder_garden3d.dynamic3d.franka:Franka3DEnv"}


def register_dynamic3d() -> list[str]:
    """Register every bundled Dynamic3D task variant; returns the ids."""
    families: dict[str, dict[str, dict[str, Any]]] = {}
    steps: dict[str, dict[str, int]] = {}
    robots: dict[str, set[str]] = {}
    for info in variant_table():
        robots.setdefault(info.family, set()).add(info.robot)
        kwargs: dict[str, Any] = {"task": info.file}
        if info.count is not None:
            kwargs["num_objects"] = info.count
        families.setdefault(info.family, {})[info.label] = kwargs
        steps.setdefault(info.family, {})[info.label] = info.max_episode_steps
    ids: list[str] = []
    for family, variants in families.items():
        if len(robots[family]) != 1 or not robots[family] <= set(ENTRY_POINTS):
            raise ValueError(
                f"Dynamic3D family {family}: its task files must name one robot model of "
                f"{sorted(ENTRY_POINTS)}, got {sorted(robots[family])}"
            )
        entry = ENTRY_POINTS[robots[family].pop()]
        ids += register_family(family, entry, variants, min(steps[family].values()), steps[family])
    return ids
