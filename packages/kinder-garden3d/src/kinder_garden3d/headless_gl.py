"""MuJoCo's headless OpenGL backend, chosen before the first ``import mujoco``.

MuJoCo picks its GL backend once, when it is imported. Modules of this package that import
mujoco call :func:`configure_headless_gl` first, so rendering works on machines without a display
(EGL, which needs no extra packages; ``MUJOCO_GL=osmesa`` also works with Debian's libosmesa6).
A value the user already set is kept. Importing the package itself sets nothing.
"""

from __future__ import annotations

import os


def configure_headless_gl() -> None:
    """Default ``MUJOCO_GL`` to ``egl`` (and PyOpenGL to the same platform) unless already set."""
    backend = os.environ.setdefault("MUJOCO_GL", "egl")
    if backend in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
