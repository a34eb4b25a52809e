"""The foundation-model planners: parser, chat client, prompts, agents, and the oracle runs.

Nothing here reaches the internet: the model is a local OpenAI-compatible HTTP server
(``fm_test_server.ChatServer``) answering from a script. Prompt snapshots live in
``tests/snapshots/fm_prompts``; regenerate them with ``KINDER_UPDATE_SNAPSHOTS=1``.
"""

from __future__ import annotations

import base64
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from kinder_bench.agents import AGENTS, agent_class, describe_args, make_agent
from kinder_bench.agents.base import AgentFailure
from kinder_bench.baselines.bilevel_planning import plan_episode, use_model
from kinder_bench.baselines.fm_planning.agents import FMPlanningAgent
from kinder_bench.baselines.fm_planning.client import CacheMiss, ChatClient, ChatError
from kinder_bench.baselines.fm_planning.parser import parse_plan
from kinder_bench.baselines.fm_planning.prompts import (
    build_prompt,
    format_call,
    format_state,
    make_examples,
    plan_calls,
    render_examples,
)
from kinder_bench.baselines.fm_planning.scripted_server import (
    ChatServer,
    oracle_answers,
    prompt_text,
    table_responder,
)
from kinder_bench.baselines.random_agent import RandomAgent
from kinder_bench.evaluation.protocol import PAPER_ENVS
from kinder_bench.evaluation.runner import TIMING_FIELDS, RunConfig, episode_seeds, run_benchmark
from kinder_core import make_object_centric
from kinder_core.wrappers import BoxObservation
from kinder_gym.models import create_model
from kinder_gym.testing import ToyPlaceEnv, make_toy_model

SNAPSHOTS = Path(__file__).parent / "snapshots" / "fm_prompts"
UPDATE = os.environ.get("KINDER_UPDATE_SNAPSHOTS") == "1"

TOY_PLAN = """The obstruction sits in the region, so move it out first.
Plan:
Pick(robot:robot, obstruction:block)[]
PlaceOut(robot:robot, obstruction:block, region:region)[0.62]
Pick(robot:robot, target:target_block)[]
PlaceIn(robot:robot, target:target_block, region:region)[0.9]
"""


def _toy_state() -> tuple[ToyPlaceEnv, Any, Any]:
    env = ToyPlaceEnv()
    x0, _ = env.reset(seed=0)
    return env, make_toy_model(env), x0


# -- parser ---------------------------------------------------------------------------------------


