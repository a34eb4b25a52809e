"""Test-session setup: MuJoCo's headless GL backend before any test module imports mujoco."""

from kinder_garden3d.headless_gl import configure_headless_gl

configure_headless_gl()
