"""Public ids: registration with gymnasium, and making environments by id.

Each garden package calls :func:`register_family` once per family when it is imported; that is all
an import does (string entry points only, no simulator imported, no environment variables set).
kinder-core keeps a static table of which package provides which family, so :func:`make` can
import the right package on demand, and say which package to install when it is missing.

Registered ids follow ``kinder/<Family>-<variant>-v<N>`` and produce the fixed-object Box view
(:class:`~kinder_core.wrappers.BoxObservation`); ``env.unwrapped`` and
:func:`make_object_centric` give the object-centric env.
"""

from __future__ import annotations

import difflib
import importlib
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium

from kinder_core.env import ObjectCentricEnv
from kinder_core.wrappers import BoxObservation

NAMESPACE = "kinder"
_ID_RE = re.compile(rf"^{NAMESPACE}/(?P<family>[A-Za-z0-9]+)(?:-(?P<variant>.+?))?-v(?P<v>\d+)$")

CATEGORIES = ("Kinematic2D", "Dynamic2D", "Kinematic3D", "Dynamic3D")


@dataclass(frozen=True)
class FamilySource:
    """Where a family lives: its category, import module and pip distribution."""

    category: str
    module: str
    distribution: str


def _families(category: str, module: str, dist: str, names: str) -> dict[str, FamilySource]:
    return {n: FamilySource(category, module, dist) for n in names.split()}


# The static table of the KinDERGarden families: the paper's 25, then the upstream 0.2.5
# families the paper does not list (KinematicShelf3D, KinematicCylinderShelf3D, PrplLab3D,
# LimbRepositioning3D, FrankaPickPlace3D, PickPlace3D).
FAMILY_SOURCES: dict[str, FamilySource] = {
    **_families(
        "Kinematic2D",
        "kinder_garden2d",
        "kinder-garden2d",
        "Motion2D Obstruction2D ClutteredRetrieval2D ClutteredStorage2D StickButton2D "
        "PushPullHook2D",
    ),
    **_families(
        "Dynamic2D",
        "kinder_garden2d",
        "kinder-garden2d",
        "DynObstruction2D DynPushT2D DynPushPullHook2D DynScoopPour2D",
    ),
    **_families(
        "Kinematic3D",
        "kinder_garden3d",
        "kinder-garden3d",
        "BaseMotion3D Obstruction3D Packing3D Table3D Transport3D KinematicShelf3D "
        "KinematicCylinderShelf3D PrplLab3D",
    ),
    **_families(
        "Dynamic3D",
        "kinder_garden3d",
        "kinder-garden3d",
        "Shelf3D ConstrainedCupboard3D Rearrange3D SortClutteredBlocks3D SweepSimple3D "
        "SweepIntoDrawer3D ScoopPour3D BalanceBeam3D Tossing3D Dynamo3D LimbRepositioning3D "
        "FrankaPickPlace3D PickPlace3D",
    ),
}


@dataclass
class FamilyInfo:
    """What :func:`register_family` recorded about a family."""

    name: str
    category: str
    entry_point: str
    max_episode_steps: int
    version: int = 0
    variants: dict[str, dict[str, Any]] = field(default_factory=dict)
    variant_steps: dict[str, int] = field(default_factory=dict)

    def env_id(self, variant: str) -> str:
        """The public id of one variant."""
        return make_id(self.name, variant, self.version)

    def step_limit(self, variant: str) -> int:
        """One variant's step budget: its own where it has one, else the family's."""
        return self.variant_steps.get(variant, self.max_episode_steps)


_REGISTERED: dict[str, FamilyInfo] = {}


def make_id(family: str, variant: str = "", version: int = 0) -> str:
    """``kinder/<Family>-<variant>-v<N>`` (no variant part when ``variant`` is empty)."""
    middle = f"{family}-{variant}" if variant else family
    return f"{NAMESPACE}/{middle}-v{version}"


def register_family(
    family: str,
    entry_point: str,
    variants: Mapping[str, Mapping[str, Any]],
    max_episode_steps: int,
    variant_steps: Mapping[str, int] | None = None,
    version: int = 0,
    vector_entry_point: str | None = None,
) -> list[str]:
    """Register every variant of a family with gymnasium; returns the ids.

    Args:
        family: A name from :data:`FAMILY_SOURCES`.
        entry_point: ``"module:Class"`` of the :class:`ObjectCentricEnv` subclass.
        variants: Variant label (``"o3"``; ``""`` for none) → constructor kwargs.
        max_episode_steps: The family's documented step budget (gymnasium's TimeLimit).
        variant_steps: Variant label → its own step budget, for variants whose objects need
            more steps than the family's (upstream registers no limits at all, so every
            budget is this project's choice and is documented with its reason).
        version: The ``-vN`` suffix; bump it on any change of dynamics, reward or observation.
        vector_entry_point: ``"module:Class"`` of a native vector env of the family, which
            ``gymnasium.make_vec(id, num_envs, vectorization_mode="vector_entry_point")`` calls
            with ``num_envs``, ``env_entry_point``, the variant's kwargs and
            ``max_episode_steps``.

    Ids already registered are left alone, so importing a package twice is harmless.
    """
    if family not in FAMILY_SOURCES:
        raise ValueError(f"Unknown family {family!r}; known: {sorted(FAMILY_SOURCES)}")
    if ":" not in entry_point:
        raise ValueError(f"entry_point must be 'module:Class', got {entry_point!r}")
    if max_episode_steps <= 0:
        raise ValueError(f"max_episode_steps must be positive, got {max_episode_steps}")
    variant_steps = dict(variant_steps or {})
    for variant, steps in variant_steps.items():
        if variant not in variants:
            raise ValueError(
                f"variant_steps names {variant!r}, which is not a variant of {family}; "
                f"variants: {sorted(variants)}"
            )
        if steps <= 0:
            raise ValueError(f"variant_steps[{variant!r}] must be positive, got {steps}")
    info = _REGISTERED.setdefault(
        family,
        FamilyInfo(
            family, FAMILY_SOURCES[family].category, entry_point, max_episode_steps, version
        ),
    )
    info.variant_steps.update(variant_steps)
    ids = []
    for variant, kwargs in variants.items():
        env_id = make_id(family, variant, version)
        info.variants[variant] = dict(kwargs)
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="kinder_core.registration:make_box_env",
                kwargs={"env_entry_point": entry_point, **kwargs},
                max_episode_steps=variant_steps.get(variant, max_episode_steps),
                vector_entry_point=vector_entry_point,
            )
        ids.append(env_id)
    return ids


