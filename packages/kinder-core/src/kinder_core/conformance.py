"""Check one of our environments against a fixture recorded from upstream kindergarden 0.2.5.

A fixture (format: ``tools/conformance/README.md``; recorder: ``tools/conformance/``) holds
upstream's seeded initial states and trajectories of one id. This module loads it and compares:

* transitions: our env starts from upstream's exact state vector (``reset(options={"init_state":
  vector})``), replays upstream's actions, and each step's state, reward and termination must
  equal upstream's within a tolerance given per family;
* reset distributions: per feature, constants must be equal, and sampled features must cover the
  same range and pass a two-sample Kolmogorov-Smirnov test (statistic computed here, in numpy);
* seeded resets: the same seed draws the same initial state (where we reproduce upstream's RNG
  calls).

Every check returns a structured report (first divergence, feature, maximum error) from which the
conformance table in ``docs/conformance.md`` is generated. numpy only.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from kinder_core.state import FloatArray

#: The type of pytest's ``record_property`` fixture. Conformance tests record what they measured
#: and the tolerance they applied under the names ``conformance_figures``,
#: ``conformance_tolerance``, ``conformance_divergence`` (where a replay stopped, and why) and
#: ``conformance_kept`` (a difference the test leaves out or allows for);
#: ``tools/conformance/table.py`` shows them in ``docs/conformance.md`` beside each test's
#: verdict.
RecordProperty = Callable[[str, object], None]

FORMAT_VERSION = 1
_ID_RE = re.compile(r"^kinder/(?P<family>[A-Za-z0-9]+)(?:-(?P<variant>.+?))?-v(?P<v>\d+)$")


def fixture_name(env_id: str) -> str:
    """The fixture file of an id: ``kinder/StickButton2D-b1-v0`` -> ``StickButton2D-b1.json``."""
    m = _ID_RE.match(env_id)
    if m is None:
        raise ValueError(
            f"{env_id!r} is not a KinDER id; expected 'kinder/<Family>-<variant>-v<N>'"
        )
    family, variant = m.group("family"), m.group("variant")
    return f"{family}-{variant}.json" if variant else f"{family}.json"


# -- fixtures -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Trajectory:
    """Upstream's run from one state: ``states[k]`` is the state after ``actions[k]``."""

    name: str
    kind: str
    seed: int
    init_state: FloatArray
    actions: FloatArray
    states: FloatArray
    rewards: FloatArray
    terminated: np.ndarray[Any, np.dtype[np.bool_]]


@dataclass(frozen=True)
class ResetRecord:
    """Upstream's seeded resets: full vectors of the first seeds, every seed's sampled features."""

    num_seeds: int
    seeds: list[int]
    vectors: FloatArray
    constants: dict[str, float]
    samples: dict[str, FloatArray]
    min: FloatArray
    max: FloatArray


@dataclass(frozen=True)
class Fixture:
    """One id's recording (see ``tools/conformance/README.md``)."""

    env_id: str
    upstream: str
    feature_names: list[str]
    action_low: FloatArray
    action_high: FloatArray
    resets: ResetRecord
    trajectories: list[Trajectory]


def _array(values: Any, what: str, path: Path, ndim: int) -> FloatArray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != ndim and arr.size:
        raise ValueError(f"{path}: {what} should be {ndim}-D, got shape {arr.shape}")
    return arr


