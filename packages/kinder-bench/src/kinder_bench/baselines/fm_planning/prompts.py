"""The prompts of the foundation-model planners, and their in-context examples.

:data:`PLAN_TEMPLATE` (LLMPlan, VLMPlan) and :data:`CON_TEMPLATE` (LLMCon, VLMCon) are the paper's
appendix templates (Figures "LLMPlan prompt template" and "LLMCon prompt template"), filled with
``str.format``:

* ``{controllers}``: one entry per skill of the env's :class:`~kinder_gym.model.PlanningModel`,
  ``Name(types=[t1, t2]), params_space=Box([lows], [highs], (n,), float64)`` as upstream. With
  ``parameter_lines`` (a labelled variant, off by default) each entry is followed by an indented
  ``parameters:`` line with the skill's ``params_doc`` (what each number means, with units). The
  paper's template has no such line: its in-context examples explain the parameters, which
  LLMPlan and VLMPlan never see, so the paper's finding that examples matter shows only without
  the line.
* ``{typed_objects}``: ``name: type`` per object of the initial state.
* ``{type_hierarchy}``: PDDL style, ``child1 child2 - parent`` per parent, then the root types
  that have no children, one per line.
* ``{goal_str}``: the env's natural-language description (``metadata["description"]``, the
  upstream's goal string).
* ``{init_state_str}``: the initial state as one table per type (:func:`format_state`).
* ``{in_context_examples}`` (Con only): see below.

**In-context examples** (upstream: hand-written markdown files per env, some of them one-paragraph
stubs) are generated: the bilevel planner (:mod:`kinder_bench.baselines.bilevel_planning`) solves
other episodes of the same env, env seeds ``EXAMPLE_SEED_BASE + k`` that are checked not to be
evaluation seeds (any episode of run seeds 0–9 with up to 1000 episodes), and each solution is
written as the objects, the initial-state table and the plan in the answer's syntax with
parameters rounded to :data:`EXAMPLE_DECIMALS` decimals. An example is kept only if that printed
plan, parsed back and executed with :class:`~kinder_gym.skill_env.SkillEnv` on a fresh env,
reaches the goal. Examples are made once per env (in the agent's constructor, which the runner
does not time: they play the role of the upstream's prepared files) and cached on disk under the
agent's cache directory, keyed by the env id, the settings and the kinder-gym and kinder-bench
versions; delete ``<cache_dir>/examples`` to make them again after changing a planning model.
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import hashlib
import io
import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinder_core import ObjectCentricEnv, ObjectCentricState, Type
from kinder_gym.model import PlanningModel
from kinder_gym.skill_env import SkillCall

PLAN_TEMPLATE = """\
You are highly skilled in robotic task planning, breaking down intricate and long-term tasks into distinct primitive actions.
Consider the following skills a robotic agent can perform. Note that each of these skills takes the form of a `ParameterizedController` and may have both discrete arguments (indicated by the `types` field, referring to objects of particular types),
as well as continuous arguments (indicated by `params_space` field, which is formatted as `Box([<param1_lower_bound>, <param2_lower_bound>, ...], [<param1_upper_bound>, <param2_upper_bound>, ...], (<number_of_params>,), <datatype_of_all_params>)`).

{controllers}

You are only allowed to use the provided skills. It's essential to stick to the format of these basic skills. When creating a plan, replace
the arguments of each skill with specific items or continuous parameters. You can first describe the provided scene and what it indicates about the provided
task objects to help you come up with a plan.

Here is a list of objects present in this scene for this task, along with their type (formatted as <object_name>: <type_name>):
{typed_objects}

And here are the available types (formatted in PDDL style as `<type_name1> <type_name2>... - <parent_type_name>`). You can infer a hierarchy of types via this:
{type_hierarchy}

Finally, here is an expression corresponding to the current task goal that must be achieved:
{goal_str}

Please return a plan that achieves the provided goal from an initial state described below.
{init_state_str}

{output_format}"""  # noqa: E501

CON_TEMPLATE = """\
Create a high-level plan for completing a task using the allowed actions and visible objects.

