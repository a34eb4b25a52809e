"""Write docs/conformance.md: per id, whether our env conforms to upstream kindergarden 0.2.5.

The verdicts are the conformance tests' own: the script runs ``test_conformance_*.py`` of
kinder-garden2d and kinder-garden3d (slow tests included) with the ``harvest`` plugin, which
writes each test's outcome and the figures and tolerance it recorded (pytest's
``record_property``). So the table applies exactly the rules the tests apply (per-feature
tolerances, pooled exchangeable objects, kept deviations, documented geometry divergences) and
cannot disagree with ``make test-all``. Each registered id gets one row; an id no test covers says
why (``UNCOVERED``).

Usage (from the repository root):
    .venv/bin/python tools/conformance/table.py [--out docs/conformance.md] [--fast]
        [--family NAME]

``--fast`` runs only the default (not slow) tests. ``--family`` (a category or a family)
limits the run to those ids and keeps the other rows of the existing file as they are.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from record_upstream import expand_family, family_of  # noqa: E402

import kinder_core  # noqa: E402
from kinder_core.registration import CATEGORIES, FAMILY_SOURCES  # noqa: E402

OUT = ROOT / "docs" / "conformance.md"
#: The test files of each category (relative to the repository root).
TEST_FILES: dict[str, list[str]] = {
    "Kinematic2D": ["packages/kinder-garden2d/tests/test_conformance_kinematic2d.py"],
    "Dynamic2D": ["packages/kinder-garden2d/tests/test_conformance_dynamic2d.py"],
    "Kinematic3D": ["packages/kinder-garden3d/tests/test_conformance_kinematic3d.py"],
    "Dynamic3D": [
        "packages/kinder-garden3d/tests/test_conformance_dynamic3d.py",
        "packages/kinder-garden3d/tests/test_conformance_limb3d.py",
    ],
}
#: Which column a test feeds, by a word in its name; other tests of an id (feature names, the
#: comparison's own sanity check) count towards the verdict only.
ASPECTS: dict[str, tuple[str, ...]] = {
    "distribution": ("distribution", "recorded_seed"),
    "seed for seed": ("seeded",),
    "transitions": ("transition", "first_steps", "one_step"),
}
#: ``--family`` selects tests by ``pytest -k``: a family whose tests are not parametrized by its
#: ids' names is selected by its test module's name.
FAMILY_KEYWORDS = {"LimbRepositioning3D": "limb3d"}
#: What a missing seed-for-seed comparison means, per category.
NO_SEED_FOR_SEED: dict[str, str] = {
    category: "not compared: our draws are not upstream's draw for draw (the distribution "
    "column compares them)"
    for category in ("Kinematic3D", "Dynamic3D")
}
# Differences from upstream that we keep on purpose, per category and per family, and why.
CATEGORY_DEVIATIONS: dict[str, str] = {
    "Kinematic2D": "Outer walls 1.0 thick instead of 2 × the step (not observed; a held object "
    "swung on the arm cannot leave the world); numpy rendering.",
    "Dynamic2D": "The PushT goal compares the wrapped angle difference (upstream compares raw "
    "angles); a held scoop is attached with the robot already in place.",
    "Dynamic3D": "The arm's PD runs every physics step (upstream holds one torque per action: "
    "Dynamic3DConfig(arm_control='held_torque')); the primitive-shape robot and gripper.",
}
#: What holds for a whole category, printed above its table.
CATEGORY_NOTES: dict[str, str] = {
    "Dynamic3D": "**Simulator and physics step.** Dynamic3D runs on upstream's simulator and "
    "step: MuJoCo 3.3 (upstream 0.2.5 requires `mujoco~=3.3.0`; the lock has 3.3.7, as "
    "upstream's venv, and mink 1.1.0, the last mink for MuJoCo 3.3) at 0.5 ms, 200 steps per "
    "action. Until commit fc661ba it ran on MuJoCo 4.0.0 at 1 ms, with two measured "
    "differences: 4.0.0 reports two boxes overlapping 1 mm face to face at a contact depth of "
    "-1 mm where 3.3.7 reports -0.5 mm (a box on a plane -1 mm in both; "
    "`benchmarks/probes/box_contact_depth.py`), so block-on-block, block-on-table and "
    "block-in-bin contacts were stiffer than upstream's and SortClutteredBlocks3D-o20's twenty "
    "dropped blocks bounced further than upstream's; and 3.3.7 at 1 ms let a 1 cm cube dropped "
    "20 cm cross ScoopPour3D-o10's 2 cm bin floor (1 of our resets 1000-1099; at 0.5 ms none, "
    "upstream none of 249). `Dynamic3DConfig(timestep=0.001, substeps=100)` keeps the 1 ms "
    "step as an option, about twice as fast. The scene turns on MuJoCo's `multiccd` (several "
    "contact points between convex shapes): on 3.3.7 without it our cylinder can, a stand-in "
    "for upstream's mesh can, keeps rocking on the island after the settle (Rearrange3D-o2: up "
    "to 0.28 rad/s, upstream's at rest).",
}
DEVIATIONS: dict[str, str] = {
    "ClutteredRetrieval2D": "The robot start's free-space component is found on a 0.02 grid, "
    "not with exact polygons: a start within a cell of a component's edge can be judged "
    "differently, which changes that seed's draw (no stored seed is affected).",
    "SweepIntoDrawer3D": "Where upstream's 100 wiper draws fail (about 1 seed in 40) it drops "
    "the wiper on the floor at the origin; ours keeps drawing.",
    "BalanceBeam3D": "The seesaw's hinge is observed (hinge_pos, hinge_vel: 88 features against "
    "upstream's 86; left out of the comparison); its pivot is a box with the footprint of "
    "upstream's triangular-prism mesh.",
    "ScoopPour3D": "Upstream reports the scoop's bounding box from its size formula "
    "(8.9 x 5.4 x 4.2 cm), ours from its geometry (8.5 x 5 x 4.2 cm, upstream's too). Upstream's "
    "contacts sink deeper the heavier the pile (the cubes 0.9 mm below ours under ten cubes, "
    "2.7 mm under fifty, 5.1 mm under a hundred): heights are compared after removing that "
    "offset, and the first step from upstream's state lifts its cubes by as much (objects "
    "tolerance 4e-3 m on o20-o50, 7e-3 m on o100). Upstream's pile of a hundred, sunk into "
    "itself, has half its cubes tilted over 1 degree (ours a quarter) and more of them still "
    "turning: o100's cube tilt (qx, qy) and angular velocities are left out.",
    "SweepSimple3D": "Upstream's upright wiper and 2 cm cubes dropped from up to 10 cm. Kept: "
    "the wiper's x range is its yaw-0 fit inside upstream's widened region at every yaw "
    "(upstream's rejection sampling lets it come up to 3.7 cm nearer the ends at 45 degrees); "
    "random actions into the side counter turn our primitive robot more than upstream's mesh "
    "robot (base max 0.2 in the test); Dynamic3DConfig(task_options=('flat_wiper',)) gives the "
    "earlier flat wiper and 1 cm cubes. With several cubes, which face a dropped cube lands on is "
    "chance: pooled, by the KS test alone.",
    "ConstrainedCupboard3D": "The cupboards' side and back panels are as thick as their shelves "
    "(2 cm; upstream's 1 cm), so the opening is 6 cm wide (upstream's 8 cm). The rods are dropped "
    "from up to 10 cm as upstream's (drop: centre) and on both sides now and then land across one "
    "another: on o2-o6 their heights, tilts and velocities are compared by the KS test alone.",
    "Dynamo3D": "The chairs' bb_x, bb_y, bb_z are our stand-ins' collision boxes (upstream's "
    "stated footprints; upstream observes 0.5 x 0.5 x 0.9 m, its mesh chairs' site box) and "
    "upstream's chairs still rock after the settle: those features are left out of the test. "
    "The lab's walls are not reproduced; upstream's re-draw of layouts whose chairs drift "
    "0.25 m while settling is not needed.",
    "Rearrange3D": "Upstream's mesh drink box still rocks after the settle and lies tipped over "
    "in 3 of 40 seeds, ours stands still (its orientation and velocities are left out of the "
    "test); the can's bounding box is round, within 0.4 mm of upstream's 6.70 x 6.62 cm; in 1 of "
    "upstream's 30 o2 seeds the can slides the island's drawer 8 mm open (drawers by the KS test "
    "alone). The right-side variant draws its 'in' objects from regions shrunk by upstream's "
    "10 cm default footprint.",
    "FrankaPickPlace3D": "The FR3 arm is a joint position servo on both sides (the arm PD "
    "note above is the mobile manipulator's); its settled elbow is 2.1e-5 rad from upstream's "
    "(compared to 1e-4 in the test); the gripper is the primitive 2F-85 stand-in (force-limited "
    "pads; upstream: a tendon-driven four-bar linkage).",
    "SortClutteredBlocks3D": "Every variant has upstream's layout. Our dropped blocks spread a "
    "little wider than upstream's (o4: x -0.047..0.058 m over 100 seeds, upstream -0.038..0.035 m "
    "over 40; both at most two high), and now and then one knocks a bin (o20 into bins, over 200 "
    "seeds: a bin pushed over 2 mm in 4 of ours and 2 of upstream's): the blocks' positions, and "
    "o20's bins, are compared by the KS test alone. Upstream's generated bowl collides as the "
    "convex hull of its mesh, a solid dome that rocks and spins after the settle and on whose "
    "top a block rests; ours is a hollow primitive bowl at rest: the bowls' tilt and "
    "velocities and the blocks' angular velocities (upstream's pile of twenty still turns) "
    "are left out, the bowls' height and yaw compared by the KS test alone, and one step of "
    "upstream's rocking bowls moves them up to 1.8 mm (objects tolerance 3e-3 m). Upstream "
    "places o12's floor objects without a collision check, so a 70 cm rod may rest across a "
    "4 cm cube; ours redraws until nothing overlaps (height and tilt by the KS test alone). "
    "Kept option: half_size_objects (o12's earlier 2 cm cubes and 35 cm rods).",
    "Shelf3D": "Variants o2-o8: upstream starts some cubes partly below the floor and places the "
    "robot without keeping it clear of them, so now and then a cube comes out of the settle "
    "turned or knocked (ours never): the cubes are compared by the KS test alone; where "
    "upstream's robot starts over a cube, our primitive base touches it and upstream's mesh base "
    "does not (objects tolerance 0.06 m on o2, 0.07 m on o8).",
}
#: Registered ids with no conformance fixture, and why.
UNCOVERED: dict[str, str] = {}
#: Registered ids whose fixture is recorded but which do not conform yet, and how (no test
#: hides them: the row says "differs").
KNOWN_DIFFERENCES: dict[str, str] = {}
HEADER = """# Conformance to upstream kindergarden 0.2.5

