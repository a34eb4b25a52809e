"""Planning models (concepts, operators, skills, samplers) per environment family.

Models live next to their env's family, mirroring the garden layout
(``models/kinematic2d/motion2d.py`` for ``kinder_garden2d/kinematic2d/motion2d.py``). Each module
has a ``create_model(env) -> PlanningModel`` function; :data:`MODELS` maps family names to them by
string, so importing this package imports no model (and no 3D simulator).
"""

from __future__ import annotations

import importlib
import re
import weakref
from collections.abc import Callable
from typing import cast

from kinder_core import ObjectCentricEnv
from kinder_core.registration import FAMILY_SOURCES, family_info
from kinder_gym.model import PlanningModel

#: Family name → ``"module:function"`` building the family's :class:`PlanningModel`.
MODELS: dict[str, str] = {
    "Motion2D": "kinder_gym.models.kinematic2d.motion2d:create_model",
    "StickButton2D": "kinder_gym.models.kinematic2d.stickbutton2d:create_model",
    "DynObstruction2D": "kinder_gym.models.dynamic2d.dyn_obstruction2d:create_model",
    "DynPushPullHook2D": "kinder_gym.models.dynamic2d.dyn_pushpullhook2d:create_model",
    "DynPushT2D": "kinder_gym.models.dynamic2d.dyn_pusht2d:create_model",
    "DynScoopPour2D": "kinder_gym.models.dynamic2d.dyn_scooppour2d:create_model",
    "BaseMotion3D": "kinder_gym.models.kinematic3d.base_motion3d:create_model",
    "Transport3D": "kinder_gym.models.kinematic3d.transport3d:create_model",
    "Shelf3D": "kinder_gym.models.dynamic3d.shelf3d:create_model",
    "SweepIntoDrawer3D": "kinder_gym.models.dynamic3d.sweep_into_drawer3d:create_model",
    "BalanceBeam3D": "kinder_gym.models.dynamic3d.balance_beam3d:create_model",
    "Tossing3D": "kinder_gym.models.dynamic3d.tossing3d:create_model",
    "Dynamo3D": "kinder_gym.models.dynamic3d.dynamo3d:create_model",
    "SweepSimple3D": "kinder_gym.models.dynamic3d.sweep_simple3d:create_model",
    "Rearrange3D": "kinder_gym.models.dynamic3d.rearrange3d:create_model",
    "SortClutteredBlocks3D": "kinder_gym.models.dynamic3d.sort_cluttered_blocks3d:create_model",
    "ScoopPour3D": "kinder_gym.models.dynamic3d.scoop_pour3d:create_model",
    "ConstrainedCupboard3D": "kinder_gym.models.dynamic3d.constrained_cupboard3d:create_model",
    "PickPlace3D": "kinder_gym.models.dynamic3d.pick_place3d:create_model",
    "FrankaPickPlace3D": "kinder_gym.models.dynamic3d.franka_pick_place3d:create_model",
    "LimbRepositioning3D": "kinder_gym.models.dynamic3d.limb_repositioning3d:create_model",
    "Obstruction2D": "kinder_gym.models.kinematic2d.obstruction2d:create_model",
    "ClutteredRetrieval2D": "kinder_gym.models.kinematic2d.clutteredretrieval2d:create_model",
    "ClutteredStorage2D": "kinder_gym.models.kinematic2d.clutteredstorage2d:create_model",
    "PushPullHook2D": "kinder_gym.models.kinematic2d.pushpullhook2d:create_model",
    "Obstruction3D": "kinder_gym.models.kinematic3d.obstruction3d:create_model",
    "Packing3D": "kinder_gym.models.kinematic3d.packing3d:create_model",
    "Table3D": "kinder_gym.models.kinematic3d.table3d:create_model",
    "KinematicShelf3D": "kinder_gym.models.kinematic3d.kinematic_shelf3d:create_model",
    "PrplLab3D": "kinder_gym.models.kinematic3d.prpl_lab3d:create_model",
    "KinematicCylinderShelf3D": (
        "kinder_gym.models.kinematic3d.kinematic_cylinder_shelf3d:create_model"
    ),
}

_ID_RE = re.compile(r"^kinder/(?P<family>[A-Za-z0-9]+)(?:-.+?)?-v\d+$")


def register_model(family: str, entry_point: str) -> None:
    """Make ``entry_point`` (``"module:function"``) the model factory of ``family``."""
    if ":" not in entry_point:
        raise ValueError(f"entry_point must be 'module:function', got {entry_point!r}")
    MODELS[family] = entry_point


def family_of(env: ObjectCentricEnv) -> str:
    """The family of an env: from its registered id, else from its class."""
    spec = env.spec
    if spec is not None:
        m = _ID_RE.match(spec.id)
        if m is not None:
            return m.group("family")
    cls = f"{type(env).__module__}:{type(env).__name__}"
    for family in FAMILY_SOURCES:
        info = family_info(family)
        if info is not None and info.entry_point == cls:
            return family
    raise ValueError(
        f"Cannot tell which KinDER family {type(env).__name__} belongs to (no registered id and "
        f"no registered entry point {cls})"
    )


def create_model(env: ObjectCentricEnv, family: str | None = None) -> PlanningModel:
    """The planning model of ``env`` (its family is inferred when not given)."""
    fam = family or family_of(env)
    entry_point = MODELS.get(fam)
    if entry_point is None:
        raise ValueError(f"No planning model for {fam}; families with a model: {sorted(MODELS)}")
    module_name, _, attr = entry_point.partition(":")
    factory = cast(
        Callable[[ObjectCentricEnv], PlanningModel],
        getattr(importlib.import_module(module_name), attr),
    )
    return factory(env)


# One model per env instance: building one can be costly and runners reuse envs.
_MODELS: weakref.WeakKeyDictionary[ObjectCentricEnv, PlanningModel] = weakref.WeakKeyDictionary()


def use_model(env: ObjectCentricEnv, model: PlanningModel) -> None:
    """Plan on ``env`` with ``model`` instead of its family's model (e.g. a custom env)."""
    _MODELS[env] = model


def model_for(env: ObjectCentricEnv) -> PlanningModel:
    """The planning model of ``env``, built once per env instance (:func:`create_model`) unless
    :func:`use_model` gave it one."""
    model = _MODELS.get(env)
    if model is None:
        model = create_model(env)
        _MODELS[env] = model
    return model


__all__ = ["MODELS", "create_model", "family_of", "model_for", "register_model", "use_model"]
