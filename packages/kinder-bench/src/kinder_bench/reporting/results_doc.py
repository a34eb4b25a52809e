"""``docs/results.md``: the project's current results, from the committed run summaries.

Every ``*_summary.csv`` in ``benchmarks/results/`` (the ``summary.csv`` the runner writes into a
run directory when a run ends, copied there, with a ``command`` column: the command that produced
each row) becomes a table, and all of them together fill the paper's Table II layout beside the
paper's figures (:mod:`kinder_bench.reporting.paper`) under its rule: a cell is filled only by a run
at the paper's protocol; every other run is a labelled variant in rows of its own; ``n/r`` only
where no run of any kind exists, with why and the command that fills it. The page opens with the
count of the paper's 13 × 8 cells in each state. A row without its command is an error: every
committed figure must say how it was measured. A row transcribed from a results page (its run
directory gone) says so in its ``provenance`` column and is never at the paper's protocol. Why a
paper cell was not run is said independently of this machine (so the page is the same everywhere).
Columns a summary has beyond the report's (e.g. ``search``) are shown after the method's name. The
page ends with every deviation of a baseline from the paper
(``kinder_bench/data/baseline_deviations.csv``). ``tools/gen_results_doc.py`` (``make results-doc``)
writes the page.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import re
from collections.abc import Callable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from kinder_bench.agents import AGENTS, agent_class, run_id_optional_defaults
from kinder_bench.evaluation.envs import short_id
from kinder_bench.evaluation.protocol import PAPER_EPISODES, PAPER_SEEDS
from kinder_bench.evaluation.summary import CSV_COLUMNS
from kinder_bench.reporting.paper import (
    PRE_CONFORMANCE,
    Result,
    at_paper_protocol,
    compare,
    csv_rows,
    fmt_stat,
    load_paper,
    metric_digits,
    paper_markdown,
    protocol_deviations,
    results_from_csv,
    variant_name,
)

GENERATOR = "make results-doc"

#: The note of the VLA (π0.5) cells: what they need and how to fill them (docs/vla.md).
VLA_REASON = (
    "needs a GPU for π0.5: π0.5 needs a GPU and its weights, which this project's machines do "
    "not have (no GPU, no model hub). On a GPU machine with openpi (docs/vla.md): "
    "`kinder demos export-openpi datasets/<name>/data/lerobot $HF_LEROBOT_HOME/kinder/<name>`; in "
    "openpi, with the `pi05_kinder` config of docs/vla.md, `uv run scripts/compute_norm_stats.py "
    "--config-name pi05_kinder`, `uv run scripts/train.py pi05_kinder --exp-name=<name>` and "
    "`uv run scripts/serve_policy.py policy:checkpoint --policy.config=pi05_kinder "
    "--policy.dir=checkpoints/pi05_kinder/<name>/29999`; then `kinder bench run --agent vla "
    "--arg url=ws://HOST:8000 -e <env> --seeds 0-4 --episodes 50`"
)

#: The note of the LLM/VLM planner cells.
ENDPOINT_REASON = (
    "needs a model endpoint for GPT-5.2: the paper's model through an OpenAI-compatible API, "
    "which this project's machines cannot reach. With `OPENAI_API_KEY` set (or "
    "`--arg base_url=...`): "
    "`kinder bench run -a <llm_plan|vlm_plan|llm_con|vlm_con> -e <env> --seeds 0-4 --episodes 50`"
)

#: The GPU measurement of the paper preset's training step (benchmarks/speed/dp_gpu_cost.py).
GPU_COST_FILE = "dp_gpu_cost.json"

#: The command that trains and evaluates DP/DPES at the paper's budget on a GPU.
DIFFUSION_COMMAND = (
    "python benchmarks/experiments/learning.py <dp|dpes> --env <env> --paper-budget --device cuda "
    "--num-workers 14 --seeds 0-4 --episodes 50 --out runs/learning/<dp|dpes>"
)


def _span(values: Sequence[float], fmt: str) -> str:
    lo, hi = min(values), max(values)
    return format(lo, fmt) if format(lo, fmt) == format(hi, fmt) else f"{lo:{fmt}}–{hi:{fmt}}"


def diffusion_reason(gpu_cost: Mapping[str, Any] | None = None) -> str:
    """The note of the DP/DPES cells: the paper's budget, its cost on this project's CPUs and,
    from the committed GPU measurement (``GPU_COST_FILE``) where there is one, on a GPU."""
    text = (
        "needs a GPU for the paper's training budget: the paper preset (a UNet over 224×224 "
        "camera images, batch 64) for 5001 epochs over each env's 100 demonstrations, which "
        "trains at 1–2 samples/s on this project's CPUs (benchmarks/results/learning.md)"
    )
    if gpu_cost:
        rows = gpu_cost["rows"]
        one = [r["samples_per_s"] for r in rows if r["cameras"] == 1]
        three = [r["samples_per_s"] for r in rows if r["cameras"] == 3]
        hours = [r["paper_hours"] for r in rows if r.get("paper_hours") is not None]
        speeds = " and ".join(
            f"{_span(v, ',.0f')} samples/s with {n}"
            for v, n in ((one, "one camera (2D)"), (three, "three (3D)"))
            if v
        )
        text += (
            f". On an {gpu_cost['machine']['device']} ({gpu_cost['machine']['date']}) the "
            f"training step alone runs at {speeds}, so the paper's budget takes "
            f"{_span(hours, ',.1f')} GPU-hours per cell, {sum(hours):,.0f} for all "
            f"{len(hours)} DP and DPES cells, if data loading keeps up "
            f"(benchmarks/results/{GPU_COST_FILE}, learning.md)"
        )
    return f"{text}: `{DIFFUSION_COMMAND}`"


#: Agents that run on this project's CPUs, and the command that fills their cells.
CPU_COMMANDS = {
    "bilevel_planning": "kinder bench run -a bilevel_planning -e <env> --seeds 0-4 --episodes 50",
    "mpc": "kinder bench run -a mpc -e <env> --arg replan_interval=<N> --seeds 0-4 --episodes 50",
    "mbrl": "python benchmarks/experiments/learning.py mbrl --env <env> --epochs 1000 --seeds 0-4 "
    "--episodes 50 --out runs/learning/mbrl",
    "gsc": "kinder train gsc --env <env> --out runs/gsc/ckpt/<env>; then kinder bench run -a gsc "
    "--arg checkpoint=runs/gsc/ckpt/<env> -e <env> --seeds 0-4 --episodes 50",
    "ppo": "python benchmarks/experiments/rl_bench.py --algo ppo --env <env> --seeds 0-4 "
    "--steps 1000000 --episodes 50 --out runs/rl",
    "sac": "python benchmarks/experiments/rl_bench.py --algo sac --env <env> --seeds 0-4 "
    "--steps 1000000 --episodes 50 --out runs/rl",
}


def summary_files(results_dir: Path | str) -> list[Path]:
    """The committed run summaries, in name order."""
    return sorted(Path(results_dir).glob("*_summary.csv"))


def _extra_columns(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return [{k: v for k, v in row.items() if k not in CSV_COLUMNS and v} for row in rows]


def _committed_reason(agent: str, env_id: str, gpu_cost: Mapping[str, Any] | None = None) -> str:
    """Why a paper cell has no run of any kind, independent of this machine (an agent's own
    :meth:`~kinder_bench.agents.Agent.unavailable` depends on checkpoints, endpoints and GPUs
    here, so the page would differ between machines), with the command that fills it and, where
    a committed page measured it, the cost."""
    if agent not in AGENTS:
        return "the project has no such agent yet"
    if agent == "vla":
        return VLA_REASON
    if agent in ("llm_plan", "vlm_plan", "llm_con", "vlm_con"):
        return ENDPOINT_REASON
    if agent in ("dp", "dpes"):
        return diffusion_reason(gpu_cost)
    command = CPU_COMMANDS.get(
        agent, f"kinder bench run -a {agent} -e <env> --seeds 0-4 --episodes 50"
    )
    if agent in ("ppo", "sac"):
        return (
            f"{agent} runs on CPU here but was not trained on these envs; each needs 5 seeds × 1M "
            "env steps, 1.4–5.6 core-hours at the 250–1,000 steps/s one core trained the three "
            "trained envs, and PPO trained Transport3D-o2's five seeds in 2.5 core-hours at "
            "509–675 steps/s (benchmarks/results/rl.md). Stepping these envs alone takes, at the "
            "steps/s of the speed pages (dynamic2d.md, kinematic3d.md, dynamic3d.md), "
            "DynObstruction2D-o1 8.7 core-hours (160 steps/s), DynPushPullHook2D-o5 8.5 (163), "
            "Transport3D-o2 0.5 (2,694), Shelf3D-o1 2.2 (619) and SweepIntoDrawer3D-o5 12.7 "
            f"(109), before the learner's own time: `{command}`"
        )
    if agent == "gsc" and env_id == "kinder/SweepIntoDrawer3D-o5-v0":
        return (
            "gsc on SweepIntoDrawer3D-o5 has no finished run: its campaign cell collects 50 "
            "bilevel-planner demonstrations (attempts take 25–70 s each on this machine's "
            "shared cores, and some reach the 60 s planning limit) before the perturbations, the "
            "training and the 250 evaluation episodes; the command resumes where it stopped: "
            "`kinder bench campaign benchmarks/campaigns/paper.toml "
            "--only gsc/SweepIntoDrawer3D-o5 --out runs/campaign/gsc_SweepIntoDrawer3D-o5`"
        )
    where = ""
    if agent == "mpc":
        where = (
            " (N, and SweepIntoDrawer3D-o5's --max-steps 700, from upstream's env configs in "
            "kinder_bench/data/paper_settings.csv)"
        )
    if agent == "mpc":
        return (
            "mpc runs on CPU here but has not run at any protocol; its cost per episode at the "
            "paper's settings, where measured, and the campaigns started are in "
            f"benchmarks/results/mpc.md (the paper's Inf-Time is in the cell): `{command}`{where}"
        )
    return (
        f"{agent} runs on CPU here but has not run at any protocol; its cost per episode on this "
        f"machine is not measured (the paper's Inf-Time is in the cell): `{command}`{where}"
    )


def _data_csv(name: str, text: str | None) -> list[list[str]]:
    """The rows of the packaged data file ``kinder_bench/data/<name>`` (or of ``text`` when
    given), blank lines and ``#`` comment lines left out."""
    if text is None:
        text = resources.files("kinder_bench.data").joinpath(name).read_text("utf-8")
    return csv_rows(text)


