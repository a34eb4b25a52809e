"""Dynamic3D task files: loading, templating and validation (no MuJoCo here).

A task file is JSON under ``tasks/<Family>/``; the schema is documented in the package README
("Dynamic3D task files"). Loading a file:

1. parses it (errors name the file, line and column);
2. picks the variant matching ``num_objects`` (if the file lists ``variants``) and applies that
   variant's ``patch`` (JSON Merge Patch, RFC 7386: ``null`` deletes a key), then the ``patch``
   of every chosen entry of the file's ``options`` (named alternatives to the default scene,
   chosen with ``Dynamic3DConfig.task_options``);
3. merges the named ``scene`` file (``tasks/scenes/<scene>.json``) underneath the task;
4. expands ``{i}`` templates for i in ``start … start + count - 1`` (dict keys and list items
   that contain ``{i}`` are repeated; ``{"cycle": [...]}`` values pick per index; ``{n}`` is the
   count);
5. validates every section. Every error is a :class:`TaskFileError` of the form
   ``"<file>: <key path>: <problem>"``.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinder_garden3d.dynamic3d.assets import CHAIR_MODELS, FIXTURE_TYPES, OBJECT_TYPES
from kinder_garden3d.dynamic3d.geometry import Array
from kinder_garden3d.dynamic3d.step_limits import DEFAULT_LIMIT

TASKS_DIR = Path(__file__).with_name("tasks")
SCENES_DIR = TASKS_DIR / "scenes"
ROBOT = "robot"
GROUND = "ground"

_TOP_KEYS = {
    "family", "description", "instruction", "max_episode_steps", "count", "variants", "scene",
    "fixtures", "objects", "regions", "cameras", "static", "initial_state", "goal", "notes",
    "arm_velocity_targets", "robot_clearance", "options", "robot",
}  # fmt: skip
#: Robot models a task file can name in its ``robot`` section (``model``), and the default.
ROBOT_MODELS = ("tidybot", "fr3")
_SCENE_KEYS = {"description", "fixtures", "objects", "regions", "cameras", "static", "notes"}
_PLACEMENT_PREDICATES = ("on", "in")


class TaskFileError(ValueError):
    """A task file is malformed; the message names the file, the key and the problem."""


@dataclass(frozen=True)
class EntitySpec:
    """A fixture or object: its asset type and parameters, and for fixtures an optional fixed
    pose (``pos``, ``yaw`` in radians) when no initial-state predicate places it."""

    name: str
    kind: str
    params: dict[str, Any]
    pos: tuple[float, float, float] | None = None
    yaw: float | None = None


@dataclass(frozen=True)
class RegionSpec:
    """A region: boxes (k × [xmin, ymin, zmin, xmax, ymax, zmax]) in a frame of ``target``.

    ``frame`` names a frame of the target's asset (``None``: the default); ``align`` is
    ``"full"`` (the frame's full orientation), ``"yaw"`` (only its heading) or ``"world"`` (only
    its position). ``yaws`` (k × 2, radians) bound the yaw of objects placed in the region.
    ``drop`` says what a box's z range bounds for an object placed in it: ``"bottom"`` (the
    default) its bottom's height, the object released above its support; ``"centre"`` its
    centre's height, as upstream's ground sampler draws it for 4-value floor ranges (centre in
    [0, 0.1] m), where an object may start partly below the floor and be pushed out by the
    contact solver (upstream tests a pose only against the objects placed before it).
    """

    name: str
    target: str
    frame: str | None
    align: str
    boxes: Array
    yaws: Array
    rgba: tuple[float, float, float, float] | None
    drop: str = "bottom"


@dataclass(frozen=True)
class CameraSpec:
    """A fixed camera: position, look-at point and vertical field of view (degrees)."""

    name: str
    pos: tuple[float, float, float]
    lookat: tuple[float, float, float]
    fovy: float


@dataclass(frozen=True)
class StaticBox:
    """Unobserved scenery (walls): a box with full ``size`` centred at ``pos``."""

    name: str
    pos: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float
    rgba: tuple[float, float, float, float]


#: A goal expression: ("on"|"in", entity, region), ("balanced", seesaw, tol_deg), or
#: ("and"|"or", [expressions]).
Goal = tuple[Any, ...]


@dataclass(frozen=True)
class TaskSpec:
    """A fully expanded and validated task."""

    file: str
    family: str
    count: int | None
    description: str
    instruction: str
    max_episode_steps: int
    fixtures: dict[str, EntitySpec]
    objects: dict[str, EntitySpec]
    regions: dict[str, RegionSpec]
    cameras: dict[str, CameraSpec]
    static: list[StaticBox]
    initial_state: list[tuple[str, str, str]]
    goal: Goal
    notes: str = ""
    scene: str | None = None
    arm_velocity_targets: bool = False
    #: Smallest distance (m) between a robot base placed without a region and the centre of any
    #: object placed on the ground (upstream kindergarden 0.2.5's ``robot_ground_clearance``).
    robot_clearance: float = 0.0
    #: The robot model (:data:`ROBOT_MODELS`): the mobile manipulator (``"tidybot"``) or the
    #: fixed-base Franka FR3 arm (``"fr3"``), mounted at the top height of the table fixture
    #: ``robot_mount`` (upstream's ``mount_surface``).
    robot: str = "tidybot"
    robot_mount: str | None = None
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class VariantInfo:
    """One registered id's worth of information, read without expanding the file."""

    family: str
    label: str
    file: str
    count: int | None
    max_episode_steps: int
    robot: str = "tidybot"


