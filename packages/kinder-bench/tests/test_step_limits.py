"""Every Dynamic3D id's step limit follows the documented rule
(``kinder_garden3d.dynamic3d.step_limits``): 1000, or for a variant whose objects need more,
1.5 × the most actions the KinDERGym skills took on its measured seeds, rounded up to 500. The
measurements are data files, ``benchmarks/results/step_limits/*.json``
(``benchmarks/probes/skill_success.py --out``; the table: ``benchmarks/probes/step_limits.py``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium
import pytest

import kinder_core

pytest.importorskip("kinder_garden3d")

from kinder_garden3d.dynamic3d.step_limits import DEFAULT_LIMIT, limit_for

MEASUREMENTS = Path(__file__).resolve().parents[3] / "benchmarks" / "results" / "step_limits"


def _measurements() -> list[dict[str, Any]]:
    return [json.loads(p.read_text()) for p in sorted(MEASUREMENTS.glob("*.json"))]


def test_the_rule() -> None:
    assert limit_for(213) == 1000  # never below the default
    assert limit_for(1000) == 1500
    assert limit_for(1467) == 2500  # 2,200.5 rounds up
    assert limit_for(2000) == 3000
    with pytest.raises(ValueError, match="actions must be >= 0"):
        limit_for(-1)


def test_measured_variants_have_the_rule_s_limit() -> None:
    rows = _measurements()
    assert rows, "no measurements under benchmarks/results/step_limits"
    for row in rows:
        solved = [
            int(n)
            for n, ok in zip(row["episode_actions"], row["episode_solved"], strict=True)
            if ok
        ]
        assert solved, f"{row['env']}: no measured episode was solved"
        assert gymnasium.spec(row["env"]).max_episode_steps == limit_for(max(solved)), row["env"]


def test_every_other_dynamic3d_id_has_the_default() -> None:
    measured = {row["env"] for row in _measurements()}
    for env_id in kinder_core.list_envs("Dynamic3D"):
        # LimbRepositioning3D (pybullet) documents its own budget in kinder_garden3d.limb3d.
        if env_id not in measured and "LimbRepositioning3D" not in env_id:
            assert gymnasium.spec(env_id).max_episode_steps == DEFAULT_LIMIT, env_id