DEVIATIONS_FILE = "baseline_deviations.csv"
_DEVIATION_COLUMNS = ("baseline", "what differs", "why", "expected effect")


def load_deviations(text: str | None = None) -> list[dict[str, str]]:
    """The rows of the baselines' deviations file (``#`` lines are comments); raises ValueError
    when its header or a row is malformed."""
    rows = _data_csv(DEVIATIONS_FILE, text)
    if not rows or tuple(rows[0]) != _DEVIATION_COLUMNS:
        raise ValueError(f"{DEVIATIONS_FILE}: expected the header {','.join(_DEVIATION_COLUMNS)}")
    out = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(_DEVIATION_COLUMNS) or not all(f.strip() for f in row):
            raise ValueError(f"{DEVIATIONS_FILE}: row {n} needs 4 non-empty fields, got {row}")
        out.append(dict(zip(_DEVIATION_COLUMNS, (f.strip() for f in row))))
    return out


def deviations_markdown(text: str | None = None) -> str:
    """The deviations file as one markdown table."""
    lines = ["| " + " | ".join(_DEVIATION_COLUMNS) + " |", "|---|---|---|---|"]
    for row in load_deviations(text):
        cells = (row[c].replace("|", "\\|") for c in _DEVIATION_COLUMNS)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _with_settings(result: Result, extra: dict[str, str]) -> Result:
    """The result named with the summary's extra columns (``bilevel_planning (search=gbfs)``)."""
    settings = ", ".join(f"{k}={v}" for k, v in extra.items())
    return dataclasses.replace(result, settings=settings)