def test_parser_reads_a_good_plan() -> None:
    _, model, x0 = _toy_state()
    parsed = parse_plan(TOY_PLAN, model, x0)
    assert parsed.found_plan
    assert [c.skill for c in parsed.calls] == ["Pick", "PlaceOut", "Pick", "PlaceIn"]
    assert parsed.calls[1].objects == ("robot", "obstruction", "region")
    assert parsed.calls[1].params == (0.62,)
    assert parsed.dropped == [] and parsed.clipped == []


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("Pick(robot:robot, ghost:block)[]", "unknown object 'ghost'"),
        ("Pick(robot:robot, obstruction:brick)[]", "unknown type 'brick'"),
        ("Pick(robot:robot, target:block)[]", "target is a target_block, not a block"),
        ("Pick(robot:robot, region:region)[]", "region is not a block"),
        ("Pick(robot:robot)[]", "Pick takes 2 object(s), the line gives 1"),
        ("Pick(robot, obstruction)[]", "'robot' is not of the form object:type"),
    ],
)
def test_parser_drops_a_bad_line_and_goes_on(line: str, reason: str) -> None:
    _, model, x0 = _toy_state()
    text = f"Plan:\n{line}\nPick(robot:robot, target:target_block)[]\n"
    parsed = parse_plan(text, model, x0)
    assert [c.objects for c in parsed.calls] == [("robot", "target")]
    (dropped,) = parsed.dropped
    assert dropped["line"] == line and dropped["effect"] == "dropped"
    assert dropped["reason"].startswith(reason)


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("1. Pick(robot:robot, target:target_block)[]", "'1. Pick' is not a known skill"),
        ("Fly(robot:robot)[]", "'Fly' is not a known skill"),
        ("PlaceIn(robot:robot, target:target_block, region:region)[0.9, 1.0]", "takes 1 finite"),
        ("PlaceIn(robot:robot, target:target_block, region:region)", "takes 1 finite"),
        ("Pick(robot:robot, target:target_block)[0.5]", "takes 0 finite"),
        ("PlaceIn(robot:robot, target:target_block, region:region)[x]", "not a bracketed list"),
        ("PlaceIn(robot:robot, target:target_block, region:region)[nan]", "takes 1 finite"),
    ],
)
def test_parser_stops_at_a_bad_line(line: str, reason: str) -> None:
    _, model, x0 = _toy_state()
    first, last = "Pick(robot:robot, obstruction:block)[]", "Pick(robot:robot, target:target_block)"
    text = f"Plan:\n{first}\n{line}\n{last}\n"
    parsed = parse_plan(text, model, x0)
    assert len(parsed.calls) == 1
    assert parsed.dropped[0]["line"] == line and parsed.dropped[0]["effect"] == "stopped"
    assert reason in parsed.dropped[0]["reason"]
    assert parsed.dropped[1] == {
        "line": "Pick(robot:robot, target:target_block)",
        "reason": "after a line that stopped parsing",
        "effect": "stopped",
    }


def test_parser_clips_skips_blank_lines_and_reads_emphasised_heading() -> None:
    _, model, x0 = _toy_state()
    text = (
        "Reasoning with a Plan: inside a sentence.\n**Plan:**\n\n"
        "Pick(robot:robot, target:target_block)\n\n"
        "PlaceIn(robot:robot, target:target_block, region:region)[ 7.5 ]\n"
    )
    parsed = parse_plan(text, model, x0)
    assert [c.skill for c in parsed.calls] == ["Pick", "PlaceIn"]
    assert parsed.calls[1].params == (1.2,)
    assert parsed.clipped == [
        {
            "line": "PlaceIn(robot:robot, target:target_block, region:region)[ 7.5 ]",
            "given": [7.5],
            "clipped": [1.2],
        }
    ]
    no_plan = parse_plan("Pick(robot:robot, target:target_block)[]", model, x0)
    assert not no_plan.found_plan and no_plan.calls == []


def test_plan_lines_round_trip_through_the_parser() -> None:
    _, model, x0 = _toy_state()
    calls = parse_plan(TOY_PLAN, model, x0).calls
    text = "Plan:\n" + "\n".join(format_call(c, x0) for c in calls)
    assert parse_plan(text, model, x0).calls == calls


# -- client ---------------------------------------------------------------------------------------


def _hello(request: dict[str, Any]) -> str:
    return f"echo {len(prompt_text(request))}"


def test_client_caches_by_the_full_request(tmp_path: Path) -> None:
    with ChatServer(_hello) as server:
        client = ChatClient("m", base_url=server.base_url, cache_dir=tmp_path, backoff=0)
        msgs = [{"role": "user", "content": "hi"}]
        first = client.complete(client.make_request(msgs, 1.0, seed=3))
        again = client.complete(client.make_request(msgs, 1.0, seed=3))
        other = client.complete(client.make_request(msgs, 1.0, seed=4))
        assert len(server.requests) == 2
    assert (first.cached, again.cached, other.cached) == (False, True, False)
    assert first.text == again.text == "echo 2"
    assert first.key == again.key != other.key
    assert first.usage == {"prompt_tokens": 1, "completion_tokens": 2, "total_tokens": 3}
    stored = json.loads(client.cache_path(first.key).read_text())
    assert stored["request"]["seed"] == 3 and stored["response"]["text"] == "echo 2"
    assert server.requests[0]["seed"] == 3 and server.requests[0]["temperature"] == 1.0
    # Cache-only: a hit needs no server, a miss names the request.
    replay = ChatClient(
        "m", base_url="http://127.0.0.1:9/v1", cache_dir=tmp_path, cache_mode="only"
    )
    assert replay.complete(replay.make_request(msgs, 1.0, seed=3)).text == "echo 2"
    with pytest.raises(
        CacheMiss, match=r"cache-only mode: no cached response for request [0-9a-f]{64}.*'hi'"
    ):
        replay.complete(replay.make_request(msgs, 1.0, seed=5))
    client.cache_path(first.key).write_text("{")
    with pytest.raises(ChatError, match="is not a cache entry"):
        replay.complete(replay.make_request(msgs, 1.0, seed=3))


