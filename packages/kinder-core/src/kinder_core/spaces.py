"""Observation spaces for object-centric states.

:class:`ObjectCentricStateSpace` is the space of states with any objects of given types.
:class:`ObjectCentricBoxSpace` is a fixed-object view of it as a ``gymnasium.spaces.Box`` (what
SB3, CleanRL and other array-based learners need): ``vectorize`` and ``devectorize`` are exact
inverses, every index has a name like ``"block0.x"``, and bounds are finite where known.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from kinder_core.objects import Object, Type
from kinder_core.state import FloatArray, ObjectCentricState, StateLayout

# Bounds are given per feature name ("x") or per type-qualified name ("block.x"); the latter wins.
FeatureBounds = Mapping[str, tuple[float, float]]


class SpaceSampleError(TypeError):
    """Raised by :meth:`ObjectCentricStateSpace.sample`, which has no meaningful distribution."""


class ObjectCentricStateSpace(spaces.Space[ObjectCentricState]):
    """All object-centric states whose objects have the given types (or their subtypes)."""

    def __init__(self, types: Collection[Type]) -> None:
        super().__init__(shape=None, dtype=None)
        self.types: frozenset[Type] = frozenset(types)

    @property
    def is_np_flattenable(self) -> bool:
        return False

    def _type_allowed(self, t: Type) -> bool:
        return any(t.is_subtype_of(allowed) for allowed in self.types)

    def contains(self, x: Any) -> bool:
        return (
            isinstance(x, ObjectCentricState)
            and all(self._type_allowed(t) for t in x.layout.types)
            and bool(np.all(np.isfinite(x.data)))
        )

    def sample(self, mask: Any = None, probability: Any = None) -> ObjectCentricState:
        raise SpaceSampleError(
            "ObjectCentricStateSpace has no sampling distribution (states depend on the objects "
            "and on each environment's constraints); use env.reset(seed=...) to sample valid "
            "states, or sample from the Box view returned by .to_box(objects)"
        )

    def to_box(
        self,
        objects: Sequence[Object],
        bounds: FeatureBounds | None = None,
        dtype: type[np.floating[Any]] = np.float64,
    ) -> ObjectCentricBoxSpace:
        """A fixed-object Box view listing ``objects`` in the given order."""
        for o in objects:
            if not self._type_allowed(o.type):
                raise ValueError(
                    f"Object {o!r} has type {o.type.name!r}, not one of this space's types "
                    f"{sorted(t.name for t in self.types)}"
                )
        return ObjectCentricBoxSpace(objects, bounds=bounds, dtype=dtype)

    def __repr__(self) -> str:
        return f"ObjectCentricStateSpace({sorted(t.name for t in self.types)})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ObjectCentricStateSpace) and other.types == self.types


class ObjectCentricBoxSpace(spaces.Box):
    """A Box view of states with a fixed, ordered list of objects.

    Args:
        objects: The objects in vector order (often the robot first, then the rest by name).
        bounds: Optional finite bounds per feature (``"x"``) or per type and feature
            (``"block.x"``); features without bounds get ``-inf``/``inf``.
        dtype: The vector dtype. float64 (the default) keeps ``devectorize(vectorize(s)) == s``
            exact; float32 rounds.
    """

    def __init__(
        self,
        objects: Sequence[Object],
        bounds: FeatureBounds | None = None,
        dtype: type[np.floating[Any]] = np.float64,
    ) -> None:
        self.objects: tuple[Object, ...] = tuple(objects)
        if not self.objects:
            raise ValueError("A Box view needs at least one object")
        self.layout: StateLayout = StateLayout.of(self.objects)
        perm = [self.layout.index(o, f) for o in self.objects for f in o.type.features]
        self._perm: NDArray[np.intp] = np.asarray(perm, dtype=np.intp)
        self._inverse: NDArray[np.intp] = np.argsort(self._perm)
        self.feature_names: list[str] = [
            f"{o.name}.{f}" for o in self.objects for f in o.type.features
        ]
        bounds = bounds or {}
        low = np.full(len(perm), -np.inf)
        high = np.full(len(perm), np.inf)
        i = 0
        for o in self.objects:
            for f in o.type.features:
                b = bounds.get(f"{o.type.name}.{f}", bounds.get(f))
                if b is not None:
                    low[i], high[i] = b
                i += 1
        if np.any(low > high):
            bad = [n for n, lo, hi in zip(self.feature_names, low, high) if lo > hi]
            raise ValueError(f"Bounds have low > high for {bad}")
        super().__init__(low=low.astype(dtype), high=high.astype(dtype), dtype=dtype)

    def vectorize(self, state: ObjectCentricState) -> NDArray[Any]:
        """The state as a vector in this view's object order."""
        if state.layout is not self.layout and state.objects != self.layout.objects:
            raise ValueError(
                f"State objects {state.layout.names} do not match this Box view's objects "
                f"{self.layout.names}"
            )
        return state.data[self._perm].astype(self.dtype, copy=False)

    def devectorize(self, vector: ArrayLike) -> ObjectCentricState:
        """The exact inverse of :meth:`vectorize`."""
        vec = np.asarray(vector, dtype=np.float64).reshape(-1)
        if vec.shape[0] != self._perm.shape[0]:
            raise ValueError(
                f"Vector has {vec.shape[0]} entries; this Box view expects {self._perm.shape[0]} "
                f"({len(self.objects)} objects)"
            )
        data: FloatArray = vec[self._inverse]
        return ObjectCentricState(self.layout, data)

    def markdown_table(self) -> str:
        """A markdown table of index → object → feature → bounds."""
        rows = ["| index | object | type | feature | low | high |", "|---|---|---|---|---|---|"]
        i = 0
        for o in self.objects:
            for f in o.type.features:
                rows.append(
                    f"| {i} | {o.name} | {o.type.name} | {f} | {_fmt(self.low[i])} | "
                    f"{_fmt(self.high[i])} |"
                )
                i += 1
        return "\n".join(rows)


def _fmt(v: float) -> str:
    if np.isinf(v):
        return "-inf" if v < 0 else "inf"
    return f"{v:.4g}"