def _per_seed(r: Result) -> int | None:
    """Episodes per run seed (None: seeds not recorded, or uneven)."""
    if not r.seeds or r.episodes % len(r.seeds):
        return None
    return r.episodes // len(r.seeds)


def _seeds_by_episodes(r: Result) -> str:
    """``5 × 50``: the run's seeds × its episodes per seed."""
    return f"{r.num_seeds} × {r.episodes // max(1, r.num_seeds)}"


def _current(r: Result) -> bool:
    """Measured by us, the same number of episodes on each seed, on the env as it is now (and
    without noise wrapped around it)."""
    return (
        not r.provenance
        and _per_seed(r) is not None
        and not r.obs_noise
        and not r.action_noise
        and PRE_CONFORMANCE not in protocol_deviations(r)
    )


def _paper_apart_from_count(r: Result) -> bool:
    """At the paper's protocol in everything but its episodes per seed (a 5 × 10 subset of a
    paper-protocol run, say)."""
    whole = dataclasses.replace(r, episodes=r.num_seeds * PAPER_EPISODES)
    return not r.is_variant and not protocol_deviations(whole)


def _full_args(r: Result) -> dict[str, Any] | None:
    """The row's agent arguments, with the defaults of options added since it was recorded
    filled in where the option's default is the behaviour it had before
    (:func:`~kinder_bench.agents.run_id_optional_defaults`). None: not recorded."""
    if r.agent_args is None:
        return None
    try:
        added = run_id_optional_defaults(agent_class(r.agent).Args)
    except (KeyError, ValueError, TypeError):
        return dict(r.agent_args)
    return {**added, **r.agent_args}


def _is_subset(r: Result) -> bool:
    """A row summarising the first episodes of each seed of a longer run
    (``kinder bench report --first-episodes``)."""
    return "--first-episodes" in r.command


def _sr(r: Result | None) -> str:
    return "not run" if r is None else fmt_stat(r.success, 2)


def heldout_markdown(results: Sequence[Result], envs: Sequence[str]) -> str:
    """Each run on the evaluation seeds (0–4) beside the same agent, arguments and env on run
    seeds never used for tuning, with the same episodes per seed (so a 5 × 10 held-out run is
    paired with the first 10 episodes of each evaluation seed): whether the figure holds on
    unseen episodes. A gap larger than the evaluation figure's std across seeds is marked."""
    lines = [
        "| env | run | episodes per seed | SR, seeds 0–4 | SR, held-out seeds | held-out seeds "
        "| gap |",
        "|---|---|---|---|---|---|---|",
    ]
    for env in envs:
        before = len(lines)
        for ev in (r for r in results if r.env_id == env and _current(r)):
            if tuple(sorted(ev.seeds or ())) != PAPER_SEEDS:
                continue
            held = [
                r
                for r in results
                if r.env_id == env
                and _current(r)
                and r.agent == ev.agent
                and r.method == ev.method
                and _full_args(r) == _full_args(ev)
                and _per_seed(r) == _per_seed(ev)
                and not set(r.seeds or ()) & set(PAPER_SEEDS)
            ]
            for h in held:
                gap = (h.success.mean or 0.0) - (ev.success.mean or 0.0)
                std = ev.success.std or 0.0
                flag = " (larger than the std)" if abs(gap) > std else ""
                seeds = f"{min(h.seeds or (0,))}–{max(h.seeds or (0,))}"
                name = variant_name(ev)
                if _is_subset(ev):
                    name += f" (the first {_per_seed(ev)} episodes of each seed of a longer run)"
                lines.append(
                    f"| {short_id(env)} | {name} | {_per_seed(ev)} | {_sr(ev)} "
                    f"| {_sr(h)} | {seeds} | {gap:+.2f}{flag} |"
                )
        if len(lines) == before:
            lines.append(f"| {short_id(env)} | -- | -- | not run | not run | -- | -- |")
    return "\n".join(lines) + "\n"


