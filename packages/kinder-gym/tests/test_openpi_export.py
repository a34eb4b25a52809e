"""The openpi export (LeRobot v2.1 layout): arrays round-trip against the source dataset, the
layout is what lerobot v2.1 reads (checked through lerobot 0.4.4's own v2.1 → v3.0 converter),
and the output directory is written atomically."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_CACHE", tempfile.mkdtemp(prefix="kinder-hf-"))

import numpy as np
import pytest

pytest.importorskip("lerobot")
import pyarrow.parquet as pq

from kinder_gym.demos.layout import StateSplit, camera_frames
from kinder_gym.demos.lerobot_format import DatasetError, load_dataset, load_records
from kinder_gym.demos.openpi_format import (
    CODEBASE_VERSION,
    ExportError,
    export_openpi,
    hf_features,
)

FIXTURE = Path(__file__).parent / "data" / "demos" / "Motion2D-p0"


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("openpi") / "kinder" / "Motion2D-p0"
    export_openpi(FIXTURE, out)
    return out


def _episode_tables(root: Path) -> list[dict[str, np.ndarray]]:
    tables = []
    for path in sorted((root / "data").glob("chunk-*/episode_*.parquet")):
        table = pq.read_table(path)
        columns: dict[str, np.ndarray] = {}
        for name in table.column_names:
            col = table.column(name).combine_chunks()
            if name.endswith("_rgb"):
                columns[name] = np.asarray(col.field("bytes").to_pylist(), dtype=object)
            elif hasattr(col, "flatten"):
                width = col.type.list_size
                columns[name] = col.flatten().to_numpy().reshape(-1, width)
            else:
                columns[name] = col.to_numpy()
        tables.append(columns)
    return tables


def test_export_round_trips_the_dataset_arrays(exported: Path) -> None:
    from PIL import Image

    import kinder_core

    source = load_dataset(FIXTURE).hf_dataset.with_format("numpy")[:]
    records = load_records(FIXTURE)
    tables = _episode_tables(exported)
    assert len(tables) == len(records) == 3
    state = np.concatenate([t["state"] for t in tables])
    np.testing.assert_array_equal(state, np.stack(source["observation.state"]))
    np.testing.assert_array_equal(
        np.concatenate([t["environment_state"] for t in tables]),
        np.stack(source["observation.environment_state"]),
    )
    np.testing.assert_array_equal(
        np.concatenate([t["actions"] for t in tables]), np.stack(source["action"])
    )
    assert state.dtype == np.float32
    np.testing.assert_array_equal(np.concatenate([t["index"] for t in tables]), np.arange(120))
    env = kinder_core.make("kinder/Motion2D-p0-v0", render_mode="rgb_array")
    for i, (table, record) in enumerate(zip(tables, records, strict=True)):
        steps = record.num_steps
        np.testing.assert_array_equal(table["frame_index"], np.arange(steps))
        np.testing.assert_array_equal(table["episode_index"], np.full(steps, i))
        np.testing.assert_array_equal(table["task_index"], np.zeros(steps))
        np.testing.assert_allclose(table["timestamp"], np.arange(steps) / 20, atol=1e-6)
        assert record.states is not None
        for t in (0, steps - 1):  # PNG is lossless: the pixels are the renderer's exactly
            png = Image.open(__import__("io").BytesIO(table["base_0_rgb"][t]))
            expected = camera_frames(env, record.states[t], 224)["render"]
            np.testing.assert_array_equal(np.asarray(png), expected)


def test_export_metadata_is_lerobot_v21(exported: Path) -> None:
    info = json.loads((exported / "meta" / "info.json").read_text())
    assert info["codebase_version"] == CODEBASE_VERSION == "v2.1"
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (3, 120, 1)
    assert info["fps"] == 20 and info["video_path"] is None and info["splits"] == {"train": "0:3"}
    split = StateSplit.from_dict(
        json.loads((FIXTURE / "meta" / "kinder.json").read_text())["split"]
    )
    features = info["features"]
    assert features["base_0_rgb"] == {
        "dtype": "image",
        "shape": [224, 224, 3],
        "names": ["height", "width", "channel"],
    }
    assert features["state"]["names"] == list(split.state_names)
    assert features["actions"]["shape"] == [5]
    episodes = [
        json.loads(x) for x in (exported / "meta" / "episodes.jsonl").read_text().splitlines()
    ]
    assert [e["length"] for e in episodes] == [r.num_steps for r in load_records(FIXTURE)]
    tasks = [json.loads(x) for x in (exported / "meta" / "tasks.jsonl").read_text().splitlines()]
    assert tasks == [{"task_index": 0, "task": episodes[0]["tasks"][0]}]
    assert tasks[0]["task"].startswith("Motion2D")
    stats = [
        json.loads(x) for x in (exported / "meta" / "episodes_stats.jsonl").read_text().splitlines()
    ]
    assert set(stats[0]["stats"]) == set(features)
    assert np.asarray(stats[0]["stats"]["base_0_rgb"]["mean"]).shape == (3, 1, 1)
    assert stats[0]["stats"]["state"]["count"] == [episodes[0]["length"]]
    schema = pq.read_schema(next((exported / "data").glob("*/*.parquet")))
    assert json.loads(schema.metadata[b"huggingface"])["info"]["features"] == hf_features(features)


def test_lerobot_reads_the_export_as_v21(exported: Path, tmp_path: Path) -> None:
    """lerobot 0.4.4's converter reads v2.1 with lerobot's own v2.1 loaders; the converted
    dataset then loads in ``LeRobotDataset`` with our keys, shapes and the task as prompt."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from lerobot.datasets.v30 import convert_dataset_v21_to_v30 as v21

    new = tmp_path / "v30"
    v21.validate_local_dataset_version(exported)
    v21.convert_info(exported, new, 100, 200)
    v21.convert_tasks(exported, new)
    v21.convert_episodes_metadata(exported, new, v21.convert_data(exported, new, 100))
    ds = LeRobotDataset("kinder/Motion2D-p0", root=new)
    assert len(ds) == 120 and ds.meta.total_episodes == 3
    item = ds[41]
    source = load_dataset(FIXTURE)[41]
    assert tuple(item["base_0_rgb"].shape) == (3, 224, 224)
    np.testing.assert_array_equal(item["state"].numpy(), source["observation.state"].numpy())
    np.testing.assert_array_equal(item["actions"].numpy(), source["action"].numpy())
    assert item["task"] == source["task"]


