"""Registration of the Kinematic2D ids (string entry points only; importing this module is cheap)."""

from kinder_core.registration import register_family

# Family → (entry point, max_episode_steps, {variant: constructor kwargs}). Filled in as the
# families land.
FAMILIES: dict[str, tuple[str, int, dict[str, dict[str, object]]]] = {}


def register_kinematic2d() -> list[str]:
    """Register every Kinematic2D id with gymnasium; returns the ids."""
    ids: list[str] = []
    for family, (entry_point, max_steps, variants) in FAMILIES.items():
        ids += register_family(family, entry_point, variants, max_steps)
    return ids
