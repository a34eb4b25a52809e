"""The policy-server path: wire format, server and client, and the ``vla`` agent end to end."""

from __future__ import annotations

import socket
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import kinder_core
from kinder_bench.baselines.vla import VLAAgent, VLAArgs
from kinder_bench.evaluation.runner import RunConfig, episode_seeds, run_benchmark
from kinder_bench.policy_server import wire
from kinder_bench.policy_server.client import PolicyClient, PolicyServerError
from kinder_bench.policy_server.replay import ReplayPolicy
from kinder_bench.policy_server.server import PolicyServer

MOTION = "kinder/Motion2D-p0-v0"


def test_wire_round_trip_keeps_arrays_exact() -> None:
    message = {
        "observation": {
            "image": np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3),
            "state": np.array([0.1, -2.5], dtype=np.float32),
            "count": np.int64(7),
        },
        "prompt": "reach the target",
        "batch_size": None,
        "list": [1, 2.5, "x"],
    }
    back = wire.unpackb(wire.packb(message))
    assert back["prompt"] == "reach the target"
    assert back["batch_size"] is None
    assert back["list"] == [1, 2.5, "x"]
    for key in ("image", "state"):
        sent, got = message["observation"][key], back["observation"][key]
        assert got.dtype == sent.dtype
        np.testing.assert_array_equal(got, sent)
    assert back["observation"]["count"] == 7
    assert isinstance(back["observation"]["count"], np.int64)


def test_wire_refuses_object_arrays_and_garbage() -> None:
    with pytest.raises(ValueError, match="object, void and complex"):
        wire.packb({"x": np.array([1 + 2j])})
    with pytest.raises(ValueError, match="msgpack"):
        wire.unpackb(b"\xc1 not msgpack")


class _Echo:
    def __init__(self) -> None:
        self.metadata: dict[str, Any] = {"policy": "echo"}

    def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
        if observation.get("fail"):
            raise RuntimeError("asked to fail")
        if observation.get("sleep"):
            time.sleep(float(observation["sleep"]))
        return {"actions": np.tile(observation["state"], (4, 1))}


def test_server_answers_metadata_actions_and_health() -> None:
    with PolicyServer(_Echo, port=0) as server:
        with urllib.request.urlopen(f"http://127.0.0.1:{server.port}/healthz", timeout=5) as r:
            assert r.status == 200
        with PolicyClient(server.url, timeout=5) as client:
            assert client.metadata == {"policy": "echo"}
            reply = client.infer({"state": np.array([1.0, 2.0])})
            np.testing.assert_array_equal(reply["actions"], [[1.0, 2.0]] * 4)
            assert reply["server_timing"]["infer_ms"] >= 0


def test_server_failure_and_timeout_become_clear_errors() -> None:
    with PolicyServer(_Echo, port=0) as server:
        with PolicyClient(server.url, timeout=5) as client:
            with pytest.raises(
                PolicyServerError, match="server failed: RuntimeError: asked to fail"
            ):
                client.infer({"state": np.zeros(1), "fail": True})
            # The server closed the connection after the failure.
            with pytest.raises(PolicyServerError, match="closed"):
                client.infer({"state": np.zeros(1)})
        with (
            PolicyClient(server.url, timeout=0.2) as client,
            pytest.raises(PolicyServerError, match=r"no reply within 0\.2 s"),
        ):
            client.infer({"state": np.zeros(1), "sleep": 1.0})


def test_client_reports_an_unreachable_server() -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(PolicyServerError, match="cannot connect"):
        PolicyClient(f"ws://127.0.0.1:{port}", timeout=2)


