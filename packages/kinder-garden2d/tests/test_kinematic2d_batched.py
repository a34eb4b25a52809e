"""The batched Kinematic2D vector env equals the single env, bit for bit.

Every comparison runs Gymnasium's own ``SyncVectorEnv`` of the single env (``make_vec(...,
vectorization_mode="sync")``) beside the batched env (``vectorization_mode="vector_entry_point"``)
on the same seeds and actions: observations, rewards, terminations, truncations and
``info["success"]`` must be equal arrays (``np.array_equal``, no tolerance), through collisions,
grasps, pushes, presses, goal states, truncations and autoresets.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import VectorEnv

from kinder_core import ObjectCentricState, list_envs
from kinder_garden2d.kinematic2d.batched.kernels import py_hypot
from kinder_garden2d.kinematic2d.batched.vector_env import Kinematic2DVectorEnv
from kinder_garden2d.kinematic2d.object_types import BUTTON_GREEN, BUTTON_RED

IDS = list_envs("Kinematic2D")
FAMILY_IDS = [
    "kinder/Motion2D-p3-v0",
    "kinder/Obstruction2D-o4-v0",
    "kinder/ClutteredRetrieval2D-o10-v0",
    "kinder/ClutteredStorage2D-b7-v0",
    "kinder/StickButton2D-b5-v0",
    "kinder/PushPullHook2D-v0",
]
Policy = Callable[[VectorEnv[Any, Any, Any], np.ndarray, int], np.ndarray]


def make_pair(
    env_id: str, n: int, max_steps: int | None = 40
) -> tuple[Kinematic2DVectorEnv, VectorEnv[Any, Any, Any]]:
    batched = gymnasium.make_vec(
        env_id, n, vectorization_mode="vector_entry_point", max_episode_steps=max_steps
    )
    sync = gymnasium.make_vec(env_id, n, vectorization_mode="sync", max_episode_steps=max_steps)
    assert isinstance(batched, Kinematic2DVectorEnv)
    return batched, sync


def assert_same(out_b: tuple[Any, ...], out_s: tuple[Any, ...], where: str) -> None:
    names = ("observations", "rewards", "terminations", "truncations")
    for name, b, s in zip(names, out_b[:4], out_s[:4]):
        assert b.dtype == s.dtype, f"{where}: {name} dtype {b.dtype} != {s.dtype}"
        assert np.array_equal(b, s), f"{where}: {name} differ in sub-envs " + str(
            np.flatnonzero((b != s).reshape(len(b), -1).any(axis=1))
        )
    assert np.array_equal(out_b[-1]["success"], out_s[-1]["success"]), f"{where}: success"


def random_policy(seed: int, hold: int = 5) -> Policy:
    """Uniform actions (a little beyond the bounds, to exercise clipping), each kept for
    ``hold`` steps so that the robot reaches walls and objects; the vacuum is on 70 % of the
    time."""
    rng = np.random.default_rng(seed)
    current: list[np.ndarray] = []

    def policy(env: VectorEnv[Any, Any, Any], obs: np.ndarray, t: int) -> np.ndarray:
        space = env.single_action_space
        if t % hold == 0 or not current:
            a = rng.uniform(space.low * 1.2, space.high * 1.2, (env.num_envs, 5))
            a[:, 4] = rng.uniform(size=env.num_envs) < 0.7
            current[:] = [a]
        return current[0].astype(np.float32)

    return policy


def seek_policy(env: Kinematic2DVectorEnv, seed: int, phase: int = 30) -> Policy:
    """Drive at an object with the arm pointed at it, extended and sucking (grasps, pushes,
    presses), then carry towards a random point (collisions of held objects); the target
    changes every ``phase`` steps."""
    rng = np.random.default_rng(seed)
    box = env.single_observation_space
    col: dict[str, int] = {}
    k = 0
    for o in box.objects:
        for f in o.type.features:
            col[f"{o.name}.{f}"] = k
            k += 1
    names = [o.name for o in box.objects if o.name != "robot"]
    xmin, xmax, ymin, ymax = env.env.config.world_bounds
    n = env.num_envs
    target = np.zeros((n, 2))
    chosen = np.zeros(n, dtype=np.intp)
    carrying = np.zeros(n, dtype=bool)

    def policy(_: VectorEnv[Any, Any, Any], obs: np.ndarray, t: int) -> np.ndarray:
        if t % phase == 0:
            carrying[:] = (t // phase) % 2 == 1
            chosen[:] = rng.integers(len(names), size=n)
            # Points a little beyond the world too: the walls stop the robot.
            target[:] = rng.uniform([xmin - 0.3, ymin - 0.3], [xmax + 0.3, ymax + 0.3], (n, 2))
        goal = target.copy()
        for i in np.flatnonzero(~carrying):
            name = names[chosen[i]]
            goal[i] = obs[i, col[f"{name}.x"]], obs[i, col[f"{name}.y"]]
        rx, ry, rth = obs[:, col["robot.x"]], obs[:, col["robot.y"]], obs[:, col["robot.theta"]]
        dx, dy = goal[:, 0] - rx, goal[:, 1] - ry
        turn = (np.arctan2(dy, dx) - rth + np.pi) % (2 * np.pi) - np.pi
        a = np.stack(
            [
                np.clip(dx, -0.05, 0.05),
                np.clip(dy, -0.05, 0.05),
                np.clip(turn, -np.pi / 16, np.pi / 16),
                np.full(n, 0.1),
                np.ones(n),
            ],
            axis=1,
        )
        a[:, :3] += rng.normal(0.0, 0.01, (n, 3))
        return a

    return policy


def run(
    env_id: str,
    policy_of: Callable[[Kinematic2DVectorEnv], Policy],
    n: int,
    steps: int,
    seed: int,
    max_steps: int = 40,
) -> dict[str, int]:
    """Step both envs with the same actions; return counts of what the run went through."""
    batched, sync = make_pair(env_id, n, max_steps)
    out_b = batched.reset(seed=seed)
    out_s = sync.reset(seed=seed)
    assert np.array_equal(out_b[0], out_s[0]), f"{env_id}: reset observations differ"
    assert np.array_equal(out_b[1]["success"], out_s[1]["success"])
    policy = policy_of(batched)
    counts = {"ended": 0, "terminated": 0, "blocked": 0, "moved_objects": 0}
    obs = out_b[0]
    robot = slice(0, 9)
    for t in range(steps):
        a = policy(batched, obs, t)
        stepped = ~batched._autoreset  # the others reset on this step
        b = batched.step(a)
        s = sync.step(a)
        assert_same(b, s, f"{env_id} step {t}")
        counts["ended"] += int(np.sum(b[2] | b[3]))
        counts["terminated"] += int(np.sum(b[2]))
        still = np.all(b[0][:, robot] == obs[:, robot], axis=1)
        counts["blocked"] += int(np.sum(still & stepped & (np.abs(a[:, :2]).max(axis=1) > 0.01)))
        counts["moved_objects"] += int(np.sum(np.any(b[0][:, 9:] != obs[:, 9:], axis=1)))
        obs = b[0]
    batched.close()
    sync.close()
    return counts


@pytest.mark.parametrize("env_id", IDS)
def test_random_actions_match_the_single_env(env_id: str) -> None:
    counts = run(env_id, lambda env: random_policy(1000), n=4, steps=90, seed=1000)
    assert counts["ended"] > 0  # truncations at 40 steps, then autoresets
    assert counts["blocked"] > 0  # collisions were reverted


@pytest.mark.parametrize("env_id", IDS)
def test_purposeful_actions_match_the_single_env(env_id: str) -> None:
    motion = env_id.startswith("kinder/Motion2D")
    # Motion2D's target lies about 40 steps from the start: longer phases and episodes.
    phase, max_steps = (45, 100) if motion else (30, 40)
    policy = lambda env: seek_policy(env, 1001, phase)  # noqa: E731
    counts = run(env_id, policy, n=4, steps=90, seed=1100, max_steps=max_steps)
    if motion:
        assert counts["blocked"] + counts["terminated"] > 0  # a passage wall, or the goal
    else:
        assert counts["moved_objects"] > 0  # grasped, pushed or pressed something


@pytest.mark.slow
@pytest.mark.parametrize("env_id", IDS)
def test_many_seeds_match_the_single_env(env_id: str) -> None:
    """Property test: 64 sub-envs (seeds 2000-2063), random and purposeful actions."""
    run(env_id, lambda env: random_policy(2000), n=64, steps=120, seed=2000)
    run(env_id, lambda env: seek_policy(env, 2001), n=64, steps=120, seed=3000)


def _near_goal(env_id: str, state: ObjectCentricState, rng: np.random.Generator) -> None:
    """Edit a state (in place) to satisfy its family's goal, or miss it narrowly."""
    env: Any = gymnasium.make(env_id).unwrapped
    jitter = float(rng.choice([0.0, 1e-3, 0.02, 0.1]))

    def put(obj: Any, **features: float) -> None:
        for f, v in features.items():
            state.set(obj, f, v + rng.normal(0.0, jitter))

    if env_id.startswith("kinder/Motion2D"):
        g = env.target_region
        put(env.robot, x=state.get(g, "x") + 0.12, y=state.get(g, "y") + 0.12)
    elif env_id.startswith("kinder/Obstruction2D"):
        s = env.target_surface
        put(env.target_block, x=state.get(s, "x") + 0.01, y=0.1 + 1e-6, theta=0.0)
        state.set(env.target_block, "width", state.get(s, "width") - 0.02)
    elif env_id.startswith("kinder/ClutteredRetrieval2D"):
        g = env.target_region
        th = state.get(g, "theta")
        off = np.array([np.cos(th) - np.sin(th), np.sin(th) + np.cos(th)]) * 0.035
        put(env.target_block, x=state.get(g, "x") + off[0], y=state.get(g, "y") + off[1], theta=th)
    elif env_id.startswith("kinder/ClutteredStorage2D"):
        sh = env.shelf
        for b in env.blocks:
            put(b, x=state.get(sh, "x1") + 0.01, y=state.get(sh, "y1") + 0.05, theta=0.0)
    else:  # buttons: press some or all
        buttons = getattr(env, "buttons", None) or [env.movable_button, env.target_button]
        for b in buttons:
            if rng.uniform() < 0.9:
                for f, v in zip(("color_r", "color_g", "color_b"), BUTTON_GREEN):
                    state.set(b, f, v)


