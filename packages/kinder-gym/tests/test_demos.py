"""Demonstrations: the record, the LeRobot v3 format, replay, skill labels, upstream import and
clear errors for corrupt files. The fixture datasets under ``tests/data/demos`` come from
``tools/make_demo_fixtures.py`` (bilevel-planner episodes of Motion2D-p0 and Obstruction2D-o1)."""

from __future__ import annotations

import dataclasses
import os
import pickle
import re
import shutil
import tempfile
from pathlib import Path

os.environ.setdefault("HF_HUB_OFFLINE", "1")
# lerobot's loader caches Arrow files under HF_DATASETS_CACHE; keep them out of the home dir.
os.environ.setdefault("HF_DATASETS_CACHE", tempfile.mkdtemp(prefix="kinder-hf-"))

import numpy as np
import pytest

import kinder_core
from kinder_gym.demos import EpisodeRecord, EpisodeRecorder, SkillLabel, StateSplit
from kinder_gym.demos.replay import replay_record
from kinder_gym.demos.store import EpisodeFileError, load_record, save_record
from kinder_gym.demos.summary import content_checksum
from kinder_gym.demos.upstream import (
    UpstreamFormatError,
    load_upstream_hdf5,
    load_upstream_pickle,
    write_upstream_hdf5,
)

lerobot_format = pytest.importorskip("kinder_gym.demos.lerobot_format")
pytest.importorskip("lerobot")

pytestmark = pytest.mark.filterwarnings("ignore:Converting input from bool:RuntimeWarning")

DATA = Path(__file__).parent / "data" / "demos"
MOTION = DATA / "Motion2D-p0"
OBSTRUCTION = DATA / "Obstruction2D-o1"
MOTION_ID = "kinder/Motion2D-p0-v0"


def _random_record(env_id: str, seed: int, steps: int, skills: bool = True) -> EpisodeRecord:
    env = kinder_core.make(env_id)
    recorder = EpisodeRecorder(env, env_id, "scripted")
    recorder.reset(seed)
    rng = np.random.default_rng(seed)
    space = env.action_space
    for t in range(steps):
        if skills and t == 0:
            recorder.begin_skill("Wander", ["robot"], [0.25, -1.5])
        if skills and t == steps // 2:
            recorder.begin_skill("Drift", ["robot", "target_region"], [])
        # Some actions out of bounds: the record keeps the clipped ones.
        recorder.step(rng.uniform(space.low * 1.5, space.high * 1.5))
        if recorder.done:
            break
    return recorder.finish(metadata={"note": "random"})


def _assert_same(a: EpisodeRecord, b: EpisodeRecord) -> None:
    assert (a.env_id, a.seed, a.source, a.terminated, a.truncated) == (
        b.env_id,
        b.seed,
        b.source,
        b.terminated,
        b.truncated,
    )
    np.testing.assert_array_equal(a.observations, b.observations)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.rewards, b.rewards)
    assert a.states is not None and b.states is not None
    np.testing.assert_array_equal(a.states, b.states)
    assert a.skills == b.skills
    assert a.metadata == b.metadata


# -- the state split ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "env_id",
    ["kinder/Motion2D-p0-v0", "kinder/DynObstruction2D-o1-v0", "kinder/StickButton2D-b1-v0"],
)
def test_state_split_by_name(env_id: str) -> None:
    env = kinder_core.make(env_id)
    split = StateSplit.from_env(env)
    assert split.robot_objects == ("robot",)
    assert all(n.startswith("robot.") for n in split.state_names)
    assert not any(n.startswith("robot.") for n in split.env_names)
    obs, _ = env.reset(seed=3)
    state, rest = split.split(obs)
    np.testing.assert_array_equal(split.join(state, rest), obs)
    # From the stored names alone (no env) the split is the same.
    again = StateSplit.from_dict(split.to_dict())
    np.testing.assert_array_equal(again.split(obs)[0], state)


def test_state_split_follows_names_not_positions() -> None:
    # DynObstruction2D lists the robot last in its Box view: a "first k dims" rule would be wrong.
    split = StateSplit.from_env(kinder_core.make("kinder/DynObstruction2D-o1-v0"))
    assert split.state_indices[0] > 0
    box = kinder_core.make("kinder/DynObstruction2D-o1-v0").unwrapped.box_space  # type: ignore[attr-defined]
    assert [box.feature_names[i] for i in split.state_indices] == split.state_names
    with pytest.raises(ValueError, match="Robot object"):
        StateSplit(("a.x", "b.y"), ("robot",))


