"""Object-centric states stored as one contiguous float64 array.

An :class:`ObjectCentricState` maps objects to feature vectors. Internally every feature of every
object lives in one flat ``numpy`` array, laid out by a shared, immutable :class:`StateLayout`
(objects sorted by name, each object's features in its type's order). Copying, vectorizing, equality
and hashing are therefore single array operations, and hot paths can gather many features at once
with precomputed index arrays (:meth:`StateLayout.indices`).
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinder_core.objects import Object, Type

FloatArray = NDArray[np.float64]


class StateLayout:
    """Where each (object, feature) lives in a state's flat array.

    Layouts are interned: :meth:`StateLayout.of` returns the same instance for the same objects, so
    states of one environment share a layout and compare layouts by identity.
    """

    _cache: ClassVar[dict[tuple[Object, ...], StateLayout]] = {}
    _lock: ClassVar[threading.Lock] = threading.Lock()

    def __init__(self, objects: tuple[Object, ...]) -> None:
        names = [o.name for o in objects]
        if len(set(names)) != len(names):
            dupes = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"Object names must be unique within a state; repeated: {dupes}")
        self.objects: tuple[Object, ...] = objects
        self._slices: dict[Object, slice] = {}
        self._feature_index: dict[Object, dict[str, int]] = {}
        self._by_name: dict[str, Object] = {}
        offset = 0
        for obj in objects:
            n = len(obj.type.features)
            self._slices[obj] = slice(offset, offset + n)
            self._feature_index[obj] = {f: offset + i for i, f in enumerate(obj.type.features)}
            self._by_name[obj.name] = obj
            offset += n
        self.size: int = offset
        self._types: tuple[Type, ...] = tuple(dict.fromkeys(o.type for o in objects))

    @classmethod
    def of(cls, objects: Iterable[Object]) -> StateLayout:
        """The interned layout for these objects (any order; they are sorted by name)."""
        key = tuple(sorted(objects, key=lambda o: o.name))
        layout = cls._cache.get(key)
        if layout is None:
            with cls._lock:
                layout = cls._cache.get(key)
                if layout is None:
                    layout = cls(key)
                    cls._cache[key] = layout
        return layout

    def __reduce__(self) -> tuple[Any, tuple[tuple[Object, ...]]]:
        return (StateLayout.of, (self.objects,))

    @property
    def types(self) -> tuple[Type, ...]:
        """The distinct types of the objects, in order of first appearance."""
        return self._types

    def slice_of(self, obj: Object) -> slice:
        """The slice of the flat array that holds ``obj``'s features."""
        try:
            return self._slices[obj]
        except KeyError:
            raise KeyError(f"Object {obj!r} is not in this state; objects: {self.names}") from None

    def index(self, obj: Object, feature: str) -> int:
        """The flat index of one feature of one object."""
        try:
            return self._feature_index[obj][feature]
        except KeyError:
            if obj not in self._feature_index:
                raise KeyError(
                    f"Object {obj!r} is not in this state; objects: {self.names}"
                ) from None
            raise KeyError(
                f"Type {obj.type.name!r} has no feature {feature!r}; features: "
                f"{list(obj.type.features)}"
            ) from None

    def indices(self, objects: Sequence[Object], features: Sequence[str]) -> NDArray[np.intp]:
        """An index array of shape (len(objects), len(features)) for vectorized gathers.

        ``state.data[layout.indices(blocks, ["x", "y"])]`` gives every block's position at once.
        """
        return np.array(
            [[self.index(o, f) for f in features] for o in objects], dtype=np.intp
        ).reshape(len(objects), len(features))

    def object_named(self, name: str) -> Object:
        """The object with this name."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"No object named {name!r}; objects: {self.names}") from None

    @property
    def names(self) -> list[str]:
        """Object names in layout order."""
        return [o.name for o in self.objects]

    def signature(self) -> str:
        """A process-independent description of the layout (object names and types)."""
        return ";".join(
            f"{o.name}:{o.type.name}({','.join(o.type.features)})" for o in self.objects
        )


class ObjectCentricState:
    """A mapping from objects to feature vectors, stored in one contiguous float64 array.

    Build one with :meth:`from_features`, or from a layout and a flat array. ``sim_state`` is an
    optional opaque array for simulator state that the features do not capture (for example
    MuJoCo's warm-start); it is copied and pickled with the state but ignored by equality,
    hashing and vectorization.

    States are mutable (``set``); do not mutate a state after using it as a dict key.
    """

    __slots__ = ("_layout", "data", "sim_state")

    def __init__(
        self,
        layout: StateLayout | Iterable[Object],
        data: ArrayLike | None = None,
        sim_state: FloatArray | None = None,
    ) -> None:
        if not isinstance(layout, StateLayout):
            layout = StateLayout.of(layout)
        self._layout = layout
        if data is None:
            self.data: FloatArray = np.zeros(layout.size, dtype=np.float64)
        else:
            arr = np.array(data, dtype=np.float64).reshape(-1)
            if arr.shape[0] != layout.size:
                raise ValueError(
                    f"State data has {arr.shape[0]} values but the objects need {layout.size} "
                    f"({layout.names})"
                )
            self.data = arr
        self.sim_state = sim_state

    @classmethod
    def from_features(
        cls, features: Mapping[Object, Mapping[str, float] | ArrayLike]
    ) -> ObjectCentricState:
        """Build a state from ``{object: {feature: value}}`` or ``{object: values_in_order}``.

        Every feature of every object must be given.
        """
        state = cls(StateLayout.of(features.keys()))
        for obj, values in features.items():
            if isinstance(values, Mapping):
                expected = set(obj.type.features)
                missing = sorted(expected - set(values))
                extra = sorted(set(values) - expected)
                if missing or extra:
                    raise ValueError(
                        f"Features for {obj!r}: missing {missing}, unknown {extra}; expected "
                        f"{list(obj.type.features)}"
                    )
                state[obj] = [values[f] for f in obj.type.features]
            else:
                state[obj] = values
        return state

    # -- access ---------------------------------------------------------------------------------
    @property
    def layout(self) -> StateLayout:
        """The state's (shared, immutable) layout."""
        return self._layout

    @property
    def objects(self) -> tuple[Object, ...]:
        """All objects, sorted by name."""
        return self._layout.objects

    def get(self, obj: Object, feature: str) -> float:
        """One feature value."""
        return float(self.data[self._layout.index(obj, feature)])

    def set(self, obj: Object, feature: str, value: float) -> None:
        """Set one feature value in place."""
        self.data[self._layout.index(obj, feature)] = value

    def __getitem__(self, obj: Object) -> FloatArray:
        """A writable view of ``obj``'s features, in its type's order."""
        return self.data[self._layout.slice_of(obj)]

    def __setitem__(self, obj: Object, values: ArrayLike) -> None:
        sl = self._layout.slice_of(obj)
        arr = np.asarray(values, dtype=np.float64).reshape(-1)
        if arr.shape[0] != sl.stop - sl.start:
            raise ValueError(
                f"{obj!r} has {sl.stop - sl.start} features {list(obj.type.features)}, "
                f"got {arr.shape[0]} values"
            )
        self.data[sl] = arr

    def __contains__(self, obj: object) -> bool:
        return isinstance(obj, Object) and obj in self._layout._slices

    def __iter__(self) -> Any:
        return iter(self._layout.objects)

    def __len__(self) -> int:
        return len(self._layout.objects)

    def get_objects(self, type_: Type) -> list[Object]:
        """Objects whose type is ``type_`` or one of its subtypes, sorted by name."""
        return [o for o in self._layout.objects if o.type.is_subtype_of(type_)]

    def get_object_from_name(self, name: str) -> Object:
        """The object with this name (KeyError listing the names if absent)."""
        return self._layout.object_named(name)

    # -- array operations -----------------------------------------------------------------------
    def copy(self) -> ObjectCentricState:
        """An independent copy (one array copy)."""
        new = ObjectCentricState.__new__(ObjectCentricState)
        new._layout = self._layout
        new.data = self.data.copy()
        new.sim_state = None if self.sim_state is None else self.sim_state.copy()
        return new

    def vectorize(self) -> FloatArray:
        """All features as one vector in layout order (objects by name)."""
        out: FloatArray = self.data.copy()
        return out

    def allclose(self, other: ObjectCentricState, atol: float = 1e-8, rtol: float = 0.0) -> bool:
        """Same objects and every feature within tolerance."""
        return self._same_layout(other) and bool(
            np.allclose(self.data, other.data, atol=atol, rtol=rtol)
        )

    def _same_layout(self, other: ObjectCentricState) -> bool:
        return self._layout is other._layout or self._layout.objects == other._layout.objects

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ObjectCentricState):
            return NotImplemented
        return self._same_layout(other) and bool(np.array_equal(self.data, other.data))

    def stable_hash(self, decimals: int | None = None) -> str:
        """A hex digest that is the same in every process for equal states.

        With ``decimals``, features are rounded first, so near-duplicates hash alike (useful for
        planners' duplicate detection).
        """
        data = self.data if decimals is None else np.round(self.data, decimals)
        data = data + 0.0  # folds -0.0 into 0.0 so equal states hash equally
        h = hashlib.blake2b(digest_size=16)
        h.update(self._layout.signature().encode())
        h.update(np.ascontiguousarray(data, dtype="<f8").tobytes())
        return h.hexdigest()

    def __hash__(self) -> int:
        return int(self.stable_hash()[:15], 16)

    # -- pickling and display -------------------------------------------------------------------
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (ObjectCentricState, (self._layout, self.data, self.sim_state))

    def pretty(self, precision: int = 3) -> str:
        """A readable table per type: one row per object, one column per feature."""
        lines: list[str] = []
        for t in self._layout.types:
            objs = [o for o in self._layout.objects if o.type == t]
            header = ["object", *t.features]
            rows = [[o.name, *(f"{v:.{precision}f}" for v in self[o])] for o in objs]
            widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
            lines.append(f"type: {t.name}")
            lines.append("  ".join(h.ljust(w) for h, w in zip(header, widths)))
            lines.extend("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)
            lines.append("")
        return "\n".join(lines).rstrip()

    def __repr__(self) -> str:
        return f"ObjectCentricState({len(self)} objects, {self._layout.size} features)"

    def __str__(self) -> str:
        return self.pretty()
