"""Dataset cards: ``datasets/<name>/README.md``, written from the data themselves.

Every number in a card is measured from the files: counts, lengths, success and checksum from the
LeRobot dataset read back through lerobot (:func:`kinder_gym.demos.summary.dataset_summary`), the
collector's kept/attempted ratio and throughput from the collection's ``attempts.jsonl``, the
write speed from its ``build.jsonl``. A dataset that is not complete says so at the top, with
the command that finishes it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from kinder_bench.demos.collection import BUILD_LOG, CONFIG_FILE, kept_attempts, read_attempts
from kinder_bench.demos.specs import DATASETS_DIR, DatasetSpec
from kinder_bench.evaluation.results import load_records

SOURCE_TEXT = {
    "bilevel_planning": "the bilevel planner (search-then-sample TAMP), skill-labelled",
    "mpc": "MPC (predictive sampling on the env model)",
    "scripted": "a scripted policy",
}


def collection_stats(spec: DatasetSpec, base: Path = DATASETS_DIR) -> dict[str, Any]:
    """Kept/attempted, throughput and write speed of a dataset's collection directory."""
    out = spec.collection_dir(base)
    attempts = read_attempts(out) if out.exists() else []
    kept = kept_attempts(attempts, spec.episodes)
    last = kept[-1]["index"] if kept else -1
    complete = len(kept) >= spec.episodes
    considered = [a for a in attempts if a["index"] <= last] if complete else attempts
    seconds = sum(float(a["seconds"]) for a in considered)
    builds = load_records(out / BUILD_LOG) if (out / BUILD_LOG).exists() else []
    b_eps = sum(int(b["episodes"]) for b in builds)
    b_frames = sum(int(b["frames"]) for b in builds)
    b_sec = sum(float(b["seconds"]) for b in builds)
    config = json.loads((out / CONFIG_FILE).read_text()) if (out / CONFIG_FILE).exists() else {}
    mean_attempt = seconds / len(considered) if considered else None
    return {
        "config": config,
        "kept": len(kept),
        "attempted": len(considered),
        "attempts_total": len(attempts),
        "errors": sum(1 for a in considered if a.get("error")),
        "collect_seconds": seconds,
        "mean_attempt_seconds": mean_attempt,
        "kept_per_minute": 60 * len(kept) / seconds if seconds > 0 else None,
        "build_episodes": b_eps,
        "build_frames": b_frames,
        "build_seconds": b_sec,
    }


