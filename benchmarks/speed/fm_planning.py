"""Prompt sizes and agent overhead of the foundation-model planners (no model needed).

``sizes``: for each of the paper's eight envs (initial state of env seed 0), the characters and
estimated tokens (``ceil(chars / 4)``, no tokenizer is installed here) of the LLMPlan and LLMCon
prompts (LLMCon with its 4 generated in-context examples; generating them runs bilevel planning,
cached under ``--cache``), and the VLM image (size and OpenAI's documented high-detail image-token
formula for GPT-4o-class models: 85 + 170 per 512-px tile after scaling into 2048² and the short
side to 768; a different model may count differently).

``overhead``: runs the ``llm_plan`` agent (or ``--agent vlm_plan``) with the runner on the given
envs, answered by the scripted local server with the bilevel planner's plans (the oracle of the
tests), and reports the agent's own time per episode excluding the model call
(``agent_info.runtime.overhead_time``: prompt and image building, parsing and running the skills'
controllers), with its prompt and parse parts.

    uv run python benchmarks/speed/fm_planning.py sizes \
        --out benchmarks/results/fm_prompt_sizes.json
    uv run python benchmarks/speed/fm_planning.py overhead --episodes 10 \
        --out benchmarks/results/fm_overhead.json
    uv run python benchmarks/speed/fm_planning.py overhead --episodes 5 \
        --env kinder/DynObstruction2D-o1-v0 --env kinder/DynPushPullHook2D-o5-v0 \
        --env kinder/Transport3D-o2-v0 \
        --env kinder/Shelf3D-o1-v0 --env kinder/SweepIntoDrawer3D-o5-v0 \
        --out benchmarks/results/fm_overhead_more.json
    uv run python benchmarks/speed/fm_planning.py overhead --agent vlm_plan --episodes 5 \
        --env kinder/Motion2D-p0-v0 --env kinder/StickButton2D-b1-v0 --env kinder/BaseMotion3D-v0 \
        --env kinder/Shelf3D-o1-v0 --out benchmarks/results/fm_overhead_vlm.json
    uv run python benchmarks/speed/fm_planning.py table \
        --inputs benchmarks/results/fm_prompt_sizes.json \
        benchmarks/results/fm_overhead.json benchmarks/results/fm_overhead_more.json \
        benchmarks/results/fm_overhead_vlm.json
"""

from __future__ import annotations

import argparse
import base64
import json
import math
import statistics
import tempfile
from pathlib import Path
from typing import Any

from kinder_bench.baselines.fm_planning.prompts import (
    build_prompt,
    estimate_tokens,
    make_examples,
    png_data_url,
    render_examples,
)
from kinder_bench.baselines.fm_planning.scripted_server import (
    ChatServer,
    oracle_answers,
    table_responder,
)
from kinder_bench.evaluation.protocol import PAPER_ENVS
from kinder_bench.evaluation.results import write_json
from kinder_bench.evaluation.runner import RunConfig, run_benchmark
from kinder_core import make_object_centric
from kinder_gym.models import create_model


def image_tokens(width: int, height: int) -> int:
    """OpenAI's documented high-detail image-token count (GPT-4o-class models)."""
    scale = min(1.0, 2048 / max(width, height))
    w, h = width * scale, height * scale
    scale = min(1.0, 768 / min(w, h))
    w, h = w * scale, h * scale
    return 85 + 170 * math.ceil(w / 512) * math.ceil(h / 512)


