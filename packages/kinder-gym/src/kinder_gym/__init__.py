"""KinDERGym: the planning layer of KinDER.

* :mod:`kinder_gym.concepts`: typed predicates with classifiers, atoms, state abstraction.
* :mod:`kinder_gym.operators`: lifted STRIPS operators, grounding, PDDL export.
* :mod:`kinder_gym.skills`: parameterized controllers (options), skills, :class:`SkillFailure`.
* :mod:`kinder_gym.motion_planning`: OMPL RRT-Connect in SE(2) and joint space with pluggable
  collision checkers.
* :mod:`kinder_gym.model`: :class:`PlanningModel`, everything a planner needs about one env.
* :mod:`kinder_gym.models`: the per-family models (``create_model(env)``).
* :mod:`kinder_gym.skill_env`: skill-level control (``SkillCall``, ``SkillExecution``, the
  Gymnasium ``SkillEnv`` whose action is one skill run to its end).
"""

from kinder_gym.concepts import (
    GroundAtom,
    LiftedAtom,
    Predicate,
    Variable,
    abstract_state,
    object_combinations,
)
from kinder_gym.model import PlanningModel
from kinder_gym.operators import (
    GroundOperator,
    LiftedOperator,
    domain_to_pddl,
    ground_operators,
    problem_to_pddl,
)
from kinder_gym.skills import (
    Controller,
    GroundSkill,
    Skill,
    SkillFailure,
    SkillRollout,
    execute_skill,
)

__version__ = "0.1.0"

__all__ = [
    "Controller",
    "GroundAtom",
    "GroundOperator",
    "GroundSkill",
    "LiftedAtom",
    "LiftedOperator",
    "PlanningModel",
    "Predicate",
    "Skill",
    "SkillFailure",
    "SkillRollout",
    "Variable",
    "abstract_state",
    "domain_to_pddl",
    "execute_skill",
    "ground_operators",
    "object_combinations",
    "problem_to_pddl",
]