# ---------------------------------------------------------------------------------------------
# File discovery


def resolve_task_path(task: str) -> tuple[Path, str]:
    """The path of a task given as ``"Family/File.json"`` (under ``tasks/``), ``"Family"`` (its
    only file) or a filesystem path; returns (path, display name)."""
    candidate = Path(task)
    if candidate.is_absolute() or candidate.exists():
        if not candidate.is_file():
            raise TaskFileError(f"{task}: no such task file")
        return candidate, str(candidate)
    inner = TASKS_DIR / task
    if inner.is_file():
        return inner, task
    if inner.is_dir():
        files = sorted(inner.glob("*.json"))
        if len(files) == 1:
            return files[0], f"{task}/{files[0].name}"
        raise TaskFileError(
            f"{task}: the family has {len(files)} task files; name one of "
            f"{[f'{task}/{f.name}' for f in files]}"
        )
    known = sorted(p.name for p in TASKS_DIR.iterdir() if p.is_dir() and p.name != "scenes")
    raise TaskFileError(f"{task}: no such task file or family; families: {known}")


def _read_json(path: Path, display: str) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise TaskFileError(
            f"{display}: invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}"
        ) from None
    if not isinstance(data, dict):
        raise TaskFileError(f"{display}: <root>: expected a JSON object, got {type(data).__name__}")
    return data


def task_files() -> Iterator[tuple[str, Path]]:
    """(display name, path) of every bundled task file, sorted."""
    for family_dir in sorted(p for p in TASKS_DIR.iterdir() if p.is_dir()):
        if family_dir.name == "scenes":
            continue
        for path in sorted(family_dir.glob("*.json")):
            yield f"{family_dir.name}/{path.name}", path


def variant_table() -> list[VariantInfo]:
    """Every registered variant of every bundled task file (reads JSON only)."""
    out = []
    for display, path in task_files():
        raw = _read_json(path, display)
        family = raw.get("family")
        if family != path.parent.name:
            raise TaskFileError(
                f"{display}: family: must equal the folder name {path.parent.name!r}, "
                f"got {family!r}"
            )
        steps = int(raw.get("max_episode_steps", DEFAULT_LIMIT))
        variants = raw.get("variants")
        if variants is None:
            stem = path.stem
            prefix = f"{family}-"
            label = stem[len(prefix) :] if stem.startswith(prefix) else stem
            count = (
                raw.get("count", {}).get("default") if isinstance(raw.get("count"), dict) else None
            )
            out.append(VariantInfo(family, label, display, count, steps, _robot_model(raw)))
            continue
        if not isinstance(variants, dict) or not variants:
            raise TaskFileError(f"{display}: variants: expected a non-empty object")
        for label, spec in variants.items():
            count = spec.get("count") if isinstance(spec, dict) else None
            if not isinstance(count, int):
                raise TaskFileError(f"{display}: variants.{label}.count: expected an integer")
            label_steps = spec.get("max_episode_steps", steps)
            if not isinstance(label_steps, int) or label_steps <= 0:
                raise TaskFileError(
                    f"{display}: variants.{label}.max_episode_steps: expected a positive "
                    f"integer, got {label_steps!r}"
                )
            out.append(VariantInfo(family, label, display, count, label_steps, _robot_model(raw)))
    return out