def sizes(envs: list[str], cache: Path, num_examples: int) -> list[dict[str, Any]]:
    rows = []
    for env_id in envs:
        env = make_object_centric(env_id)
        x0, _ = env.reset(seed=0)
        model = create_model(env)
        plan = build_prompt(env, model, x0)
        examples = make_examples(env_id, num_examples, cache_dir=cache)
        con = build_prompt(env, model, x0, render_examples(examples))
        frame = env.render_state(x0)
        png = base64.b64decode(png_data_url(frame).split(",", 1)[1])
        row = {
            "env_id": env_id,
            "plan_chars": len(plan),
            "plan_tokens_est": estimate_tokens(plan),
            "con_chars": len(con),
            "con_tokens_est": estimate_tokens(con),
            "con_examples": len(examples),
            "image": f"{frame.shape[1]}x{frame.shape[0]}",
            "image_png_bytes": len(png),
            "image_tokens_est": image_tokens(frame.shape[1], frame.shape[0]),
        }
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def overhead(envs: list[str], episodes: int, agent: str) -> list[dict[str, Any]]:
    rows = []
    for env_id in envs:
        answers = oracle_answers(env_id, 0, episodes)
        with tempfile.TemporaryDirectory() as tmp, ChatServer(table_responder(answers)) as server:
            args = {"base_url": server.base_url, "cache_dir": str(Path(tmp) / "cache")}
            records = run_benchmark(
                [RunConfig(env_id, agent, args, seeds=(0,), episodes=episodes)],
                Path(tmp) / "run",
                executor="inline",
                progress=False,
            ).records
        rt = [r["agent_info"]["runtime"] for r in records]
        row = {
            "env_id": env_id,
            "agent": agent,
            "episodes": len(records),
            "success": sum(r["success"] for r in records) / len(records),
            "steps_mean": statistics.mean(r["steps"] for r in records),
            "overhead_mean": statistics.mean(x["overhead_time"] for x in rt),
            "overhead_max": max(x["overhead_time"] for x in rt),
            "prompt_time_mean": statistics.mean(x["prompt_time"] for x in rt),
            "parse_time_mean": statistics.mean(x["parse_time"] for x in rt),
            "model_time_mean": statistics.mean(x["model_time"] for x in rt),
        }
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def tables(sizes_path: Path, overhead_paths: list[Path]) -> str:
    """The two markdown tables of the README from the JSON files."""
    out = [
        "| env | LLMPlan prompt chars | ≈ tokens | LLMCon prompt chars | ≈ tokens | examples "
        "| image | ≈ image tokens |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in json.loads(sizes_path.read_text()):
        out.append(
            f"| {r['env_id']} | {r['plan_chars']} | {r['plan_tokens_est']} | {r['con_chars']} "
            f"| {r['con_tokens_est']} | {r['con_examples']} | {r['image']} "
            f"| {r['image_tokens_est']} |"
        )
    out += [
        "",
        "| env | agent | episodes | oracle SR | steps | overhead s (mean) | overhead s (max) "
        "| prompt ms | parse ms |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for path in overhead_paths:
        for r in json.loads(path.read_text()):
            out.append(
                f"| {r['env_id']} | {r.get('agent', 'llm_plan')} | {r['episodes']} "
                f"| {r['success']:.2f} | {r['steps_mean']:.1f} "
                f"| {r['overhead_mean']:.3f} | {r['overhead_max']:.3f} "
                f"| {1000 * r['prompt_time_mean']:.2f} | {1000 * r['parse_time_mean']:.2f} |"
            )
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=["sizes", "overhead", "table"])
    parser.add_argument("--env", action="append", help="env id (repeatable); default: see below")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--agent", default="llm_plan", help="overhead: llm_plan or vlm_plan")
    parser.add_argument("--num-examples", type=int, default=4)
    parser.add_argument("--cache", type=Path, default=Path("runs/fm_cache"))
    parser.add_argument("--out", type=Path, help="JSON file to write (sizes, overhead)")
    parser.add_argument("--inputs", type=Path, nargs="*", help="table: sizes JSON, overhead JSONs")
    a = parser.parse_args()
    if a.what == "table":
        print(tables(a.inputs[0], a.inputs[1:]))
        return
    if a.out is None:
        parser.error("--out is required for sizes and overhead")
    if a.what == "sizes":
        rows = sizes(a.env or list(PAPER_ENVS), a.cache, a.num_examples)
    else:
        default = ["kinder/Motion2D-p0-v0", "kinder/StickButton2D-b1-v0", "kinder/BaseMotion3D-v0"]
        rows = overhead(a.env or default, a.episodes, a.agent)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    write_json(a.out, rows)


if __name__ == "__main__":
    main()