def load_fixture(path: str | Path) -> Fixture:
    """Read a fixture file, rebuilding each trajectory's states from its per-step deltas."""
    path = Path(path)
    raw = json.loads(path.read_text())
    if raw.get("format") != FORMAT_VERSION:
        raise ValueError(
            f"{path}: fixture format {raw.get('format')!r}; expected {FORMAT_VERSION} "
            f"(re-record with tools/conformance/record_upstream.py)"
        )
    names = list(raw["feature_names"])
    r = raw["resets"]
    resets = ResetRecord(
        num_seeds=int(r["num_seeds"]),
        seeds=[int(s) for s in r["seeds"]],
        vectors=_array(r["vectors"], "resets.vectors", path, 2).reshape(-1, len(names)),
        constants={k: float(v) for k, v in r["constants"].items()},
        samples={k: _array(v, f"resets.samples[{k}]", path, 1) for k, v in r["samples"].items()},
        min=_array(r["min"], "resets.min", path, 1),
        max=_array(r["max"], "resets.max", path, 1),
    )
    trajectories = []
    for t in raw["trajectories"]:
        state = _array(t["init_state"], "init_state", path, 1)
        if state.shape != (len(names),):
            raise ValueError(f"{path}: {t['name']}: init_state has {state.size} features, "
                             f"expected {len(names)}")  # fmt: skip
        states = []
        for delta in t["deltas"]:
            state = state.copy()
            for i, v in delta:
                state[int(i)] = float(v)
            states.append(state)
        trajectories.append(
            Trajectory(
                name=str(t["name"]),
                kind=str(t["kind"]),
                seed=int(t["seed"]),
                init_state=_array(t["init_state"], "init_state", path, 1),
                actions=_array(t["actions"], "actions", path, 2),
                states=np.array(states, dtype=np.float64).reshape(-1, len(names)),
                rewards=_array(t["rewards"], "rewards", path, 1),
                terminated=np.asarray(t["terminated"], dtype=bool),
            )
        )
    return Fixture(
        env_id=str(raw["env_id"]),
        upstream=str(raw["upstream"]),
        feature_names=names,
        action_low=_array(raw["action_low"], "action_low", path, 1),
        action_high=_array(raw["action_high"], "action_high", path, 1),
        resets=resets,
        trajectories=trajectories,
    )


def _check_names(env: gymnasium.Env[Any, Any], fixture: Fixture) -> None:
    """Our Box features must be upstream's, in the same order."""
    space = getattr(env.unwrapped, "box_space", None)
    ours = list(getattr(space, "feature_names", []))
    if ours != fixture.feature_names:
        diff = [(i, a, b) for i, (a, b) in enumerate(zip(ours, fixture.feature_names)) if a != b]
        raise ValueError(
            f"{fixture.env_id}: our Box features differ from upstream's ({len(ours)} vs "
            f"{len(fixture.feature_names)} features; first differences (index, ours, upstream): "
            f"{diff[:3]})"
        )


def _vector(obs: Any) -> FloatArray:
    return np.asarray(obs, dtype=np.float64).ravel()


# -- transitions --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Divergence:
    """The first place a replay left upstream's trajectory."""

    step: int  # 0-based index of the action after which it diverged
    what: str  # "state", "reward" or "terminated"
    feature: str | None  # for "state": the feature with the largest error
    ours: float
    upstream: float
    error: float


@dataclass(frozen=True)
class TrajectoryReport:
    """One replayed trajectory: how far ours followed upstream's."""

    name: str
    kind: str
    steps: int
    atol: float
    max_error: float  # over every step compared (state features), up to the end or a stop
    first_divergence: Divergence | None

    @property
    def ok(self) -> bool:
        return self.first_divergence is None


def replay(
    env: gymnasium.Env[Any, Any], fixture: Fixture, trajectory: Trajectory, atol: float
) -> TrajectoryReport:
    """Replay one trajectory in ``env`` (Box observations in upstream's order).

    The replay runs to the end even after a divergence (it follows our own states), so the
    report's ``max_error`` is the largest state error along the whole trajectory, while
    ``first_divergence`` marks the first step exceeding ``atol``.
    """
    names = fixture.feature_names
    obs, _ = env.reset(options={"init_state": trajectory.init_state.copy()})
    start_err = np.abs(_vector(obs) - trajectory.init_state)
    first: Divergence | None = None
    if start_err.size and start_err.max() > atol:
        i = int(np.argmax(start_err))
        first = Divergence(-1, "state", names[i], float(_vector(obs)[i]),
                           float(trajectory.init_state[i]), float(start_err[i]))  # fmt: skip
    max_error = float(start_err.max()) if start_err.size else 0.0
    for k, action in enumerate(trajectory.actions):
        obs, reward, terminated, _, _ = env.step(action.copy())
        ours = _vector(obs)
        err = np.abs(ours - trajectory.states[k])
        max_error = max(max_error, float(err.max()) if err.size else 0.0)
        if first is None:
            if err.size and err.max() > atol:
                i = int(np.argmax(err))
                first = Divergence(
                    k, "state", names[i], float(ours[i]), float(trajectory.states[k][i]),
                    float(err[i]),
                )  # fmt: skip
            elif abs(float(reward) - trajectory.rewards[k]) > atol:
                first = Divergence(k, "reward", None, float(reward), float(trajectory.rewards[k]),
                                   abs(float(reward) - float(trajectory.rewards[k])))  # fmt: skip
            elif bool(terminated) != bool(trajectory.terminated[k]):
                first = Divergence(k, "terminated", None, float(bool(terminated)),
                                   float(trajectory.terminated[k]), 1.0)  # fmt: skip
        if terminated:
            break
    if first is None and len(trajectory.actions) and not terminated and trajectory.terminated[-1]:
        k = len(trajectory.actions) - 1
        first = Divergence(k, "terminated", None, 0.0, 1.0, 1.0)
    return TrajectoryReport(
        name=trajectory.name,
        kind=trajectory.kind,
        steps=len(trajectory.actions),
        atol=atol,
        max_error=max_error,
        first_divergence=first,
    )


