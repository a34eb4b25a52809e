"""Microbenchmarks of kinder-core's object-centric state: µs per copy, vectorize, devectorize,
get and set, for states of 5 and 50 objects.

Usage: python benchmarks/speed/core_bench.py [--repeat N]
"""

from __future__ import annotations

import argparse
import timeit
from collections.abc import Callable

import numpy as np

from kinder_core import Object, ObjectCentricState, ObjectCentricStateSpace, Type

ROBOT = Type("robot", ["x", "y", "theta", "base_radius", "arm_joint", "arm_length", "vacuum"])
BLOCK = Type("block", ["x", "y", "theta", "width", "height", "static", "r", "g", "b", "z"])


def make_state(num_objects: int) -> tuple[ObjectCentricState, list[Object]]:
    rng = np.random.default_rng(0)
    objs = [Object("robot", ROBOT)] + [Object(f"block{i}", BLOCK) for i in range(num_objects - 1)]
    state = ObjectCentricState.from_features(
        {o: rng.uniform(size=len(o.type.features)) for o in objs}
    )
    return state, objs


def operations(num_objects: int) -> tuple[int, dict[str, Callable[[], object]]]:
    """The timed operations on a state of ``num_objects`` objects, and its feature count."""
    state, objs = make_state(num_objects)
    box = ObjectCentricStateSpace([ROBOT, BLOCK]).to_box(objs)
    vec = box.vectorize(state)
    block = objs[-1]
    return state.data.size, {
        "copy": lambda: state.copy(),
        "vectorize": lambda: box.vectorize(state),
        "devectorize": lambda: box.devectorize(vec),
        "get": lambda: state.get(block, "theta"),
        "set": lambda: state.set(block, "theta", 0.5),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timing repeats (best is reported)")
    args = parser.parse_args()
    print("| objects | features | copy µs | vectorize µs | devectorize µs | get µs | set µs |")
    print("|---|---|---|---|---|---|---|")
    for n in (5, 50):
        size, ops = operations(n)
        cells = []
        for fn in ops.values():
            number = 20_000
            best = min(timeit.repeat(fn, number=number, repeat=args.repeat))
            cells.append(f"{1e6 * best / number:.2f}")
        print(f"| {n} | {size} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
