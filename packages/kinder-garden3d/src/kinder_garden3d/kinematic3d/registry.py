"""Registration of the Kinematic3D ids (string entry points only: nothing here imports pybullet)."""

from __future__ import annotations

from kinder_core.registration import register_family

_MODULE = "kinder_garden3d.kinematic3d"

#: (family, entry point, variant label → kwargs, max_episode_steps)
KINEMATIC3D_FAMILIES: tuple[tuple[str, str, dict[str, dict[str, int]], int], ...] = (
    ("BaseMotion3D", f"{_MODULE}.base_motion3d:BaseMotion3DEnv", {"": {}}, 200),
    (
        "Obstruction3D",
        f"{_MODULE}.obstruction3d:Obstruction3DEnv",
        {f"o{n}": {"num_obstructions": n} for n in range(5)},
        500,
    ),
    (
        "Packing3D",
        f"{_MODULE}.packing3d:Packing3DEnv",
        {f"p{n}": {"num_parts": n} for n in (1, 2, 3)},
        500,
    ),
    (
        "Table3D",
        f"{_MODULE}.table3d:Table3DEnv",
        {f"o{n}": {"num_cubes": n} for n in (1, 2, 3)},
        300,
    ),
    (
        "Transport3D",
        f"{_MODULE}.transport3d:Transport3DEnv",
        {f"o{n}": {"num_cubes": n} for n in (1, 2)},
        500,
    ),
    (
        "KinematicShelf3D",
        f"{_MODULE}.kinematic_shelf3d:KinematicShelf3DEnv",
        {f"o{n}": {"num_cubes": n} for n in (1, 2, 3, 5, 10)},
        500,
    ),
    (
        "KinematicCylinderShelf3D",
        f"{_MODULE}.kinematic_cylinder_shelf3d:KinematicCylinderShelf3DEnv",
        {f"o{n}": {"num_cylinders": n} for n in (1, 2, 3)},
        500,
    ),
    (
        "PrplLab3D",
        f"{_MODULE}.prpl_lab3d:PrplLab3DEnv",
        {f"o{n}": {"num_cubes": n} for n in (1, 2)},
        500,
    ),
)


#: Variants whose objects need more steps than their family's budget: family → variant → steps.
#: KinematicShelf3D: BP's plans take about 115 steps a block (226 for o2 on seeds 1000–1002), so
#: o5 and o10 get 200 a block.
KINEMATIC3D_VARIANT_STEPS: dict[str, dict[str, int]] = {
    "KinematicShelf3D": {"o5": 1000, "o10": 2000},
}


def register_kinematic3d() -> list[str]:
    """Register every Kinematic3D id with gymnasium; returns the ids."""
    ids: list[str] = []
    for family, entry_point, variants, max_steps in KINEMATIC3D_FAMILIES:
        ids += register_family(
            family,
            entry_point,
            variants,
            max_episode_steps=max_steps,
            variant_steps=KINEMATIC3D_VARIANT_STEPS.get(family),
        )
    return ids