def _robot_model(raw: dict[str, Any]) -> str:
    """The ``robot.model`` of a raw task file (the default ``"tidybot"`` when absent)."""
    robot = raw.get("robot")
    model = robot.get("model", "tidybot") if isinstance(robot, dict) else "tidybot"
    return str(model)


# ---------------------------------------------------------------------------------------------
# Loading


def merge_patch(target: Any, patch: Any) -> Any:
    """RFC 7386 JSON Merge Patch: objects merge recursively, ``null`` deletes, anything else
    replaces."""
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    out = dict(target) if isinstance(target, dict) else {}
    for key, value in patch.items():
        if value is None:
            out.pop(key, None)
        else:
            out[key] = merge_patch(out.get(key), value)
    return out


def _contains_i(x: Any) -> bool:
    if isinstance(x, str):
        return "{i}" in x
    if isinstance(x, list):
        return any(_contains_i(v) for v in x)
    if isinstance(x, dict):
        return any(_contains_i(k) or _contains_i(v) for k, v in x.items())
    return False


def _subst(x: Any, i: int | None, k: int, n: int | None, where: str) -> Any:
    """Substitute ``{i}``/``{n}`` in strings and resolve ``{"cycle": [...]}`` for index k."""
    if isinstance(x, str):
        if "{i}" in x and i is None:
            raise TaskFileError(f"{where}: '{{i}}' used outside a repeated entry")
        out = x.replace("{i}", str(i)) if i is not None else x
        return out.replace("{n}", str(n)) if n is not None else out
    if isinstance(x, list):
        return [_subst(v, i, k, n, where) for v in x]
    if isinstance(x, dict):
        if set(x) == {"cycle"}:
            values = x["cycle"]
            if not isinstance(values, list) or not values:
                raise TaskFileError(f"{where}: cycle: expected a non-empty list")
            if i is None:
                raise TaskFileError(f"{where}: 'cycle' used outside a repeated entry")
            return _subst(values[k % len(values)], i, k, n, where)
        return {
            _subst(key, i, k, n, where): _subst(v, i, k, n, f"{where}.{key}")
            for key, v in x.items()
        }
    return x


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _expand(x: Any, indices: list[int], n: int | None, where: str) -> Any:
    """Repeat dict entries and list items that contain ``{i}`` once per index."""
    if isinstance(x, dict):
        out: dict[str, Any] = {}
        for key, value in x.items():
            if "{i}" in key:
                if not indices:
                    raise TaskFileError(f"{_join(where, key)}: '{{i}}' needs a 'count' section")
                for k, i in enumerate(indices):
                    out[key.replace("{i}", str(i))] = _subst(value, i, k, n, _join(where, key))
            else:
                out[key] = _expand(value, indices, n, _join(where, key))
        return out
    if isinstance(x, list):
        items: list[Any] = []
        for j, value in enumerate(x):
            if _contains_i(value) and not (isinstance(value, dict) and "cycle" in value):
                if not indices:
                    raise TaskFileError(f"{where}[{j}]: '{{i}}' needs a 'count' section")
                items.extend(_subst(value, i, k, n, f"{where}[{j}]") for k, i in enumerate(indices))
            else:
                items.append(_expand(value, indices, n, f"{where}[{j}]"))
        return items
    return _subst(x, None, 0, n, where)