def test_client_retries_transient_errors_only(tmp_path: Path) -> None:
    msgs = [{"role": "user", "content": "hi"}]
    with ChatServer(_hello, fail_first=(429, 500, 503)) as server:
        client = ChatClient("m", base_url=server.base_url, cache_mode="off", backoff=0)
        response = client.complete(client.make_request(msgs))
        assert response.attempts == 4 and response.text == "echo 2"
    with ChatServer(_hello, fail_first=(500, 500, 500)) as server:
        client = ChatClient(
            "m", base_url=server.base_url, cache_mode="off", backoff=0, max_retries=2
        )
        with pytest.raises(ChatError, match="InternalServerError after 3 attempt"):
            client.complete(client.make_request(msgs))
    with ChatServer(_hello, fail_first=(400,)) as server:
        client = ChatClient("m", base_url=server.base_url, cache_dir=tmp_path, backoff=0)
        with pytest.raises(ChatError, match=r"BadRequestError .*not retried"):
            client.complete(client.make_request(msgs))
        assert len(server.requests) == 1
    assert not list(tmp_path.rglob("*.json"))  # failures are not cached


def test_client_rejects_bad_settings() -> None:
    with pytest.raises(ValueError, match="cache_mode must be one of"):
        ChatClient("m", cache_mode="sometimes")
    with pytest.raises(ValueError, match="cache_mode must be one of"):
        make_agent("llm_plan", BoxObservation(ToyPlaceEnv()), {"cache_mode": "x"})


# -- prompts --------------------------------------------------------------------------------------


def _check_snapshot(name: str, text: str) -> None:
    path = SNAPSHOTS / name
    if UPDATE:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert path.exists(), f"no snapshot {path}; run with KINDER_UPDATE_SNAPSHOTS=1 to write it"
    assert text == path.read_text(), f"{name} differs from its snapshot (KINDER_UPDATE_SNAPSHOTS=1)"


def _short(env_id: str) -> str:
    return env_id.removeprefix("kinder/").removesuffix("-v0")


@pytest.mark.parametrize("env_id", PAPER_ENVS)
def test_plan_prompt_snapshot(env_id: str) -> None:
    env = make_object_centric(env_id)
    x0, _ = env.reset(seed=0)
    model = create_model(env)
    prompt = build_prompt(env, model, x0)
    _check_snapshot(f"{_short(env_id)}.plan.txt", prompt)
    for skill in model.skills:
        assert f"{skill.name}(types=[" in prompt
    assert format_state(x0) in prompt
    assert "In-context examples" not in prompt


def test_parameter_lines_are_a_variant_off_by_default() -> None:
    """The paper's template lists the skills without what their parameters mean; our line per
    skill is an option, off by default."""
    env = make_object_centric("kinder/StickButton2D-b1-v0")
    x0, _ = env.reset(seed=0)
    model = create_model(env)
    assert "parameters:" not in build_prompt(env, model, x0)
    with_lines = build_prompt(env, model, x0, parameter_lines=True)
    for skill in model.skills:
        assert f"    parameters: {' '.join(skill.controller_cls.params_doc.split())}" in with_lines
    for name in ("llm_plan", "vlm_plan", "llm_con", "vlm_con"):
        assert agent_class(name).Args().parameter_lines is False