# -- round trip through LeRobot -----------------------------------------------------------------
def test_round_trip_through_lerobot(tmp_path: Path) -> None:
    records = [_random_record(MOTION_ID, seed, steps) for seed, steps in ((1, 6), (2, 9))]
    root = tmp_path / "ds"
    with lerobot_format.DemoWriter(root, MOTION_ID) as writer:
        writer.add(records[0])
    with lerobot_format.DemoWriter(root, MOTION_ID) as writer:  # reopening appends
        writer.add(records[1])
    loaded = lerobot_format.load_records(root)
    assert len(loaded) == 2
    for a, b in zip(records, loaded):
        _assert_same(a, b)
        assert b.step_seconds is not None and a.step_seconds is not None
        np.testing.assert_array_equal(a.step_seconds, b.step_seconds)
    # The LeRobotDataset view: float32 policy features are the split of the exact columns.
    ds = lerobot_format.load_dataset(root)
    assert ds.num_episodes == 2 and len(ds) == 15
    item = ds[7]  # episode 1, frame 1
    split = StateSplit.from_env(kinder_core.make(MOTION_ID))
    state, rest = split.split(records[1].observations[1])
    np.testing.assert_allclose(item["observation.state"].numpy(), state.astype(np.float32))
    np.testing.assert_allclose(
        item["observation.environment_state"].numpy(), rest.astype(np.float32)
    )
    np.testing.assert_allclose(item["action"].numpy(), records[1].actions[1].astype(np.float32))
    assert tuple(item["observation.images.render"].shape) == (3, 224, 224)
    assert item["task"] == records[1].task or item["task"]
    assert int(item["episode_seed"]) == 2
    assert item["subtask"] == "Wander"
    assert int(item["skill_index"]) == 0
    info = ds.meta.features
    assert info["observation.state"]["names"] == split.state_names


def test_writer_refuses_other_env_and_bad_dirs(tmp_path: Path) -> None:
    record = _random_record(MOTION_ID, 0, 3)
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "file.txt").write_text("x")
    with pytest.raises(lerobot_format.DatasetError, match="not a dataset"):
        lerobot_format.DemoWriter(tmp_path / "junk", MOTION_ID, images=False)
    with lerobot_format.DemoWriter(tmp_path / "ds", MOTION_ID, images=False) as writer:
        other = dataclasses.replace(record, env_id="kinder/Motion2D-p1-v0")
        with pytest.raises(ValueError, match="cannot go into"):
            writer.add(other)
        writer.add(record)
    with pytest.raises(lerobot_format.DatasetError, match="cameras"):
        lerobot_format.DemoWriter(tmp_path / "ds", MOTION_ID, images=True)


def test_checksum_is_deterministic_and_content_based(tmp_path: Path) -> None:
    records = [_random_record(MOTION_ID, s, 4) for s in (5, 6)]
    sums = []
    for name in ("a", "b"):
        with lerobot_format.DemoWriter(tmp_path / name, MOTION_ID, images=False) as w:
            for r in records:
                w.add(r)
        sums.append(content_checksum(lerobot_format.load_records(tmp_path / name)))
    assert sums[0] == sums[1]
    loaded = lerobot_format.load_records(tmp_path / "a")
    changed = dataclasses.replace(loaded[0], actions=loaded[0].actions + 1e-6)
    assert content_checksum([changed, loaded[1]]) != sums[0]
    # Timings and versions are not content.
    retimed = [
        dataclasses.replace(r, step_seconds=np.ones(r.num_steps), versions={}) for r in loaded
    ]
    assert content_checksum(retimed) == sums[0]


# -- the fixture datasets: replay and skill labels ----------------------------------------------
@pytest.mark.parametrize("root", [MOTION, OBSTRUCTION], ids=["Motion2D-p0", "Obstruction2D-o1"])
def test_fixture_episodes_replay(root: Path) -> None:
    meta = lerobot_format.read_kinder_meta(root)
    env = kinder_core.make(meta["env_id"])
    records = lerobot_format.load_records(root)
    assert len(records) >= 2
    for i, record in enumerate(records):
        assert record.source == "bilevel_planning" and record.success
        result = replay_record(env, record, atol=1e-9, name=f"episode {i}")
        assert result.ok, result.message


def test_replay_reports_a_tampered_episode() -> None:
    record = lerobot_format.load_records(MOTION, episodes=[0])[0]
    env = kinder_core.make(MOTION_ID)
    actions = record.actions.copy()
    actions[5] += 0.01
    bad = replay_record(env, dataclasses.replace(record, actions=actions), name="episode 0")
    assert not bad.ok and bad.first_bad_step == 6 and "episode 0" in bad.message