def attribution_markdown(results: Sequence[Result], envs: Sequence[str]) -> str:
    """BP at the paper's settings (upstream's planner: one refinement round, no replanning, no
    plan-length check) beside our default BP, on the evaluation seeds and the env as it is now:
    how much of our BP's figure comes from the planner's monitoring and how much from the
    skills the two share. Our default BP may carry a label (a campaign's ``bp-ours``): its
    arguments, not its name, say what it is; the paper-settings column takes unlabelled rows
    only, as the paper's cells do. The two are compared on the same episodes: 50 per seed
    where both ran them, else the most episodes per seed both have (the first N of each seed
    are the same instances in every run)."""
    default_args = dataclasses.asdict(agent_class("bilevel_planning").Args())
    lines = [
        "| env | episodes per seed | BP at the paper's settings (SR) | BP, our default (SR) "
        "| ours − paper settings |",
        "|---|---|---|---|---|",
    ]
    for env in envs:
        runs = [
            r
            for r in results
            if r.env_id == env
            and r.agent == "bilevel_planning"
            and _current(r)
            and tuple(sorted(r.seeds or ())) == PAPER_SEEDS
        ]
        # A run of that many episodes per seed wins over the first episodes of a longer run:
        # it ran under the same conditions as a run it is compared with.
        runs.sort(key=_is_subset, reverse=True)
        paper_runs = {_per_seed(r): r for r in runs if _paper_apart_from_count(r)}
        ours_runs = {_per_seed(r): r for r in runs if _full_args(r) == default_args}
        both = sorted((n for n in paper_runs if n in ours_runs), key=lambda n: n or 0)
        count = both[-1] if both else PAPER_EPISODES
        paper_run, ours = paper_runs.get(count), ours_runs.get(count)
        diff = (
            f"{(ours.success.mean or 0.0) - (paper_run.success.mean or 0.0):+.2f}"
            if ours is not None and paper_run is not None
            else "--"
        )
        lines.append(f"| {short_id(env)} | {count} | {_sr(paper_run)} | {_sr(ours)} | {diff} |")
    return "\n".join(lines) + "\n"


NOISE_FILE = "paper_noise.csv"
_NOISE_COLUMNS = ("env_id", "noise", "std", "sr")
_NOISE_KINDS = ("obs", "action")


def load_paper_noise(text: str | None = None) -> dict[tuple[str, str, float], str]:
    """The paper's noise table, ``(env id, "obs" | "action", std) → SR`` as printed
    (``kinder_bench/data/paper_noise.csv``; ``#`` lines are comments). Raises ValueError naming
    the row when the header or a row is malformed."""
    rows = _data_csv(NOISE_FILE, text)
    if not rows or tuple(rows[0]) != _NOISE_COLUMNS:
        raise ValueError(f"{NOISE_FILE}: expected the header {','.join(_NOISE_COLUMNS)}")
    out: dict[tuple[str, str, float], str] = {}
    for n, row in enumerate(rows[1:], start=2):
        try:
            env_id, kind, std, sr = (f.strip() for f in row)
            if kind not in _NOISE_KINDS:
                raise ValueError(f"noise {kind!r} is not one of {_NOISE_KINDS}")
            float(sr)
            out[(env_id, kind, float(std))] = sr
        except ValueError as e:
            raise ValueError(f"{NOISE_FILE}: row {n} {row}: {e}") from None
    return out


def _noise_of(r: Result, kind: str) -> float:
    return r.obs_noise if kind == "obs" else r.action_noise


