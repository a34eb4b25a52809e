"""The guard that no success rate lives only in prose: every SR a results page quotes is for a
(method, env) that a committed summary row holds."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import re
from pathlib import Path

import pytest

from kinder_bench.agents import agent_class
from kinder_bench.baselines.diffusion import training_budget
from kinder_bench.evaluation.metrics import Stat
from kinder_bench.reporting.paper import Result, paper_settings, results_from_csv
from kinder_bench.reporting.results_doc import (
    GPU_COST_FILE,
    attribution_markdown,
    diffusion_reason,
    heldout_markdown,
    load_paper_noise,
    load_paper_ood,
    noise_markdown,
    ood_markdown,
    summary_files,
    unbacked_quotes,
)

REPO = Path(__file__).resolve().parents[3]
MOTION = "kinder/Motion2D-p0-v0"
BUTTON = "kinder/StickButton2D-b1-v0"


def _row(env_id: str, agent: str, method: str | None = None) -> Result:
    stat = Stat(0.5, 0.1, 5)
    return Result(env_id, method or agent, agent, "r" * 12, stat, stat, stat, 5, 250, 0, "cmd")


def _pages() -> dict[str, str]:
    pages = sorted((REPO / "benchmarks" / "results").glob("*.md"))
    pages += [REPO / "README.md", REPO / "docs" / "results.md"]
    return {str(p.relative_to(REPO)): p.read_text() for p in pages if p.exists()}


def test_every_quoted_success_rate_has_its_summary_row() -> None:
    files = summary_files(REPO / "benchmarks" / "results")
    if not files:
        pytest.skip("not in the repository checkout")
    results = [r for f in files for r in results_from_csv(f)]
    bad = unbacked_quotes(_pages(), results)
    assert not bad, (
        "SR quoted without a committed summary row (add the row, e.g. a transcribed "
        "one with its provenance, to benchmarks/results/*_summary.csv):\n"
        + "\n".join(map(str, bad))
    )


def test_the_guard_finds_tables_and_prose_and_spares_the_papers_figures() -> None:
    rows = [_row(MOTION, "ppo"), _row(BUTTON, "bilevel_planning")]
    page = "\n".join(
        [
            "## MBRL on Motion2D-p0",
            "",
            "| Env | Metric | mbrl | paper MBRL |",  # the report's layout
            "|---|---|---|---|",
            "| Motion2D-p0 | SR ↑ | **0.98 ± 0.04** | 0.16 |",
            "|  | Rwd ↑ | -62.7 | |",
            "",
            "| env | seeds × episodes | SR | paper SR |",  # a column named SR
            "|---|---|---|---|",
            "| kinder/StickButton2D-b1-v0 | 5 × 10 | 0.10 ± 0.07 (0.36) | 0.36 |",
            "",
            "PPO on StickButton2D-b1 reached SR 0.27 ± 0.07 (paper 0.14).",
            "The paper's SR 0.54 on Motion2D-p0 is its MPC.",
        ]
    )
    bad = unbacked_quotes({"page.md": page}, rows)
    assert [(q.line, q.figure, set(q.methods)) for q in bad] == [
        (5, "0.98", {"mbrl"}),
        (10, "0.10", {"mbrl"}),  # no method in the row: the heading's
        (12, "0.27", {"ppo"}),
    ]
    # With the rows, nothing is left; the paper's figures never needed one.
    more = [*rows, _row(MOTION, "mbrl"), _row(BUTTON, "mbrl"), _row(BUTTON, "ppo")]
    assert unbacked_quotes({"page.md": page}, more) == []
    # A labelled variant's row backs a quote of its label.
    dense = dataclasses.replace(_row(MOTION, "ppo", "ppo-dense"))
    quote = "| Env | Metric | ppo-dense |\n|---|---|---|\n| Motion2D-p0 | SR ↑ | 0.68 |"
    assert unbacked_quotes({"p.md": quote}, [dense]) == []
    assert len(unbacked_quotes({"p.md": quote}, [_row(MOTION, "sac")])) == 1


def _bp(seeds: tuple[int, ...], sr: float, **args: object) -> Result:
    defaults = dataclasses.asdict(agent_class("bilevel_planning").Args())
    stat = Stat(sr, 0.02, len(seeds))
    return dataclasses.replace(
        _row(BUTTON, "bilevel_planning"),
        success=stat,
        seeds=seeds,
        num_seeds=len(seeds),
        episodes=50 * len(seeds),
        max_steps=200,
        agent_args={**defaults, **args},
        run_id=f"{sr:.2f}{seeds[0]:08d}"[:12],
    )


PAPER_BP = {"refinement_rounds": 1, "replan_on_divergence": False, "respect_episode_limit": False}


def test_heldout_table_pairs_the_same_run_on_unseen_seeds_and_marks_a_gap() -> None:
    evaluation = _bp((0, 1, 2, 3, 4), 0.90)
    heldout = _bp((100, 101, 102, 103, 104), 0.80)
    other_args = _bp((100, 101, 102, 103, 104), 0.10, samples_per_step=7)
    table = heldout_markdown([evaluation, heldout, other_args], [BUTTON, MOTION])
    (row,) = [line for line in table.splitlines() if line.startswith("| StickButton2D-b1")]
    assert "| 50 | 0.90 ± 0.02 | 0.80 ± 0.02 | 100–104 |" in row
    assert "-0.10 (larger than the std)" in row
    assert "| Motion2D-p0 | -- | -- | not run | not run |" in table
    # A transcribed row or one measured before its env followed upstream is never paired.
    gone = dataclasses.replace(heldout, provenance="transcribed from x.md @ abc")
    assert "not run" in heldout_markdown([evaluation, gone], [BUTTON])
    # A 5 x 10 held-out run pairs with the first 10 episodes of each evaluation seed, never
    # with the whole 5 x 50 run.
    short = dataclasses.replace(heldout, episodes=50, success=Stat(0.70, 0.1, 5))
    assert "not run" in heldout_markdown([evaluation, short], [BUTTON])
    first_ten = dataclasses.replace(evaluation, episodes=50, success=Stat(0.72, 0.1, 5))
    table = heldout_markdown([evaluation, first_ten, short], [BUTTON])
    (row,) = [line for line in table.splitlines() if line.startswith("| StickButton2D-b1")]
    assert "| 10 | 0.72 ± 0.10 | 0.70 ± 0.10 | 100–104 | -0.02 |" in row
    # The first 10 episodes of the 5 x 50 run say so; a 5 x 10 run made beside the held-out
    # run is listed too.
    subset = dataclasses.replace(
        first_ten, command="x; then kinder bench report d --first-episodes 10"
    )
    table = heldout_markdown([evaluation, subset, first_ten, short], [BUTTON])
    rows = [line for line in table.splitlines() if line.startswith("| StickButton2D-b1")]
    assert len(rows) == 2
    assert sum("the first 10 episodes of each seed of a longer run" in r for r in rows) == 1


def test_attribution_table_sets_the_papers_bp_beside_our_default() -> None:
    ours = _bp((0, 1, 2, 3, 4), 0.98)
    paper_bp = _bp((0, 1, 2, 3, 4), 0.60, **PAPER_BP)
    table = attribution_markdown([ours, paper_bp], [BUTTON, MOTION])
    assert "| StickButton2D-b1 | 50 | 0.60 ± 0.02 | 0.98 ± 0.02 | +0.38 |" in table
    assert "| Motion2D-p0 | 50 | not run | not run | -- |" in table
    # Held-out seeds never stand in for the evaluation seeds.
    later = dataclasses.replace(paper_bp, seeds=(100, 101, 102, 103, 104))
    assert "| StickButton2D-b1 | 50 | not run | 0.98 ± 0.02 | -- |" in attribution_markdown(
        [ours, later], [BUTTON]
    )
    # Without a 5 x 50 pair, the two compare on the most episodes per seed both ran: our 5 x 10
    # run against the first 10 episodes of each seed of the paper-settings run.
    ours_ten = dataclasses.replace(ours, episodes=50, success=Stat(0.90, 0.1, 5))
    paper_ten = dataclasses.replace(paper_bp, episodes=50, success=Stat(0.70, 0.1, 5))
    assert "| StickButton2D-b1 | 10 | 0.70 ± 0.10 | 0.90 ± 0.10 | +0.20 |" in (
        attribution_markdown([paper_bp, paper_ten, ours_ten], [BUTTON])
    )
    assert "| StickButton2D-b1 | 50 | 0.60 ± 0.02 | 0.98 ± 0.02 | +0.38 |" in (
        attribution_markdown([paper_bp, paper_ten, ours_ten, ours], [BUTTON])
    )
    # A 5 x 10 run at the paper's settings wins over the first 10 episodes of the 5 x 50 run.
    subset = dataclasses.replace(
        paper_ten,
        success=Stat(0.50, 0.1, 5),
        command="x; then kinder bench report d --first-episodes 10",
    )
    for rows in ([subset, paper_ten, ours_ten], [paper_ten, subset, ours_ten]):
        assert "| 10 | 0.70 ± 0.10 | 0.90 ± 0.10 | +0.20 |" in attribution_markdown(rows, [BUTTON])
    assert "| 10 | 0.50 ± 0.10 | 0.90 ± 0.10 | +0.40 |" in (
        attribution_markdown([subset, ours_ten], [BUTTON])
    )
    # A row recorded before planning_clock existed is our default too (the option's default is
    # the behaviour it had); one recorded before respect_episode_limit existed is not.
    args = dict(ours.agent_args or {})
    before_clock = {k: v for k, v in args.items() if k != "planning_clock"}
    legacy = dataclasses.replace(ours, agent_args=before_clock)
    assert "| 0.98 ± 0.02 | +0.38 |" in attribution_markdown([legacy, paper_bp], [BUTTON])
    older = {k: v for k, v in args.items() if k not in ("planning_clock", "respect_episode_limit")}
    unknown = dataclasses.replace(ours, agent_args=older)
    assert "| not run | -- |" in attribution_markdown([unknown, paper_bp], [BUTTON])
    # Our default BP run by a campaign under its label counts as ours; a labelled run at the
    # paper's settings is a variant, never the paper's cell.
    labelled = dataclasses.replace(ours, method="bp-ours")
    labelled_paper = dataclasses.replace(paper_bp, method="bp-paper")
    assert "| StickButton2D-b1 | 50 | 0.60 ± 0.02 | 0.98 ± 0.02 | +0.38 |" in (
        attribution_markdown([labelled, paper_bp], [BUTTON])
    )
    assert "| StickButton2D-b1 | 50 | not run | 0.98 ± 0.02 | -- |" in attribution_markdown(
        [labelled, labelled_paper], [BUTTON]
    )


def test_noise_table_sets_bp_under_noise_beside_the_papers() -> None:
    paper_bp = _bp((0, 1, 2, 3, 4), 1.00, **PAPER_BP, search="astar")
    open_loop = dataclasses.replace(
        paper_bp, agent_args={**(paper_bp.agent_args or {}), "max_replans": 0}
    )
    obs = dataclasses.replace(open_loop, success=Stat(0.30, 0.05, 5), obs_noise=0.01)
    act = dataclasses.replace(open_loop, success=Stat(0.20, 0.05, 5), action_noise=0.1)
    replan = dataclasses.replace(
        paper_bp, method="bp-paper-replan", success=Stat(0.40, 0.05, 5), obs_noise=0.01
    )
    ours = dataclasses.replace(_bp((0, 1, 2, 3, 4), 0.90), method="bp-ours", obs_noise=0.01)
    both = dataclasses.replace(obs, obs_noise=0.1, action_noise=0.1)  # in no column
    short = dataclasses.replace(obs, obs_noise=0.1, episodes=50)  # 5 x 10: not the protocol
    labelled = dataclasses.replace(act, method="bp-x", action_noise=0.01)  # not the paper's BP
    table = noise_markdown([paper_bp, obs, act, replan, ours, both, short, labelled])
    rows = {
        r.split(" | ")[1]: r.split(" | ")[2:]
        for r in table.splitlines()
        if r.startswith("| StickButton2D-b1")
    }
    assert rows["paper's BP, open loop (paper)"] == [
        "1.00 ± 0.02 (1.00)",
        "0.30 ± 0.05 (0.22)",
        "not run (0.06)",
        "1.00 ± 0.02 (1.00)",
        "not run (0.41)",
        "0.20 ± 0.05 (0.05) |",
    ]
    # Without noise the paper cell (recorded with max_replans=5) stands for both settings.
    assert rows["paper's settings, re-planning when the plan runs out"][:3] == [
        "1.00 ± 0.02",
        "0.40 ± 0.05",
        "not run",
    ]
    assert rows["our default"][:2] == ["not run", "0.90 ± 0.02"]
    # A run under noise never fills the paper's BP cell, nor the held-out or attribution
    # tables (it is a variant named by its noise).
    assert "noise" not in heldout_markdown([obs], [BUTTON]) and "not run" in heldout_markdown(
        [obs, dataclasses.replace(obs, seeds=(100, 101, 102, 103, 104))], [BUTTON]
    )
    assert "| StickButton2D-b1 | 50 | not run |" in attribution_markdown([obs, ours], [BUTTON])
    # The paper's figures load, and a malformed file says which row is wrong.
    assert load_paper_noise()[("kinder/Motion2D-p0-v0", "action", 0.01)] == "0.13"
    with pytest.raises(ValueError, match="row 2"):
        load_paper_noise("env_id,noise,std,sr\nkinder/Motion2D-p0-v0,sound,0.1,0.5\n")


def test_every_results_page_says_when_it_was_measured() -> None:
    """A results page names a date (YYYY-MM-DD) or a commit, so a reader knows which code its
    figures describe."""
    pages = sorted((REPO / "benchmarks" / "results").glob("*.md"))
    if not pages:
        pytest.skip("not in the repository checkout")
    when = re.compile(r"\b20\d\d-\d\d-\d\d\b|commit `?[0-9a-f]{7,40}\b")
    undated = [p.name for p in pages if not when.search(p.read_text())]
    assert not undated, f"results pages without a date or commit: {undated}"


def test_the_diffusion_note_quotes_the_gpu_measurement_and_a_command_that_runs() -> None:
    cost = json.loads((REPO / "benchmarks/results" / GPU_COST_FILE).read_text())
    text = diffusion_reason(cost)
    one = [r["samples_per_s"] for r in cost["rows"] if r["cameras"] == 1]
    hours = sum(r["paper_hours"] for r in cost["rows"])
    assert f"{min(one):,.0f}–{max(one):,.0f} samples/s with one camera" in text
    assert f"{hours:,.0f} for all {len(cost['rows'])} DP and DPES cells" in text
    assert "GPU-hours" not in diffusion_reason(None)
    # The command names a script that exists and takes these flags, and a run of it records the
    # paper's training budget, so it can fill the cell.
    match = re.search(r"`(python [^`]+)`", text)
    assert match is not None
    _, script, _, *argv = match.group(1).split()
    spec = importlib.util.spec_from_file_location("learning_script", REPO / script)
    assert spec is not None and spec.loader is not None
    learning = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(learning)
    args = learning.parse_args("dp", [a.replace("<env>", "Motion2D-p0") for a in argv])
    assert args.paper_budget and args.device == "cuda" and args.episodes == 50
    paper = paper_settings("dp", MOTION)["training"]
    assert training_budget("dp", MOTION, "paper", 64, 9, True) == paper
    assert training_budget("dp", MOTION, "paper", 64, 9, False) != paper
    cpu = training_budget("dp", MOTION, "cpu", 16, 9, True)
    assert cpu == "9 steps × batch 16, preset cpu"


def test_ood_table_fills_the_papers_row_only_at_its_protocol() -> None:
    paper = load_paper_ood()
    envs = [f"kinder/DynObstruction2D-o{n}-v0" for n in (1, 0, 2, 3)]
    assert list(dict.fromkeys(e for e, _ in paper)) == envs
    assert paper[(envs[1], "dp")] == "0.35" and paper[(envs[3], "vla")] == "0.40"
    empty = ood_markdown([])
    assert "| DP (paper) |  | n/r (0.33) | n/r (0.35) | n/r (0.30) | n/r (0.26) |" in empty

    def dp(env: str, sr: float, episodes: int, training: str) -> Result:
        stat = Stat(sr, 0.05, 5)
        return Result(
            env, "dp", "dp", f"{env[-5:]}{episodes}", stat, stat, stat, 5, 5 * episodes, 0,
            "kinder train ood ...", seeds=(0, 1, 2, 3, 4), max_steps=200,
            agent_args={"checkpoint": f"runs/{training[:3]}", "device": "cpu"},
            training=training,
        )  # fmt: skip

    # A small budget on four envs: its own row, named by what differs, one SR per env.
    small = [
        dp(e, 0.1 * (i + 1), 5, "1500 steps × batch 16, preset cpu") for i, e in enumerate(envs)
    ]
    md = ood_markdown(small)
    assert "| DP (paper) |  | n/r (0.33) |" in md
    assert (
        "| DP · 5×5, training 1500 steps × batch 16, preset cpu | 5 × 5 | 0.10 ± 0.05 | "
        "0.20 ± 0.05 | 0.30 ± 0.05 | 0.40 ± 0.05 |"
    ) in md
    # The paper's budget at 5 × 50 fills the paper's row, on o0 as on o1.
    budget = str(paper_settings("dp", envs[0])["training"])
    full = [dp(e, 0.3, 50, budget) for e in envs[:2]]
    md = ood_markdown(full)
    assert "| DP (paper) | 5 × 50 | 0.30 ± 0.05 (0.33) | 0.30 ± 0.05 (0.35) | n/r (0.30) |" in md
    assert "| DP ·" not in md
    # A checkpoint evaluated only on the training env is a first-table variant, not a row here.
    assert "| DP ·" not in ood_markdown(small[:1])
    with pytest.raises(ValueError, match="row 2"):
        load_paper_ood("env_id,baseline,sr\nkinder/X-v0,dp,high\n")
    with pytest.raises(ValueError, match="header"):
        load_paper_ood("env,baseline\n")