def load_entry_point(entry_point: str) -> type[ObjectCentricEnv]:
    """Import ``"module:Class"``."""
    module_name, _, attr = entry_point.partition(":")
    cls = getattr(importlib.import_module(module_name), attr)
    if not (isinstance(cls, type) and issubclass(cls, ObjectCentricEnv)):
        raise TypeError(f"{entry_point} is not an ObjectCentricEnv subclass")
    return cls


def make_box_env(env_entry_point: str, **kwargs: Any) -> BoxObservation:
    """The registered ids' entry point: the object-centric env behind a Box view."""
    return BoxObservation(load_entry_point(env_entry_point)(**kwargs))


def _parse_family(env_id: str) -> str:
    m = _ID_RE.match(env_id)
    if m is None:
        raise ValueError(
            f"{env_id!r} is not a KinDER id; expected '{NAMESPACE}/<Family>-<variant>-v<N>', "
            f"e.g. 'kinder/Motion2D-p0-v0'"
        )
    family = m.group("family")
    if family not in FAMILY_SOURCES:
        close = difflib.get_close_matches(family, list(FAMILY_SOURCES), n=3)
        hint = f"; did you mean {close}?" if close else f"; known: {sorted(FAMILY_SOURCES)}"
        raise ValueError(f"Unknown KinDER family {family!r} in {env_id!r}{hint}")
    return family


def ensure_registered(env_id: str) -> None:
    """Import the package that provides ``env_id``'s family, with a clear error if missing."""
    if env_id.startswith(f"{NAMESPACE}/") and env_id in gymnasium.registry:
        return
    family = _parse_family(env_id)
    src = FAMILY_SOURCES[family]
    try:
        importlib.import_module(src.module)
    except ModuleNotFoundError as e:
        if e.name is not None and e.name.split(".")[0] == src.module:
            raise ModuleNotFoundError(
                f"{env_id} is a {src.category} environment provided by {src.distribution}, which "
                f"is not installed; install it with `pip install {src.distribution}`"
            ) from e
        raise
    if env_id not in gymnasium.registry:
        known = [i for i in gymnasium.registry if i.startswith(f"{NAMESPACE}/")]
        close = difflib.get_close_matches(env_id, known, n=3, cutoff=0.5)
        hint = f"; did you mean {close}?" if close else ""
        raise gymnasium.error.UnregisteredEnv(f"No KinDER environment {env_id!r}{hint}")


def make(env_id: str, **kwargs: Any) -> gymnasium.Env[Any, Any]:
    """``gymnasium.make`` for a KinDER id, importing the providing package on demand."""
    ensure_registered(env_id)
    return gymnasium.make(env_id, **kwargs)


def make_object_centric(env_id: str, **kwargs: Any) -> ObjectCentricEnv:
    """The object-centric env of a registered id (no Box view, no TimeLimit)."""
    ensure_registered(env_id)
    spec = gymnasium.spec(env_id)
    spec_kwargs = dict(spec.kwargs)
    entry_point = spec_kwargs.pop("env_entry_point")
    env = load_entry_point(entry_point)(**{**spec_kwargs, **kwargs})
    env.spec = spec
    return env


def _import_available() -> None:
    for module in sorted({s.module for s in FAMILY_SOURCES.values()}):
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as e:
            if e.name is None or e.name.split(".")[0] != module:
                raise


def families(category: str | None = None) -> list[str]:
    """All family names (optionally of one category), installed or not."""
    _check_category(category)
    return [f for f, s in FAMILY_SOURCES.items() if category in (None, s.category)]


def variants(family: str) -> list[str]:
    """The registered variant labels of a family (imports its package)."""
    if family not in FAMILY_SOURCES:
        raise ValueError(f"Unknown family {family!r}; known: {sorted(FAMILY_SOURCES)}")
    src = FAMILY_SOURCES[family]
    try:
        importlib.import_module(src.module)
    except ModuleNotFoundError as e:
        raise ModuleNotFoundError(
            f"{family} is provided by {src.distribution}; `pip install {src.distribution}`"
        ) from e
    info = _REGISTERED.get(family)
    return list(info.variants) if info else []


def family_info(family: str) -> FamilyInfo | None:
    """What was registered for a family (None when its package registered nothing)."""
    _import_available()
    return _REGISTERED.get(family)


def list_envs(category: str | None = None) -> list[str]:
    """Registered KinDER ids of the installed packages, by family order then variant order."""
    _check_category(category)
    _import_available()
    return [
        info.env_id(v)
        for fam, src in FAMILY_SOURCES.items()
        if category in (None, src.category) and (info := _REGISTERED.get(fam)) is not None
        for v in info.variants
    ]


def _check_category(category: str | None) -> None:
    if category is not None and category not in CATEGORIES:
        raise ValueError(f"Unknown category {category!r}; expected one of {list(CATEGORIES)}")
