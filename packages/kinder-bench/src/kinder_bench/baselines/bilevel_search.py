"""The abstract half of bilevel planning: the hFF heuristic and a plan enumerator (A* or GBFS).

* :class:`HFF` is the FF heuristic (Hoffmann & Nebel 2001) over ground STRIPS operators: the size
  of a relaxed plan extracted from the delete-relaxed planning graph. Static atoms (never added or
  deleted by any operator) are compiled away once per problem; operators whose static
  preconditions fail are dropped; each grounding counts separately; values are memoised per
  abstract state.
* :func:`abstract_plans` lazily enumerates distinct abstract plans in best-first order, with
  priority ``g + h`` (A*, the upstream code's choice) or ``h`` (greedy best-first, the paper's
  wording); ties go to the smaller ``h``, then to a draw from the seeded RNG.
  To enumerate *several* plans without exploring every reordering, each abstract state may be
  expanded at most ``max_expansions_per_state`` times (the k-shortest-paths trick: one expansion
  per plan wanted), and a plan never revisits a state it already passed through.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from kinder_gym.concepts import GroundAtom
from kinder_gym.operators import GroundOperator

SEARCH_ALGORITHMS = ("astar", "gbfs")


class HFF:
    """The FF heuristic for one problem (fixed ground operators and goal).

    Args:
        operators: Every ground operator of the problem.
        goal: The goal atoms.
        init: The initial atoms; atoms that no operator adds or deletes keep their initial truth
            value forever ("static") and are compiled away.
    """

    def __init__(
        self,
        operators: Sequence[GroundOperator],
        goal: frozenset[GroundAtom],
        init: frozenset[GroundAtom],
    ) -> None:
        fluent = set().union(*(o.add_effects | o.delete_effects for o in operators))
        self.unsolvable = any(g not in fluent and g not in init for g in goal)
        ops = [o for o in operators if all(p in fluent or p in init for p in o.preconditions)]
        self.operators = ops
        index: dict[GroundAtom, int] = {}

        def fid(atom: GroundAtom) -> int:
            return index.setdefault(atom, len(index))

        self._pre = [tuple(fid(p) for p in o.preconditions if p in fluent) for o in ops]
        self._add = [tuple(fid(a) for a in o.add_effects) for o in ops]
        self._goal = tuple(fid(g) for g in goal if g in fluent)
        self._index = index
        self._consumers: list[list[int]] = [[] for _ in range(len(index))]
        for i, pre in enumerate(self._pre):
            for f in pre:
                self._consumers[f].append(i)
        self._no_pre = [i for i, pre in enumerate(self._pre) if not pre]
        self._cache: dict[frozenset[GroundAtom], float] = {}

    def __call__(self, atoms: frozenset[GroundAtom]) -> float:
        """The relaxed-plan length from ``atoms`` (``inf`` if the goal is relaxed-unreachable)."""
        cached = self._cache.get(atoms)
        if cached is None:
            cached = self._compute(atoms)
            self._cache[atoms] = cached
        return cached

    def _compute(self, atoms: frozenset[GroundAtom]) -> float:
        if self.unsolvable:
            return math.inf
        index = self._index
        level: dict[int, int] = {index[a]: 0 for a in atoms if a in index}
        goal = self._goal
        if all(g in level for g in goal):
            return 0.0
        achiever: dict[int, int] = {}
        missing = [len(p) for p in self._pre]
        layer = list(level)
        ready = list(self._no_pre)
        depth = 0
        while True:
            for f in layer:
                for i in self._consumers[f]:
                    missing[i] -= 1
                    if missing[i] == 0:
                        ready.append(i)
            depth += 1
            nxt = []
            for i in ready:
                for f in self._add[i]:
                    if f not in level:
                        level[f] = depth
                        achiever[f] = i
                        nxt.append(f)
            ready = []
            if all(g in level for g in goal):
                break
            if not nxt:
                return math.inf
            layer = nxt
        # Extract a relaxed plan backwards from the goals.
        chosen: set[int] = set()
        stack = [g for g in goal if level[g] > 0]
        seen = set(stack)
        while stack:
            f = stack.pop()
            op = achiever[f]
            if op in chosen:
                continue
            chosen.add(op)
            for p in self._pre[op]:
                if level[p] > 0 and p not in seen:
                    seen.add(p)
                    stack.append(p)
        return float(len(chosen))


@dataclass(frozen=True)
class AbstractPlan:
    """A sequence of ground operators and the abstract states it predicts
    (``len(states) == len(operators) + 1``)."""

    operators: tuple[GroundOperator, ...]
    states: tuple[frozenset[GroundAtom], ...]

    def __len__(self) -> int:
        return len(self.operators)

    def __str__(self) -> str:
        return " → ".join(o.name for o in self.operators) or "(empty plan)"


@dataclass
class _Node:
    atoms: frozenset[GroundAtom]
    g: int
    parent: _Node | None
    op: GroundOperator | None

    def path(self) -> AbstractPlan:
        ops: list[GroundOperator] = []
        states: list[frozenset[GroundAtom]] = []
        node: _Node | None = self
        while node is not None:
            states.append(node.atoms)
            if node.op is not None:
                ops.append(node.op)
            node = node.parent
        return AbstractPlan(tuple(reversed(ops)), tuple(reversed(states)))

    def on_path(self, atoms: frozenset[GroundAtom]) -> bool:
        node: _Node | None = self
        while node is not None:
            if node.atoms == atoms:
                return True
            node = node.parent
        return False


def abstract_plans(
    init: frozenset[GroundAtom],
    goal: frozenset[GroundAtom],
    operators: Sequence[GroundOperator],
    rng: np.random.Generator,
    algorithm: str = "astar",
    max_expansions_per_state: int = 10,
    deadline: float = math.inf,
    max_plan_length: int = 100,
    heuristic: HFF | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> Iterator[AbstractPlan]:
    """Distinct abstract plans from ``init`` to a state containing ``goal``, best first.

    Lazy: the search resumes where it stopped when the next plan is asked for. Stops when the
    open list is empty or ``deadline`` (a ``clock()`` value: wall-clock by default) passes.
    """
    if algorithm not in SEARCH_ALGORITHMS:
        raise ValueError(f"algorithm must be one of {SEARCH_ALGORITHMS}, got {algorithm!r}")
    h_fn = heuristic if heuristic is not None else HFF(operators, goal, init)
    ops = list(h_fn.operators)
    # Successor generation: index operators by one precondition to avoid scanning all of them.
    by_pre: dict[GroundAtom | None, list[GroundOperator]] = {}
    for o in ops:
        key = min(o.preconditions) if o.preconditions else None
        by_pre.setdefault(key, []).append(o)
    always = by_pre.get(None, [])

    def successors(atoms: frozenset[GroundAtom]) -> Iterator[GroundOperator]:
        for o in always:
            yield o
        for a in sorted(atoms):
            for o in by_pre.get(a, ()):
                if o.preconditions <= atoms:
                    yield o

    counter = itertools.count()
    h0 = h_fn(init)
    if math.isinf(h0):
        return
    root = _Node(init, 0, None, None)
    open_list: list[tuple[float, float, float, int, _Node]] = []

    def push(node: _Node, h: float) -> None:
        primary = h if algorithm == "gbfs" else node.g + h
        heapq.heappush(open_list, (primary, h, float(rng.random()), next(counter), node))

    push(root, h0)
    expansions: dict[frozenset[GroundAtom], int] = {}
    emitted: set[tuple[str, ...]] = set()
    while open_list:
        if clock() > deadline:
            return
        _, _, _, _, node = heapq.heappop(open_list)
        if goal <= node.atoms:
            plan = node.path()
            names = tuple(o.name for o in plan.operators)
            if names not in emitted:
                emitted.add(names)
                yield plan
            continue
        count = expansions.get(node.atoms, 0)
        if count >= max_expansions_per_state or node.g >= max_plan_length:
            continue
        expansions[node.atoms] = count + 1
        for o in successors(node.atoms):
            nxt = o.apply(node.atoms)
            if nxt == node.atoms or node.on_path(nxt):
                continue
            h = h_fn(nxt)
            if math.isinf(h):
                continue
            push(_Node(nxt, node.g + 1, node, o), h)
