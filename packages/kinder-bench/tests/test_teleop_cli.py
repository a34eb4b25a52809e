"""``kinder teleop``: argument checks and the dataset build of saved episodes (no window)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

pytest.importorskip("pygame")

from kinder_bench.cli import app

runner = CliRunner()


def test_web_needs_a_3d_env_and_unknown_ids_fail(tmp_path: Path) -> None:
    result = runner.invoke(app, ["teleop", "Motion2D-p0", "--web", "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "2D env" in result.output
    result = runner.invoke(app, ["teleop", "NoSuchEnv", "--out", str(tmp_path)])
    assert result.exit_code == 2 and "Unknown environment" in result.output


def test_build_only_with_nothing_saved(tmp_path: Path) -> None:
    result = runner.invoke(
        app, ["teleop", "Motion2D-p0", "--build-only", "--no-images", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    assert "added 0 episodes" in result.output