@pytest.mark.parametrize("env_id", IDS)
def test_goal_states_terminate_and_autoreset_alike(env_id: str) -> None:
    """Sub-envs set to (near-)goal states: the goal test, the terminal reward, the success info
    and the next step's autoreset match."""
    n = 8
    rng = np.random.default_rng(1200)
    batched, sync = make_pair(env_id, n)
    batched.reset(seed=1200)
    sync.reset(seed=1200)
    for i in range(n):
        state = batched.get_state(i)
        _near_goal(env_id, state, rng)
        batched.set_state(i, state)
        sync.envs[i].unwrapped.set_state(state)  # type: ignore[attr-defined]
    zero = np.zeros((n, 5), dtype=np.float32)
    first = batched.step(zero)
    assert_same(first, sync.step(zero), f"{env_id} goal step")
    assert first[2].any()  # some sub-envs reached the goal
    assert_same(batched.step(zero), sync.step(zero), f"{env_id} autoreset step")


def _hook_states(n: int, rng: np.random.Generator) -> list[ObjectCentricState]:
    """PushPullHook2D states with the hook held and the movable button just above its short arm
    (jittered), so that pushing up moves the button into the target button."""
    env: Any = gymnasium.make("kinder/PushPullHook2D-v0").unwrapped
    out = []
    for k in range(n):
        s, _ = env.reset(seed=1300 + k)
        rx, ry, ay = 1.0 + rng.uniform(-0.1, 0.1), 0.8, 1.6
        for f, v in (("x", rx), ("y", ry), ("theta", 0.0), ("vacuum", 1.0)):
            s.set(env.robot, f, v)
        s.set(env.robot, "arm_joint", s.get(env.robot, "base_radius"))
        ax = rx + 0.11
        for f, v in (("x", ax), ("y", ay), ("theta", np.pi / 2)):
            s.set(env.hook, f, v)
        s.set(env.movable_button, "x", ax + 0.3 + rng.uniform(-0.05, 0.05))
        s.set(env.movable_button, "y", 1.6 + 0.05 + rng.uniform(0.0, 0.02))
        s.set(env.target_button, "x", ax + 0.3)
        s.set(env.target_button, "y", 1.74 + rng.uniform(0.0, 0.05))
        for b in (env.movable_button, env.target_button):
            for f, v in zip(("color_r", "color_g", "color_b"), BUTTON_RED):
                s.set(b, f, v)
        out.append(s)
    return out