def noise_markdown(
    results: Sequence[Result], paper_noise: Mapping[tuple[str, str, float], str] | None = None
) -> str:
    """The paper's noise table beside ours: BP's SR on each env of the paper's table under
    observation noise and under action noise of each std the paper used, from runs on seeds 0–4
    × 50. Three rows per env:

    * the paper's BP: the paper's settings and, as upstream's agent, open loop (it fails when
      its plan's actions run out: ``max_replans=0``), unlabelled, as a paper cell would be;
    * the paper's settings with our agent's re-planning when the plan runs out
      (``max_replans`` at its default; any label);
    * our default BP (any label).

    At σ=0 the first two rows take the same runs: without noise the executed states are the
    planned ones, the plan never runs out, and ``max_replans`` changes nothing, so the paper cell
    (recorded with the default) is both. ``ours (paper)`` in the first row; ``not run`` where no
    such run exists."""
    paper = load_paper_noise() if paper_noise is None else paper_noise
    envs = list(dict.fromkeys(e for e, _, _ in paper))
    columns = sorted(
        {(k, std) for _, k, std in paper}, key=lambda c: (_NOISE_KINDS.index(c[0]), c[1])
    )
    default_args = dataclasses.asdict(agent_class("bilevel_planning").Args())
    header = " | ".join(
        f"{'observation' if k == 'obs' else 'action'} σ={std:g}" for k, std in columns
    )
    lines = [f"| env | BP | {header} |", "|---|---|" + "---|" * len(columns)]

    def runs_at(env: str, kind: str, std: float) -> list[Result]:
        other = "action" if kind == "obs" else "obs"
        return [
            r
            for r in results
            if r.env_id == env
            and r.agent == "bilevel_planning"
            and not r.provenance
            and tuple(sorted(r.seeds or ())) == PAPER_SEEDS
            and _per_seed(r) == PAPER_EPISODES
            and _noise_of(r, kind) == std
            and not _noise_of(r, other)
            and PRE_CONFORMANCE not in protocol_deviations(r)
        ]

    def paper_settings_apart_from_noise(r: Result) -> bool:
        return not protocol_deviations(dataclasses.replace(r, obs_noise=0.0, action_noise=0.0))

    def replans(r: Result) -> Any:
        return (r.agent_args or {}).get("max_replans")

    def open_loop(r: Result, std: float) -> bool:
        return (
            not r.is_variant
            and paper_settings_apart_from_noise(r)
            and (replans(r) == 0 or std == 0)
        )

    def replanning(r: Result, std: float) -> bool:
        del std
        return paper_settings_apart_from_noise(r) and replans(r) == default_args["max_replans"]

    def our_default(r: Result, std: float) -> bool:
        del std
        return _full_args(r) == default_args

    rows: tuple[tuple[str, Callable[[Result, float], bool]], ...] = (
        ("paper's BP, open loop (paper)", open_loop),
        ("paper's settings, re-planning when the plan runs out", replanning),
        ("our default", our_default),
    )
    for env in envs:
        for n, (name, wanted) in enumerate(rows):
            cells = []
            for kind, std in columns:
                run = next((r for r in runs_at(env, kind, std) if wanted(r, std)), None)
                figure = f" ({paper.get((env, kind, std), '--')})" if n == 0 else ""
                cells.append(_sr(run) + figure)
            lines.append(f"| {short_id(env)} | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


SUBTASKS_FILE = "paper_subtasks.csv"


def load_paper_subtasks(text: str | None = None) -> dict[tuple[str, str], dict[str, str]]:
    """The paper's subtask table, ``(env id, agent) → {milestone: rate as printed}``
    (``kinder_bench/data/paper_subtasks.csv``; ``#`` lines are comments). Raises ValueError
    naming the row when the header or a row is malformed."""
    rows = _data_csv(SUBTASKS_FILE, text)
    if not rows or tuple(rows[0][:2]) != ("env_id", "baseline") or len(rows[0]) < 3:
        raise ValueError(f"{SUBTASKS_FILE}: expected the header env_id,baseline,<milestones...>")
    names = [n.strip() for n in rows[0][2:]]
    out: dict[tuple[str, str], dict[str, str]] = {}
    for n, row in enumerate(rows[1:], start=2):
        try:
            if len(row) != len(rows[0]):
                raise ValueError(f"expected {len(rows[0])} fields")
            for rate in row[2:]:
                float(rate)
            out[(row[0].strip(), row[1].strip())] = {k: v.strip() for k, v in zip(names, row[2:])}
        except ValueError as e:
            raise ValueError(f"{SUBTASKS_FILE}: row {n} {row}: {e}") from None
    return out


def subtasks_markdown(
    results: Sequence[Result],
    paper_subtasks: Mapping[tuple[str, str], Mapping[str, str]] | None = None,
) -> str:
    """The paper's subtask table beside ours: per env of the paper's table, a row per baseline
    the paper broke down (``ours (paper)``; ours only from a run at the paper's protocol,
    ``n/r`` without one), then a row for every other run that tracked the milestones, named by
    what differs (:func:`~kinder_bench.reporting.paper.variant_name`), with its seeds ×
    episodes."""
    paper = load_paper_subtasks() if paper_subtasks is None else paper_subtasks
    table = load_paper()
    lines: list[str] = []
    for env in dict.fromkeys(e for e, _ in paper):
        names = list(next(v for (e, _), v in paper.items() if e == env))
        tracked = [r for r in results if r.env_id == env and r.subtasks]
        lines += [
            f"| {short_id(env)} | seeds × episodes | " + " | ".join(names) + " |",
            "|---|---|" + "---|" * len(names),
        ]
        used: set[int] = set()
        for (e, agent), rates in paper.items():
            if e != env:
                continue
            run = next(
                (r for r in tracked if r.agent == agent and at_paper_protocol(r, table)), None
            )
            if run is not None:
                used.add(id(run))
            cells = [
                f"{fmt_stat(run.subtasks[n], 2) if run is not None else 'n/r'} ({rates[n]})"
                for n in names
            ]
            method = table.method_of(agent) or agent
            budget = _seeds_by_episodes(run) if run is not None else ""
            lines.append(f"| {method} (paper) | {budget} | " + " | ".join(cells) + " |")
        for r in tracked:
            if id(r) in used:
                continue
            cells = [fmt_stat(r.subtasks[n], 2) if n in r.subtasks else "" for n in names]
            lines.append(
                f"| {variant_name(r)} | {_seeds_by_episodes(r)} | " + " | ".join(cells) + " |"
            )
        lines.append("")
    return "\n".join(lines)


OOD_FILE = "paper_ood.csv"


def load_paper_ood(text: str | None = None) -> dict[tuple[str, str], str]:
    """The paper's out-of-distribution table, ``(env id, baseline) → SR`` as printed, in the
    file's order, the training env first (``kinder_bench/data/paper_ood.csv``; ``#`` lines are
    comments). Raises ValueError naming the row when the header or a row is malformed."""
    rows = _data_csv(OOD_FILE, text)
    if not rows or [c.strip() for c in rows[0]] != ["env_id", "baseline", "sr"]:
        raise ValueError(f"{OOD_FILE}: expected the header env_id,baseline,sr")
    out: dict[tuple[str, str], str] = {}
    for n, row in enumerate(rows[1:], start=2):
        try:
            if len(row) != 3:
                raise ValueError("expected 3 fields")
            float(row[2])
            out[(row[0].strip(), row[1].strip())] = row[2].strip()
        except ValueError as e:
            raise ValueError(f"{OOD_FILE}: row {n} {row}: {e}") from None
    return out


def ood_markdown(
    results: Sequence[Result], paper_ood: Mapping[tuple[str, str], str] | None = None
) -> str:
    """The paper's out-of-distribution table beside ours: a column per env (the training env
    first), a row per baseline the paper ran (``ours (paper)``; ours only from a run whose
    settings, apart from the env, are the paper's protocol on the training env, ``n/r``
    without one), then a row per other checkpoint of those baselines evaluated beyond the
    training env, named by what differs (:func:`~kinder_bench.reporting.paper.variant_name` on
    the training env), with its SR on each env it ran."""
    paper = load_paper_ood() if paper_ood is None else paper_ood
    envs = list(dict.fromkeys(e for e, _ in paper))
    train_env = envs[0]
    baselines = list(dict.fromkeys(b for _, b in paper))
    table = load_paper()

    def as_trained(r: Result) -> Result:
        return dataclasses.replace(r, env_id=train_env)

    runs = [r for r in results if r.env_id in envs and r.agent in baselines]

    def paper_run(agent: str, env: str) -> Result | None:
        return next(
            (
                r
                for r in runs
                if r.agent == agent and r.env_id == env and at_paper_protocol(as_trained(r), table)
            ),
            None,
        )

    lines = [
        "| Run | seeds × episodes | " + " | ".join(short_id(e) for e in envs) + " |",
        "|---|---|" + "---|" * len(envs),
    ]
    used: set[int] = set()
    for agent in baselines:
        cells, budget = [], ""
        for env in envs:
            run = paper_run(agent, env)
            if run is not None:
                used.add(id(run))
                budget = _seeds_by_episodes(run)
            ours = fmt_stat(run.success, 2) if run is not None else "n/r"
            cells.append(f"{ours} ({paper[(env, agent)]})" if (env, agent) in paper else "")
        method = table.method_of(agent) or agent
        lines.append(f"| {method} (paper) | {budget} | " + " | ".join(cells) + " |")
    groups: dict[tuple[str, str], list[Result]] = {}
    for r in runs:
        if id(r) not in used:
            key = (r.agent, str((r.agent_args or {}).get("checkpoint", "")))
            groups.setdefault(key, []).append(r)
    for group in groups.values():
        if all(r.env_id == train_env for r in group):
            continue  # a plain run on the training env: a variant of the first table
        by_env = {r.env_id: r for r in group}
        cells = [fmt_stat(by_env[e].success, 2) if e in by_env else "" for e in envs]
        lines.append(
            f"| {variant_name(as_trained(group[0]))} | {_seeds_by_episodes(group[0])} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines) + "\n"


def results_markdown(files: Sequence[Path], link_root: Path) -> str:
    """The page for the given summary files (links relative to ``link_root``, the page's folder).

    Raises ValueError naming the file and row when a row has no command.
    """
    if not files:
        raise ValueError("No *_summary.csv files to build the results page from")
    cost_file = Path(files[0]).parent / GPU_COST_FILE
    gpu_cost = json.loads(cost_file.read_text()) if cost_file.exists() else None

    def reason(agent: str, env_id: str) -> str:
        return _committed_reason(agent, env_id, gpu_cost)

    per_file = []
    everything = []
    for path in files:
        results = [
            _with_settings(r, extra)
            for r, extra in zip(results_from_csv(path), _extra_columns(path))
        ]
        for n, r in enumerate(results, start=2):
            if not r.command:
                raise ValueError(
                    f"{path}:{n}: the row of {r.method} on {r.env_id} has no command; add the "
                    "command that produced it in a 'command' column"
                )
        everything += results
        per_file.append((path, results))
    lines = [
        "# KinDERBench results",
        "",
        f"Generated by `{GENERATOR}` (`python tools/gen_results_doc.py`) from the run summaries "
        "committed in `benchmarks/results/` (`*_summary.csv`); do not edit it by hand. Every row "
        "links to the command that measured it. The machine, its load and the caveats of each "
        "measurement are in the notes next to each summary.",
        "",
        "## Beside the paper",
        "",
        "One rule fills the paper's Table II layout (its eight benchmark envs and thirteen "
        "baselines): a cell holds our figure only when a run at the paper's protocol made it — "
        "seeds 0–4 × 50 episodes, the paper's step budget, the baseline's paper settings and its "
        "paper training budget (`kinder_bench/data/paper_settings.csv`), decided from the "
        "settings each summary row records. Every other run is a variant, named by what "
        "differs, in the rows under the table with its budget; `n/r` only where no run of any "
        "kind exists, with why and the command that fills it. The first table counts the "
        "paper's cells in each state.",
        "",
        paper_markdown(compare(everything, reason=reason)).rstrip("\n"),
        "",
        "## Evaluation seeds against held-out seeds",
        "",
        "Skills and planners were tuned, in part, on the evaluation episodes (runner seeds 0–4) "
        "before the rule that keeps them for the table (DEVELOPING.md). Each run below is "
        "repeated with the same agent and arguments on run seeds never used before; a gap "
        "larger than the seeds' std says the evaluation figure is optimistic. Only runs on "
        "the envs as they are now (not before they followed upstream) are paired, each with "
        "the same episodes per seed (a 5 × 10 run with the first 10 instances of each seed). "
        "Where BP's failures are planning calls cut off by its 60 s wall-clock budget "
        "(DynPushPullHook2D-o5, Transport3D-o2, SweepIntoDrawer3D-o5), its SR also depends on "
        "how busy the machine was, so a run of the evaluation seeds made beside the held-out "
        "run is shown too (benchmarks/results/bp_heldout.md).",
        "",
        heldout_markdown(everything, load_paper().envs).rstrip("\n"),
        "",
        "## Attribution: the paper's BP against ours",
        "",
        "Our BP re-plans when the observed state leaves the plan, refines each abstract plan in "
        "three rounds and rejects plans longer than the steps left; the paper's (upstream's) "
        "does none of these. Both use the same skills, so the difference is what the "
        "planner's monitoring adds; the paper's column minus the paper's published figure is "
        "what our skills and envs change. `not run`: no run of that setting on the env as it "
        "is now (`kinder bench run -a bilevel_planning -e <env> --seeds 0-4 --episodes 50`, "
        "with `--arg refinement_rounds=1 --arg replan_on_divergence=false "
        "--arg respect_episode_limit=false` for the paper's settings).",
        "",
        attribution_markdown(everything, load_paper().envs).rstrip("\n"),
        "",
        "## BP under observation and action noise",
        "",
        "The paper's noise table: bilevel planning with Gaussian noise of the given std on "
        "every observation entry, or on every action entry (`kinder_core.NoisyObservation` and "
        "`NoisyAction`, clipped to the space's bounds as upstream's wrappers do), on run seeds "
        "0–4 × 50 at the paper's step budget (`benchmarks/campaigns/noise.toml`; σ=0 is the BP "
        "cell of the table above). The paper names the families only; these rows use its "
        "Table II variants. The paper's BP is upstream's open-loop agent (`max_replans=0`: it "
        "fails when its plan's actions run out); the second row adds our agent's re-planning "
        "when the plan runs out, the third is our default BP, which also re-plans whenever "
        "the observed state leaves its plan. Each run is a variant (named by its noise) in the "
        "rows under the first table (benchmarks/results/noise.md).",
        "",
        noise_markdown(everything).rstrip("\n"),
        "",
        "## SweepIntoDrawer3D subtasks",
        "",
        "The paper's subtask table: the rate of episodes that opened the drawer, grasped the "
        "sweeper, swept at least one cube into the drawer and swept all of them "
        "(`kinder_bench.evaluation.subtasks`: the milestones are the planning model's concepts, "
        "tracked on the true state after every step; one reached counts whatever happens "
        "later). The runner records them in every SweepIntoDrawer3D episode. Each cell: ours "
        "(paper); ours only from a run at the paper's protocol. The paper's three rows need "
        "trained policies: DP and DPES at the paper's budget need a GPU, VLA a GPU and π0.5 "
        "(note [b], [c] above); other runs that tracked the milestones follow, named by what "
        "differs.",
        "",
        subtasks_markdown(everything).rstrip("\n"),
        "",
        "## DynObstruction2D out of distribution",
        "",
        "The paper's out-of-distribution table: imitation policies trained on "
        "DynObstruction2D-o1's demonstrations (one obstruction) and evaluated on its variants "
        "with 0, 2 and 3 obstructions (`kinder train ood --checkpoint RUN --out DIR`: the "
        "runner on o0–o3 at the paper's 200-step budget; DP sees only the image and the robot "
        "state, which every variant has). Each cell: ours (paper) SR; ours only from a run at "
        "the paper's protocol apart from the env (seeds 0–4 × 50, the paper's training budget). "
        "The paper's rows need a GPU (DP's budget, note [c]) and π0.5 (VLA, note [b]); other "
        "checkpoints evaluated beyond o1 follow, named by what differs.",
        "",
        ood_markdown(everything).rstrip("\n"),
        "",
        "## Deviations of the baselines from the paper",
        "",
        "What our implementation of each baseline does differently from the paper's, even at "
        "the paper's protocol (`kinder_bench/data/baseline_deviations.csv`).",
        "",
        deviations_markdown().rstrip("\n"),
        "",
        "## Every committed result",
        "",
    ]
    commands: dict[str, int] = {}
    for path, results in per_file:
        rel = os.path.relpath(path, link_root)
        lines.append(f"### `{path.name}`")
        lines.append("")
        note = path.with_name(path.name.replace("_summary.csv", ".md"))
        if note.exists():
            note_rel = os.path.relpath(note, link_root)
            lines += [f"Notes and caveats: [{note.name}]({note_rel}).", ""]
        lines += [
            f"Source: [{path.name}]({rel}).",
            "",
            "| env | run (named as beside the paper) | seeds × episodes | SR ↑ | Rwd ↑ "
            "| Inf-Time (s) ↓ | errors | provenance | command |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in results:
            number = commands.setdefault(r.command, len(commands) + 1)
            cells = [
                fmt_stat(r.stat(m), metric_digits(m, r.stat(m))) for m in ("SR", "Rwd", "Inf-Time")
            ]
            where = r.provenance or "measured"
            lines.append(
                f"| {r.env_id} | {variant_name(r)} | {_seeds_by_episodes(r)} | "
                + " | ".join(cells)
                + f" | {r.errors} | {where} | [#{number}](#command-{number}) |"
            )
        lines.append("")
    lines += ["## Commands", ""]
    for command, number in commands.items():
        lines += [f'<a id="command-{number}"></a>**#{number}**', "", "```bash", command, "```", ""]
    return "\n".join(lines).rstrip("\n") + "\n"


# -- the guard: no success rate lives only in prose ------------------------------------------------

#: A success-rate figure as printed: ``0.27``, ``**0.27 ± 0.07**``, ``1.00 ± 0.000``.
_FIGURE = re.compile(r"\*{0,2}\b([01]\.\d{2})(?: ± \d\.\d{2,4})?\b\*{0,2}")
#: A prose quote: ``SR`` then, within the same clause, a figure.
_PROSE_SR = re.compile(r"\bSR\b[^.;:\n|]{0,40}?(?<![\d.])([01]\.\d{2})(?![\d])")
#: Words that label a figure as the paper's (allowed without a summary row of ours).
_PAPER_WORDS = ("paper", "upstream")


@dataclasses.dataclass(frozen=True)
class Quote:
    """A success rate a results page quotes, and what it is tied to."""

    page: str
    line: int
    figure: str
    env_ids: frozenset[str]
    methods: frozenset[str]
    """Agent names the quote's context names (empty: none named)."""

    def __str__(self) -> str:
        methods = ", ".join(sorted(self.methods)) or "any method"
        envs = ", ".join(sorted(short_id(e) for e in self.env_ids))
        return f"{self.page}:{self.line}: SR {self.figure} of {methods} on {envs}"


def _method_names(results: Sequence[Result]) -> dict[str, str]:
    """Name as a page may write it (lower case) → agent: agent names, the paper's method names
    and every label in the summaries (``ppo-dense``)."""
    names = {a.lower(): a for a in AGENTS}
    names.update({m.lower(): a for m, a in load_paper().agents.items()})
    names.update({r.method.lower(): r.agent for r in results})
    names.update({"bilevel planning": "bilevel_planning", "bilevel planner": "bilevel_planning"})
    return names


def _named(text: str, names: Mapping[str, str]) -> set[str]:
    low = text.lower()
    return {
        agent
        for name, agent in names.items()
        if re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", low)
    }


def _envs_in(text: str, env_ids: Sequence[str]) -> set[str]:
    """The env ids a text names, by full id or short name (``Motion2D-p0``)."""
    out = set()
    for env_id in env_ids:
        short = short_id(env_id)
        if env_id in text or re.search(rf"(?<![\w-]){re.escape(short)}(?![\w-]*\w)", text):
            out.add(env_id)
    return out


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _is_paper(text: str) -> bool:
    low = text.lower()
    return any(word in low for word in _PAPER_WORDS)


def sr_quotes(
    page: str, text: str, env_ids: Sequence[str], names: Mapping[str, str]
) -> list[Quote]:
    """Every success rate ``text`` quotes of ours, tied to the envs and methods its context
    names: the ``SR`` cells of tables (the report's ``| Env | Metric |`` layout, or a column
    whose header starts with ``SR``), and ``SR 0.xx`` in prose. A figure is tied to the envs its
    row (or line) names — a table row of the report's layout inherits its env from the row above
    — and to the methods its column header, its row, or else the nearest heading names. Figures
    labelled as the paper's or upstream's (in the column header, or within the clause before a
    prose figure) are not ours and are left out, and so is a ``(paper)`` figure after ours."""
    quotes: list[Quote] = []
    header: list[str] | None = None
    heading = ""
    row_envs: set[str] = set()
    for n, line in enumerate(text.splitlines(), start=1):
        if line.startswith("#"):
            heading = line
        if not line.startswith("|"):
            header = None
            for m in _PROSE_SR.finditer(line):
                before = line[max(0, m.start() - 30) : m.start(1)]
                if _is_paper(before):
                    continue
                envs = _envs_in(line, env_ids) or _envs_in(heading, env_ids)
                methods = _named(line, names) or _named(heading, names)
                if envs:
                    quotes.append(Quote(page, n, m.group(1), frozenset(envs), frozenset(methods)))
            continue
        cells = _cells(line)
        if header is None:
            header = cells
            continue
        if set(line.replace("|", "").strip()) <= set("-: "):
            continue
        report_layout = len(header) > 2 and header[1].lower() == "metric"
        if report_layout:
            if cells[0]:
                row_envs = _envs_in(cells[0], env_ids)
            if not cells[1].startswith("SR"):
                continue
            columns = list(zip(header[2:], cells[2:]))
            envs = row_envs
        else:
            columns = [(h, c) for h, c in zip(header, cells) if h.startswith("SR")]
            envs = _envs_in(" ".join(cells), env_ids)
        for head, cell in columns:
            figure = _FIGURE.fullmatch(cell.split(" (")[0].strip())
            if figure is None or _is_paper(head) or not envs:
                continue
            methods = _named(head, names)
            if report_layout and not methods:
                # The report's column header is the method's label, known or not.
                methods = {head.strip("* ").lower()}
            methods = (
                methods
                or _named(" ".join(cells), names)
                or _named(heading, names)
                or _named(page, names)
            )
            quotes.append(Quote(page, n, figure.group(1), frozenset(envs), frozenset(methods)))
    return quotes


def unbacked_quotes(
    pages: Mapping[str, str], results: Sequence[Result], extra_envs: Sequence[str] = ()
) -> list[Quote]:
    """The quotes of ``pages`` (name → text) for a (method, env) that no summary row holds: no
    row of that env by one of the named methods (an agent, or a row's label such as
    ``ppo-dense``; any method when the context names none)."""
    names = _method_names(results)
    env_ids = sorted({r.env_id for r in results} | set(load_paper().envs) | set(extra_envs))
    held = {(r.env_id, r.agent) for r in results} | {(r.env_id, r.method.lower()) for r in results}
    held_envs = {r.env_id for r in results}
    bad = []
    for page, text in pages.items():
        for q in sr_quotes(page, text, env_ids, names):
            if q.methods:
                ok = any((e, m) in held for e in q.env_ids for m in q.methods)
            else:
                ok = bool(q.env_ids & held_envs)
            if not ok:
                bad.append(q)
    return bad
