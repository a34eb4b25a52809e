"""A user who installs only kinder-core and kinder-garden2d gets no MuJoCo, pybullet or torch."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
# `uv run` (how `make test` runs pytest) names its own executable in UV, also when uv is not on
# PATH (bootstrapped with pip --user, run as `python3 -m uv`).
UV = os.environ.get("UV") or shutil.which("uv")


@pytest.mark.skipif(UV is None, reason="needs uv to build the fresh venv")
def test_garden2d_installs_alone_without_3d_simulators_or_torch(tmp_path: Path) -> None:
    assert UV is not None
    venv = tmp_path / "venv"
    subprocess.run([UV, "venv", "-q", "--python", sys.executable, str(venv)], check=True)
    py = venv / "bin" / "python"
    subprocess.run(
        [
            UV, "pip", "install", "-q", "--python", str(py),
            str(ROOT / "packages" / "kinder-core"), str(ROOT / "packages" / "kinder-garden2d"),
        ],
        check=True,
    )  # fmt: skip
    probe = (
        "import importlib.util as u, kinder_garden2d, kinder_core; "
        "print(','.join(m for m in ('mujoco', 'pybullet', 'torch', 'mink', 'kinder_garden3d') "
        "if u.find_spec(m) is not None))"
    )
    out = subprocess.run([str(py), "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"unexpected heavy packages installed: {out.stdout}"