def _scripted_motion2d_episode(env_seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Robot states and actions of a straight-line run to the target (Motion2D-p0 has no walls)."""
    env = kinder_core.make(MOTION)
    obs, _ = env.reset(seed=env_seed)
    names = env.unwrapped.box_space.feature_names
    robot = [i for i, n in enumerate(names) if n.startswith("robot.")]
    rx, ry = names.index("robot.x"), names.index("robot.y")
    tx, ty = names.index("target_region.x"), names.index("target_region.y")
    states, actions = [obs[robot]], []
    for _ in range(300):
        goal = np.array([obs[tx] + 0.125, obs[ty] + 0.125])  # the region's centre
        delta = np.clip(goal - obs[[rx, ry]], -0.05, 0.05)
        action = np.array([delta[0], delta[1], 0.0, 0.0, 0.0])
        obs, _, terminated, _, _ = env.step(action)
        actions.append(action)
        states.append(obs[robot])
        if terminated:
            return np.array(states), np.array(actions)
    raise AssertionError("the scripted run did not reach the target")


def test_vla_agent_reproduces_a_demonstration_through_the_runner(tmp_path: Path) -> None:
    env_seed = episode_seeds(0, 1)[0]
    states, actions = _scripted_motion2d_episode(env_seed)
    with PolicyServer(lambda: ReplayPolicy(states, actions, horizon=10), port=0) as server:
        out = run_benchmark(
            [RunConfig(MOTION, "vla", {"url": server.url}, (0,), 1, max_steps=400)],
            tmp_path / "run",
            executor="inline",
            progress=False,
        )
    (record,) = out.records
    assert record["error"] is None
    assert record["success"]
    assert record["steps"] == len(actions)


def test_vla_agent_fails_clearly_on_server_errors(tmp_path: Path) -> None:
    class Malformed:
        def __init__(self) -> None:
            self.metadata: dict[str, Any] = {}

        def infer(self, observation: dict[str, Any]) -> dict[str, Any]:
            return {"actions": np.zeros((4, 2))}  # Motion2D needs 5 action dimensions

    with PolicyServer(Malformed, port=0) as server:
        out = run_benchmark(
            [RunConfig(MOTION, "vla", {"url": server.url}, (0,), 1, max_steps=20)],
            tmp_path / "run",
            executor="inline",
            progress=False,
        )
    (record,) = out.records
    assert not record["success"]
    assert "AgentFailure" in record["error"] and "(4, 2)" in record["error"]


def test_vla_agent_needs_a_url() -> None:
    env = kinder_core.make(MOTION)
    with pytest.raises(ValueError, match="needs a policy server"):
        VLAAgent(env, VLAArgs(), seed=0)


def test_vla_agent_says_it_needs_a_server() -> None:
    assert "needs a policy server" in str(VLAAgent.unavailable(VLAArgs(), MOTION))
    assert VLAAgent.unavailable(VLAArgs(url="ws://127.0.0.1:8000"), MOTION) is None


def test_vla_sends_the_overview_image_by_default_and_all_cameras_as_a_variant() -> None:
    """Upstream's 3D evaluation sent the overview image only, and so does the default;
    ``cameras=all`` sends the three cameras of our openpi export, the overview one last."""
    env = kinder_core.make("kinder/BaseMotion3D-v0")
    obs, _ = env.reset(seed=1000)
    assert VLAArgs().cameras == "overview"
    only = VLAAgent(env, VLAArgs(url="ws://127.0.0.1:1"), seed=0).request(obs)["observation"]
    every = VLAAgent(env, VLAArgs(url="ws://127.0.0.1:1", cameras="all"), seed=0)
    three = every.request(obs)["observation"]
    assert {"base_0_rgb", "left_wrist_0_rgb", "right_wrist_0_rgb"} <= set(three)
    assert "left_wrist_0_rgb" not in only and "right_wrist_0_rgb" not in only
    np.testing.assert_array_equal(only["base_0_rgb"], three["right_wrist_0_rgb"])
    assert not np.array_equal(three["base_0_rgb"], three["right_wrist_0_rgb"])
    with pytest.raises(ValueError, match="cameras must be one of"):
        VLAArgs(url="ws://127.0.0.1:1", cameras="wrist")
