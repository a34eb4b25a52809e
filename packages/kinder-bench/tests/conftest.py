"""Shared fixtures: the toy env id (registered by importing kinder_bench_toy)."""

from __future__ import annotations

import kinder_bench_toy
import pytest


@pytest.fixture
def toy_id() -> str:
    return kinder_bench_toy.TOY_ID