Generated by `.venv/bin/python tools/conformance/table.py` from the conformance tests' own
verdicts ({which}); do not edit by hand. The tests compare our envs with
fixtures recorded from upstream by `tools/conformance/record_upstream.py` (format, recording and
the family rules: `tools/conformance/README.md` and each test module's docstring); `make test`
runs their fast part and `make test-all` all of them.

Columns: **verdict**: *conforms* (every test of the id passes), *conforms, kept deviation* (it
passes with a kept difference the tests name: an expected failure, or a trajectory stopped where
upstream's and our collision shapes disagree, or a difference the test leaves out or allows a
wider tolerance for, named in the cell), *differs* (a test fails; its message is given) or
*not recorded* (no fixture; the reason). **distribution**: reset distributions feature by
feature (constants equal, sampled features by range and a two-sample KS test; ours on seeds
1000.. against upstream's seeds 0..N−1). **seed for seed**: upstream's stored seeds whose
initial state ours reproduces. **transitions**: recorded trajectories (random and scripted:
contact, grasp, carry, press, push) replayed from upstream's states; kinematic families step for
step, dynamic ones one step at a time from upstream's state before each step (upstream cannot
reproduce its own dynamic runs from its state vector). **first divergence**: where a
trajectory stops being compared, and why. **tolerance**: what the transition test allows.
Figures are measured by the tests on this run.
"""


@dataclass
class TestResult:
    """One test's verdict for one id (a line of the harvest file)."""

    test: str
    outcome: str  # passed, failed, xfailed, skipped, error
    message: str
    slow: bool
    properties: dict[str, str] = field(default_factory=dict)


def _cell(text: str) -> str:
    """Text safe inside a markdown table cell."""
    return " ".join(text.replace("|", "\\|").split())


def env_id_of(param: str) -> str | None:
    """The registered id a test parameter names (a fixture stem or a Limb variant)."""
    for candidate in (f"kinder/{param}-v0", f"kinder/LimbRepositioning3D-{param}-v0"):
        if candidate in KNOWN_IDS:
            return candidate
    return None


KNOWN_IDS: set[str] = set()


def run_tests(files: list[str], fast: bool, keyword: str | None) -> list[dict[str, object]]:
    """Run the conformance tests of ``files`` (per package) with the harvest plugin."""
    lines: list[dict[str, object]] = []
    by_package: dict[Path, list[str]] = {}
    for f in files:
        by_package.setdefault(ROOT / Path(f).parents[1], []).append(str(ROOT / f))
    for package, tests in sorted(by_package.items()):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "results.jsonl"
            env = {
                **os.environ,
                "KINDER_CONFORMANCE_RESULTS": str(out),
                "PYTHONPATH": os.pathsep.join(
                    [str(HERE), *filter(None, [os.environ.get("PYTHONPATH")])]
                ),
            }
            cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "harvest"]
            cmd += ["-m", "not slow" if fast else "slow or not slow", *tests]
            if keyword:
                cmd += ["-k", keyword]
            print("$", " ".join(cmd), flush=True)
            subprocess.run(cmd, cwd=package, env=env, check=False)
            if not out.exists():
                raise SystemExit(f"{package}: pytest wrote no results (see its output above)")
            lines += [json.loads(line) for line in out.read_text().splitlines()]
    return lines


