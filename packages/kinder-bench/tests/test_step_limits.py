"""Every Dynamic3D id's step limit follows the documented rule (``benchmarks/step_limits.py``):
1000, or for a variant whose objects need more, 1.5 × the most actions the KinDERGym skills
took on its measured seeds, rounded up to 500 (``benchmarks/results/step_limits/*.json``)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import gymnasium
import pytest

import kinder_core

pytest.importorskip("kinder_garden3d")

SCRIPT = Path(__file__).resolve().parents[3] / "benchmarks" / "step_limits.py"


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("step_limits", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["step_limits"] = module
    spec.loader.exec_module(module)
    return module


step_limits = _load()


def test_the_rule() -> None:
    assert step_limits.limit_for(213) == 1000  # never below the default
    assert step_limits.limit_for(1000) == 1500
    assert step_limits.limit_for(1467) == 2500  # 2,200.5 rounds up
    assert step_limits.limit_for(2000) == 3000


def test_measured_variants_have_the_rule_s_limit() -> None:
    rows = step_limits.measurements()
    assert rows, "no measurements under benchmarks/results/step_limits"
    for row in rows:  # every measured variant was solved at least once
        assert any(row["episode_solved"]), row["env"]
    assert step_limits.table()[1] == []


def test_every_other_dynamic3d_id_has_the_default() -> None:
    measured = {row["env"] for row in step_limits.measurements()}
    for env_id in kinder_core.list_envs("Dynamic3D"):
        if env_id not in measured:
            limit = gymnasium.spec(env_id).max_episode_steps
            assert limit == step_limits.DEFAULT_LIMIT, env_id