def test_hook_pushes_and_presses_alike() -> None:
    n = 8
    rng = np.random.default_rng(1300)
    batched, sync = make_pair("kinder/PushPullHook2D-v0", n)
    batched.reset(seed=1300)
    sync.reset(seed=1300)
    for i, s in enumerate(_hook_states(n, rng)):
        batched.set_state(i, s)
        sync.envs[i].unwrapped.set_state(s)  # type: ignore[attr-defined]
    terminated = 0
    y0 = np.array([batched.get_state(i).get(batched.env.movable_button, "y") for i in range(n)])
    for t in range(30):
        a = np.tile([0.0, 0.05, 0.0, 0.0, 1.0], (n, 1))
        a[:, :3] += rng.normal(0.0, 0.01, (n, 3))
        b = batched.step(a)
        assert_same(b, sync.step(a), f"hook step {t}")
        terminated += int(b[2].sum())
        if t == 0:
            y1 = np.array(
                [batched.get_state(i).get(batched.env.movable_button, "y") for i in range(n)]
            )
            assert np.any(y1 != y0)  # the held hook pushed buttons
    assert terminated > 0


def test_reset_seeds_sub_env_i_with_s_plus_i() -> None:
    env_id = "kinder/Obstruction2D-o2-v0"
    batched = gymnasium.make_vec(env_id, 3, vectorization_mode="vector_entry_point")
    obs, _ = batched.reset(seed=1400)
    for i in range(3):
        single = gymnasium.make(env_id)
        assert np.array_equal(obs[i], single.reset(seed=1400 + i)[0])
    again, _ = batched.reset(seed=1400)
    assert np.array_equal(obs, again)
    listed, _ = batched.reset(seed=[1401, 1402, 1403])
    assert np.array_equal(listed[:2], obs[1:])
    with pytest.raises(ValueError, match="expected one int, None or 3 seeds"):
        batched.reset(seed=[1, 2])