@pytest.mark.parametrize("env_id", ["kinder/Motion2D-p0-v0", "kinder/StickButton2D-b1-v0"])
def test_con_prompt_snapshot(env_id: str, tmp_path: Path) -> None:
    env = make_object_centric(env_id)
    x0, _ = env.reset(seed=0)
    examples = make_examples(env_id, 4, cache_dir=tmp_path)
    assert len(examples) == 4
    assert all(e.env_seed not in episode_seeds(s, 50) for e in examples for s in range(5))
    prompt = build_prompt(env, create_model(env), x0, render_examples(examples))
    _check_snapshot(f"{_short(env_id)}.con.txt", prompt)
    assert "Example 4:" in prompt and "Completed plans: No plan has yet been executed." in prompt
    assert make_examples(env_id, 4, cache_dir=tmp_path) == examples  # from the disk cache
    assert len(list((tmp_path / "examples").iterdir())) == 1


# -- agents ---------------------------------------------------------------------------------------


def test_agents_are_registered_with_their_arguments() -> None:
    for name in ("llm_plan", "vlm_plan", "llm_con", "vlm_con"):
        cls = agent_class(name)
        assert (
            issubclass(cls, FMPlanningAgent)
            and cls.name == name
            and AGENTS[name].endswith(cls.__name__)
        )
        docs = {n: d for n, _, _, d in describe_args(cls)}
        assert docs["model"] and docs["cache_mode"]
        assert ("num_examples" in docs) == name.endswith("_con")


def _drive(agent: Any, env: Any, seed: int, steps: int = 300) -> tuple[bool, str | None]:
    obs, info = env.reset(seed=seed)
    try:
        agent.reset(obs, info)
        for _ in range(steps):
            obs, _, terminated, truncated, _ = env.step(agent.act(obs))
            if terminated:
                return True, None
            if truncated:
                break
    except AgentFailure as e:
        return False, str(e)
    return False, "out of steps"


def _toy_agent(name: str, server: ChatServer, tmp_path: Path) -> tuple[Any, Any]:
    env = BoxObservation(ToyPlaceEnv())
    use_model(env.unwrapped, make_toy_model(env.unwrapped))  # type: ignore[arg-type]
    args = {"base_url": server.base_url, "cache_dir": str(tmp_path), "backoff": 0.0}
    return make_agent(name, env, args, seed=0), env


@pytest.mark.parametrize(
    ("answer", "failure"),
    [
        (TOY_PLAN, None),
        ("I am not sure.", "empty plan (no 'Plan:' line; 0 line(s) dropped)"),
        ("Plan:\nPick(robot:robot, ghost:block)[]", "empty plan (no valid plan line; 1 line"),
        ("Plan:\nPick(robot:robot, obstruction:block)[]", "the plan ran out after 1 skill(s)"),
        (
            "Plan:\nPick(robot:robot, obstruction:block)[]\n"
            "PlaceOut(robot:robot, obstruction:block, region:region)[{target_x}]",
            "skill PlaceOut(robot:robot, obstruction:block, region:region)",
        ),
    ],
)
def test_agent_executes_or_fails_with_a_reason(
    answer: str, failure: str | None, tmp_path: Path
) -> None:
    env0 = ToyPlaceEnv()
    x0, _ = env0.reset(seed=0)
    answer = answer.replace("{target_x}", repr(x0.get(env0.target, "x")))
    with ChatServer(lambda _: answer) as server:
        agent, env = _toy_agent("llm_plan", server, tmp_path)
        ok, error = _drive(agent, env, seed=0)
    info = agent.episode_info()
    assert ok == (failure is None)
    if failure is None:
        assert error is None and info["failure"] is None
        assert [e["skill"].split("(")[0] for e in info["executed"]] == [
            "Pick",
            "PlaceOut",
            "Pick",
            "PlaceIn",
        ]
        assert all(e["finished"] for e in info["executed"])
    else:
        assert error is not None and failure in error and info["failure"] == error
    assert info["usage"]["prompt_tokens"] > 100
    assert info["episode_timeout"] == 1800.0
    assert info["runtime"]["cached"] is False and info["runtime"]["model_time"] > 0
    json.dumps(info, allow_nan=False)


