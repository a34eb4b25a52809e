"""User documentation from an environment's class docstring.

Each environment's class docstring *is* its user documentation, written in Gymnasium's style as
markdown sections (``## Description``, ``## Observation Space``, ...). This module splits it into
the sections that go into ``env.metadata`` and into the generated ``docs/envs/<id>.md`` pages.
"""

from __future__ import annotations

import inspect
import re

# Section heading → metadata key. The first seven are required of every environment.
REQUIRED_SECTIONS: dict[str, str] = {
    "Description": "description",
    "Observation Space": "observation_space",
    "Action Space": "action_space",
    "Reward": "reward",
    "Starting State": "starting_state",
    "Episode End": "episode_end",
    "Version History": "version_history",
}
OPTIONAL_SECTIONS: dict[str, str] = {
    "Arguments": "arguments",
    "Deviations": "deviations",
    "References": "references",
    "Variants": "variants",
}

_HEADING = re.compile(r"^##\s+(.+?)\s*$", re.MULTILINE)


def parse_doc_sections(cls: type) -> dict[str, str]:
    """Split ``cls``'s docstring into metadata entries.

    Returns a dict with the summary (text before the first heading) under ``"summary"`` and one
    entry per known section. Raises ``ValueError`` naming the class and the missing sections if a
    required section is absent.
    """
    doc = inspect.cleandoc(cls.__doc__ or "")
    matches = list(_HEADING.finditer(doc))
    out: dict[str, str] = {"summary": doc[: matches[0].start()].strip() if matches else doc}
    known = {**REQUIRED_SECTIONS, **OPTIONAL_SECTIONS}
    for i, m in enumerate(matches):
        end = matches[i + 1].start() if i + 1 < len(matches) else len(doc)
        key = known.get(m.group(1))
        if key is not None:
            out[key] = doc[m.end() : end].strip()
    missing = [h for h, k in REQUIRED_SECTIONS.items() if not out.get(k)]
    if missing:
        raise ValueError(
            f"{cls.__name__}'s docstring lacks the section(s) {missing}; every environment "
            f"documents {list(REQUIRED_SECTIONS)} as '## <Heading>' markdown sections"
        )
    return out
