"""KinDER core: object-centric states, spaces, the environment contract, registry and test kit."""

from kinder_core.env import ObjectCentricEnv
from kinder_core.objects import Object, Type
from kinder_core.registration import (
    FAMILY_SOURCES,
    families,
    family_info,
    list_envs,
    make,
    make_object_centric,
    register_family,
    variants,
)
from kinder_core.spaces import ObjectCentricBoxSpace, ObjectCentricStateSpace, SpaceSampleError
from kinder_core.state import ObjectCentricState, StateLayout
from kinder_core.wrappers import BoxObservation, NoisyAction, NoisyObservation

__version__ = "0.1.0"

__all__ = [
    "FAMILY_SOURCES",
    "BoxObservation",
    "NoisyAction",
    "NoisyObservation",
    "Object",
    "ObjectCentricBoxSpace",
    "ObjectCentricEnv",
    "ObjectCentricState",
    "ObjectCentricStateSpace",
    "SpaceSampleError",
    "StateLayout",
    "Type",
    "families",
    "family_info",
    "list_envs",
    "make",
    "make_object_centric",
    "register_family",
    "variants",
]
