"""The Dynamic3D variants whose step limit is raised above 1000, and the measurements behind it.

Upstream kindergarden 0.2.5 registers no step limit at all (spec environments.md §9), so every
limit is this project's choice; the rule is ``kinder_garden3d.dynamic3d.step_limits``: 1000
steps, except variants whose objects need more with the KinDERGym skills (the reference
solution: one object at a time), which get ``limit_for`` of the most actions a planner-free run
of the skills took on the measured seeds.

The measurements are ``benchmarks/probes/skill_success.py`` outputs, one JSON file per variant under
``benchmarks/results/step_limits/``, named after the id (made with ``--out``, as below). New
measurements use development seeds (1000 on, the tool's default); the committed files record
the env reset seeds they were measured on (``seeds``).
``python benchmarks/probes/step_limits.py`` prints the markdown table of ``step_limits.md`` and
exits non-zero when a registered limit disagrees with the rule (a test checks the same).

    python benchmarks/probes/skill_success.py pickplace --env kinder/ScoopPour3D-o20-v0 \\
        --seeds 1000-1002 \\
        --out benchmarks/results/step_limits/ScoopPour3D-o20.json
    python benchmarks/probes/step_limits.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from kinder_garden3d.dynamic3d.step_limits import limit_for

RESULTS = Path(__file__).resolve().parents[1] / "results" / "step_limits"


def measurements() -> list[dict[str, Any]]:
    """Every measurement file, sorted by env id."""
    rows = [json.loads(p.read_text()) for p in sorted(RESULTS.glob("*.json"))]
    return sorted(rows, key=lambda r: str(r["env"]))


def solved_actions(row: dict[str, Any]) -> list[int]:
    """The actions of each solved episode (an unsolved one counts only what it did)."""
    pairs = zip(row["episode_actions"], row["episode_solved"], strict=True)
    return [int(n) for n, ok in pairs if ok]


def table() -> tuple[str, list[str]]:
    """The markdown table and the ids whose registered limit breaks the rule."""
    import gymnasium

    import kinder_garden3d  # noqa: F401  (registers the ids)

    lines = [
        "| env | seeds | solved | actions per solved episode | rule: limit | registered |",
        "|---|---|---|---|---|---|",
    ]
    wrong = []
    for row in measurements():
        acts = solved_actions(row)
        rule = limit_for(max(acts)) if acts else None
        registered = gymnasium.spec(row["env"]).max_episode_steps
        if rule is None or registered != rule:
            wrong.append(row["env"])
        span = (
            "--"
            if not acts
            else f"{min(acts):,}–{max(acts):,}"
            if len(acts) > 1
            else f"{acts[0]:,}"
        )
        lines.append(
            f"| {row['env']} | {row['seeds']} | {sum(row['episode_solved'])} of "
            f"{len(row['episode_solved'])} | {span} | {rule or '--'} | {registered} |"
        )
    return "\n".join(lines), wrong


def main() -> None:
    text, wrong = table()
    print(text)
    if wrong:
        print(f"registered limits that break the rule: {wrong}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