def check_transitions(
    env: gymnasium.Env[Any, Any], fixture: Fixture, atol: float
) -> list[TrajectoryReport]:
    """Replay every trajectory of a fixture in ``env`` (see :func:`replay`)."""
    _check_names(env, fixture)
    return [replay(env, fixture, t, atol) for t in fixture.trajectories]


# -- reset distributions -----------------------------------------------------------------------
def ks_statistic(a: Sequence[float] | FloatArray, b: Sequence[float] | FloatArray) -> float:
    """The two-sample Kolmogorov-Smirnov statistic: the largest gap between the empirical CDFs."""
    x, y = np.sort(np.asarray(a, dtype=np.float64)), np.sort(np.asarray(b, dtype=np.float64))
    if x.size == 0 or y.size == 0:
        raise ValueError("ks_statistic: both samples must be non-empty")
    grid = np.concatenate([x, y])
    fx = np.searchsorted(x, grid, side="right") / x.size
    fy = np.searchsorted(y, grid, side="right") / y.size
    return float(np.max(np.abs(fx - fy)))


def ks_critical(n: int, m: int, alpha: float) -> float:
    """The asymptotic two-sample KS critical value at significance ``alpha``."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"ks_critical: alpha must be in (0, 1), got {alpha}")
    return math.sqrt(-math.log(alpha / 2.0) / 2.0) * math.sqrt((n + m) / (n * m))


@dataclass(frozen=True)
class FeatureReport:
    """One feature's reset distribution, ours against upstream's."""

    name: str
    kind: str  # "constant" (upstream's value is the same on every seed) or "sampled"
    ok: bool
    ours_min: float
    ours_max: float
    upstream_min: float
    upstream_max: float
    ks: float | None = None  # sampled features only
    ks_critical: float | None = None
    detail: str = ""


@dataclass(frozen=True)
class DistributionReport:
    """Every feature's reset distribution for one id."""

    env_id: str
    num_ours: int
    num_upstream: int
    features: list[FeatureReport] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(f.ok for f in self.features)

    @property
    def failures(self) -> list[FeatureReport]:
        return [f for f in self.features if not f.ok]

    def summary(self) -> str:
        """One line for the conformance table: how many features match, on how many seeds."""
        ok = sum(f.ok for f in self.features)
        return (
            f"{ok}/{len(self.features)} features; {self.num_ours} of our seeds against "
            f"{self.num_upstream} of upstream's"
        )


def sample_resets(env: gymnasium.Env[Any, Any], seeds: Iterable[int]) -> FloatArray:
    """Our initial states (Box vectors) for the given seeds, one row per seed."""
    return np.array([_vector(env.reset(seed=int(s))[0]) for s in seeds], dtype=np.float64)