Allowed actions: Consider the following skills a robotic agent can perform. Note that each of these skills takes the form of a `ParameterizedController` and may have both discrete arguments (indicated by the `types` field, referring to objects of particular types),
as well as continuous arguments (indicated by `params_space` field, which is formatted as `Box([<param1_lower_bound>, <param2_lower_bound>, ...], [<param1_upper_bound>, <param2_upper_bound>, ...], (<number_of_params>,), <datatype_of_all_params>)`).
{controllers}

Visible objects: Here is a list of objects present in this scene for this task, along with their type (formatted as <object_name>: <type_name>):
{typed_objects}

Here are the available types (formatted in PDDL style as `<type_name1> <type_name2>... - <parent_type_name>`). You can infer a hierarchy of types via this:
{type_hierarchy}

Task description:
{goal_str}

In-context examples:
{in_context_examples}

Please return a plan that achieves the provided goal from an initial state described below.
{init_state_str}

Completed plans: No plan has yet been executed.

Next plans: {output_format}"""  # noqa: E501

OUTPUT_FORMAT = """\
Please provide your output in the following format (excluding the angle brackets and ellipsis, which are just for illustration purposes).
Be sure to include the parens '(' and ')', as well as square brackets '[' and ']' even if there are no objects/continuous parameters.
Do not bold or italicize or otherwise apply any extra formating to the plan text. Do not provide any numbers for steps in the plan, or
any reasoning for each step below the 'Plan:' heading:
<Explanation of scene + your reasoning>
Plan:
<skill 1 name>(<obj1_name>:<obj1_type_name>, <obj2_name>:<obj2_type_name>, ...)[<continuous_param1_value>, <continuous_param2_value>, ...]
<skill 2 name>(<obj1_name>:<obj1_type_name>, <obj2_name>:<obj2_type_name>, ...)[<continuous_param1_value>, <continuous_param2_value>, ...]
..."""  # noqa: E501

#: Decimals of the parameters printed in in-context examples.
EXAMPLE_DECIMALS = 3
#: Env seeds of in-context examples start here (far from the small seeds of tests and demos).
EXAMPLE_SEED_BASE = 1_000_000


_NEGATIVE_ZERO = re.compile(r"(?<!\S)-(0\.000)(?!\S)")


def _num(x: float) -> str:
    return repr(round(float(x), 4))


def format_controllers(model: PlanningModel, parameter_lines: bool = False) -> str:
    """The ``{controllers}`` block (see the module docstring); ``parameter_lines`` adds what each
    skill's parameters mean (our variant; the paper's template has no such line)."""
    out = []
    for s in model.skills:
        box = s.params_space
        types = ", ".join(v.type.name for v in s.operator.parameters)
        low = ", ".join(_num(x) for x in box.low)
        high = ", ".join(_num(x) for x in box.high)
        entry = (
            f"{s.name}(types=[{types}]), params_space=Box([{low}], [{high}], "
            f"({box.shape[0]},), {np.dtype(box.dtype).name})"
        )
        if parameter_lines:
            entry += f"\n    parameters: {' '.join(s.controller_cls.params_doc.split())}"
        out.append(entry)
    return "\n".join(out)


def format_typed_objects(state: ObjectCentricState) -> str:
    """The ``{typed_objects}`` block: ``name: type`` per object."""
    return "\n".join(f"{o.name}: {o.type.name}" for o in state.objects)


def format_type_hierarchy(types: Sequence[Type]) -> str:
    """The ``{type_hierarchy}`` block (PDDL style) of ``types`` and their ancestors."""
    every: dict[str, Type] = {}
    for t in types:
        cur: Type | None = t
        while cur is not None:
            every[cur.name] = cur
            cur = cur.parent
    children: dict[str, list[str]] = {}
    for t in every.values():
        if t.parent is not None:
            children.setdefault(t.parent.name, []).append(t.name)
    lines = [f"{' '.join(sorted(c))} - {p}" for p, c in sorted(children.items())]
    lines += [
        name for name, t in sorted(every.items()) if t.parent is None and name not in children
    ]
    return "\n".join(lines)


def format_state(state: ObjectCentricState) -> str:
    """The ``{init_state_str}`` block: one table per type, 3 decimals, ``-0.000`` written as
    ``0.000`` (simulator noise around zero would otherwise change the prompt), no trailing
    spaces."""
    text = _NEGATIVE_ZERO.sub(r"\1 ", state.pretty(precision=3))
    return "\n".join(line.rstrip() for line in text.splitlines())


def format_call(call: SkillCall, state: ObjectCentricState, decimals: int | None = None) -> str:
    """A plan line ``name(obj:type, ...)[p, ...]``; ``decimals=None`` prints exact floats."""
    types = {o.name: o.type.name for o in state.objects}
    objs = ", ".join(f"{n}:{types[n]}" for n in call.objects)
    if decimals is None:
        params = ", ".join(repr(float(p)) for p in call.params)
    else:
        params = ", ".join(f"{p:.{decimals}f}" for p in call.params)
    return f"{call.skill}({objs})[{params}]"


def goal_string(env: ObjectCentricEnv) -> str:
    """The natural-language goal: the env's ``metadata["description"]``."""
    text = env.metadata.get("description")
    if not text:
        raise ValueError(f"{env.env_name} has no metadata['description'] to use as the goal")
    return str(text).strip()


