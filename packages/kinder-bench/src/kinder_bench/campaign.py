"""One driver for a whole benchmark campaign: cells from one data file, trained where needed,
evaluated through the runner, resumable (``kinder bench campaign FILE.toml``).

A **campaign file** (TOML) holds the campaign's defaults and a list of cells; a cell is a method
on a list of envs (``"paper"``: the paper's eight), so a method × env grid is one entry::

    [campaign]
    name = "paper"
    out = "runs/campaign/paper"   # relative to the working directory
    seeds = "0-4"                 # run seeds ("0-4", "0,1" or a list); the paper's: 0-4
    episodes = 50                 # per seed
    imports = []                  # modules that register extra envs or agents

    [[cells]]
    name = "mbrl"                 # unique; names the training directories
    agent = "mbrl"
    envs = "paper"
    paper_settings = true         # the agent's arguments and step budget from the paper's
                                  # settings (kinder_bench/data/paper_settings.csv), per env
    args = {}                     # argument overrides for every env ...
    env_args = {}                 # ... and per env: { "Motion2D-p0" = { horizon = 50 } }
    # label = "mbrl-5x10"         # a name other than the agent's marks a variant
    # seeds, episodes, max_steps  # override the campaign's
    # obs_noise, action_noise     # Gaussian noise stds on the env (the paper's noise table)

    [cells.train]                 # optional: train before evaluating
    method = "mbrl"               # `kinder train mbrl`
    args = { dataset = "datasets/{env}/data/lerobot", epochs = 1000, progress = false }
    per_seed = false              # true: one model per run seed (PPO, SAC)
    checkpoint_arg = "checkpoint" # the agent argument that receives the training directory
    budget = "1000 epochs"        # the training budget in words: the run's `training` (the
                                  # summary rows'; a paper cell needs the paper's budget text)

Strings in the training arguments may name ``{env}`` (short id, ``Motion2D-p0``), ``{env_id}``
and, with ``per_seed``, ``{seed}``. A cell's models go to ``OUT/train/<cell>/<env>[/seed<S>]``;
``kinder train <method> --out DIR --<key> <value> ...`` trains them (a trainer resumes from its
last checkpoint). A finished training writes ``campaign_train.json`` beside its checkpoints and
is skipped on the next call unless its command changed. Then every cell's episodes go to one
runner call (:func:`~kinder_bench.evaluation.runner.run_benchmark`) into ``OUT/eval``, over the
chosen executor (``inline``, ``process`` or ``ray``, with a cluster ``address``): the runner skips
episodes already in ``results.jsonl`` and writes ``summary.csv``. ``OUT/campaign.json`` records
every cell: its run arguments, training commands and budget, and episodes done out of planned.

A cell whose training fails is reported and not evaluated; the other cells go on.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import time
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from kinder_bench.agents import Agent, agent_class, make_args, parse_value
from kinder_bench.evaluation.envs import resolve_env_id, short_id
from kinder_bench.evaluation.protocol import PAPER_ENVS
from kinder_bench.evaluation.results import load_records, write_json
from kinder_bench.evaluation.runner import RunConfig, check_noise, resolve_run, run_benchmark
from kinder_bench.reporting.paper import paper_settings

TRAIN_MARKER = "campaign_train.json"
STATUS_FILE = "campaign.json"
_RUN_SETTINGS = ("max_steps", "training")
_CAMPAIGN_KEYS = {"name", "out", "seeds", "episodes", "imports"}
_CELL_KEYS = {"name", "agent", "envs", "paper_settings", "args", "env_args", "label", "seeds",
              "episodes", "max_steps", "train", "obs_noise", "action_noise"}  # fmt: skip
_TRAIN_KEYS = {"method", "args", "per_seed", "checkpoint_arg", "budget"}


@dataclasses.dataclass(frozen=True)
class TrainSpec:
    """How a cell's models are trained (``kinder train <method>``)."""

    method: str
    args: Mapping[str, Any]
    per_seed: bool = False
    checkpoint_arg: str = "checkpoint"
    budget: str = ""


