"""The kinder-core contract over every Dynamic2D id, plus the ids, layouts and Box sizes."""

from __future__ import annotations

import pytest

import kinder_core
from kinder_core.testing import CHECKS, check_cross_process_determinism

DYNAMIC2D_IDS = [
    *(f"kinder/DynObstruction2D-o{n}-v0" for n in (0, 1, 2, 3)),
    "kinder/DynPushT2D-t1-v0",
    *(f"kinder/DynPushPullHook2D-o{n}-v0" for n in (0, 1, 5)),
    *(f"kinder/DynScoopPour2D-o{n}-v0" for n in (10, 20, 30, 50)),
]


def test_all_ids_registered() -> None:
    assert sorted(kinder_core.list_envs("Dynamic2D")) == sorted(DYNAMIC2D_IDS)


@pytest.mark.parametrize("check", sorted(CHECKS))
@pytest.mark.parametrize("env_id", DYNAMIC2D_IDS)
def test_contract(env_id: str, check: str) -> None:
    CHECKS[check](env_id)


@pytest.mark.parametrize(
    "env_id",
    [
        "kinder/DynObstruction2D-o2-v0",
        "kinder/DynPushT2D-t1-v0",
        "kinder/DynPushPullHook2D-o1-v0",
        "kinder/DynScoopPour2D-o10-v0",
    ],
)
def test_cross_process_rollout(env_id: str) -> None:
    check_cross_process_determinism(env_id)


# (id, Box size, first objects of the Box view in order, last object)
LAYOUTS = [
    (
        "kinder/DynObstruction2D-o1-v0",
        14 + 15 + 15 + 24,
        ["target_surface", "target_block"],
        "robot",
    ),
    (
        "kinder/DynObstruction2D-o3-v0",
        14 + 15 + 45 + 24,
        ["target_surface", "target_block"],
        "robot",
    ),
    ("kinder/DynPushT2D-t1-v0", 45, ["tblock", "robot", "goal_tblock"], "goal_tblock"),
    (
        "kinder/DynPushPullHook2D-o5-v0",
        24 + 16 + 15 + 75,
        ["robot", "hook", "target_block"],
        "obstruction4",
    ),
    (
        "kinder/DynScoopPour2D-o10-v0",
        24 + 16 + 140,
        ["robot", "hook", "small_circle0"],
        "small_square4",
    ),
    (
        "kinder/DynScoopPour2D-o50-v0",
        24 + 16 + 700,
        ["robot", "hook", "small_circle0", "small_circle1", "small_circle10"],
        "small_square9",
    ),
]


@pytest.mark.parametrize(("env_id", "size", "first", "last"), LAYOUTS)
def test_box_layout(env_id: str, size: int, first: list[str], last: str) -> None:
    env = kinder_core.make(env_id)
    box = env.get_wrapper_attr("box")
    names = [o.name for o in box.objects]
    assert box.shape == (size,)
    assert names[: len(first)] == first
    assert names[-1] == last
    assert str(box.dtype) == "float64"


def test_type_feature_counts() -> None:
    from kinder_garden2d.dynamic2d import object_types as ot

    counts = {
        ot.KIN_RECTANGLE: 14,
        ot.DYN_RECTANGLE: 15,
        ot.LOBJECT: 16,
        ot.TOBJECT: 16,
        ot.SMALL_CIRCLE: 14,
        ot.SMALL_SQUARE: 14,
        ot.DOT_ROBOT: 13,
        ot.KIN_ROBOT: 24,
    }
    for t, n in counts.items():
        assert len(t.features) == n, t


def test_package_import_does_not_import_pymunk() -> None:
    import subprocess
    import sys

    code = "import sys, kinder_garden2d; print('pymunk' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