def build_prompt(
    env: ObjectCentricEnv,
    model: PlanningModel,
    state: ObjectCentricState,
    in_context_examples: str | None = None,
    parameter_lines: bool = False,
) -> str:
    """The prompt for ``state``: the Plan template, or the Con template with examples
    (``parameter_lines``: see :func:`format_controllers`)."""
    fields: dict[str, str] = {
        "controllers": format_controllers(model, parameter_lines),
        "typed_objects": format_typed_objects(state),
        "type_hierarchy": format_type_hierarchy([*model.types, *(o.type for o in state.objects)]),
        "goal_str": goal_string(env),
        "init_state_str": format_state(state),
        "output_format": OUTPUT_FORMAT,
    }
    if in_context_examples is None:
        return PLAN_TEMPLATE.format(**fields)
    return CON_TEMPLATE.format(in_context_examples=in_context_examples, **fields)


def png_data_url(frame: NDArray[np.uint8]) -> str:
    """An RGB frame as a ``data:image/png;base64,...`` URL (the VLM agents' image part)."""
    import imageio.v3 as iio

    buf = io.BytesIO()
    iio.imwrite(buf, np.asarray(frame, dtype=np.uint8), extension=".png")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def user_message(prompt: str, image_url: str | None = None) -> dict[str, Any]:
    """One user message: the prompt, and the image as a content part when given."""
    if image_url is None:
        return {"role": "user", "content": prompt}
    return {
        "role": "user",
        "content": [
            {"type": "text", "text": prompt},
            {"type": "image_url", "image_url": {"url": image_url}},
        ],
    }