def _fmt_mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def card_text(spec: DatasetSpec, base: Path = DATASETS_DIR) -> str:
    """The card of one dataset (see the module docstring)."""
    from kinder_gym.demos.summary import dataset_summary, disk_size

    stats = collection_stats(spec, base)
    dataset = spec.dataset_dir(base)
    summary: dict[str, Any] | None = None
    if (dataset / "meta" / "info.json").exists():
        summary = dataset_summary(dataset)
    built = summary["episodes"] if summary else 0
    command = f"make datasets DATASETS={spec.name}"
    lines = [f"# {spec.name} demonstrations", ""]
    complete = built >= spec.episodes
    if not complete:
        lines += [
            f"> **Partial:** {built} of {spec.episodes} episodes are in the dataset "
            f"({stats['kept']} kept by the collection so far, {stats['attempts_total']} "
            f"attempts made). `{command}` resumes and finishes it.",
            "",
        ]
    lines += [spec.why, ""]
    rate = stats["kept"] / stats["attempted"] if stats["attempted"] else None
    args = stats["config"].get("agent_args", dict(spec.agent_args))
    short_args = {k: args[k] for k in sorted(spec.agent_args)} if args else {}
    rows: list[tuple[str, str]] = [
        ("env id", f"`{spec.env_id}`"),
        ("versions", _versions_text(spec, base, summary)),
        (
            "source",
            f"{SOURCE_TEXT.get(spec.agent, spec.agent)}; agent `{spec.agent}` with "
            f"{short_args or 'its defaults'} (other arguments: defaults); collection seed "
            f"{spec.seed}; step budget {stats['config'].get('max_steps', 'n/a')}",
        ),
        ("episodes", f"{built} (wanted {spec.episodes})"),
        (
            "collector success rate",
            f"{stats['kept']}/{stats['attempted']} = {rate:.2f} (kept / attempts up to the last "
            f"kept one)"
            if rate is not None
            else "n/a",
        ),
    ]
    if summary:
        rows += [
            (
                "episode length",
                f"mean {summary['length_mean']:.1f} steps (min {summary['length_min']}, max "
                f"{summary['length_max']}); {summary['frames']} frames",
            ),
            (
                "skill labels",
                f"{summary['skill_labelled']} of {summary['episodes']} episodes; operators "
                f"{summary['skills'] or 'none'}",
            ),
            (
                "observation",
                f"`observation.state` {summary['state_dim'] - _env_dim(dataset)} robot features "
                f"({', '.join(summary['robot_objects'])}), `observation.environment_state` "
                f"{_env_dim(dataset)}; action {summary['action_dim']}",
            ),
            (
                "images",
                f"{', '.join(summary['cameras'])} at {summary['image_size']}×"
                f"{summary['image_size']} (video, {summary['fps']} fps)"
                if summary["cameras"]
                else "none",
            ),
            ("task", f"“{summary['task']}”"),
            ("size on disk", f"{_fmt_mb(summary['size_bytes'])} (LeRobot dataset)"),
            ("content checksum", f"`{summary['checksum']}`"),
        ]
    coll = spec.collection_dir(base)
    if coll.exists():
        rows.append(("collection files", f"{_fmt_mb(disk_size(coll))} (attempt log, episodes)"))
    if stats["kept_per_minute"]:
        rows.append(
            (
                "collection throughput",
                f"{stats['kept_per_minute']:.1f} kept episodes/min, "
                f"{stats['mean_attempt_seconds']:.2f} s per attempt (one process, shared 2-core "
                f"machine)",
            )
        )
    if stats["build_seconds"]:
        rows.append(
            (
                "write speed",
                f"{stats['build_frames'] / stats['build_seconds']:.0f} frames/s, "
                f"{60 * stats['build_episodes'] / stats['build_seconds']:.1f} episodes/min "
                f"(rendering and video encoding included)",
            )
        )
    rows.append(("regenerate", f"`{command}` (= `uv run kinder demos datasets {spec.name}`)"))
    lines += ["| field | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in rows]
    lines += [
        "",
        "## Files",
        "",
        "The data are regenerated, not committed (`data/` is gitignored):",
        "",
        "* `data/lerobot/`: the LeRobotDataset v3 (lerobot 0.4.4). Features and the KinDER "
        "sidecar files are documented in `kinder_gym.demos.lerobot_format`.",
        "* `data/collection/`: the collection (`attempts.jsonl`, one `.npz` per kept episode, "
        "`collect.json`, `build.jsonl`), from which the dataset is built.",
        "",
        "```python",
        "from kinder_gym.demos.lerobot_format import load_dataset, load_records",
        "",  # ruff formats Python blocks in markdown: the card is written already formatted
        f'ds = load_dataset("datasets/{spec.name}/data/lerobot")  # a LeRobotDataset',
        f'records = load_records("datasets/{spec.name}/data/lerobot")  # EpisodeRecords',
        "```",
        "",
        "The checksum covers the content (episodes' arrays, seeds, labels, metadata), not the "
        "files' bytes or timings; see `kinder_gym.demos.summary`. `kinder demos replay "
        f"datasets/{spec.name}/data/lerobot` checks that every episode replays from its seed.",
        "",
    ]
    return "\n".join(lines)


def _versions_text(spec: DatasetSpec, base: Path, summary: dict[str, Any] | None) -> str:
    """The producing packages' versions (from the dataset, else from a kept episode file)."""
    versions: dict[str, str] = dict((summary or {}).get("versions", {}))
    if not versions and spec.collection_dir(base).exists():
        from kinder_bench.demos.collection import kept_files
        from kinder_gym.demos.store import load_record

        files = kept_files(spec.collection_dir(base))
        if files:
            versions = load_record(files[0]).versions
    text = ", ".join(f"{k} {v}" for k, v in sorted(versions.items())) or "n/a"
    if summary:
        text += f"; written with lerobot {_version('lerobot')}"
    return text


def _version(name: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "(not installed)"


def _env_dim(dataset: Path) -> int:
    from kinder_gym.demos.layout import StateSplit
    from kinder_gym.demos.lerobot_format import read_kinder_meta

    split = StateSplit.from_dict(read_kinder_meta(dataset)["split"])
    return len(split.env_names)


def write_card(spec: DatasetSpec, base: Path = DATASETS_DIR) -> Path:
    """Write ``<base>/<name>/README.md`` (atomically); returns its path."""
    import os

    path = spec.root(base) / "README.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(card_text(spec, base))
    os.replace(tmp, path)
    return path


__all__ = ["card_text", "collection_stats", "write_card"]
