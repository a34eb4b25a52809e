"""MBRL: a learned state-delta model driving the MPC agent's predictive sampling.

The paper's "MBRL" baseline (appendix; spec baselines §3.2). A transition model is trained on the
demonstrations' transitions (consecutive frames of one episode of a KinDER dataset, see
:mod:`kinder_bench.baselines.demo_data`) by :func:`train_mbrl` (``kinder train mbrl``), and the
agent ``mbrl`` runs the existing MPC (:class:`~kinder_bench.baselines.mpc.MPCAgent`, same arguments
and defaults) with rollouts on that model instead of the env's ``transition``.

Model (``StateDeltaModel``): input ``[state, action]`` (state = the full Box observation vector
of the dataset's env; the dataset's ``StateSplit`` says which features are the robot's), a trunk
of two hidden layers of 256 with SiLU, and two linear heads predicting the robot-state delta and
the environment-state delta. Inputs and both targets are z-scored per feature (mean and std over
the training transitions, std + 1e-8 as upstream; but an *input* std below 1e-6 is replaced by 1,
because a feature that never varies in the training episodes but does in held-out ones, e.g. a
rarely pressed button, otherwise blows the inputs up by 1e8); the loss is MSE(robot head) +
MSE(env head); Adam, lr 1e-3, batch 512, shuffled every epoch (upstream's default: 1000 epochs).

Prediction: ``next = state + delta``, except that

* features constant across the training episodes are copied from the current state (upstream's
  ``preserved_indices``: constant across all demos), and
* angles (features named ``*.theta`` or ``*.yaw`` whose data lie in [-π, π]) are trained on the
  wrapped delta and re-wrapped after the step (upstream wraps StickButton2D's two angles).

Reward and termination come from the env's own goal check (``goal_reached``) and ``reward`` on the
*predicted* state, as the issue specifies (the upstream code evaluated them on the current state).
Features of the env that the dataset does not hold are kept fixed during rollouts.

Planning speed: the agent scores the MPC's candidates together (:class:`LearnedModelRollouts`,
with the MPC's ``batched`` argument, the default): one model call per step for all live
candidates, each of whose rows is computed exactly as a one-row call computes it (a stack of
one-row products, not one matrix product, whose BLAS kernel may round differently), the goal
check and reward vectorised on the Kinematic2D families (their batched worlds), the goal check of
other envs through their ``goals_reached`` (whole-array numpy on DynObstruction2D,
DynPushPullHook2D and the MuJoCo Dynamic3D families, a loop over ``goal_reached`` by default), and
the −1 reward without a call
where an env does not override it. The costs, hence the actions, equal the one-by-one loop's.

Held-out evaluation (:func:`open_loop_errors`): a deterministic 10% of the episodes (at least one)
is held out; from every start frame the model is rolled out open loop for ``k`` steps on the
recorded actions, and the error against the recorded state is reported as the mean L2 norm in
raw units and in per-feature z-units, next to the constant-state predictor (``s_{t+k} ≈ s_t``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from kinder_bench.agents.base import needs_checkpoint
from kinder_bench.baselines.demo_data import read_dataset_spec, resolve_dataset_env
from kinder_bench.baselines.mpc import (
    MPCAgent,
    MPCArgs,
    RolloutModel,
    batched_world_of,
    lockstep_costs,
)
from kinder_bench.evaluation.results import package_versions, write_json
from kinder_bench.training.checkpoints import (
    Checkpoint,
    check_resume_config,
    latest_checkpoint,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)
from kinder_bench.training.csvlog import CsvLog
from kinder_core import ObjectCentricEnv, ObjectCentricState

if TYPE_CHECKING:
    import torch

    from kinder_gym.demos.record import EpisodeRecord

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
ANGLE_FEATURES = ("theta", "yaw")
EVAL_HORIZONS = (1, 10)


def wrap_angle(x: NDArray[Any]) -> NDArray[Any]:
    """Angles wrapped to [-π, π)."""
    return (x + np.pi) % (2 * np.pi) - np.pi


@dataclasses.dataclass(frozen=True)
class MBRLTrainArgs:
    """Arguments of ``kinder train mbrl``."""

    dataset: Path
    """The demonstration dataset (a LeRobotDataset v3 directory)."""
    out: Path
    """The run directory (config.json, progress.csv, eval.json, checkpoints/)."""
    epochs: int = 1000
    """Passes over the training transitions in total (a resumed run continues up to this)."""
    batch_size: int = 512
    """Transitions per step."""
    lr: float = 1e-3
    """Adam learning rate."""
    hidden: int = 256
    """Width of the two hidden layers."""
    val_fraction: float = 0.1
    """Fraction of episodes held out for the open-loop evaluation (at least one)."""
    env: str | None = None
    """The env id (default: the one the dataset names)."""
    save_every: int = 50
    """Write a checkpoint every this many epochs (and at the end)."""
    seed: int = 0
    """Seeds the weights, the held-out split and the sample order."""
    keep: int = 2
    """Checkpoints to keep."""

    def __post_init__(self) -> None:
        checks = [
            (self.epochs >= 1, "epochs must be >= 1"),
            (self.batch_size >= 1, "batch_size must be >= 1"),
            (self.lr > 0, "lr must be > 0"),
            (self.hidden >= 1, "hidden must be >= 1"),
            (0 <= self.val_fraction < 1, "val_fraction must be in [0, 1)"),
            (self.save_every >= 1, "save_every must be >= 1"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"MBRLTrainArgs: {msg}, got {self}")


def _torch_model(in_dim: int, robot_dim: int, env_dim: int, hidden: int) -> Any:
    from torch import nn

    class StateDeltaModel(nn.Module):
        """Trunk (2 × ``hidden`` SiLU) and two linear heads (robot delta, environment delta)."""

        def __init__(self) -> None:
            super().__init__()
            self.trunk = nn.Sequential(
                nn.Linear(in_dim, hidden), nn.SiLU(), nn.Linear(hidden, hidden), nn.SiLU()
            )
            self.robot_head = nn.Linear(hidden, robot_dim)
            self.env_head = nn.Linear(hidden, env_dim)

        def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            h = self.trunk(x)
            return self.robot_head(h), self.env_head(h)

    return StateDeltaModel()


@dataclasses.dataclass(frozen=True)
class Transitions:
    """Stacked transitions: states, actions, next states (``(N, ·)`` float64)."""

    state: FloatArray
    action: FloatArray
    next_state: FloatArray


def episode_states(episode: EpisodeRecord) -> FloatArray:
    """The ``T + 1`` Box observations of an episode (the agent plans on observations)."""
    return np.asarray(episode.observations, dtype=np.float64)


def transitions(episodes: Sequence[EpisodeRecord]) -> Transitions:
    """Every ``(observation, action, next observation)`` of the episodes (the final one too)."""
    s, a, n = [], [], []
    for e in episodes:
        states = episode_states(e)
        s.append(states[:-1])
        a.append(np.asarray(e.actions, dtype=np.float64))
        n.append(states[1:])
    if not s or sum(len(x) for x in s) == 0:
        raise ValueError("No transitions: every episode is empty")
    return Transitions(np.concatenate(s), np.concatenate(a), np.concatenate(n))


def split_episodes(
    episodes: Sequence[EpisodeRecord], val_fraction: float, seed: int
) -> tuple[list[EpisodeRecord], list[EpisodeRecord]]:
    """(train, held-out): a seeded ``val_fraction`` of the episodes (at least one when there are
    two or more and the fraction is positive) is held out."""
    n = len(episodes)
    n_val = 0 if val_fraction <= 0 or n < 2 else max(1, round(val_fraction * n))
    order = np.random.default_rng([seed, 7]).permutation(n)
    val = set(order[:n_val].tolist())
    return (
        [e for i, e in enumerate(episodes) if i not in val],
        [e for i, e in enumerate(episodes) if i in val],
    )


def _dense(x: FloatArray, weight: FloatArray, bias: FloatArray, row_stable: bool) -> FloatArray:
    """``x @ weight.T + bias``; with ``row_stable`` every row is its own one-row product, so a
    row's result does not depend on the other rows of the batch."""
    if row_stable:
        out: FloatArray = (x[:, None, :] @ weight.T)[:, 0, :] + bias
        return out
    out = x @ weight.T + bias
    return out