def load_task(task: str, num_objects: int | None = None, options: Sequence[str] = ()) -> TaskSpec:
    """Load, template and validate a task file (see the module docstring); ``options`` names
    entries of the file's ``options`` section whose patches are applied, in order."""
    path, display = resolve_task_path(task)
    raw = _read_json(path, display)
    v = _Validator(display)
    unknown = sorted(set(raw) - _TOP_KEYS)
    if unknown:
        raise v.error("<root>", f"unknown key(s) {unknown}; allowed: {sorted(_TOP_KEYS)}")
    family = v.string(raw.get("family"), "family")
    if path.parent.parent == TASKS_DIR and family != path.parent.name:
        raise v.error("family", f"must equal the folder name {path.parent.name!r}")

    count_cfg = raw.get("count")
    count: int | None = None
    start = 0
    if count_cfg is not None:
        count_cfg = v.obj(count_cfg, "count", {"default", "min", "max", "start"})
        default = v.integer(count_cfg.get("default"), "count.default")
        low = v.integer(count_cfg.get("min", 1), "count.min")
        high = v.integer(count_cfg.get("max", 10_000), "count.max")
        start = v.integer(count_cfg.get("start", 0), "count.start")
        count = default if num_objects is None else int(num_objects)
        if not low <= count <= high:
            raise TaskFileError(
                f"{display}: num_objects must be in [{low}, {high}] for this task, got {count}"
            )
    elif num_objects is not None:
        raise TaskFileError(
            f"{display}: this task has no 'count' section, so num_objects cannot be set "
            f"(got {num_objects})"
        )

    variants = raw.get("variants")
    instruction = raw.get("instruction", "")
    if variants is not None:
        variants = v.obj(variants, "variants", None)
        for label, spec in variants.items():
            spec = v.obj(
                spec, f"variants.{label}", {"count", "instruction", "max_episode_steps", "patch"}
            )
            if v.integer(spec.get("count"), f"variants.{label}.count") == count:
                if "patch" in spec:
                    raw = merge_patch(raw, v.obj(spec["patch"], f"variants.{label}.patch", None))
                if "max_episode_steps" in spec:
                    key = f"variants.{label}.max_episode_steps"
                    steps = v.integer(spec["max_episode_steps"], key)
                    if steps <= 0:
                        raise v.error(key, f"must be positive, got {steps}")
                    raw = {**raw, "max_episode_steps": steps}
                instruction = spec.get("instruction", instruction)
    offered = v.obj(raw.get("options", {}), "options", None)
    for label, spec in offered.items():
        spec = v.obj(spec, f"options.{label}", {"description", "patch"})
        v.string(spec.get("description"), f"options.{label}.description")
        v.obj(spec.get("patch"), f"options.{label}.patch", None)
    for label in options:
        if label not in offered:
            raise TaskFileError(
                f"{display}: task option {label!r} is not offered; this task offers "
                f"{sorted(offered)}"
            )
        raw = merge_patch(raw, offered[label]["patch"])
    raw = {k: val for k, val in raw.items() if k not in ("variants", "options")}

    scene = raw.get("scene")
    if scene is not None:
        scene = v.string(scene, "scene")
        scene_path = SCENES_DIR / f"{scene}.json"
        if not scene_path.is_file():
            known = sorted(p.stem for p in SCENES_DIR.glob("*.json"))
            raise v.error("scene", f"unknown scene {scene!r}; known: {known}")
        scene_raw = _read_json(scene_path, f"scenes/{scene}.json")
        bad = sorted(set(scene_raw) - _SCENE_KEYS)
        if bad:
            raise TaskFileError(f"scenes/{scene}.json: <root>: unknown key(s) {bad}")
        for key in ("fixtures", "objects", "regions", "cameras"):
            if key in scene_raw:  # the task patches the scene (RFC 7386)
                raw[key] = merge_patch(scene_raw[key], raw.get(key, {}))
        if "static" in scene_raw:
            raw["static"] = [*scene_raw["static"], *raw.get("static", [])]

    indices = list(range(start, start + count)) if count is not None else []
    try:
        raw = _expand(raw, indices, count, "")
    except TaskFileError as e:
        raise TaskFileError(f"{display}: {e}") from None
    instruction = _subst(instruction, None, 0, count, "instruction")

    fixtures = {
        name: v.entity(name, spec, f"fixtures.{name}", FIXTURE_TYPES, fixture=True)
        for name, spec in v.obj(raw.get("fixtures", {}), "fixtures", None).items()
    }
    objects = {
        name: v.entity(name, spec, f"objects.{name}", OBJECT_TYPES, fixture=False)
        for name, spec in v.obj(raw.get("objects", {}), "objects", None).items()
    }
    clash = sorted(
        set(fixtures) & set(objects) | ({ROBOT, GROUND} & (set(fixtures) | set(objects)))
    )
    if clash:
        raise v.error("objects", f"names used twice or reserved: {clash}")
    entities = {**fixtures, **objects}
    regions = {
        name: v.region(name, spec, f"regions.{name}", entities)
        for name, spec in v.obj(raw.get("regions", {}), "regions", None).items()
    }
    cameras = {
        name: v.camera(name, spec, f"cameras.{name}")
        for name, spec in v.obj(raw.get("cameras", {}), "cameras", None).items()
    }
    if "task_view" not in cameras:
        raise v.error("cameras", "every task defines a 'task_view' camera")
    static = [v.static(spec, f"static[{j}]") for j, spec in enumerate(raw.get("static", []))]

    initial = []
    placed: set[str] = set()
    for j, pred in enumerate(v.array(raw.get("initial_state", []), "initial_state")):
        where = f"initial_state[{j}]"
        if not (isinstance(pred, list) and len(pred) == 3 and pred[0] in _PLACEMENT_PREDICATES):
            raise v.error(where, f'expected ["on"|"in", entity, region], got {pred!r}')
        _, ent, reg = pred
        if ent != ROBOT and ent not in entities:
            raise v.error(where, f"unknown entity {ent!r}; known: {sorted(entities)}")
        if reg not in regions:
            raise v.error(where, f"unknown region {reg!r}; known: {sorted(regions)}")
        if regions[reg].target == ent:
            raise v.error(where, f"{ent!r} cannot be placed in its own region {reg!r}")
        if ent in placed:
            raise v.error(where, f"{ent!r} is placed twice")
        placed.add(ent)
        initial.append((str(pred[0]), str(ent), str(reg)))
    for name in objects:
        if name not in placed:
            raise v.error(f"objects.{name}", "every object needs an initial_state predicate")
    for name, ent in fixtures.items():
        if name not in placed and ent.pos is None:
            raise v.error(f"fixtures.{name}", "needs a 'pos' or an initial_state predicate")

    if "goal" not in raw:
        raise v.error("goal", "missing")
    goal = v.goal(raw["goal"], "goal", entities, regions, objects)
    steps = v.integer(raw.get("max_episode_steps", DEFAULT_LIMIT), "max_episode_steps")
    if steps <= 0:
        raise v.error("max_episode_steps", f"must be positive, got {steps}")
    clearance = v.number(raw.get("robot_clearance", 0.0), "robot_clearance")
    if clearance < 0:
        raise v.error("robot_clearance", f"must be >= 0, got {clearance}")
    robot_cfg = v.obj(raw.get("robot", {}), "robot", {"model", "mount_surface"})
    robot_model = v.string(robot_cfg.get("model", "tidybot"), "robot.model")
    if robot_model not in ROBOT_MODELS:
        raise v.error("robot.model", f"must be one of {list(ROBOT_MODELS)}, got {robot_model!r}")
    robot_mount: str | None = None
    if robot_model == "fr3":
        robot_mount = v.string(robot_cfg.get("mount_surface"), "robot.mount_surface")
        if robot_mount not in fixtures or fixtures[robot_mount].kind != "table":
            tables = sorted(n for n, f in fixtures.items() if f.kind == "table")
            raise v.error(
                "robot.mount_surface",
                f"the fr3 arm is mounted on a table fixture; got {robot_mount!r}, tables: {tables}",
            )
    elif "mount_surface" in robot_cfg:
        raise v.error("robot.mount_surface", "only the fixed-base 'fr3' robot has a mount")
    return TaskSpec(
        file=display,
        family=family,
        count=count,
        description=v.string(raw.get("description"), "description"),
        instruction=v.string(instruction, "instruction") if instruction else "",
        max_episode_steps=steps,
        fixtures=fixtures,
        objects=objects,
        regions=regions,
        cameras=cameras,
        static=static,
        initial_state=initial,
        goal=goal,
        notes=str(raw.get("notes", "")),
        scene=scene,
        arm_velocity_targets=v.boolean(
            raw.get("arm_velocity_targets", False), "arm_velocity_targets"
        ),
        robot_clearance=clearance,
        robot=robot_model,
        robot_mount=robot_mount,
        raw=raw,
    )


