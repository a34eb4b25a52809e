"""The trainers' one checkpoint format (:mod:`kinder_bench.training.checkpoints`): layout,
metadata, atomic writes, rotation with kept steps, and the errors for checkpoints it cannot use."""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from kinder_bench.training.checkpoints import (
    FORMAT_VERSION,
    METADATA_FILE,
    CheckpointError,
    find_checkpoint,
    latest_checkpoint,
    list_checkpoints,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)


@dataclasses.dataclass(frozen=True)
class _Args:
    dataset: Path
    steps: int = 10
    sizes: tuple[int, ...] = (4, 8)


def _write(text: str = "weights") -> Callable[[Path], None]:
    def write(d: Path) -> None:
        (d / "model.bin").write_text(text)

    return write


def test_round_trip_records_the_method_args_step_versions_and_info(tmp_path: Path) -> None:
    args = _Args(tmp_path / "data")
    path = save_checkpoint(tmp_path, 7, "dp", args, _write(), info={"env_id": "kinder/X-v0"})
    assert path == tmp_path / "checkpoints" / "step_000000007"
    assert (path / "model.bin").read_text() == "weights"
    raw = json.loads((path / METADATA_FILE).read_text())
    assert raw["format_version"] == FORMAT_VERSION
    ckpt = load_checkpoint(tmp_path, ("dp",))
    assert ckpt.path == path and ckpt.method == "dp" and ckpt.step == 7 and not ckpt.kept
    assert ckpt.args == {"dataset": str(tmp_path / "data"), "steps": 10, "sizes": [4, 8]}
    assert ckpt.info == {"env_id": "kinder/X-v0"}
    assert {"python", "kinder-bench", "kinder-core", "numpy", "pymunk"} <= set(ckpt.versions)
    assert load_checkpoint(path).step == 7  # one checkpoint directory is accepted too
    assert (tmp_path / "checkpoints" / "latest").read_text().strip() == path.name


def test_latest_is_the_highest_step_and_rotation_spares_kept_ones(tmp_path: Path) -> None:
    save_checkpoint(tmp_path, 5, "ppo", {}, _write(), keep=2, kept=True)
    for step in (10, 100, 1_000_000_000):  # more digits than the name pads to still sort
        save_checkpoint(tmp_path, step, "ppo", {}, _write(), keep=2)
    assert [s for s, _ in list_checkpoints(tmp_path)] == [5, 100, 1_000_000_000]
    assert latest_checkpoint(tmp_path) == tmp_path / "checkpoints" / "step_1000000000"
    # A second write at one step keeps the files and only records kept=True.
    again = save_checkpoint(tmp_path, 100, "ppo", {}, _write("other"), keep=1, kept=True)
    assert (again / "model.bin").read_text() == "weights" and read_checkpoint(again).kept
    save_checkpoint(tmp_path, 2_000_000_000, "ppo", {}, _write(), keep=1)
    assert [s for s, _ in list_checkpoints(tmp_path)] == [5, 100, 2_000_000_000]


def test_a_partially_written_checkpoint_is_ignored(tmp_path: Path) -> None:
    save_checkpoint(tmp_path, 1, "mbrl", {}, _write())

    def killed(d: Path) -> None:
        (d / "model.bin").write_text("half")
        raise KeyboardInterrupt  # stands for a kill in the middle of the trainer's write

    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(tmp_path, 2, "mbrl", {}, killed)
    root = tmp_path / "checkpoints"
    assert (root / ".tmp-step_000000002").is_dir() and not (root / "step_000000002").exists()
    # A step directory without its metadata (written by hand or by another tool) is no checkpoint.
    (root / "step_000000003").mkdir()
    (root / "step_000000003" / "model.bin").write_text("half")
    assert latest_checkpoint(tmp_path) == root / "step_000000001"
    assert [s for s, _ in list_checkpoints(tmp_path)] == [1]
    with pytest.raises(CheckpointError, match=r"checkpoint\.json is missing"):
        read_checkpoint(root / "step_000000003")
    # The next write at that step replaces the leftovers.
    path = save_checkpoint(tmp_path, 2, "mbrl", {}, _write())
    assert (path / "model.bin").read_text() == "weights"
    assert not (root / ".tmp-step_000000002").exists()
    assert latest_checkpoint(tmp_path) == path


def test_wrong_version_method_and_unreadable_metadata_are_clear_errors(tmp_path: Path) -> None:
    path = save_checkpoint(tmp_path, 3, "ppo", {}, _write())
    with pytest.raises(CheckpointError, match=r"holds a ppo policy.*not dp or dpes.*--agent ppo"):
        load_checkpoint(tmp_path, ("dp", "dpes"))
    meta = json.loads((path / METADATA_FILE).read_text())
    (path / METADATA_FILE).write_text(json.dumps({**meta, "format_version": 99}))
    with pytest.raises(CheckpointError, match=r"format_version 99; this code reads format 1"):
        load_checkpoint(tmp_path)
    (path / METADATA_FILE).write_text('{"format_version": 1, "meth')
    with pytest.raises(CheckpointError, match="unreadable"):
        load_checkpoint(tmp_path)
    (path / METADATA_FILE).write_text(json.dumps({"format_version": 1, "method": "ppo"}))
    with pytest.raises(CheckpointError, match=r"lacks \['step', 'args', 'versions', 'info'\]"):
        load_checkpoint(tmp_path)
    with pytest.raises(ValueError, match="Unknown trainer method 'bc'"):
        save_checkpoint(tmp_path, 4, "bc", {}, _write())


def test_missing_checkpoints_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="No checkpoint given"):
        find_checkpoint("")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        find_checkpoint(tmp_path / "missing")
    with pytest.raises(FileNotFoundError, match="holds no checkpoint"):
        find_checkpoint(tmp_path)
    assert latest_checkpoint(tmp_path) is None


@pytest.mark.parametrize(
    ("where", "name", "writer"),
    [
        ("checkpoints/step_000051200", "meta.json", "ppo|sac"),
        ("checkpoints/step_00000020", "kinder.json", "dp|dpes|mbrl"),
        ("", "model.pt", "gsc"),
    ],
)
def test_legacy_layouts_are_named_as_such(
    tmp_path: Path, where: str, name: str, writer: str
) -> None:
    """The layouts before format 1 are recognised, so that resuming never starts over silently
    and an agent says what it was given."""
    place = tmp_path / where
    place.mkdir(parents=True, exist_ok=True)
    (place / name).write_text("{}")
    expected = "legacy layout: .*" + re.escape(f"{name} (written by `kinder train {writer}`")
    with pytest.raises(CheckpointError, match=expected):
        latest_checkpoint(tmp_path)
    with pytest.raises(CheckpointError, match=expected):
        load_checkpoint(tmp_path)
    with pytest.raises(CheckpointError, match=expected):
        read_checkpoint(place)