def _aspect(test: str) -> str | None:
    for aspect, words in ASPECTS.items():
        if any(w in test for w in words):
            return aspect
    return None


def _aspect_cell(results: list[TestResult]) -> str:
    """One column: the failing test's message, else the figures of the fullest test that ran
    (a slow test over a fast one)."""
    if not results:
        return ""
    bad = [r for r in results if r.outcome in ("failed", "error")]
    if bad:
        return f"✗ {bad[0].test}: {bad[0].message}"
    kept = [r for r in results if r.outcome == "xfailed"]
    ranked = sorted(results, key=lambda r: (r.slow, "figures" in r.properties))
    figures = ranked[-1].properties.get("figures", "passed")
    if kept:
        return f"✓ kept difference: {kept[0].message}; {figures}"
    noted = [r.properties["kept"] for r in results if "kept" in r.properties]
    if noted:
        return f"✓ {figures}; kept: {noted[0]}"
    return f"✓ {figures}"


def row_for(env_id: str, results: list[TestResult]) -> str:
    family = family_of(env_id)
    category = FAMILY_SOURCES[family].category
    deviation = " ".join(
        d for d in (CATEGORY_DEVIATIONS.get(category, ""), DEVIATIONS.get(family, "")) if d
    )
    if not results and env_id in KNOWN_DIFFERENCES:
        cells = [f"differs: {KNOWN_DIFFERENCES[env_id]}", "", "", "", "", "", deviation]
        return "| " + " | ".join([f"`{env_id}`", *map(_cell, cells)]) + " |"
    if not results:
        reason = UNCOVERED.get(env_id, "no fixture recorded")
        cells = [f"not recorded: {reason}", "", "", "", "", "", deviation]
        return "| " + " | ".join([f"`{env_id}`", *map(_cell, cells)]) + " |"
    by_aspect: dict[str, list[TestResult]] = {a: [] for a in ASPECTS}
    for r in results:
        aspect = _aspect(r.test)
        if aspect is not None:
            by_aspect[aspect].append(r)
    failed = [r for r in results if r.outcome in ("failed", "error")]
    divergence = "; ".join(
        r.properties["divergence"] for r in by_aspect["transitions"] if "divergence" in r.properties
    )
    if failed:
        verdict = f"differs ({len(failed)} of {len(results)} tests fail)"
    elif any(r.outcome == "xfailed" or "kept" in r.properties for r in results) or divergence:
        verdict = "conforms, kept deviation"
    else:
        verdict = "conforms"
    seeded = _aspect_cell(by_aspect["seed for seed"]) or NO_SEED_FOR_SEED.get(category, "")
    transitions = by_aspect["transitions"]
    tolerance = next(
        (r.properties["tolerance"] for r in transitions if "tolerance" in r.properties), ""
    )
    first = divergence or ("none" if transitions and not failed else "")
    cells = [
        verdict,
        _aspect_cell(by_aspect["distribution"]),
        seeded,
        _aspect_cell(transitions),
        first,
        tolerance,
        deviation,
    ]
    return "| " + " | ".join([f"`{env_id}`", *map(_cell, cells)]) + " |"