def estimate_tokens(text: str) -> int:
    """A token estimate: ``ceil(characters / 4)``, OpenAI's rule of thumb for English text
    (no tokenizer is installed here; an endpoint's reported usage is the real figure)."""
    return -(-len(text) // 4)


# -- in-context examples ---------------------------------------------------------------------------


@functools.cache
def evaluation_env_seeds(run_seeds: int = 10, episodes: int = 1000) -> frozenset[int]:
    """Every env seed the runner uses for run seeds ``0..run_seeds-1`` × ``episodes``."""
    from kinder_bench.evaluation.runner import episode_seeds

    return frozenset(s for seed in range(run_seeds) for s in episode_seeds(seed, episodes))


@dataclasses.dataclass(frozen=True)
class Example:
    """One in-context example: a solved episode of the env."""

    env_seed: int
    objects: str
    init_state: str
    plan: tuple[str, ...]

    def render(self, index: int) -> str:
        """The example as prompt text."""
        return (
            f"Example {index}:\nObjects:\n{self.objects}\nInitial state:\n{self.init_state}\n"
            f"Plan:\n" + "\n".join(self.plan)
        )


def render_examples(examples: Sequence[Example]) -> str:
    """The ``{in_context_examples}`` block."""
    return "\n\n".join(e.render(i + 1) for i, e in enumerate(examples))


def plan_calls(skills: Sequence[tuple[str, Any, int]]) -> list[SkillCall]:
    """The skill calls of a bilevel-planning solution (``RefinedPlan.skills``: ground operator
    names ``Op(obj1, obj2)``, parameters, action counts)."""
    calls = []
    for name, params, _ in skills:
        skill, _, rest = name.partition("(")
        objs = tuple(o.strip() for o in rest.rstrip(")").split(",") if o.strip())
        calls.append(SkillCall(skill, objs, tuple(float(p) for p in params)))
    return calls


def _example_for_seed(
    env_id: str, seed: int, planning_timeout: float
) -> tuple[Example | None, str]:
    """An example from the env's episode with ``seed``, or None and why not."""
    from kinder_bench.baselines.bilevel_planning import BilevelPlanningArgs, plan_episode
    from kinder_bench.baselines.fm_planning.parser import parse_plan
    from kinder_core import make_object_centric
    from kinder_gym.models import create_model
    from kinder_gym.skill_env import SkillEnv, run_plan

    env = make_object_centric(env_id)
    x0, _ = env.reset(seed=seed)
    plan, stats = plan_episode(
        env, x0, BilevelPlanningArgs(planning_timeout=planning_timeout), seed=seed
    )
    if plan is None:
        return None, f"seed {seed}: BP found no plan ({stats.time:.1f} s)"
    model = create_model(env)
    lines = tuple(format_call(c, x0, EXAMPLE_DECIMALS) for c in plan_calls(plan.skills))
    parsed = parse_plan("Plan:\n" + "\n".join(lines), model, x0)
    check_env = make_object_centric(env_id)
    skill_env = SkillEnv(check_env, create_model(check_env))
    skill_env.reset(seed=seed)
    ok, _, _ = run_plan(skill_env, parsed.calls)
    if not ok:
        return None, f"seed {seed}: the plan rounded to {EXAMPLE_DECIMALS} decimals fails"
    return Example(seed, format_typed_objects(x0), format_state(x0), lines), ""


def make_examples(
    env_id: str,
    num: int,
    cache_dir: str | Path | None = None,
    planning_timeout: float = 60.0,
    max_tries: int | None = None,
) -> list[Example]:
    """``num`` in-context examples of ``env_id`` (see the module docstring), cached on disk under
    ``cache_dir/examples`` when given. Fewer are returned when the planner fails on the first
    ``max_tries`` (default ``3·num``) candidate seeds."""
    if num <= 0:
        return []
    from kinder_bench.evaluation.results import package_versions

    tries = max_tries if max_tries is not None else 3 * num
    versions = package_versions()
    settings = [env_id, num, planning_timeout, tries, EXAMPLE_DECIMALS]
    settings += [versions.get("kinder-gym"), versions.get("kinder-bench")]
    key = hashlib.sha256(json.dumps(settings).encode()).hexdigest()[:16]
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / "examples" / f"{env_id.replace('/', '_')}__{key}.json"
        if path.exists():
            return [
                Example(**{**e, "plan": tuple(e["plan"])}) for e in json.loads(path.read_text())
            ]
    excluded = evaluation_env_seeds()
    examples: list[Example] = []
    seed = EXAMPLE_SEED_BASE
    for _ in range(tries):
        while seed in excluded:
            seed += 1
        example, _why = _example_for_seed(env_id, seed, planning_timeout)
        seed += 1
        if example is not None:
            examples.append(example)
            if len(examples) == num:
                break
    if path is not None:
        from kinder_bench.evaluation.results import write_json

        path.parent.mkdir(parents=True, exist_ok=True)
        write_json(path, [dataclasses.asdict(e) for e in examples])
    return examples
