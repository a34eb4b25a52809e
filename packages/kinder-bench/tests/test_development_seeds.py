"""Development seeds: every tool that analyses failures, tunes skills, measures step needs or
collects data defaults to seeds from :data:`~kinder_bench.evaluation.protocol.DEVELOPMENT_SEED` on,
never to the evaluation seeds whose episodes fill the results table."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from kinder_bench.baselines.fm_planning.prompts import EXAMPLE_SEED_BASE
from kinder_bench.demos.collection import COLLECTION_SEED, CollectConfig, evaluation_overlap
from kinder_bench.evaluation.protocol import DEVELOPMENT_SEED, PAPER_SEEDS

BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"
#: The development tools and their seed options (``benchmarks/*.py``).
TOOLS = {
    "probes/bp_failure_causes.py": "--seed",
    "probes/skill_success.py": "--seeds",
    "speed/bp_planning_cpu.py": "--seeds",
    "probes/grasp_slip.py": "--seeds",
    "probes/gsc_open_loop.py": "--seed-start",
}


def _lowest(value: str | int) -> int:
    """The lowest seed of a default: ``1000``, ``"1000-1009"`` or ``"1000,1003"``."""
    if isinstance(value, int):
        return value
    return min(int(part.split("-")[0]) for part in value.split(","))


def _default_of(source: str, option: str, constants: dict[str, int]) -> str | int:
    """The ``default=`` of ``add_argument(option, ...)`` in a script, evaluated with the names
    it may use (``DEVELOPMENT_SEED``)."""
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument"):
            continue
        if not node.args or not isinstance(node.args[0], ast.Constant):
            continue
        if node.args[0].value != option:
            continue
        for kw in node.keywords:
            if kw.arg == "default":
                expr = ast.Expression(kw.value)
                value = eval(compile(expr, "<default>", "eval"), {}, dict(constants))
                assert isinstance(value, (str, int))
                return value
    raise AssertionError(f"no add_argument({option!r}, default=...) found")


@pytest.mark.parametrize(("script", "option"), sorted(TOOLS.items()))
def test_development_tools_default_to_development_seeds(script: str, option: str) -> None:
    path = BENCHMARKS / script
    if not path.exists():
        pytest.skip("not in the repository checkout")
    default = _default_of(path.read_text(), option, {"DEVELOPMENT_SEED": DEVELOPMENT_SEED})
    assert _lowest(default) >= DEVELOPMENT_SEED, f"{script} {option} defaults to {default}"


def test_collection_and_examples_use_development_seeds() -> None:
    assert max(PAPER_SEEDS) < DEVELOPMENT_SEED
    assert COLLECTION_SEED >= DEVELOPMENT_SEED
    assert CollectConfig(env_id="kinder/Motion2D-p0-v0", agent="random").seed >= DEVELOPMENT_SEED
    assert not evaluation_overlap(COLLECTION_SEED, 1000)
    assert EXAMPLE_SEED_BASE >= DEVELOPMENT_SEED


def test_the_default_finder_reads_what_a_script_says() -> None:
    source = 'p.add_argument("--seeds", default=f"{DEVELOPMENT_SEED}-{DEVELOPMENT_SEED + 9}")\n'
    assert _default_of(source, "--seeds", {"DEVELOPMENT_SEED": 1000}) == "1000-1009"
    assert _lowest(_default_of('p.add_argument("--seed", type=int, default=0)', "--seed", {})) == 0
    with pytest.raises(AssertionError, match="no add_argument"):
        _default_of("p.add_argument('--other', default=1)", "--seed", {})