@pytest.mark.parametrize("root", [MOTION, OBSTRUCTION], ids=["Motion2D-p0", "Obstruction2D-o1"])
def test_fixture_skill_labels_match_the_steps(root: Path) -> None:
    from kinder_gym.models import create_model

    meta = lerobot_format.read_kinder_meta(root)
    env = kinder_core.make(meta["env_id"])
    model = create_model(env.unwrapped)  # type: ignore[arg-type]
    box = env.unwrapped.box_space  # type: ignore[attr-defined]
    ds = lerobot_format.load_dataset(root)
    table = ds.hf_dataset.with_format("numpy")[:]
    subtasks = list(ds.meta.subtasks.sort_values("subtask_index").index)
    multi = 0
    for e, record in enumerate(lerobot_format.load_records(root)):
        assert record.states is not None and record.skills
        multi += len(record.skills) > 1
        # Contiguous, in order, covering every step.
        assert record.skills[0].start == 0 and record.skills[-1].end == record.num_steps
        for a, b in zip(record.skills, record.skills[1:]):
            assert a.end == b.start
        # The per-frame columns agree with the labels.
        rows = np.flatnonzero(table["episode_index"] == e)
        for i, label in enumerate(record.skills):
            frames = rows[label.start : label.end]
            assert set(table["skill_index"][frames].tolist()) == {i}
            assert {subtasks[j] for j in table["subtask_index"][frames].tolist()} == {
                label.operator
            }
        # Each skill starts where its operator applies and ends where its effects hold.
        x0 = box.devectorize(record.states[0])
        operators = {
            (o.parent.name, tuple(x.name for x in o.objects)): o for o in model.ground_operators(x0)
        }
        for label in record.skills:
            op = operators[(label.operator, label.objects)]
            before = model.abstract(box.devectorize(record.states[label.start]))
            after = model.abstract(box.devectorize(record.states[label.end]))
            assert op.preconditions <= before, label
            assert op.add_effects <= after or env.unwrapped.goal_reached(  # type: ignore[attr-defined]
                box.devectorize(record.states[label.end])
            ), label
    if root == OBSTRUCTION:
        assert multi > 0  # the fixture has multi-skill episodes


def test_skill_labels_are_validated() -> None:
    with pytest.raises(ValueError, match="start <= end"):
        SkillLabel("Pick", ("a",), (), 5, 2)
    record = _random_record(MOTION_ID, 0, 3, skills=False)
    with pytest.raises(ValueError, match="covers steps up to"):
        dataclasses.replace(record, skills=[SkillLabel("Pick", ("a",), (), 0, 99)])


# -- episode files and upstream formats ---------------------------------------------------------
def test_episode_file_round_trip(tmp_path: Path) -> None:
    record = _random_record(MOTION_ID, 4, 5)
    loaded = load_record(save_record(tmp_path / "e.npz", record))
    _assert_same(record, loaded)
    assert not list(tmp_path.glob(".*tmp"))


def _upstream_dict(record: EpisodeRecord) -> dict[str, object]:
    """The dict the upstream collectors pickle (baselines spec §4)."""
    return {
        "env_id": record.env_id,
        "timestamp": 1700000000,
        "seed": record.seed,
        "observations": [o.astype(np.float32) for o in record.observations],
        "actions": [a.astype(np.float32) for a in record.actions],
        "rewards": [float(r) for r in record.rewards],
        "terminated": record.terminated,
        "truncated": record.truncated,
        "skill_info": [
            {
                "operator_name": s.operator,
                "operator_objects": [(o, "object") for o in s.objects],
                "controller_class": "SomeController",
                "controller_objects": [(o, "object") for o in s.objects],
                "params": np.asarray(s.params, dtype=np.float32),
                "num_actions": s.end - s.start,
            }
            for s in record.skills
        ],
    }