def test_model_call_failure_ends_the_episode(tmp_path: Path) -> None:
    with ChatServer(_hello, fail_first=(401,)) as server:
        agent, env = _toy_agent("llm_plan", server, tmp_path)
        ok, error = _drive(agent, env, seed=0)
    assert not ok and error is not None and "model call failed: AuthenticationError" in error


def test_vlm_agents_send_the_rendered_initial_state(tmp_path: Path) -> None:
    import imageio.v3 as iio

    with ChatServer(lambda _: "Plan:\n") as server:
        env_id = "kinder/Motion2D-p0-v0"
        from kinder_bench.evaluation.envs import make_env

        env = make_env(env_id)
        agent = make_agent(
            "vlm_plan", env, {"base_url": server.base_url, "cache_dir": str(tmp_path)}, seed=0
        )
        ok, _ = _drive(agent, env, seed=0)
        content = server.requests[0]["messages"][0]["content"]
    assert not ok
    assert [p["type"] for p in content] == ["text", "image_url"]
    url = content[1]["image_url"]["url"]
    assert url.startswith("data:image/png;base64,")
    image = iio.imread(io.BytesIO(base64.b64decode(url.split(",", 1)[1])), extension=".png")
    np.testing.assert_array_equal(image, env.render())


# -- oracle runs: answers scripted from bilevel-planning plans -------------------------------------

ORACLE_EPISODES = 4


