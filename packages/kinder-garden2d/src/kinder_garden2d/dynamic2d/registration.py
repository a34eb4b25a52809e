"""Registration of the Dynamic2D ids (string entry points only; importing this module is cheap)."""

from kinder_core.registration import register_family

# Family → (entry point, max_episode_steps, {variant: constructor kwargs}). The step budgets are
# documented in each env's docstring (Episode End).
_MODULE = "kinder_garden2d.dynamic2d"
FAMILIES: dict[str, tuple[str, int, dict[str, dict[str, object]]]] = {
    "DynObstruction2D": (
        f"{_MODULE}.dyn_obstruction2d:DynObstruction2DEnv",
        500,
        {f"o{n}": {"num_obstructions": n} for n in (0, 1, 2, 3)},
    ),
    "DynPushT2D": (f"{_MODULE}.dyn_pusht2d:DynPushT2DEnv", 1000, {"t1": {"num_tee": 1}}),
    "DynPushPullHook2D": (
        f"{_MODULE}.dyn_pushpullhook2d:DynPushPullHook2DEnv",
        500,
        {f"o{n}": {"num_obstructions": n} for n in (0, 1, 5)},
    ),
    "DynScoopPour2D": (
        f"{_MODULE}.dyn_scooppour2d:DynScoopPour2DEnv",
        1000,
        {f"o{n}": {"num_objects": n} for n in (10, 20, 30, 50)},
    ),
}


def register_dynamic2d() -> list[str]:
    """Register every Dynamic2D id with gymnasium; returns the ids."""
    ids: list[str] = []
    for family, (entry_point, max_steps, variants) in FAMILIES.items():
        ids += register_family(family, entry_point, variants, max_steps)
    return ids