def compare_resets(
    ours: FloatArray,
    fixture: Fixture,
    alpha: float = 1e-3,
    range_slack: float = 0.02,
    const_atol: float = 1e-9,
) -> DistributionReport:
    """Compare our reset vectors (rows) with upstream's, feature by feature.

    A feature upstream holds constant must be that constant on every one of our resets (within
    ``const_atol``). A sampled feature passes when the two samples cover the same range and the
    KS statistic is below its critical value at ``alpha`` divided by the number of sampled
    features (so ``alpha`` bounds the chance that an id whose distribution matches fails). The
    range test allows for sampling: the probability mass outside the range of ``n`` draws is
    Beta(2, n − 1) distributed, so each sample (``m`` values) may have as many values outside the
    other's range (widened by ``range_slack`` of it at each end) as that mass's upper
    ``alpha``-quantile (per feature, as for KS) gives, plus four binomial standard deviations.
    """
    names = fixture.feature_names
    if ours.ndim != 2 or ours.shape[1] != len(names):
        raise ValueError(
            f"{fixture.env_id}: our reset vectors have shape {ours.shape}; expected "
            f"(num_seeds, {len(names)})"
        )
    r = fixture.resets
    feats = []
    for i, name in enumerate(names):
        col = ours[:, i]
        lo, hi = float(col.min()), float(col.max())
        if name in r.constants:
            want = r.constants[name]
            err = float(np.max(np.abs(col - want)))
            ok = err <= const_atol
            detail = "" if ok else f"upstream constant {want!r}; ours {lo!r}..{hi!r}"
            feats.append(FeatureReport(name, "constant", ok, lo, hi, want, want, detail=detail))
            continue
        up = r.samples[name]
        ulo, uhi = float(up.min()), float(up.max())
        a = alpha / max(1, len(r.samples))
        range_ok = _outside(col, ulo, uhi, range_slack) <= _allowed_outside(col.size, up.size, a)
        range_ok = range_ok and _outside(up, lo, hi, range_slack) <= _allowed_outside(
            up.size, col.size, a
        )
        ks = ks_statistic(col, up)
        crit = ks_critical(col.size, up.size, a)
        ok = range_ok and ks <= crit
        detail = ""
        if not range_ok:
            detail = f"range {lo:.4g}..{hi:.4g} vs upstream {ulo:.4g}..{uhi:.4g}"
        elif ks > crit:
            detail = f"KS {ks:.3f} > {crit:.3f}"
        feats.append(FeatureReport(name, "sampled", ok, lo, hi, ulo, uhi, ks, crit, detail))
    return DistributionReport(fixture.env_id, ours.shape[0], r.num_seeds, feats)


def _outside(values: FloatArray, lo: float, hi: float, slack: float) -> int:
    """How many ``values`` lie outside ``[lo, hi]`` widened by ``slack`` of its width."""
    pad = slack * (hi - lo)
    return int(np.count_nonzero((values < lo - pad) | (values > hi + pad)))


def _allowed_outside(m: int, n: int, alpha: float) -> float:
    """The most of ``m`` draws that may fall outside the range of ``n`` draws from the same
    distribution: ``m·x + 4·sqrt(m·x) + 1`` where ``x`` is the upper ``alpha``-quantile of the
    uncovered mass, Beta(2, n − 1), whose tail is ``(1 − x)^(n−1)·(1 + (n − 1)·x)``."""

    def tail(x: float) -> float:
        return float((1.0 - x) ** (n - 1) * (1.0 + (n - 1) * x))

    lo, hi = 0.0, 1.0
    for _ in range(60):  # bisection: tail() falls from 1 at x = 0 to 0 at x = 1
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tail(mid) > alpha else (lo, mid)
    mean = m * hi
    return mean + 4.0 * math.sqrt(mean) + 1.0


def check_resets(
    env: gymnasium.Env[Any, Any],
    fixture: Fixture,
    num_seeds: int | None = None,
    first_seed: int = 1000,
    alpha: float = 1e-3,
    range_slack: float = 0.02,
) -> DistributionReport:
    """Sample our resets on seeds ``first_seed..`` (as many as upstream recorded unless
    ``num_seeds``) and compare them with upstream's (see :func:`compare_resets`)."""
    _check_names(env, fixture)
    n = fixture.resets.num_seeds if num_seeds is None else num_seeds
    ours = sample_resets(env, range(first_seed, first_seed + n))
    return compare_resets(ours, fixture, alpha=alpha, range_slack=range_slack)


@dataclass(frozen=True)
class SeededReport:
    """Same seed, same initial state: how many of upstream's stored seeds we reproduce."""

    env_id: str
    matched: int
    total: int
    first_mismatch_seed: int | None
    feature: str | None
    max_error: float

    @property
    def ok(self) -> bool:
        return self.matched == self.total


def check_seeded_resets(
    env: gymnasium.Env[Any, Any], fixture: Fixture, atol: float = 1e-9
) -> SeededReport:
    """Reset ours with each seed whose full vector upstream stored and compare the states."""
    _check_names(env, fixture)
    r = fixture.resets
    matched, first, feature, max_error = 0, None, None, 0.0
    for seed, want in zip(r.seeds, r.vectors):
        err = np.abs(_vector(env.reset(seed=seed)[0]) - want)
        e = float(err.max()) if err.size else 0.0
        max_error = max(max_error, e)
        if e <= atol:
            matched += 1
        elif first is None:
            first, feature = seed, fixture.feature_names[int(np.argmax(err))]
    return SeededReport(fixture.env_id, matched, len(r.seeds), first, feature, max_error)