@dataclasses.dataclass(frozen=True)
class Cell:
    """One method on one env: what to train and what the runner evaluates."""

    name: str
    agent: str
    env_id: str
    args: Mapping[str, Any]
    seeds: tuple[int, ...]
    episodes: int
    max_steps: int | None
    label: str | None
    train: TrainSpec | None
    obs_noise: float = 0.0
    action_noise: float = 0.0

    @property
    def key(self) -> str:
        """``<cell name>/<env short id>``."""
        return f"{self.name}/{short_id(self.env_id)}"

    def train_dir(self, out: Path, seed: int | str | None = None) -> Path:
        """Where this cell's model (of run seed ``seed`` when trained per seed) goes."""
        base = out / "train" / self.name / short_id(self.env_id)
        return base if seed is None else base / f"seed{seed}"

    def run_config(self, out: Path) -> RunConfig:
        """The runner's run of this cell (its checkpoint argument filled in)."""
        args = dict(self.args)
        if self.train is not None:
            seed = "{seed}" if self.train.per_seed else None
            args[self.train.checkpoint_arg] = str(self.train_dir(out, seed))
        training = self.train.budget if self.train is not None else ""
        return RunConfig(self.env_id, self.agent, args, self.seeds, self.episodes,
                         self.max_steps, self.label, training,
                         obs_noise=self.obs_noise, action_noise=self.action_noise)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Campaign:
    """A campaign file, loaded: its name, output root, imports and cells."""

    name: str
    out: Path
    imports: tuple[str, ...]
    cells: tuple[Cell, ...]


def _seeds(value: Any, where: str) -> tuple[int, ...]:
    if isinstance(value, list) and value and all(isinstance(s, int) for s in value):
        return tuple(value)
    if isinstance(value, str):
        seeds: list[int] = []
        try:
            for part in filter(None, (p.strip() for p in value.split(","))):
                lo, sep, hi = part.partition("-")
                seeds += range(int(lo), int(hi) + 1) if sep else [int(part)]
        except ValueError:
            seeds = []
        if seeds:
            return tuple(dict.fromkeys(seeds))
    raise ValueError(f"{where}: seeds {value!r}: expected '0-4', '0,1,2' or a list of integers")