def _deterministic(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    out = []
    for r in records:
        r = {k: v for k, v in r.items() if k not in (*TIMING_FIELDS, "run_id", "agent_args")}
        info = dict(r.get("agent_info", {}))
        info.pop("runtime", None)
        r["agent_info"] = info
        out.append(r)
    return out


@pytest.mark.parametrize(
    ("env_id", "agent"),
    [
        ("kinder/Motion2D-p0-v0", "llm_plan"),
        ("kinder/StickButton2D-b1-v0", "llm_plan"),
        ("kinder/BaseMotion3D-v0", "llm_plan"),
        ("kinder/StickButton2D-b1-v0", "vlm_con"),
    ],
)
def test_oracle_answers_reach_bilevel_plannings_success(
    env_id: str, agent: str, tmp_path: Path
) -> None:
    bp = run_benchmark(
        [RunConfig(env_id, "bilevel_planning", seeds=(0,), episodes=ORACLE_EPISODES)],
        tmp_path / "bp",
        executor="inline",
        progress=False,
    ).records
    args = {"cache_dir": str(tmp_path / "cache"), "backoff": 0.0, "num_examples": 2}
    if agent.endswith("_plan"):
        del args["num_examples"]
    with ChatServer(table_responder(oracle_answers(env_id, 0, ORACLE_EPISODES))) as server:
        live = run_benchmark(
            [
                RunConfig(
                    env_id,
                    agent,
                    {**args, "base_url": server.base_url},
                    seeds=(0,),
                    episodes=ORACLE_EPISODES,
                )
            ],
            tmp_path / "live",
            executor="inline",
            progress=False,
        ).records
        assert len(server.requests) == ORACLE_EPISODES
    assert [r["success"] for r in live] == [r["success"] for r in bp] == [True] * ORACLE_EPISODES
    assert [r["steps"] for r in live] == [r["steps"] for r in bp]
    for r in live:
        info = r["agent_info"]
        assert r["error"] is None and info["failure"] is None and info["plan"]["dropped"] == []
        assert info["runtime"]["cached"] is False and info["usage"]["total_tokens"] > 0
        assert info["prompt_tokens_estimate"] > 0
    # Replay from the cache alone: the server is gone, the results are the same.
    replay = run_benchmark(
        [
            RunConfig(
                env_id,
                agent,
                {**args, "base_url": server.base_url, "cache_mode": "only"},
                seeds=(0,),
                episodes=ORACLE_EPISODES,
            )
        ],
        tmp_path / "replay",
        executor="inline",
        progress=False,
    ).records
    assert all(r["agent_info"]["runtime"]["cached"] for r in replay)
    assert _deterministic(replay) == _deterministic(live)


def test_cache_only_miss_is_a_recorded_failure(tmp_path: Path) -> None:
    records = run_benchmark(
        [
            RunConfig(
                "kinder/Motion2D-p0-v0",
                "llm_plan",
                {"cache_dir": str(tmp_path), "cache_mode": "only"},
                seeds=(0,),
                episodes=1,
            )
        ],
        tmp_path / "run",
        executor="inline",
        progress=False,
    ).records
    (r,) = records
    assert not r["success"] and r["error_in"] == "agent"
    assert "cache-only mode: no cached response for request" in r["error"]
    assert r["agent_info"]["failure"] == r["error"].split(": ", 1)[1]


def test_skill_env_runs_bilevel_plans_on_a_registered_box_env() -> None:
    from kinder_bench.evaluation.envs import make_env
    from kinder_gym.skill_env import SkillEnv, run_plan

    env_id = "kinder/StickButton2D-b1-v0"
    model_env = make_object_centric(env_id)
    senv = SkillEnv(make_env(env_id))
    for seed in (0, 1):
        x0, _ = model_env.reset(seed=seed)
        plan, _ = plan_episode(model_env, x0, seed=seed)
        assert plan is not None
        obs, _ = senv.reset(seed=seed)
        assert obs.shape == senv.observation_space.shape
        ok, steps, infos = run_plan(senv, plan_calls(plan.skills))
        assert ok and steps == len(plan.actions), infos


class _BadInfoAgent(RandomAgent):
    """Reports a NaN, which cannot go into a JSON line."""

    name = "bad_info"

    def episode_info(self) -> dict[str, Any]:
        return {"x": float("nan")}


def test_runner_keeps_the_episode_when_agent_info_is_not_json(toy_id: str, tmp_path: Path) -> None:
    (record,) = run_benchmark(
        [RunConfig(toy_id, f"{__name__}:_BadInfoAgent", seeds=(0,), episodes=1)],
        tmp_path,
        executor="inline",
        progress=False,
    ).records
    assert "agent_info" not in record
    assert record["agent_info_error"].startswith("ValueError: Out of range float values")


def test_fm_agents_say_what_they_need(monkeypatch: pytest.MonkeyPatch) -> None:
    from kinder_bench.baselines.fm_planning.agents import FMConArgs, FMPlanArgs, LLMPlanAgent

    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    monkeypatch.delenv("OPENAI_BASE_URL", raising=False)
    motion = "kinder/Motion2D-p0-v0"
    assert "needs a model endpoint" in str(LLMPlanAgent.unavailable(FMPlanArgs(), motion))
    assert LLMPlanAgent.unavailable(FMPlanArgs(base_url="http://127.0.0.1:1/v1"), motion) is None
    assert LLMPlanAgent.unavailable(FMConArgs(cache_mode="only"), motion) is None
    monkeypatch.setenv("OPENAI_API_KEY", "sk-test")
    assert LLMPlanAgent.unavailable(FMPlanArgs(), motion) is None
    from kinder_gym.models import MODELS

    monkeypatch.delitem(MODELS, "DynPushT2D")  # a family without a planning model
    assert "planning model" in str(
        LLMPlanAgent.unavailable(FMPlanArgs(), "kinder/DynPushT2D-t1-v0")
    )
