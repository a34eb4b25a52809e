"""The rule for Dynamic3D step limits.

Upstream kindergarden 0.2.5 registers no step limit, so every limit is this project's choice.
A Dynamic3D id gets :data:`DEFAULT_LIMIT` steps unless its objects need more with the KinDERGym
skills (the reference solution: one object at a time). Then its task file sets
``max_episode_steps`` to :func:`limit_for` of the most actions a planner-free run of the skills
took: 1.5 times it, rounded up to a multiple of 500, so that a plan with unlucky samples still
fits. The measurements and the table are ``benchmarks/probes/step_limits.py`` and
``benchmarks/results/step_limits.md``.
"""

from __future__ import annotations

import math

#: Every Dynamic3D id's limit unless measured otherwise.
DEFAULT_LIMIT = 1000
#: Margin over the most actions the skills took, and the rounding step.
MARGIN, ROUND_TO = 1.5, 500


def limit_for(actions: int) -> int:
    """The step limit for a variant whose skills took at most ``actions`` actions."""
    if actions < 0:
        raise ValueError(f"actions must be >= 0, got {actions}")
    return max(DEFAULT_LIMIT, math.ceil(MARGIN * actions / ROUND_TO) * ROUND_TO)