def _check_keys(table: Mapping[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; expected some of {sorted(allowed)}")


def _envs(value: Any, where: str) -> list[str]:
    if value == "paper":
        return list(PAPER_ENVS)
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value or not all(isinstance(e, str) for e in value):
        raise ValueError(f"{where}: envs {value!r}: expected 'paper' or a list of env ids")
    return [resolve_env_id(e) for e in value]


def _table(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"{where}: expected a table, got {value!r}")
    return dict(value)


def _check_args(cls: type[Agent[Any]], args: Mapping[str, Any], trained: bool) -> None:
    """Raise unless ``args`` are arguments of the agent with values of their types; when the
    cell trains its checkpoint, the arguments are not built (the agent's checks may need the
    checkpoint to exist)."""
    if not trained:
        make_args(cls, args)
        return
    fields = {f.name for f in dataclasses.fields(cls.Args)}
    unknown = sorted(set(args) - fields)
    if unknown:
        raise ValueError(
            f"Unknown argument(s) {unknown} for agent {cls.name!r}; its arguments: {sorted(fields)}"
        )
    hints = typing.get_type_hints(cls.Args)
    for key, value in args.items():
        parse_value(value, hints[key], f"agent {cls.name!r} argument {key!r}")


def _train_spec(value: Any, where: str) -> TrainSpec:
    table = _table(value, where)
    _check_keys(table, _TRAIN_KEYS, where)
    if not isinstance(table.get("method"), str) or not table["method"]:
        raise ValueError(f"{where}: method: expected a `kinder train` command name (e.g. 'mbrl')")
    args = _table(table.get("args", {}), f"{where}.args")
    if "out" in args:
        raise ValueError(f"{where}.args: 'out' is set by the campaign (OUT/train/<cell>/<env>)")
    return TrainSpec(
        method=table["method"],
        args=args,
        per_seed=bool(table.get("per_seed", False)),
        checkpoint_arg=str(table.get("checkpoint_arg", "checkpoint")),
        budget=str(table.get("budget", "")),
    )


def _cells(raw: Mapping[str, Any], defaults: Mapping[str, Any], where: str) -> list[Cell]:
    _check_keys(raw, _CELL_KEYS, where)
    name, agent = raw.get("name"), raw.get("agent")
    if not isinstance(agent, str) or not agent:
        raise ValueError(f"{where}: agent: expected an agent name (see `kinder agents`)")
    name = name if isinstance(name, str) and name else agent
    where = f"{where} ({name})"
    cls = agent_class(agent)
    seeds = _seeds(raw.get("seeds", defaults["seeds"]), where)
    episodes = raw.get("episodes", defaults["episodes"])
    if not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"{where}: episodes {episodes!r}: expected an integer >= 1")
    train = _train_spec(raw["train"], f"{where}.train") if "train" in raw else None
    noise = {}
    for key in ("obs_noise", "action_noise"):
        value = raw.get(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{where}: {key} {value!r}: expected a number >= 0 (a Gaussian std)")
        try:
            noise[key] = check_noise(key, value)
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None
    common = _table(raw.get("args", {}), f"{where}.args")
    per_env = {
        resolve_env_id(e): _table(a, f"{where}.env_args.{e}")
        for e, a in _table(raw.get("env_args", {}), f"{where}.env_args").items()
    }
    envs = _envs(raw.get("envs"), where)
    stray = sorted(set(per_env) - set(envs))
    if stray:
        raise ValueError(f"{where}: env_args names env(s) the cell does not run: {stray}")
    out = []
    for env_id in envs:
        args: dict[str, Any] = {}
        max_steps = raw.get("max_steps")
        if raw.get("paper_settings", False):
            settings = paper_settings(agent, env_id)
            args = {k: v for k, v in settings.items() if k not in _RUN_SETTINGS}
            if max_steps is None:
                max_steps = settings.get("max_steps")
        args.update(common)
        args.update(per_env.get(env_id, {}))
        try:  # bad argument names or values fail here, before anything runs
            _check_args(cls, args, trained=train is not None)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{where} on {env_id}: {e}") from None
        if max_steps is not None and (not isinstance(max_steps, int) or max_steps < 1):
            raise ValueError(f"{where}: max_steps {max_steps!r}: expected an integer >= 1")
        label = raw.get("label")
        out.append(Cell(name, agent, env_id, args, seeds, episodes, max_steps,
                        str(label) if label else None, train, **noise))  # fmt: skip
    return out


def parse_campaign(data: Mapping[str, Any], source: str = "campaign") -> Campaign:
    """A campaign from a parsed campaign file (see the module docstring); errors name the
    offending entry and what was expected."""
    head = _table(data.get("campaign", {}), f"{source}: [campaign]")
    _check_keys(head, _CAMPAIGN_KEYS, f"{source}: [campaign]")
    _check_keys(data, {"campaign", "cells"}, source)
    name = str(head.get("name", Path(source).stem))
    defaults = {"seeds": head.get("seeds", "0-4"), "episodes": head.get("episodes", 50)}
    raw_cells = data.get("cells")
    if not isinstance(raw_cells, list) or not raw_cells:
        raise ValueError(f"{source}: expected at least one [[cells]] entry")
    imports = tuple(head.get("imports", ()))
    if imports:
        from kinder_bench.evaluation.runner import import_modules

        import_modules(imports)
    cells: list[Cell] = []
    for i, raw in enumerate(raw_cells):
        cells += _cells(_table(raw, f"{source}: cells[{i}]"), defaults, f"{source}: cells[{i}]")
    keys = [c.key for c in cells]
    dupes = sorted({k for k in keys if keys.count(k) > 1})
    if dupes:
        raise ValueError(f"{source}: cells given twice (cell name/env): {dupes}")
    out = Path(str(head.get("out", Path("runs") / "campaign" / name)))
    return Campaign(name, out, imports, tuple(cells))


def load_campaign(path: Path | str) -> Campaign:
    """Read and check a campaign file (TOML)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"No campaign file at {path}; expected a TOML file")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: not valid TOML: {e}") from None
    return parse_campaign(data, str(path))


def _fill(value: Any, cell: Cell, seed: int | None) -> Any:
    if not isinstance(value, str):
        return value
    out = value.replace("{env}", short_id(cell.env_id)).replace("{env_id}", cell.env_id)
    return out.replace("{seed}", str(seed)) if seed is not None else out


def train_command(cell: Cell, out: Path, seed: int | None = None) -> list[str]:
    """The ``kinder train`` command line of a cell's model (of run seed ``seed``)."""
    assert cell.train is not None
    cmd = ["kinder", "train", cell.train.method, "--out", str(cell.train_dir(out, seed))]
    for key, value in cell.train.args.items():
        flag = "--" + key.replace("_", "-")
        value = _fill(value, cell, seed)
        if isinstance(value, bool):
            cmd.append(flag if value else f"--no-{key.replace('_', '-')}")
        elif isinstance(value, list):
            for item in value:
                cmd += [flag, str(_fill(item, cell, seed))]
        else:
            cmd += [flag, str(value)]
    return cmd


def run_train_command(cmd: Sequence[str]) -> None:
    """Run a ``kinder train`` command line in a child process (``python -m kinder_bench``)."""
    subprocess.run([sys.executable, "-m", "kinder_bench", *cmd[1:]], check=True)


TrainFn = Callable[[Sequence[str]], None]


def _train(cell: Cell, out: Path, train_fn: TrainFn, log: Callable[[str], None]) -> dict[str, Any]:
    """Train what a cell needs (skipping finished trainings); its status entry."""
    assert cell.train is not None
    seeds: Sequence[int | None] = cell.seeds if cell.train.per_seed else [None]
    commands, trained = [], 0
    for seed in seeds:
        cmd = train_command(cell, out, seed)
        commands.append(" ".join(cmd))
        marker = cell.train_dir(out, seed) / TRAIN_MARKER
        if marker.exists() and json.loads(marker.read_text()).get("command") == cmd:
            continue
        log(f"{cell.key}: {' '.join(cmd)}")
        t0 = time.perf_counter()
        train_fn(cmd)
        write_json(marker, {"command": cmd, "wall_s": round(time.perf_counter() - t0, 1)})
        trained += 1
    return {"commands": commands, "budget": cell.train.budget, "trained_now": trained}


@dataclasses.dataclass
class CampaignOutcome:
    """What :func:`run_campaign` did."""

    status: list[dict[str, Any]]
    """One entry per cell (also written to ``OUT/campaign.json``)."""
    trained: int
    """Models trained by this call."""
    episodes_ran: int
    episodes_skipped: int
    failed: list[str]
    """Cells (``name/env``) whose training failed (not evaluated)."""


def run_campaign(
    campaign: Campaign,
    out: Path | None = None,
    executor: str = "process",
    workers: int | None = None,
    address: str | None = None,
    only: Sequence[str] = (),
    train_fn: TrainFn = run_train_command,
    progress: bool = True,
    log: Callable[[str], None] = print,
    command: str | None = None,
) -> CampaignOutcome:
    """Train and evaluate every cell of ``campaign`` (those named in ``only``: cell names or
    ``name/env`` keys), resuming what ``out`` (default: the campaign's) already has."""
    root = Path(out) if out is not None else campaign.out
    cells = [c for c in campaign.cells if not only or c.name in only or c.key in only]
    if not cells:
        known = sorted({c.name for c in campaign.cells})
        raise ValueError(f"--only {list(only)} matches no cell; cells: {known}")
    status: dict[str, dict[str, Any]] = {}
    failed: list[str] = []
    trained = 0
    runs: list[RunConfig] = []
    for cell in cells:
        entry: dict[str, Any] = {"cell": cell.name, "env_id": cell.env_id, "agent": cell.agent,
                                 "label": cell.label, "args": dict(cell.args),
                                 "seeds": list(cell.seeds), "episodes": cell.episodes,
                                 "max_steps": cell.max_steps, "obs_noise": cell.obs_noise,
                                 "action_noise": cell.action_noise}  # fmt: skip
        if cell.train is not None:
            try:
                entry["train"] = _train(cell, root, train_fn, log)
                trained += entry["train"]["trained_now"]
            except (subprocess.CalledProcessError, OSError, ValueError) as e:
                entry["train"] = {"error": f"{type(e).__name__}: {e}"}
                failed.append(cell.key)
                log(f"{cell.key}: training failed ({e}); not evaluated")
        status[cell.key] = entry
        if cell.key not in failed:
            runs.append(cell.run_config(root))
    eval_dir = root / "eval"
    ran = skipped = 0
    if runs:
        outcome = run_benchmark(runs, eval_dir, executor=executor, workers=workers,
                                address=address, imports=campaign.imports, progress=progress,
                                command=command)  # fmt: skip
        ran, skipped = outcome.num_ran, outcome.num_skipped
    episodes = {(r["run_id"], r["seed"], r["episode"]) for r in load_records(eval_dir)}
    for cell, run in zip([c for c in cells if c.key not in failed], runs):
        run_id = resolve_run(run).run_id
        planned = {(run_id, s, e) for s in cell.seeds for e in range(cell.episodes)}
        entry = status[cell.key]
        entry["run_id"] = run_id
        entry["episodes_done"] = len(planned & episodes)
        entry["episodes_planned"] = len(planned)
        entry["finished"] = planned <= episodes
    _write_status(root, campaign, status)
    return CampaignOutcome(list(status.values()), trained, ran, skipped, failed)


def _write_status(root: Path, campaign: Campaign, status: Mapping[str, dict[str, Any]]) -> None:
    """Merge this call's cells into ``OUT/campaign.json`` (cells of earlier calls stay)."""
    path = root / STATUS_FILE
    old = json.loads(path.read_text()).get("cells", {}) if path.exists() else {}
    write_json(path, {"campaign": campaign.name, "cells": {**old, **status}})


__all__ = [
    "Campaign",
    "CampaignOutcome",
    "Cell",
    "TrainSpec",
    "load_campaign",
    "parse_campaign",
    "run_campaign",
    "train_command",
]
