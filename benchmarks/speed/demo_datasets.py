"""Demonstration datasets: collection throughput, write speed, sizes and `make datasets` time.

Reads what ``make datasets`` (``kinder demos datasets``) left under ``datasets/<name>/data/``:
every attempt's wall-clock seconds (``collection/attempts.jsonl``), every build call's frames and
seconds (``collection/build.jsonl``) and the files on disk, and prints one markdown table (also
written to ``benchmarks/results/demo_datasets.{md,json}``). Nothing is re-run, so the figures are
those of the machine and load the datasets were made on (this project: a shared 2-core machine,
one process, ``nice -n 10``).

For a dataset that is not complete, the time ``make datasets`` still needs is projected from its
own rates: remaining episodes × (collection seconds per kept episode + build seconds per episode).
Envs not built yet use the mean build rate per frame of the built 3D (or 2D) datasets.

    uv run python benchmarks/speed/demo_datasets.py
    uv run python benchmarks/speed/demo_datasets.py --only SweepIntoDrawer3D-o5
    uv run python benchmarks/speed/demo_datasets.py --write-bench Motion2D-p0 --episodes 20

``--only NAME ...`` measures those datasets and keeps the other rows of the committed
``demo_datasets.json`` as they were measured (datasets are gitignored, so a machine may hold only
the ones it made). The notes written under the table in ``demo_datasets.md`` (after its "`make
datasets` so far" line) are kept when the table is rewritten.

``--write-bench NAME`` also times :class:`~kinder_gym.demos.lerobot_format.DemoWriter` alone on
the first ``--episodes`` kept episodes of a collected dataset, into a temporary directory, with
and without images (frames/s; the first call includes lerobot's import, so a warm-up episode is
written first and not counted). Wall-clock and this process's CPU time are both reported: on a
loaded machine the CPU figure is the one that carries over.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from kinder_bench.demos.collection import BUILD_LOG, kept_attempts, read_attempts
from kinder_bench.demos.specs import DATASETS
from kinder_bench.evaluation.results import load_records, write_text

ROOT = Path(__file__).resolve().parents[2]


def _size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.exists() else 0


def measure(base: Path, names: list[str] | None = None) -> list[dict[str, Any]]:
    """One row per dataset of ``names`` (default: all), from what ``base`` holds."""
    unknown = sorted(set(names or ()) - set(DATASETS))
    if unknown:
        raise SystemExit(f"unknown dataset(s) {unknown}; known: {sorted(DATASETS)}")
    rows = []
    for spec in DATASETS.values():
        if names is not None and spec.name not in names:
            continue
        coll = spec.collection_dir(base)
        attempts = read_attempts(coll) if coll.exists() else []
        kept = kept_attempts(attempts, spec.episodes)
        complete = len(kept) >= spec.episodes
        last = kept[-1]["index"] if kept else -1
        considered = [a for a in attempts if a["index"] <= last] if complete else attempts
        seconds = sum(float(a["seconds"]) for a in considered)
        kept_steps = sum(int(a["steps"]) for a in kept)
        builds = load_records(coll / BUILD_LOG) if (coll / BUILD_LOG).exists() else []
        dataset = spec.dataset_dir(base)
        info_path = dataset / "meta" / "info.json"
        built = json.loads(info_path.read_text())["total_episodes"] if info_path.exists() else 0
        rows.append(
            {
                "name": spec.name,
                "env_id": spec.env_id,
                "is_3d": "3D" in spec.name,
                "wanted": spec.episodes,
                "kept": len(kept),
                "attempted": len(considered),
                "collect_seconds": seconds,
                "kept_steps": kept_steps,
                "build_episodes": sum(int(b["episodes"]) for b in builds),
                "build_frames": sum(int(b["frames"]) for b in builds),
                "build_seconds": sum(float(b["seconds"]) for b in builds),
                "built": built,
                "dataset_bytes": _size(dataset),
                "collection_bytes": _size(coll),
            }
        )
    # Build-rate fallback (seconds per frame) for datasets not built yet.
    for is_3d in (False, True):
        group = [r for r in rows if r["is_3d"] == is_3d and r["build_frames"]]
        frames = sum(r["build_frames"] for r in group)
        rate = sum(r["build_seconds"] for r in group) / frames if frames else None
        for r in rows:
            if r["is_3d"] == is_3d:
                r["fallback_s_per_frame"] = rate
    for r in rows:
        s_per_kept = r["collect_seconds"] / r["kept"] if r["kept"] else None
        steps_per_ep = r["kept_steps"] / r["kept"] if r["kept"] else None
        if r["build_frames"]:
            s_per_frame = r["build_seconds"] / r["build_frames"]
        else:
            s_per_frame = r["fallback_s_per_frame"]
        remaining_collect = r["wanted"] - r["kept"]
        remaining_build = r["wanted"] - r["built"]
        r["kept_per_min"] = 60 / s_per_kept if s_per_kept else None
        r["write_frames_per_s"] = 1 / s_per_frame if s_per_frame else None
        r["write_eps_per_min"] = (
            60 * r["build_episodes"] / r["build_seconds"] if r["build_seconds"] else None
        )
        project = None
        if s_per_kept is not None and steps_per_ep is not None and s_per_frame is not None:
            project = remaining_collect * s_per_kept + remaining_build * steps_per_ep * s_per_frame
        r["projected_remaining_seconds"] = project
        r["spent_seconds"] = r["collect_seconds"] + r["build_seconds"]
    return rows


def _f(v: float | None, fmt: str) -> str:
    return "—" if v is None else format(v, fmt)


def table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| dataset | kept / attempted | collector SR | kept eps/min | write frames/s | write "
        "eps/min | in dataset | dataset MB | collection MB | spent (min) | still needed (min) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        sr = r["kept"] / r["attempted"] if r["attempted"] else None
        left = r["projected_remaining_seconds"]
        left_min = left / 60 if left is not None else None
        lines.append(
            f"| {r['name']} | {r['kept']} / {r['attempted']} | {_f(sr, '.2f')} | "
            f"{_f(r['kept_per_min'], '.1f')} | {_f(r['write_frames_per_s'], '.0f')} | "
            f"{_f(r['write_eps_per_min'], '.1f')} | {r['built']} / {r['wanted']} | "
            f"{r['dataset_bytes'] / 1e6:.1f} | {r['collection_bytes'] / 1e6:.1f} | "
            f"{r['spent_seconds'] / 60:.1f} | {_f(left_min, '.1f')} |"
        )
    spent = sum(r["spent_seconds"] for r in rows)
    left_all = [r["projected_remaining_seconds"] for r in rows]
    known = sum(v for v in left_all if v is not None)
    unknown = [r["name"] for r, v in zip(rows, left_all) if v is None]
    lines += [
        "",
        f"`make datasets` so far: {spent / 60:.1f} min of collection and building (sum of the "
        f"measured per-attempt and per-build wall-clock times); projected still needed: "
        f"{known / 60:.1f} min"
        + (f" plus the unmeasured {', '.join(unknown)}" if unknown else "")
        + f"; total {(spent + known) / 60:.1f} min on this machine.",
    ]
    return "\n".join(lines)


def write_bench(base: Path, name: str, episodes: int) -> str:
    """Frames/s of DemoWriter alone, with and without images (see the module docstring)."""
    import tempfile
    import time

    from kinder_bench.demos.collection import kept_files
    from kinder_gym.demos.lerobot_format import DemoWriter
    from kinder_gym.demos.store import load_record

    spec = DATASETS[name]
    records = [load_record(p) for p in kept_files(spec.collection_dir(base))[: episodes + 1]]
    lines = [
        f"DemoWriter on {episodes} episodes of {name} "
        f"({sum(r.num_steps for r in records[1:])} frames):",
        "",
        "| images | wall s | CPU s | frames/s (wall) | frames/s (CPU) |",
        "|---|---|---|---|---|",
    ]
    for images in (False, True):
        with (
            tempfile.TemporaryDirectory() as tmp,
            DemoWriter(Path(tmp) / "ds", spec.env_id, images=images) as writer,
        ):
            writer.add(records[0])  # warm-up: imports, encoder start
            start, cpu = time.perf_counter(), time.process_time()
            for r in records[1:]:
                writer.add(r)
            seconds = time.perf_counter() - start
            cpu_seconds = time.process_time() - cpu
        frames = sum(r.num_steps for r in records[1:])
        lines.append(
            f"| {images} | {seconds:.1f} | {cpu_seconds:.1f} | {frames / seconds:.0f} | "
            f"{frames / cpu_seconds:.0f} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, default=ROOT / "datasets")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    parser.add_argument("--write-bench", metavar="NAME", default=None)
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--only", nargs="+", metavar="NAME", default=None)
    args = parser.parse_args()
    if args.write_bench:
        md = write_bench(args.base, args.write_bench, args.episodes)
        print(md)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "demo_write_speed.md").write_text(md + "\n")
        return
    json_path, md_path = args.out / "demo_datasets.json", args.out / "demo_datasets.md"
    rows = measure(args.base, args.only)
    if args.only is not None and json_path.exists():
        rows = merge_rows(json.loads(json_path.read_text()), rows)
    md = table(rows)
    print(md)
    notes = kept_notes(md_path)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(md_path, md + "\n" + (f"\n{notes}" if notes else ""))
    write_text(json_path, json.dumps(rows, indent=2) + "\n")


def merge_rows(old: list[dict[str, Any]], new: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``old`` with the rows of ``new`` in place of those of the same dataset, in the specs'
    order."""
    by_name = {r["name"]: r for r in old} | {r["name"]: r for r in new}
    return [by_name[name] for name in DATASETS if name in by_name]


def kept_notes(md_path: Path) -> str:
    """The text under the generated table of ``md_path`` (after its "`make datasets` so far"
    line), or "" (no file, or nothing there)."""
    if not md_path.exists():
        return ""
    lines = md_path.read_text().splitlines()
    for i, line in enumerate(lines):
        if line.startswith("`make datasets` so far:"):
            return "\n".join(lines[i + 1 :]).strip("\n") + "\n" if lines[i + 1 :] else ""
    return ""


if __name__ == "__main__":
    main()