def _silu(x: FloatArray) -> FloatArray:
    """``x * sigmoid(x)``, without overflow for large ``|x|`` (rollouts far from the data)."""
    out: FloatArray = x * 0.5 * (1.0 + np.tanh(0.5 * x))
    return out


@dataclasses.dataclass
class DeltaModel:
    """A trained state-delta model in numpy (what the agent rolls out; no torch needed).

    ``predict`` maps ``(B, state)`` and ``(B, action)`` to the next states.
    """

    weights: dict[str, FloatArray]
    state_mean: FloatArray
    state_std: FloatArray
    action_mean: FloatArray
    action_std: FloatArray
    delta_mean: FloatArray
    delta_std: FloatArray
    robot_index: NDArray[np.intp]
    env_index: NDArray[np.intp]
    constant: NDArray[np.bool_]
    angle: NDArray[np.bool_]
    names: tuple[str, ...]

    def predict(
        self, state: FloatArray, action: FloatArray, row_stable: bool = False
    ) -> FloatArray:
        """Next states of ``(B, state)`` under ``(B, action)``; ``row_stable``: each row exactly
        as a one-row call computes it (slower for large batches)."""
        x = np.concatenate(
            [
                (state - self.state_mean) / self.state_std,
                (action - self.action_mean) / self.action_std,
            ],
            axis=-1,
        )
        w = self.weights
        h = _silu(_dense(x, w["trunk.0.weight"], w["trunk.0.bias"], row_stable))
        h = _silu(_dense(h, w["trunk.2.weight"], w["trunk.2.bias"], row_stable))
        robot = _dense(h, w["robot_head.weight"], w["robot_head.bias"], row_stable)
        env = _dense(h, w["env_head.weight"], w["env_head.bias"], row_stable)
        delta = np.empty(robot.shape[:-1] + self.delta_mean.shape)
        delta[..., self.robot_index] = robot
        delta[..., self.env_index] = env
        delta = delta * self.delta_std + self.delta_mean
        nxt = state + delta
        nxt = np.where(self.angle, wrap_angle(nxt), nxt)
        return np.where(self.constant, state, nxt)

    def rollout(self, state: FloatArray, actions: FloatArray) -> FloatArray:
        """States after each of ``actions`` from ``state`` (open loop)."""
        out = []
        for a in actions:
            state = self.predict(state[None], a[None])[0]
            out.append(state)
        return np.asarray(out)


