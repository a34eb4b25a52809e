"""Parsing a model's answer into skill calls, with the upstream's rules.

The answer is free text, then a ``Plan:`` line, then one skill per line:
``name(obj:type, obj:type, ...)[p1, p2, ...]``. For each line after the first ``Plan:`` line:

* a line whose text before ``(`` is not a known skill name **stops** parsing (upstream);
* a line is **dropped** (parsing goes on) when an object or type name is unknown, when an
  object's declared type is not its own type, when a declared type is not a subtype of the
  skill's parameter type, or when the number of objects differs from the skill's arity (upstream);
* a line with a parameter list that is not a bracketed list of numbers, or with a different number
  of numbers than the skill's ``params_space`` dimension, **stops** parsing (upstream);
* continuous parameters are clipped to ``params_space`` (recorded per line).

Deviations from the upstream parser: blank lines are skipped (upstream would stop at one), a
``Plan:`` line may carry trailing spaces or markdown emphasis (``**Plan:**``), and a missing
bracket list on a skill without parameters counts as ``[]``. Everything dropped or not parsed is
reported in :attr:`ParsedPlan.dropped` with the reason, so it lands in the episode's record.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from kinder_core import ObjectCentricState, Type
from kinder_gym.model import PlanningModel
from kinder_gym.skill_env import SkillCall, skills_by_name

_PLAN_RE = re.compile(r"^\s*[*_#\s]*plan\s*:[*_\s]*$", re.IGNORECASE)
_PAIR_RE = re.compile(r"^\s*([^\s,:()\[\]]+)\s*:\s*([^\s,:()\[\]]+)\s*$")
_LINE_RE = re.compile(r"^(?P<name>[^(]*)\((?P<objs>[^)]*)\)\s*(?P<rest>.*)$")


@dataclasses.dataclass
class ParsedPlan:
    """The calls parsed from an answer and what was left out."""

    calls: list[SkillCall]
    lines: list[str]
    """The plan lines the calls come from (one each)."""
    dropped: list[dict[str, Any]]
    """Per line not turned into a call: ``{"line", "reason", "effect"}`` with effect
    ``"dropped"`` (the line is skipped) or ``"stopped"`` (this and every later line)."""
    clipped: list[dict[str, Any]]
    """Per call whose parameters were clipped: ``{"line", "given", "clipped"}``."""
    found_plan: bool
    """Whether the answer had a ``Plan:`` line."""

    def to_record(self) -> dict[str, Any]:
        """A JSON-able summary for the episode record."""
        return {
            "found_plan": self.found_plan,
            "lines": list(self.lines),
            "dropped": list(self.dropped),
            "clipped": list(self.clipped),
        }


def _types_in(model: PlanningModel, state: ObjectCentricState) -> dict[str, Type]:
    out: dict[str, Type] = {}
    for t in [*model.types, *(o.type for o in state.objects)]:
        cur: Type | None = t
        while cur is not None:
            out[cur.name] = cur
            cur = cur.parent
    return out


def plan_section(text: str) -> tuple[list[str], bool]:
    """The lines after the first ``Plan:`` line (and whether there was one)."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if _PLAN_RE.match(line):
            return lines[i + 1 :], True
    return [], False


def _parse_floats(rest: str) -> list[float] | None:
    rest = rest.strip()
    if not rest:
        return []
    if not (rest.startswith("[") and rest.endswith("]")):
        return None
    body = rest[1:-1].strip()
    if not body:
        return []
    try:
        return [float(x) for x in body.split(",")]
    except ValueError:
        return None


def parse_plan(text: str, model: PlanningModel, state: ObjectCentricState) -> ParsedPlan:
    """Skill calls from a model's answer (see the module docstring for the rules)."""
    skills = skills_by_name(model)
    objects = {o.name: o for o in state.objects}
    types = _types_in(model, state)
    calls: list[SkillCall] = []
    kept: list[str] = []
    dropped: list[dict[str, Any]] = []
    clipped: list[dict[str, Any]] = []
    body, found = plan_section(text)
    if not found:
        return ParsedPlan([], [], [], [], found_plan=False)

    def stop(i: int, reason: str) -> None:
        rest = [ln.strip() for ln in body[i:] if ln.strip()]
        dropped.append({"line": rest[0], "reason": reason, "effect": "stopped"})
        dropped.extend(
            {"line": ln, "reason": "after a line that stopped parsing", "effect": "stopped"}
            for ln in rest[1:]
        )

    for i, raw in enumerate(body):
        line = raw.strip()
        if not line:
            continue
        m = _LINE_RE.match(line)
        name = (m.group("name") if m else line.split("(")[0]).strip()
        skill = skills.get(name)
        if m is None or skill is None:
            stop(i, f"{name!r} is not a known skill (known: {sorted(skills)})")
            break
        params_spec = skill.operator.parameters
        objs_text = m.group("objs").strip()
        pairs = [p for p in objs_text.split(",")] if objs_text else []
        reason = None
        names: list[str] = []
        if len(pairs) != len(params_spec):
            reason = f"{name} takes {len(params_spec)} object(s), the line gives {len(pairs)}"
        for pair, var in zip(pairs, params_spec):
            if reason is not None:
                break
            pm = _PAIR_RE.match(pair)
            if pm is None:
                reason = f"{pair.strip()!r} is not of the form object:type"
                break
            obj_name, type_name = pm.group(1), pm.group(2)
            obj = objects.get(obj_name)
            declared = types.get(type_name)
            if obj is None:
                reason = f"unknown object {obj_name!r}"
            elif declared is None:
                reason = f"unknown type {type_name!r}"
            elif obj.type != declared:
                reason = f"{obj_name} is a {obj.type.name}, not a {type_name}"
            elif not declared.is_subtype_of(var.type):
                reason = f"{type_name} is not a {var.type.name} ({name}'s parameter {var.name})"
            names.append(obj_name)
        if reason is not None:
            dropped.append({"line": line, "reason": reason, "effect": "dropped"})
            continue
        values = _parse_floats(m.group("rest"))
        dim = skill.params_space.shape[0]
        if values is None:
            stop(i, f"{m.group('rest').strip()!r} is not a bracketed list of numbers")
            break
        if len(values) != dim or not all(np.isfinite(values)):
            stop(i, f"{name} takes {dim} finite parameter(s), the line gives {values}")
            break
        low = skill.params_space.low.astype(np.float64)
        high = skill.params_space.high.astype(np.float64)
        given = np.asarray(values, dtype=np.float64)
        params = np.clip(given, low, high)
        if not np.array_equal(params, given):
            clipped.append({"line": line, "given": values, "clipped": params.tolist()})
        calls.append(SkillCall(name, tuple(names), tuple(params.tolist())))
        kept.append(line)
    return ParsedPlan(calls, kept, dropped, clipped, found_plan=True)
