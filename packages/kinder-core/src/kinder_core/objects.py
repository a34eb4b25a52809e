"""Types and objects: the vocabulary of object-centric states.

A :class:`Type` names a kind of object and its ordered features; a child type inherits its parent's
features first, then adds its own. An :class:`Object` is a named instance of a type. Objects order
by name, so every state lists its objects in the same, reproducible order.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Type:
    """A named object type with an ordered feature list.

    Args:
        name: The type's name, e.g. ``"rectangle"``.
        own_features: The features this type adds to its parent's.
        parent: The parent type, whose features come first; ``None`` for a root type.

    ``features`` is the full ordered list: the parent's features, then ``own_features``.
    """

    name: str
    own_features: tuple[str, ...] = ()
    parent: Type | None = None
    features: tuple[str, ...] = field(init=False, compare=False, repr=False)

    def __init__(
        self, name: str, own_features: Iterable[str] = (), parent: Type | None = None
    ) -> None:
        if not name or not isinstance(name, str):
            raise ValueError(f"Type name must be a non-empty string, got {name!r}")
        own = tuple(own_features)
        inherited = parent.features if parent is not None else ()
        full = inherited + own
        duplicates = sorted({f for f in full if full.count(f) > 1})
        if duplicates:
            raise ValueError(
                f"Type {name!r} repeats feature(s) {duplicates}; each feature name must be unique "
                f"across the type and its ancestors"
            )
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "own_features", own)
        object.__setattr__(self, "parent", parent)
        object.__setattr__(self, "features", full)

    def is_subtype_of(self, other: Type) -> bool:
        """True if this type is ``other`` or descends from it."""
        t: Type | None = self
        while t is not None:
            if t == other:
                return True
            t = t.parent
        return False

    def __repr__(self) -> str:
        return f"Type({self.name!r})"


@dataclass(frozen=True, eq=False)
class Object:
    """A named instance of a :class:`Type`. Objects compare by (name, type) and sort by name."""

    name: str
    type: Type
    _hash: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError(f"Object name must be a non-empty string, got {self.name!r}")
        object.__setattr__(self, "_hash", hash((self.name, self.type.name)))

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other: object) -> bool:
        if self is other:
            return True
        if not isinstance(other, Object):
            return NotImplemented
        return self.name == other.name and self.type == other.type

    def __lt__(self, other: Object) -> bool:
        return self.name < other.name

    def __repr__(self) -> str:
        return f"{self.name}:{self.type.name}"

    def __reduce__(self) -> tuple[Any, tuple[str, Type]]:
        return (Object, (self.name, self.type))