def test_export_refuses_a_used_directory_and_replaces_atomically(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ExportError, match="not empty"):
        export_openpi(FIXTURE, out, images=False)
    assert (out / "keep.txt").read_text() == "mine"
    summary = export_openpi(FIXTURE, out, images=False, overwrite=True, episodes=[1])
    assert summary.episodes == 1 and summary.image_keys == ()
    assert not (out / "keep.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary leftovers
    info = json.loads((out / "meta" / "info.json").read_text())
    assert "base_0_rgb" not in info["features"] and info["total_episodes"] == 1
    with pytest.raises(DatasetError, match="missing"):
        export_openpi(tmp_path / "nowhere", tmp_path / "x")


def test_an_interrupted_export_resumes(tmp_path: Path) -> None:
    class Stop(Exception):
        pass

    def stop_after_two(done: int, total: int) -> None:
        if done == 2:
            raise Stop

    out = tmp_path / "out"
    with pytest.raises(Stop):
        export_openpi(FIXTURE, out, images=False, progress=stop_after_two)
    assert not out.exists()
    partial = tmp_path / ".out.openpi-partial"
    first = partial / "data" / "chunk-000" / "episode_000000.parquet"
    written = first.stat().st_mtime_ns
    assert not (partial / "data" / "chunk-000" / "episode_000002.parquet").exists()
    export_openpi(FIXTURE, out, images=False)  # resumes: episodes 0 and 1 are kept
    assert (out / "data" / "chunk-000" / "episode_000000.parquet").stat().st_mtime_ns == written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    fresh = tmp_path / "fresh"
    export_openpi(FIXTURE, fresh, images=False)
    for name in ("data/chunk-000/episode_000002.parquet", "meta/episodes_stats.jsonl"):
        assert (out / name).read_bytes() == (fresh / name).read_bytes(), name
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == sorted(
        p.relative_to(fresh) for p in fresh.rglob("*")
    )