def test_truncation_and_autoreset_follow_gymnasium() -> None:
    batched, sync = make_pair("kinder/Motion2D-p1-v0", 2, max_steps=3)
    batched.reset(seed=1500)
    sync.reset(seed=1500)
    zero = np.zeros((2, 5))
    for t in range(3):
        b = batched.step(zero)
        assert_same(b, sync.step(zero), f"step {t}")
    assert b[3].all() and not b[2].any()
    nxt = batched.step(zero)  # the autoreset step: new episodes, reward 0, action ignored
    assert_same(nxt, sync.step(zero), "autoreset")
    assert np.all(nxt[1] == 0.0) and not nxt[3].any()


def test_bad_actions_raise_the_single_envs_errors() -> None:
    batched = gymnasium.make_vec(
        "kinder/Motion2D-p0-v0", 2, vectorization_mode="vector_entry_point"
    )
    with pytest.raises(RuntimeError, match="call reset"):
        batched.step(np.zeros((2, 5)))
    batched.reset(seed=1600)
    with pytest.raises(ValueError, match=r"shape \(2, 4\); expected shape \(2, 5\)"):
        batched.step(np.zeros((2, 4)))
    bad = np.zeros((2, 5))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="sub-env 1's action contains NaN or inf"):
        batched.step(bad)
    single = gymnasium.make("kinder/Motion2D-p0-v0")
    single.reset(seed=1600)
    with pytest.raises(ValueError, match="action contains NaN or inf"):
        single.step(bad[1])
    with pytest.raises(ValueError, match="not numeric"):
        batched.step([["a"] * 5] * 2)


def test_bad_construction_is_refused() -> None:
    entry = "kinder_garden2d.kinematic2d.motion2d:Motion2DEnv"
    with pytest.raises(ValueError, match="num_envs must be an int >= 1"):
        Kinematic2DVectorEnv(0, entry)
    with pytest.raises(ValueError, match="render_mode"):
        Kinematic2DVectorEnv(2, entry, render_mode="human")
    with pytest.raises(ValueError, match="sub-env index"):
        Kinematic2DVectorEnv(2, entry, render_index=2)
    with pytest.raises(ValueError, match="not a Kinematic2D env"):
        Kinematic2DVectorEnv(2, "kinder_garden2d.dynamic2d.dyn_obstruction2d:DynObstruction2DEnv")


def test_render_draws_one_sub_env() -> None:
    env_id = "kinder/StickButton2D-b1-v0"
    batched = gymnasium.make_vec(
        env_id, 3, vectorization_mode="vector_entry_point", render_mode="rgb_array", render_index=2
    )
    batched.reset(seed=1700)
    (frame,) = batched.render()
    single = gymnasium.make(env_id, render_mode="rgb_array")
    single.reset(seed=1702)
    assert np.array_equal(frame, single.render())
    assert np.array_equal(batched.render_env(0), (single.reset(seed=1700), single.render())[1])


def test_spaces_are_the_box_views() -> None:
    batched = gymnasium.make_vec(
        "kinder/ClutteredStorage2D-b3-v0", 5, vectorization_mode="vector_entry_point"
    )
    single = gymnasium.make("kinder/ClutteredStorage2D-b3-v0")
    assert batched.single_observation_space == single.observation_space
    assert batched.single_action_space == single.action_space
    assert batched.observation_space.shape == (5, *single.observation_space.shape)
    assert batched.metadata["autoreset_mode"] == single.metadata["autoreset_mode"]


def test_py_hypot_is_math_hypot() -> None:
    import math

    rng = np.random.default_rng(1800)
    x = rng.normal(size=20_000) * rng.choice([1e-3, 1.0, 1e3], 20_000)
    y = rng.normal(size=20_000) * rng.choice([1e-3, 1.0, 1e3], 20_000)
    x[:3], y[:3] = [0.0, 3.0, 0.0], [0.0, 4.0, -2.0]
    expected = np.array([math.hypot(a, b) for a, b in zip(x.tolist(), y.tolist())])
    assert np.array_equal(py_hypot(x, y), expected)
    assert not np.array_equal(np.hypot(x, y), expected)  # why py_hypot exists