def _scale(x: FloatArray) -> FloatArray:
    """Per-feature std for z-scoring; 1 where the std is below 1e-6 (a feature that does not vary
    in the training data must not blow up when it does vary at test time)."""
    std = x.std(0)
    scale: FloatArray = np.where(std < 1e-6, 1.0, std)
    return scale


def _targets(data: Transitions, angle: NDArray[np.bool_]) -> FloatArray:
    delta = data.next_state - data.state
    return np.where(angle, wrap_angle(delta), delta)


def _feature_flags(
    names: Sequence[str], states: FloatArray
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    constant = np.all(states == states[:1], axis=0)
    in_range = np.all(np.abs(states) <= np.pi + 1e-6, axis=0)
    angle = np.array([n.rpartition(".")[2] in ANGLE_FEATURES for n in names]) & in_range
    return constant, angle


def open_loop_errors(
    model: DeltaModel, episodes: Sequence[EpisodeRecord], horizons: Sequence[int] = EVAL_HORIZONS
) -> dict[str, float]:
    """Mean open-loop errors of ``model`` and of the constant-state predictor after ``k`` steps
    (for every start frame with ``k`` recorded steps ahead): ``model_l2_k``/``const_l2_k`` in raw
    units, ``model_z_k``/``const_z_k`` in per-feature z-units, and ``count_k``."""
    out: dict[str, float] = {}
    for k in horizons:
        m_l2, c_l2, m_z, c_z = [], [], [], []
        for e in episodes:
            states = episode_states(e)
            actions = np.asarray(e.actions, dtype=np.float64)
            starts = np.arange(len(states) - k)
            if len(starts) == 0:
                continue
            pred = states[starts]
            for j in range(k):
                pred = model.predict(pred, actions[starts + j])
            truth = states[starts + k]
            err_m = pred - truth
            err_c = states[starts] - truth
            err_m = np.where(model.angle, wrap_angle(err_m), err_m)
            err_c = np.where(model.angle, wrap_angle(err_c), err_c)
            m_l2 += np.linalg.norm(err_m, axis=1).tolist()
            c_l2 += np.linalg.norm(err_c, axis=1).tolist()
            m_z += np.linalg.norm(err_m / model.state_std, axis=1).tolist()
            c_z += np.linalg.norm(err_c / model.state_std, axis=1).tolist()
        out[f"count_{k}"] = float(len(m_l2))
        for name, values in (
            ("model_l2", m_l2),
            ("const_l2", c_l2),
            ("model_z", m_z),
            ("const_z", c_z),
        ):
            out[f"{name}_{k}"] = float(np.mean(values)) if values else math.nan
    return out


def train_mbrl(args: MBRLTrainArgs, progress: bool = True) -> Path:
    """Train (or resume) the MBRL state-delta model into ``args.out``; returns the last
    checkpoint. Writes ``config.json``, ``progress.csv`` (epoch, loss, held-out one-step error,
    samples/s), ``eval.json`` (:func:`open_loop_errors` on the held-out episodes) and
    ``checkpoints/step_*/`` (step = epoch)."""
    import torch
    from tqdm import tqdm

    spec = read_dataset_spec(args.dataset)
    env_id = resolve_dataset_env(spec, args.env)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    record = {
        "trainer": "mbrl",
        "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
        "env_id": env_id,
        "versions": package_versions(),
    }
    check_resume_config(out, record, ("dataset", "seed", "batch_size", "hidden", "val_fraction"))
    write_json(out / "config.json", record)

    from kinder_gym.demos.lerobot_format import load_records

    episodes = load_records(spec.root)
    train_eps, val_eps = split_episodes(episodes, args.val_fraction, args.seed)
    data = transitions(train_eps)
    names = tuple(spec.split.feature_names)
    robot_index = spec.split.state_indices
    env_index = spec.split.env_indices
    train_states = np.concatenate([episode_states(e) for e in train_eps])
    constant, angle = _feature_flags(names, train_states)
    deltas = _targets(data, angle)
    s_mean, s_std = data.state.mean(0), _scale(data.state)
    a_mean, a_std = data.action.mean(0), _scale(data.action)
    d_mean, d_std = deltas.mean(0), deltas.std(0) + 1e-8  # a delta that never varies stays ~0

    torch.manual_seed(args.seed)
    in_dim = data.state.shape[1] + data.action.shape[1]
    net = _torch_model(in_dim, len(robot_index), len(env_index), args.hidden)
    optimizer = torch.optim.Adam(net.parameters(), lr=args.lr)
    x_all = torch.as_tensor(
        np.concatenate([(data.state - s_mean) / s_std, (data.action - a_mean) / a_std], 1),
        dtype=torch.float32,
    )
    y_norm = (deltas - d_mean) / d_std
    y_robot = torch.as_tensor(y_norm[:, robot_index], dtype=torch.float32)
    y_env = torch.as_tensor(y_norm[:, env_index], dtype=torch.float32)

    epoch = 0
    resume = latest_checkpoint(out)
    if resume is not None:
        read_checkpoint(resume, ("mbrl",))  # this format and method, or a clear error
        state = torch.load(resume / "training_state.pt", weights_only=False)
        net.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"])
        epoch = int(state["epoch"])

    def numpy_model() -> DeltaModel:
        weights = {k: v.detach().double().numpy().copy() for k, v in net.state_dict().items()}
        return DeltaModel(
            weights, s_mean, s_std, a_mean, a_std, d_mean, d_std, robot_index, env_index,
            constant, angle, names,
        )  # fmt: skip

    def write(ckpt: Path) -> None:
        torch.save(
            {"model": net.state_dict(), "optimizer": optimizer.state_dict(), "epoch": epoch,
             "torch_rng": torch.get_rng_state()},
            ckpt / "training_state.pt",
        )  # fmt: skip
        save_delta_model(ckpt, numpy_model())

    log = CsvLog(out / "progress.csv", ("epoch", "loss", "val_z_1", "samples_per_s", "elapsed_s"))
    last = resume
    n = len(x_all)
    bar = tqdm(total=args.epochs, initial=epoch, disable=not progress, desc=f"mbrl {env_id}")
    t0 = time.perf_counter()
    while epoch < args.epochs:
        t_epoch = time.perf_counter()
        perm = torch.as_tensor(np.random.default_rng([args.seed, epoch]).permutation(n))
        total = 0.0
        for lo in range(0, n, args.batch_size):
            idx = perm[lo : lo + args.batch_size]
            robot, env = net(x_all[idx])
            loss = torch.mean((robot - y_robot[idx]) ** 2)
            if len(env_index):
                loss = loss + torch.mean((env - y_env[idx]) ** 2)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()  # type: ignore[no-untyped-call]
            optimizer.step()
            total += float(loss.detach()) * len(idx)
        epoch += 1
        bar.update(1)
        is_last = epoch == args.epochs
        if epoch % args.save_every == 0 or is_last:
            val = open_loop_errors(numpy_model(), val_eps, (1,)) if val_eps else {}
            log.write(
                {
                    "epoch": epoch,
                    "loss": total / n,
                    "val_z_1": val.get("model_z_1", ""),
                    "samples_per_s": n / max(time.perf_counter() - t_epoch, 1e-9),
                    "elapsed_s": time.perf_counter() - t0,
                }
            )
            info = _info(env_id, names)
            last = save_checkpoint(out, epoch, "mbrl", args, write, info=info, keep=args.keep)
    bar.close()
    model = numpy_model()
    evaluation = {
        "held_out_episode_seeds": [e.seed for e in val_eps],
        "train_transitions": n,
        "epochs": epoch,
        **(open_loop_errors(model, val_eps) if val_eps else {}),
    }
    write_json(out / "eval.json", evaluation)
    assert last is not None
    return last


def save_delta_model(ckpt: Path, model: DeltaModel) -> None:
    """Write the model's weights and normalisation as ``model.npz`` into ``ckpt``."""
    arrays: dict[str, NDArray[Any]] = {f"w/{k}": v for k, v in model.weights.items()}
    arrays.update(
        state_mean=model.state_mean, state_std=model.state_std, action_mean=model.action_mean,
        action_std=model.action_std, delta_mean=model.delta_mean, delta_std=model.delta_std,
        constant=model.constant, angle=model.angle, robot_index=model.robot_index,
        env_index=model.env_index,
    )  # fmt: skip
    with (ckpt / "model.npz").open("wb") as f:
        np.savez(f, **arrays)  # type: ignore[arg-type]


def _info(env_id: str, names: Sequence[str]) -> dict[str, Any]:
    """The checkpoint's ``info``: the env and the feature names the model predicts."""
    return {"env_id": env_id, "names": list(names)}


def write_delta_checkpoint(
    run_dir: Path | str,
    model: DeltaModel,
    env_id: str,
    step: int,
    args: MBRLTrainArgs | Mapping[str, Any] | None = None,
) -> Path:
    """Write ``model`` alone (no training state) as the MBRL checkpoint at ``step`` of
    ``run_dir``, for a model made without :func:`train_mbrl`; returns the checkpoint."""
    return save_checkpoint(
        run_dir, step, "mbrl", args or {}, lambda d: save_delta_model(d, model),
        info=_info(env_id, model.names),
    )  # fmt: skip


def load_delta_model(path: Path | str) -> tuple[DeltaModel, Checkpoint]:
    """The model of a checkpoint (or of a run directory's latest one) and its checkpoint.

    Raises:
        FileNotFoundError: no checkpoint at ``path``.
        CheckpointError: not an MBRL checkpoint of this format.
    """
    checkpoint = load_checkpoint(path, ("mbrl",))
    with np.load(checkpoint.path / "model.npz") as z:
        weights = {k[2:]: z[k] for k in z.files if k.startswith("w/")}
        model = DeltaModel(
            weights, z["state_mean"], z["state_std"], z["action_mean"], z["action_std"],
            z["delta_mean"], z["delta_std"], z["robot_index"], z["env_index"], z["constant"],
            z["angle"], tuple(checkpoint.info["names"]),
        )  # fmt: skip
    return model, checkpoint


@dataclasses.dataclass(frozen=True)
class MBRLArgs(MPCArgs):
    """The MPC agent's arguments (same defaults) plus the learned model's checkpoint."""

    checkpoint: str = ""
    """A run directory of ``kinder train mbrl`` (its latest checkpoint) or one checkpoint."""


class MBRLAgent(MPCAgent):
    """MPC's predictive sampling rolled out on a learned state-delta model (MBRL).

    The planning state is the Box observation vector; a step predicts the dataset's features with
    the model (others stay fixed) and scores the predicted state with the env's ``goal_reached``
    and ``reward``.
    """

    name = "mbrl"
    Args = MBRLArgs

    @classmethod
    def unavailable(cls, args: Any, env_id: str) -> str | None:
        """Needs a trained checkpoint."""
        del env_id
        return needs_checkpoint(args, cls.name)

    def __init__(self, env: gymnasium.Env[Any, Any], args: MBRLArgs, seed: int) -> None:
        if not args.checkpoint:
            raise ValueError("Agent 'mbrl' needs --arg checkpoint=DIR (a `kinder train mbrl` run)")
        super().__init__(env, args, seed)
        self.delta_model, self.checkpoint = load_delta_model(args.checkpoint)
        box = self._model.box_space
        position = {n: i for i, n in enumerate(box.feature_names)}
        missing = [n for n in self.delta_model.names if n not in position]
        if missing:
            raise ValueError(
                f"{self._model.env_name} lacks {len(missing)} feature(s) the MBRL model was "
                f"trained on, e.g. {missing[:5]}"
            )
        self._index = np.asarray([position[n] for n in self.delta_model.names], dtype=np.intp)

    def planning_state(self, obs: Any) -> FloatArray:
        state: FloatArray = np.array(obs, dtype=np.float64)
        return state

    def fast_model(self) -> RolloutModel | None:
        return LearnedModelRollouts(self)

    def transition(self, state: Any, action: FloatArray) -> tuple[Any, float, bool]:
        vec = np.asarray(state, dtype=np.float64)
        action = self.clip(action)
        nxt = vec.copy()
        nxt[self._index] = self.delta_model.predict(vec[self._index][None], action[None])[0]
        box = self._model.box_space
        next_state = box.devectorize(nxt)
        terminated = bool(self._model.goal_reached(next_state))
        reward = float(self._model.reward(box.devectorize(vec), action, next_state, terminated))
        return nxt, reward, terminated


class LearnedModelRollouts:
    """MBRL's candidates stepped together on the learned model, with exactly the costs of
    :meth:`MBRLAgent.transition`'s one-by-one loop (see the module docstring)."""

    def __init__(self, agent: MBRLAgent) -> None:
        model = agent.model
        box = model.box_space
        self.agent = agent
        self.model = model
        self.layout = box.layout
        order = [box.layout.index(o, f) for o in box.objects for f in o.type.features]
        self._to_layout = np.argsort(np.asarray(order, dtype=np.intp))
        self._world = batched_world_of(model)
        self._default_reward = type(model).reward is ObjectCentricEnv.reward

    def costs(self, state: Any, plans: FloatArray) -> tuple[FloatArray, int]:
        agent, model, layout = self.agent, self.model, self.layout
        index = agent._index
        low, high = agent.action_space.low, agent.action_space.high

        def step(vecs: FloatArray, actions: FloatArray) -> tuple[FloatArray, FloatArray, BoolArray]:
            actions = np.clip(actions, low, high)
            nxt = vecs.copy()
            nxt[:, index] = agent.delta_model.predict(vecs[:, index], actions, row_stable=True)
            data = nxt[:, self._to_layout]
            if self._world is not None:
                terminated: BoolArray = np.asarray(self._world.goal(data), dtype=bool)
            else:
                terminated = np.asarray(model.goals_reached(data, layout), dtype=bool)
            if self._world is not None:
                rewards: FloatArray = np.asarray(self._world.reward(terminated), dtype=np.float64)
            elif self._default_reward:
                rewards = np.full(len(nxt), -1.0)
            else:
                rewards = np.array([
                    float(model.reward(ObjectCentricState(layout, v[self._to_layout]), a,
                                       ObjectCentricState(layout, d), bool(t)))
                    for v, a, d, t in zip(vecs, actions, data, terminated)
                ])  # fmt: skip
            return nxt, rewards, terminated

        return lockstep_costs(step, np.asarray(state, dtype=np.float64), plans)
