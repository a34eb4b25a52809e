"""Task files: schema validation errors name the file, the key and the problem; templates,
variants and scenes expand as documented; a new task needs no Python."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from kinder_garden3d.dynamic3d.env import Dynamic3DConfig, Dynamic3DEnv
from kinder_garden3d.dynamic3d.taskfile import (
    TaskFileError,
    load_task,
    merge_patch,
    task_files,
    variant_table,
)

MINIMAL: dict[str, Any] = {
    "family": "Shelf3D",
    "description": "A small custom task.",
    "instruction": "Put the {n} cubes on the table.",
    "count": {"default": 2, "min": 1, "max": 5, "start": 1},
    "fixtures": {"table_1": {"type": "table", "pos": [1.0, 0.0, 0.0], "length": 0.6}},
    "objects": {
        "cube{i}": {"type": "cube", "size": 0.03, "rgba": {"cycle": [[1, 0, 0, 1], [0, 0, 1, 1]]}}
    },
    "regions": {
        "floor_region": {
            "target": "ground",
            "boxes": [[0.3, -0.3, 0, 0.5, 0.3, 0]],
            "yaw": [[0, 90]],
        },
        "table_region": {"target": "table_1", "boxes": [[-0.25, -0.25, 0, 0.25, 0.25, 0.05]]},
        "robot_region": {"target": "ground", "boxes": [[-0.1, -0.1, 0, 0.1, 0.1, 0]]},
    },
    "cameras": {"task_view": {"pos": [-1.0, 0.0, 1.5], "lookat": [0.8, 0.0, 0.2]}},
    "initial_state": [["on", "cube{i}", "floor_region"], ["on", "robot", "robot_region"]],
    "goal": ["and", ["on", "cube{i}", "table_region"]],
}


def write(tmp_path: Path, data: Any, name: str = "custom.json") -> str:
    path = tmp_path / name
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return str(path)


def broken(**changes: Any) -> dict[str, Any]:
    return merge_patch(copy.deepcopy(MINIMAL), changes)  # type: ignore[no-any-return]


@pytest.mark.parametrize(
    ("patch", "key", "problem"),
    [
        ({"colour": "red"}, "<root>", "unknown key(s) ['colour']"),
        (
            {"objects": {"cube{i}": {"sise": 0.02}}},
            "objects.cube1",
            "unknown parameter(s) ['sise']",
        ),
        (
            {"objects": {"cube{i}": {"type": "sphere"}}},
            "objects.cube1.type",
            "unknown type 'sphere'",
        ),
        ({"objects": {"cube{i}": {"size": -0.02}}}, "objects.cube1.size", "must be positive"),
        (
            {"objects": {"cube{i}": {"rgba": [1, 0, 0]}}},
            "objects.cube1.rgba",
            "expected a list of 4",
        ),
        (
            {"regions": {"table_region": {"target": "desk"}}},
            "regions.table_region.target",
            "unknown target 'desk'",
        ),
        (
            {"regions": {"floor_region": {"boxes": [[1, 0, 0, 0, 1, 0]]}}},
            "regions.floor_region.boxes[0]",
            "expected [xmin",
        ),
        (
            {"regions": {"floor_region": {"drop": "sideways"}}},
            "regions.floor_region.drop",
            "expected bottom or centre, got 'sideways'",
        ),
        (
            {"regions": {"floor_region": {"yaw": [[10, 0]]}}},
            "regions.floor_region.yaw[0]",
            "lo <= hi",
        ),
        (
            {"cameras": {"task_view": None, "side": {"pos": [0, 0, 1], "lookat": [1, 0, 0]}}},
            "cameras",
            "task_view",
        ),
        (
            {"goal": ["and", ["on", "cube{i}", "shelf_region"]]},
            "goal[1]",
            "unknown region 'shelf_region'",
        ),
        ({"goal": ["near", "cube1", "table_region"]}, "goal", "unknown predicate 'near'"),
        ({"goal": ["balanced", "cube1", 5.0]}, "goal", "is not a seesaw"),
        (
            {"initial_state": [["on", "robot", "robot_region"]]},
            "objects.cube1",
            "needs an initial_state",
        ),
        (
            {"initial_state": [["under", "cube{i}", "floor_region"]]},
            "initial_state[0]",
            'expected ["on"|"in"',
        ),
        ({"max_episode_steps": 0}, "max_episode_steps", "must be positive"),
        ({"count": {"default": "two"}}, "count.default", "expected an integer"),
        ({"scene": "moon_base"}, "scene", "unknown scene 'moon_base'"),
        ({"fixtures": {"table_1": {"pos": None}}}, "fixtures.table_1", "needs a 'pos'"),
    ],
)
def test_schema_errors_name_file_key_and_problem(tmp_path, patch, key, problem):
    path = write(tmp_path, broken(**patch))
    with pytest.raises(TaskFileError) as info:
        load_task(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {key}: "), msg
    assert problem in msg, msg


def test_invalid_json_names_line_and_column(tmp_path):
    path = write(tmp_path, '{"family": "Shelf3D",\n  "description": oops}')
    with pytest.raises(TaskFileError, match=r"custom.json: invalid JSON at line 2, column 18"):
        load_task(path)


def test_count_outside_the_range_and_count_without_template(tmp_path):
    path = write(tmp_path, MINIMAL)
    with pytest.raises(TaskFileError, match=r"num_objects must be in \[1, 5\].*got 9"):
        load_task(path, 9)
    no_count = {k: v for k, v in MINIMAL.items() if k != "count"}
    with pytest.raises(TaskFileError, match="'count' section"):
        load_task(write(tmp_path, no_count, "nocount.json"))


def test_unknown_fixture_frame_is_reported_when_building(tmp_path):
    path = write(tmp_path, broken(regions={"table_region": {"frame": "shelf:3"}}))
    with pytest.raises(
        TaskFileError, match=r"regions.table_region.frame: fixture 'table_1' has no frame 'shelf:3'"
    ):
        Dynamic3DEnv(path)


def test_templates_expand_per_index():
    task = load_task("Shelf3D/Shelf3D.json", num_objects=3)
    assert list(task.objects) == ["cube1", "cube2", "cube3"]
    assert task.objects["cube1"].params["rgba"] != task.objects["cube2"].params["rgba"]
    assert [p[1] for p in task.initial_state] == ["cupboard_1", "cube1", "cube2", "cube3"]
    assert [p[2] for p in task.initial_state][1:] == [
        f"ground_{i}_object_init_region" for i in (1, 2, 3)
    ]
    assert task.goal[0] == "and" and len(task.goal[1]) == 3
    assert task.instruction.startswith("Pick up the 3 cube(s)")
    sort = load_task(
        "SortClutteredBlocks3D/SortClutteredBlocks3D-sort_the_cluttered_blocks_into_bins.json", 8
    )
    goal_regions = [g[2] for g in sort.goal[1]]
    assert goal_regions[:5] == [
        "bin_red_goal_region", "bin_green_goal_region", "bin_blue_goal_region",
        "bin_yellow_goal_region", "bin_red_goal_region",
    ]  # fmt: skip


def test_variant_patches_apply_by_count():
    small = load_task("ConstrainedCupboard3D/ConstrainedCupboard3D.json", 2)
    assert sorted(small.fixtures) == ["cupboard_0", "cupboard_1", "cupboard_2"]
    assert {g[2] for g in small.goal[1]} == {"cupboard_1_shelf_0_goal_region"}
    wide = load_task("ConstrainedCupboard3D/ConstrainedCupboard3D.json", 5)
    assert len(wide.fixtures) == 11
    assert [g[2] for g in wide.goal[1]] == [f"cupboard_{i}_goal_region" for i in range(5)]
    assert wide.regions["cupboard_3_goal_region"].frame == "shelf:0"
    o20 = load_task(
        "SortClutteredBlocks3D/SortClutteredBlocks3D-sort_the_cluttered_blocks_into_bins.json", 20
    )
    o4 = load_task(
        "SortClutteredBlocks3D/SortClutteredBlocks3D-sort_the_cluttered_blocks_into_bins.json", 4
    )
    # o20 patches the cubes' colours and goals (blocks 1-5 red, ...), o4 cycles them.
    assert [g[2] for g in o20.goal[1]][4:6] == ["bin_red_goal_region", "bin_green_goal_region"]
    assert [g[2] for g in o4.goal[1]][:2] == ["bin_red_goal_region", "bin_green_goal_region"]


SWEEP = "SweepSimple3D/SweepSimple3D-sweep_the_blocks_to_the_left_side_of_the_kitchen_island.json"


def test_task_options_patch_the_task_after_the_variant(tmp_path):
    default, flat = load_task(SWEEP, 1), load_task(SWEEP, 1, ["flat_wiper"])
    assert default.objects["wiper_0"].params["upright"] is True
    assert flat.objects["wiper_0"].params["upright"] is False
    assert (default.objects["cube_0"].params["size"], flat.objects["cube_0"].params["size"]) == (
        0.02,
        0.01,
    )
    # o50's own patch makes the wiper 1 m tall; the option, applied after it, restores 30 cm.
    assert load_task(SWEEP, 50).objects["wiper_0"].params["handle_length"] == 1.0
    assert load_task(SWEEP, 50, ["flat_wiper"]).objects["wiper_0"].params["handle_length"] == 0.3
    with pytest.raises(
        TaskFileError, match=r"task option 'round_wiper' is not offered; this task offers \['flat"
    ):
        load_task(SWEEP, 1, ["round_wiper"])
    path = write(tmp_path, broken(options={"tall": {"patch": {}}}))
    with pytest.raises(
        TaskFileError, match=r"options\.tall\.description: expected a non-empty string"
    ):
        load_task(path)
    with pytest.raises(ValueError, match="task_options must be a sequence of option names"):
        Dynamic3DConfig(task_options="flat_wiper")  # type: ignore[arg-type]


CUPBOARD = "SortClutteredBlocks3D/SortClutteredBlocks3D-sort_the_blocks_into_the_cupboard.json"


def test_the_cupboard_variant_has_upstreams_objects_and_keeps_the_earlier_ones_as_an_option():
    """Upstream's cube and cuboid sizes are half extents: 4 cm cubes and 70 cm rods by default;
    ``half_size_objects`` gives the earlier 2 cm cubes and 35 cm rods."""
    default, half = load_task(CUPBOARD, 12), load_task(CUPBOARD, 12, ["half_size_objects"])
    assert default.objects["red_cube1"].params["size"] == 0.04
    assert default.objects["blue_cuboid1"].params["size"] == [0.03, 0.7, 0.03]
    assert half.objects["red_cube1"].params["size"] == 0.02
    assert half.objects["blue_cuboid1"].params["size"] == [0.015, 0.35, 0.015]
    # Upstream's goal heights: 2 cm above shelf 0, the whole 10 cm level on shelves 1 and 2.
    assert default.regions["cupboard_0_shelf_0_red_goal"].boxes[0][5] == 0.02
    assert default.regions["cupboard_0_shelf_1_green_goal"].boxes[0][5] == 0.1


def test_a_variant_can_have_its_own_step_limit(tmp_path):
    data = broken(
        max_episode_steps=300,
        variants={"o1": {"count": 1}, "o4": {"count": 4, "max_episode_steps": 900}},
    )
    path = write(tmp_path, data)
    assert load_task(path, 1).max_episode_steps == 300
    assert load_task(path, 4).max_episode_steps == 900
    data["variants"]["o4"]["max_episode_steps"] = 0
    with pytest.raises(TaskFileError, match=r"variants\.o4\.max_episode_steps: must be positive"):
        load_task(write(tmp_path, data), 4)
    # Registration reads the same number without loading the file.
    limits = {i.label: i.max_episode_steps for i in variant_table() if i.family == "Shelf3D"}
    assert set(limits.values()) == {1000}


def test_scene_is_patched_by_the_task():
    task = load_task("SweepIntoDrawer3D/SweepIntoDrawer3D.json")
    island = task.fixtures["kitchen_island"]
    assert island.kind == "cupboard" and island.params["working_drawers"] == [[1, 1]]
    assert task.fixtures["kitchen_cooking_area"].params["working_drawers"] == []


def test_every_bundled_file_loads_at_every_registered_count():
    table = variant_table()
    assert len(table) == 47
    for info in table:
        task = load_task(info.file, info.count)
        assert task.family == info.family
    assert len(list(task_files())) == 25


def test_merge_patch_follows_rfc7386():
    assert merge_patch({"a": 1, "b": {"c": 2, "d": 3}}, {"b": {"c": None, "e": 4}, "f": [1]}) == {
        "a": 1,
        "b": {"d": 3, "e": 4},
        "f": [1],
    }


def test_a_new_task_needs_no_python(tmp_path):
    """A user task file runs as is: placement from regions, the goal from predicates."""
    env = Dynamic3DEnv(write(tmp_path, MINIMAL), num_objects=3)
    try:
        state, info = env.reset(seed=4)
        assert info["success"] is False
        cubes = [env.objects[f"cube{i}"] for i in (1, 2, 3)]
        for cube in cubes:
            x, y, z = (state.get(cube, f) for f in ("x", "y", "z"))
            assert 0.3 <= x <= 0.5 and -0.3 <= y <= 0.3 and abs(z - 0.015) < 2e-3
        # Put every cube on the table top: the goal holds.
        on_table = state.copy()
        for k, cube in enumerate(cubes):
            on_table.set(cube, "x", 0.9 + 0.06 * k)
            on_table.set(cube, "y", 0.0)
            on_table.set(cube, "z", 0.4 + 0.015)
        assert env.goal_reached(on_table)
        assert np.isfinite(env.step(env.action_space.sample())[0].data).all()
    finally:
        env.close()


def test_a_centre_drop_draws_the_centre_height_and_may_start_below_the_floor(tmp_path):
    """``drop: centre`` (upstream's ground sampler for 4-value ranges): the box's z range bounds
    the object's centre, and a pose partly below the floor is accepted (the settle pushes the
    object out); ``drop: bottom`` never places it below the floor."""

    def start_heights(drop: str) -> list[float]:
        task = broken(
            regions={"floor_region": {"drop": drop, "boxes": [[0.3, -0.3, 0, 0.5, 0.3, 0.1]]}}
        )
        env = Dynamic3DEnv(
            task=write(tmp_path, task, f"{drop}.json"), config=Dynamic3DConfig(settle_actions=0)
        )
        out = []
        for seed in range(12):
            env.reset(seed=seed)
            out.append(float(env._qpos_of("cube1")[2]))
        return out

    centre = start_heights("centre")
    bottom = start_heights("bottom")
    assert min(centre) < 0.015 < max(centre) <= 0.1 + 1e-9  # some start partly below the floor
    assert min(bottom) >= 0.015 - 1e-9 and max(bottom) > 0.1