def test_import_upstream_pickle(tmp_path: Path) -> None:
    record = lerobot_format.load_records(OBSTRUCTION, episodes=[0])[0]
    path = tmp_path / "Obstruction2D-o1" / str(record.seed) / "1700000000.p"
    path.parent.mkdir(parents=True)
    with open(path, "wb") as f:
        pickle.dump(_upstream_dict(record), f)
    imported = load_upstream_pickle(path)
    assert imported.source == "imported" and imported.seed == record.seed
    np.testing.assert_allclose(imported.observations, record.observations, rtol=1e-6, atol=1e-6)
    assert [(s.operator, s.objects, s.start, s.end) for s in imported.skills] == [
        (s.operator, s.objects, s.start, s.end) for s in record.skills
    ]
    assert imported.metadata["controllers"][0]["controller_class"] == "SomeController"
    # It goes into a dataset like any other record (images rendered from its observations).
    with lerobot_format.DemoWriter(tmp_path / "ds", record.env_id, images=False) as w:
        w.add(dataclasses.replace(imported, states=imported.observations))
    assert lerobot_format.load_records(tmp_path / "ds")[0].skills == imported.skills


def test_upstream_hdf5_round_trip_and_completion(tmp_path: Path) -> None:
    import h5py

    records = lerobot_format.load_records(OBSTRUCTION)
    env = kinder_core.make(records[0].env_id)
    split = StateSplit.from_env(env)
    path = write_upstream_hdf5(tmp_path / "demos.hdf5", records, split)
    back = load_upstream_hdf5(path, records[0].env_id)
    for a, b in zip(records, back):
        np.testing.assert_array_equal(a.observations, b.observations)
        np.testing.assert_array_equal(a.actions, b.actions)
        assert b.seed == a.seed and b.terminated
    # An upstream file has no states or seeds: the final observation and rewards come from the
    # env's model, which reproduces the recorded ones.
    with h5py.File(path, "r+") as f:
        for name in f["data"]:
            del f["data"][name]["states"]
            del f["data"][name].attrs["seed"]
            del f["data"][name].attrs["terminated"]
    bare = load_upstream_hdf5(path, records[0].env_id)
    for a, b in zip(records, bare):
        assert b.seed == -1 and b.terminated
        np.testing.assert_allclose(b.observations, a.observations, atol=1e-9)
        np.testing.assert_array_equal(b.rewards, a.rewards)
    unknown = replay_record(env, bare[0], name="demo_0")
    assert not unknown.ok and "seed is unknown" in unknown.message


# -- corrupt and truncated files ----------------------------------------------------------------
def _truncate(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def test_corrupt_dataset_files_are_named(tmp_path: Path) -> None:
    root = tmp_path / "ds"
    shutil.copytree(MOTION, root)
    data_file = next((root / "data").rglob("*.parquet"))
    _truncate(data_file)
    with pytest.raises(lerobot_format.DatasetError, match=re.escape(str(data_file))):
        lerobot_format.load_records(root)

    shutil.rmtree(root)
    shutil.copytree(MOTION, root)
    sidecar = root / lerobot_format.EPISODES_META
    sidecar.write_text(sidecar.read_text()[:-40] + "\n")
    with pytest.raises(lerobot_format.DatasetError, match=re.escape("kinder_episodes.jsonl")):
        lerobot_format.load_records(root)

    shutil.rmtree(root)
    shutil.copytree(MOTION, root)
    (root / lerobot_format.KINDER_META).write_text("{not json")
    with pytest.raises(lerobot_format.DatasetError, match=re.escape("kinder.json")):
        lerobot_format.load_dataset(root)

    shutil.rmtree(root)
    shutil.copytree(MOTION, root)
    video = next((root / "videos").rglob("*.mp4"))
    video.write_bytes(b"")
    with pytest.raises(lerobot_format.DatasetError, match=re.escape(str(video))):
        lerobot_format.check_dataset(root)


def test_corrupt_episode_and_upstream_files_are_named(tmp_path: Path) -> None:
    record = _random_record(MOTION_ID, 0, 3)
    npz = save_record(tmp_path / "e.npz", record)
    _truncate(npz)
    with pytest.raises(EpisodeFileError, match=re.escape("e.npz")):
        load_record(npz)
    pkl = tmp_path / "demo.p"
    with open(pkl, "wb") as f:
        pickle.dump(_upstream_dict(record), f)
    _truncate(pkl)
    with pytest.raises(UpstreamFormatError, match=re.escape("demo.p")):
        load_upstream_pickle(pkl)
    other = tmp_path / "other.p"
    with open(other, "wb") as f:
        pickle.dump({"actions": []}, f)
    with pytest.raises(UpstreamFormatError, match="missing key"):
        load_upstream_pickle(other)
    h5 = tmp_path / "demos.hdf5"
    h5.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 10)
    with pytest.raises(UpstreamFormatError, match=re.escape("demos.hdf5")):
        load_upstream_hdf5(h5, MOTION_ID)