#: A row of the per-id tables, keyed by its id.
ROW_LINE = re.compile(r"^\| `(kinder/[^`]+)` \|")
#: A suite-wide check's line, keyed by its test (and parameter).
SUITE_LINE = re.compile(r"^- (`[^`]+`(?: \[[^\]]*\])?):")


def read_lines(path: Path, pattern: re.Pattern[str]) -> dict[str, str]:
    """The existing table's lines that match ``pattern``, by its first group (a ``--family``
    run keeps the rows and suite-wide checks it did not regenerate)."""
    out: dict[str, str] = {}
    if path.exists():
        for line in path.read_text().splitlines():
            m = pattern.match(line)
            if m:
                out[m.group(1)] = line
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--fast", action="store_true", help="only the default (not slow) tests")
    parser.add_argument("--family", help="a category or a family: regenerate only its rows")
    args = parser.parse_args(argv)
    all_ids = kinder_core.list_envs()
    KNOWN_IDS.update(all_ids)
    todo = expand_family(args.family) if args.family else all_ids
    categories = {FAMILY_SOURCES[family_of(i)].category for i in todo}
    files = [f for c in CATEGORIES if c in categories for f in TEST_FILES[c]]
    keyword = args.family if args.family and args.family not in CATEGORIES else None
    keyword = FAMILY_KEYWORDS.get(keyword or "", keyword)
    start = time.monotonic()
    results: dict[str, list[TestResult]] = {}
    suite: list[str] = []
    for line in run_tests(files, args.fast, keyword):
        result = TestResult(
            test=str(line["test"]),
            outcome=str(line["outcome"]),
            message=str(line["message"]),
            slow=bool(line.get("slow")),
            properties=dict(line["properties"]),  # type: ignore[call-overload]
        )
        env_id = env_id_of(str(line["param"])) if line["param"] else None
        if env_id is None:
            suite.append(
                f"- `{result.test}`"
                + (f" [{line['param']}]" if line["param"] else "")
                + f": {result.outcome}"
                + (f" ({_cell(result.message)})" if result.message else "")
            )
        else:
            results.setdefault(env_id, []).append(result)
    lines = read_lines(args.out, ROW_LINE) if args.family else {}
    if args.family:  # the checks this run did not repeat stay as they were
        kept = read_lines(args.out, SUITE_LINE)
        for line in suite:
            m = SUITE_LINE.match(line)
            kept[m.group(1) if m else line] = line
        suite = list(kept.values())
    for env_id in todo:
        lines[env_id] = row_for(env_id, results.get(env_id, []))
        print(lines[env_id], flush=True)
    minutes = (time.monotonic() - start) / 60
    which = "the default tests only" if args.fast else "every test, slow ones included"
    if not args.family:
        which += f"; {minutes:.0f} minutes on the project's 2-core machine"
    out = [HEADER.format(which=which)]
    out.append("\n## Summary\n")
    out.append("| category | ids | conforms | conforms, kept deviation | differs | not recorded |")
    out.append("|---|---|---|---|---|---|")
    for category in CATEGORIES:
        ids = [i for i in all_ids if FAMILY_SOURCES[family_of(i)].category == category]
        verdicts = [lines.get(i, "").split(" | ")[1] if lines.get(i) else "" for i in ids]
        count = [
            sum(v == "conforms" for v in verdicts),
            sum(v == "conforms, kept deviation" for v in verdicts),
            sum(v.startswith("differs") for v in verdicts),
            sum(v.startswith("not recorded") for v in verdicts),
        ]
        out.append(f"| {category} | {len(ids)} | " + " | ".join(map(str, count)) + " |")
    for category in CATEGORIES:
        ids = [i for i in all_ids if FAMILY_SOURCES[family_of(i)].category == category]
        out.append(f"\n## {category}\n")
        if category in CATEGORY_NOTES:
            out.append(CATEGORY_NOTES[category] + "\n")
        out.append(
            "| id | verdict | distribution | seed for seed | transitions | first divergence "
            "| tolerance | kept deviations |"
        )
        out.append("|---|---|---|---|---|---|---|---|")
        for env_id in ids:
            out.append(lines.get(env_id, f"| `{env_id}` | not run |  |  |  |  |  |  |"))
    if suite:
        out.append("\n## Suite-wide checks\n")
        out += suite
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text("\n".join(out) + "\n")
    tmp.replace(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
