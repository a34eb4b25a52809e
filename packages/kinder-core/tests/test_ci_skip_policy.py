"""The repository's test-run policy (its root ``conftest.py``): under CI a skip is a failure.

Runs pytest on a small test file next to a copy of the root conftest, once with ``CI`` unset and
once with ``CI=true``, and reads the outcome counts.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT_CONFTEST = Path(__file__).resolve().parents[3] / "conftest.py"

SAMPLE = """
import pytest

def test_runs():
    pass

def test_skips_for_a_missing_browser():
    pytest.skip("chromium is not installed")

@pytest.mark.skipif(True, reason="npm package iwer not installed")
def test_skipif():
    pass

@pytest.mark.skip_by_design(reason="holds on every machine")
def test_by_design():
    pytest.skip("never runs here")

@pytest.mark.xfail(reason="a known failure")
def test_xfail():
    assert False
"""


def _run(tmp_path: Path, ci: str | None) -> dict[str, int]:
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    if ci is not None:
        env["CI"] = ci
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_sample.py"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    last = out.stdout.strip().splitlines()[-1]
    return {word: int(n) for n, word in re.findall(r"(\d+) (\w+)", last)}


@pytest.fixture
def sample_dir(tmp_path: Path) -> Path:
    if not ROOT_CONFTEST.exists():
        pytest.skip("the repository's root conftest.py is not in this checkout")
    shutil.copy(ROOT_CONFTEST, tmp_path / "conftest.py")
    (tmp_path / "test_sample.py").write_text(SAMPLE)
    return tmp_path


def test_outside_ci_skips_stay_skips(sample_dir: Path) -> None:
    counts = _run(sample_dir, None)
    assert counts == {"passed": 1, "skipped": 3, "xfailed": 1}
    assert _run(sample_dir, "false") == counts


def test_under_ci_only_skips_by_design_remain(sample_dir: Path) -> None:
    counts = _run(sample_dir, "true")
    assert counts.get("skipped") == 1  # the skip_by_design one
    assert counts.get("failed", 0) + counts.get("error", 0) + counts.get("errors", 0) == 2
    assert counts.get("xfailed") == 1