class _Validator:
    """Type checks with errors of the form ``<file>: <key path>: <problem>``."""

    def __init__(self, display: str) -> None:
        self.display = display

    def error(self, where: str, problem: str) -> TaskFileError:
        return TaskFileError(f"{self.display}: {where}: {problem}")

    def obj(self, x: Any, where: str, allowed: set[str] | None) -> dict[str, Any]:
        if not isinstance(x, dict):
            raise self.error(where, f"expected an object, got {type(x).__name__}")
        if allowed is not None:
            bad = sorted(set(x) - allowed)
            if bad:
                raise self.error(where, f"unknown key(s) {bad}; allowed: {sorted(allowed)}")
        return x

    def array(self, x: Any, where: str) -> list[Any]:
        if not isinstance(x, list):
            raise self.error(where, f"expected a list, got {type(x).__name__}")
        return x

    def string(self, x: Any, where: str) -> str:
        if not isinstance(x, str) or not x:
            raise self.error(where, f"expected a non-empty string, got {x!r}")
        return x

    def boolean(self, x: Any, where: str) -> bool:
        if not isinstance(x, bool):
            raise self.error(where, f"expected true or false, got {x!r}")
        return x

    def integer(self, x: Any, where: str) -> int:
        if isinstance(x, bool) or not isinstance(x, int):
            raise self.error(where, f"expected an integer, got {x!r}")
        return x

    def number(self, x: Any, where: str) -> float:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise self.error(where, f"expected a finite number, got {x!r}")
        return float(x)

    def vec(self, x: Any, n: int | None, where: str) -> list[float]:
        if not isinstance(x, list) or (n is not None and len(x) != n):
            what = f"a list of {n} numbers" if n is not None else "a list of numbers"
            raise self.error(where, f"expected {what}, got {x!r}")
        return [self.number(val, f"{where}[{j}]") for j, val in enumerate(x)]

    def rgba(self, x: Any, where: str) -> tuple[float, float, float, float]:
        vals = self.vec(x, 4, where)
        if not all(0.0 <= c <= 1.0 for c in vals):
            raise self.error(where, f"rgba components must lie in [0, 1], got {vals}")
        return (vals[0], vals[1], vals[2], vals[3])

    def param(self, key: str, value: Any, default: Any, where: str) -> Any:
        if key.startswith("rgba") or key.endswith("_rgba"):
            return list(self.rgba(value, where))
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise self.error(where, f"expected true or false, got {value!r}")
            return value
        if isinstance(default, str):
            value = self.string(value, where)
            if key == "model" and value not in CHAIR_MODELS:
                raise self.error(
                    where, f"unknown chair model {value!r}; known: {list(CHAIR_MODELS)}"
                )
            return value
        if isinstance(default, int) and not isinstance(default, bool):
            out = self.integer(value, where)
            if out <= 0:
                raise self.error(where, f"must be positive, got {out}")
            return out
        if isinstance(default, float) or (default is None and not isinstance(value, list)):
            out_f = self.number(value, where)
            signed = key == "origin_height" or "range" in key  # may be zero or negative
            if key not in ("leg_height",) and out_f <= 0 and not signed:
                raise self.error(where, f"must be positive, got {out_f}")
            if key == "leg_height" and out_f < 0:
                raise self.error(where, f"must be >= 0, got {out_f}")
            return out_f
        if key == "working_drawers":
            pairs = self.array(value, where)
            for j, pair in enumerate(pairs):
                if not (
                    isinstance(pair, list)
                    and len(pair) == 2
                    and all(isinstance(v, int) and not isinstance(v, bool) for v in pair)
                ):
                    raise self.error(f"{where}[{j}]", f"expected [level, cell], got {pair!r}")
            return value
        if key in ("shelf_partitions", "shelf_drawers"):
            rows = self.array(value, where)
            for j, row in enumerate(rows):
                self.array(row, f"{where}[{j}]")
                for c, cell in enumerate(row):
                    ok = (
                        isinstance(cell, bool)
                        if key == "shelf_drawers"
                        else isinstance(cell, (int, float)) and not isinstance(cell, bool)
                    )
                    if not ok:
                        kind = "true/false" if key == "shelf_drawers" else "a number"
                        raise self.error(f"{where}[{j}][{c}]", f"expected {kind}, got {cell!r}")
            return value
        n = len(default) if isinstance(default, list) and key != "shelf_heights" else None
        vals = self.vec(value, n, where)
        if key != "hinge_range" and any(val <= 0 for val in vals):
            raise self.error(where, f"values must be positive, got {vals}")
        return vals

    def entity(
        self, name: str, spec: Any, where: str, registry: dict[str, Any], fixture: bool
    ) -> EntitySpec:
        spec = self.obj(spec, where, None)
        kind = spec.get("type")
        if kind not in registry:
            raise self.error(f"{where}.type", f"unknown type {kind!r}; known: {sorted(registry)}")
        defaults = registry[kind][1]
        pose_keys = {"pos", "yaw"} if fixture else set()
        allowed = {"type", *defaults, *pose_keys}
        bad = sorted(set(spec) - allowed)
        if bad:
            raise self.error(
                where, f"unknown parameter(s) {bad} for a {kind}; allowed: {sorted(allowed)}"
            )
        params = {
            key: self.param(key, value, defaults[key], f"{where}.{key}")
            for key, value in spec.items()
            if key in defaults
        }
        pos = None
        yaw = None
        if fixture and "pos" in spec:
            p = self.vec(spec["pos"], 3, f"{where}.pos")
            pos = (p[0], p[1], p[2])
            yaw = math.radians(self.number(spec.get("yaw", 0.0), f"{where}.yaw"))
        elif fixture and "yaw" in spec:
            raise self.error(f"{where}.yaw", "'yaw' needs 'pos'")
        return EntitySpec(name, str(kind), params, pos, yaw)

    def region(
        self, name: str, spec: Any, where: str, entities: dict[str, EntitySpec]
    ) -> RegionSpec:
        spec = self.obj(spec, where, {"target", "frame", "align", "boxes", "yaw", "rgba", "drop"})
        target = self.string(spec.get("target"), f"{where}.target")
        drop = spec.get("drop", "bottom")
        if drop not in ("bottom", "centre"):
            raise self.error(f"{where}.drop", f"expected bottom or centre, got {drop!r}")
        if target != GROUND and target not in entities:
            raise self.error(
                f"{where}.target", f"unknown target {target!r}; known: ground, {sorted(entities)}"
            )
        frame = spec.get("frame")
        if frame is not None:
            frame = self.string(frame, f"{where}.frame")
            if target == GROUND:
                raise self.error(f"{where}.frame", "the ground has no named frames")
        align = spec.get("align", "full")
        if align not in ("full", "yaw", "world"):
            raise self.error(f"{where}.align", f"expected full, yaw or world, got {align!r}")
        boxes_raw = self.array(spec.get("boxes"), f"{where}.boxes")
        if not boxes_raw:
            raise self.error(f"{where}.boxes", "needs at least one box")
        boxes = []
        for j, box in enumerate(boxes_raw):
            b = self.vec(box, 6, f"{where}.boxes[{j}]")
            if not (b[0] <= b[3] and b[1] <= b[4] and b[2] <= b[5]):
                raise self.error(
                    f"{where}.boxes[{j}]", f"expected [xmin, ymin, zmin, xmax, ymax, zmax], got {b}"
                )
            boxes.append(b)
        yaw_raw = spec.get("yaw", [[0.0, 0.0]])
        yaws = [
            self.vec(y, 2, f"{where}.yaw[{j}]")
            for j, y in enumerate(self.array(yaw_raw, f"{where}.yaw"))
        ]
        if len(yaws) == 1:
            yaws = yaws * len(boxes)
        if len(yaws) != len(boxes):
            raise self.error(f"{where}.yaw", f"give one [lo, hi] or one per box ({len(boxes)})")
        for j, (lo, hi) in enumerate(yaws):
            if lo > hi:
                raise self.error(
                    f"{where}.yaw[{j}]", f"expected [lo, hi] with lo <= hi, got {[lo, hi]}"
                )
        rgba = self.rgba(spec["rgba"], f"{where}.rgba") if "rgba" in spec else None
        return RegionSpec(
            name,
            target,
            frame,
            str(align),
            np.array(boxes),
            np.radians(np.array(yaws)),
            rgba,
            str(drop),
        )

    def camera(self, name: str, spec: Any, where: str) -> CameraSpec:
        spec = self.obj(spec, where, {"pos", "lookat", "fovy"})
        pos = self.vec(spec.get("pos"), 3, f"{where}.pos")
        look = self.vec(spec.get("lookat"), 3, f"{where}.lookat")
        fovy = self.number(spec.get("fovy", 45.0), f"{where}.fovy")
        if not 1.0 <= fovy <= 170.0:
            raise self.error(f"{where}.fovy", f"must be in [1, 170] degrees, got {fovy}")
        if np.allclose(pos, look):
            raise self.error(where, "pos and lookat coincide")
        return CameraSpec(name, (pos[0], pos[1], pos[2]), (look[0], look[1], look[2]), fovy)

    def static(self, spec: Any, where: str) -> StaticBox:
        spec = self.obj(spec, where, {"name", "pos", "size", "yaw", "rgba"})
        name = self.string(spec.get("name"), f"{where}.name")
        pos = self.vec(spec.get("pos"), 3, f"{where}.pos")
        size = self.vec(spec.get("size"), 3, f"{where}.size")
        if any(s <= 0 for s in size):
            raise self.error(f"{where}.size", f"values must be positive, got {size}")
        yaw = math.radians(self.number(spec.get("yaw", 0.0), f"{where}.yaw"))
        rgba = self.rgba(spec.get("rgba", [0.85, 0.85, 0.82, 1.0]), f"{where}.rgba")
        return StaticBox(name, (pos[0], pos[1], pos[2]), (size[0], size[1], size[2]), yaw, rgba)

    def goal(
        self,
        x: Any,
        where: str,
        entities: dict[str, EntitySpec],
        regions: dict[str, RegionSpec],
        objects: dict[str, EntitySpec],
    ) -> Goal:
        if not isinstance(x, list) or not x:
            raise self.error(where, f"expected a predicate list, got {x!r}")
        head = x[0]
        if head in ("and", "or"):
            if len(x) < 2:
                raise self.error(where, f"'{head}' needs at least one operand")
            return (head, [self.goal(e, f"{where}[{j + 1}]", entities, regions, objects)
                           for j, e in enumerate(x[1:])])  # fmt: skip
        if isinstance(head, list):  # a bare list of predicates means "and"
            return ("and", [self.goal(e, f"{where}[{j}]", entities, regions, objects)
                            for j, e in enumerate(x)])  # fmt: skip
        if head in _PLACEMENT_PREDICATES:
            if len(x) != 3:
                raise self.error(where, f'expected ["{head}", entity, region], got {x!r}')
            _, ent, reg = x
            if ent != ROBOT and ent not in objects:
                raise self.error(where, f"unknown object {ent!r}; known: robot, {sorted(objects)}")
            if reg not in regions:
                raise self.error(where, f"unknown region {reg!r}; known: {sorted(regions)}")
            return (str(head), str(ent), str(reg))
        if head == "balanced":
            if len(x) != 3:
                raise self.error(where, f'expected ["balanced", seesaw, tol_deg], got {x!r}')
            _, ent, tol = x
            if ent not in objects or objects[ent].kind != "seesaw":
                seesaws = sorted(n for n, o in objects.items() if o.kind == "seesaw")
                raise self.error(where, f"{ent!r} is not a seesaw; seesaws: {seesaws}")
            tol_deg = self.number(tol, f"{where}[2]")
            if tol_deg <= 0:
                raise self.error(f"{where}[2]", f"tolerance must be positive, got {tol_deg}")
            return ("balanced", str(ent), tol_deg)
        raise self.error(where, f"unknown predicate {head!r}; expected on, in, balanced, and, or")
