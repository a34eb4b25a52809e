"""GSC's learned parts for one env: per skill an ε-model over ``[s, a, s′]`` and a feasibility
classifier over ``[s, a]``, with the shared feature layout and normalisation.

* **Layout.** States are the env's Box-view vectors (every object). A skill sees them reordered
  with its operator's arguments first, in parameter order, then the other objects sorted by
  (type name, Box-view position), so one model serves every grounding of its operator.
* **Normalisation** to [-1, 1]: states per ``type.feature`` (one min/max over every object of
  that type and every state in the data, so reordering objects never changes the scaling);
  parameters by the controller's parameter bounds (by the data where a bound is infinite).
  A feature that is constant in the data maps to 0 (scale 1 around its value).
* **Noise** (GSC's VP-SDE): ``ᾱ(t) = cos²(((t + 0.008) / 1.008)·π/2)`` for ``t ∈ (0, 1]``,
  clamped to ``[1e-4, 1]``; the networks predict ε and are trained with the MSE.
* **Networks**: a residual MLP (``depth`` blocks of LayerNorm → Linear → SiLU → Linear, width
  ``hidden``, with a sinusoidal time embedding added to every block) for ε, zero-initialised
  output; an MLP with SiLU for the classifier's logit. GSC uses a 24-layer DiT over object tokens;
  the spec's flat-vector adaptation (learning-stack §3.3) is this MLP.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from kinder_bench.training.checkpoints import load_checkpoint
from kinder_core import ObjectCentricEnv

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: File name of the model inside a checkpoint directory.
MODEL_FILE = "model.pt"
#: Bumped when the layout of ``model.pt`` changes (the checkpoint's own format is
#: :data:`kinder_bench.training.checkpoints.FORMAT_VERSION`).
FORMAT_VERSION = 1


def alpha_bar(t: torch.Tensor) -> torch.Tensor:
    """GSC's cosine schedule ``ᾱ(t)``, clamped to ``[1e-4, 1]``."""
    return (torch.cos((t + 0.008) / 1.008 * math.pi / 2) ** 2).clamp(1e-4, 1.0)


def time_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """Sinusoidal embedding of ``t ∈ [0, 1]`` (scaled by 1000, as for discrete steps)."""
    half = dim // 2
    freqs = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=t.dtype) / half)
    args = 1000.0 * t[:, None] * freqs[None, :]
    return torch.cat([torch.sin(args), torch.cos(args)], dim=-1)


class ScoreNet(nn.Module):
    """ε-prediction network on a flat vector (module docstring)."""

    def __init__(self, dim: int, hidden: int, depth: int, temb: int = 64) -> None:
        super().__init__()
        self.temb_dim = temb
        self.inp = nn.Linear(dim, hidden)
        self.temb = nn.Sequential(nn.Linear(temb, hidden), nn.SiLU(), nn.Linear(hidden, hidden))
        self.blocks = nn.ModuleList(
            nn.Sequential(
                nn.LayerNorm(hidden),
                nn.Linear(hidden, hidden),
                nn.SiLU(),
                nn.Linear(hidden, hidden),
            )
            for _ in range(depth)
        )
        self.out = nn.Sequential(nn.LayerNorm(hidden), nn.Linear(hidden, dim))
        last = self.out[1]
        assert isinstance(last, nn.Linear)
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)

    def forward(self, x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        e = self.temb(time_embedding(t, self.temb_dim))
        h = self.inp(x)
        for block in self.blocks:
            h = h + block(h + e)
        out: torch.Tensor = self.out(h)
        return out


class Classifier(nn.Module):
    """Feasibility logit of ``[s, a]``."""

    def __init__(self, dim: int, hidden: int, depth: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        width = dim
        for _ in range(max(1, depth)):
            layers += [nn.Linear(width, hidden), nn.SiLU()]
            width = hidden
        layers.append(nn.Linear(width, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.net(x).squeeze(-1)
        return out


@dataclasses.dataclass(frozen=True)
class Layout:
    """The Box view's objects: names, type names, and each object's slice of the vector."""

    names: tuple[str, ...]
    types: tuple[str, ...]
    sizes: tuple[int, ...]
    features: tuple[str, ...]
    """``type.feature`` of every vector entry."""

    @classmethod
    def of_env(cls, env: ObjectCentricEnv) -> Layout:
        objs = env.box_space.objects
        return cls(
            tuple(o.name for o in objs),
            tuple(o.type.name for o in objs),
            tuple(len(o.type.features) for o in objs),
            tuple(f"{o.type.name}.{f}" for o in objs for f in o.type.features),
        )

    @property
    def dim(self) -> int:
        return len(self.features)

    def object_dims(self, name: str) -> IntArray:
        """The vector entries of one object."""
        i = self.names.index(name)
        start = sum(self.sizes[:i])
        return np.arange(start, start + self.sizes[i], dtype=np.intp)

    def order(self, args: Sequence[str]) -> IntArray:
        """The permutation putting ``args`` first (then the rest by type name, position):
        ``window = vector[order]``."""
        unknown = [a for a in args if a not in self.names]
        if unknown:
            raise ValueError(f"Objects {unknown} are not in this env's objects {list(self.names)}")
        rest = sorted(
            (i for i, n in enumerate(self.names) if n not in args),
            key=lambda i: (self.types[i], i),
        )
        objs = [self.names.index(a) for a in args] + rest
        return np.concatenate([self.object_dims(self.names[i]) for i in objs])

    def to_dict(self) -> dict[str, Any]:
        return {
            "names": list(self.names),
            "types": list(self.types),
            "sizes": list(self.sizes),
            "features": list(self.features),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Layout:
        return cls(
            tuple(d["names"]),
            tuple(d["types"]),
            tuple(int(s) for s in d["sizes"]),
            tuple(d["features"]),
        )


@dataclasses.dataclass
class Scaler:
    """Affine map ``z = (x − mid) / half`` to [-1, 1] per entry."""

    mid: FloatArray
    half: FloatArray

    @classmethod
    def from_bounds(cls, lo: FloatArray, hi: FloatArray) -> Scaler:
        half = (hi - lo) / 2.0
        half = np.where(half > 1e-9, half, 1.0)
        return cls((hi + lo) / 2.0, half)

    def norm(self, x: FloatArray) -> FloatArray:
        return (x - self.mid) / self.half

    def denorm(self, z: FloatArray) -> FloatArray:
        return z * self.half + self.mid


def state_scaler(layout: Layout, states: FloatArray) -> Scaler:
    """Per ``type.feature`` min/max over ``states`` (rows: Box-view vectors)."""
    keys = np.asarray(layout.features)
    lo = np.zeros(layout.dim)
    hi = np.zeros(layout.dim)
    for key in set(layout.features):
        cols = keys == key
        lo[cols] = states[:, cols].min()
        hi[cols] = states[:, cols].max()
    return Scaler.from_bounds(lo, hi)


@dataclasses.dataclass
class SkillSpec:
    """One skill's sizes and parameter scaling."""

    operator: str
    param_dim: int
    param_lo: FloatArray
    param_hi: FloatArray

    @property
    def scaler(self) -> Scaler:
        return Scaler.from_bounds(self.param_lo, self.param_hi)


@dataclasses.dataclass(frozen=True)
class NetConfig:
    """Network sizes (saved with the model)."""

    hidden: int = 128
    depth: int = 3
    classifier_hidden: int = 256
    classifier_depth: int = 3


class GSCModel:
    """Everything GSC learned for one env (module docstring)."""

    def __init__(
        self,
        env_id: str,
        layout: Layout,
        state: Scaler,
        static: NDArray[np.bool_],
        skills: Sequence[SkillSpec],
        net: NetConfig,
    ) -> None:
        self.env_id = env_id
        self.layout = layout
        self.state = state
        self.static = np.asarray(static, dtype=bool)
        """Box-view entries no recorded skill ever changed; inpainted from the initial state."""
        self.skills = {s.operator: s for s in skills}
        self.net = net
        d = layout.dim
        self.score_nets = nn.ModuleDict(
            {s.operator: ScoreNet(2 * d + s.param_dim, net.hidden, net.depth) for s in skills}
        )
        self.classifiers = nn.ModuleDict(
            {
                s.operator: Classifier(d + s.param_dim, net.classifier_hidden, net.classifier_depth)
                for s in skills
            }
        )

    def eval(self) -> GSCModel:
        self.score_nets.eval()
        self.classifiers.eval()
        return self

    def meta(self) -> dict[str, Any]:
        return {
            "format": FORMAT_VERSION,
            "env_id": self.env_id,
            "layout": self.layout.to_dict(),
            "state_mid": self.state.mid.tolist(),
            "state_half": self.state.half.tolist(),
            "static": self.static.tolist(),
            "skills": [
                {
                    "operator": s.operator,
                    "param_dim": s.param_dim,
                    "param_lo": s.param_lo.tolist(),
                    "param_hi": s.param_hi.tolist(),
                }
                for s in self.skills.values()
            ],
            "net": dataclasses.asdict(self.net),
        }

    def state_dict(self) -> dict[str, Any]:
        return {
            "meta": self.meta(),
            "score_nets": self.score_nets.state_dict(),
            "classifiers": self.classifiers.state_dict(),
        }

    @classmethod
    def from_state_dict(cls, data: dict[str, Any]) -> GSCModel:
        meta = data["meta"]
        if meta.get("format") != FORMAT_VERSION:
            raise ValueError(
                f"GSC checkpoint format {meta.get('format')!r}; this code reads {FORMAT_VERSION}"
            )
        skills = [
            SkillSpec(
                s["operator"],
                int(s["param_dim"]),
                np.asarray(s["param_lo"], dtype=np.float64),
                np.asarray(s["param_hi"], dtype=np.float64),
            )
            for s in meta["skills"]
        ]
        model = cls(
            meta["env_id"],
            Layout.from_dict(meta["layout"]),
            Scaler(np.asarray(meta["state_mid"]), np.asarray(meta["state_half"])),
            np.asarray(meta["static"], dtype=bool),
            skills,
            NetConfig(**meta["net"]),
        )
        model.score_nets.load_state_dict(data["score_nets"])
        model.classifiers.load_state_dict(data["classifiers"])
        return model

    def save(self, directory: Path | str) -> Path:
        """Write ``model.pt`` into ``directory`` (a checkpoint being written) atomically."""
        path = Path(directory) / MODEL_FILE
        atomic_torch_save(self.state_dict(), path)
        return path

    @classmethod
    def load(cls, path: Path | str) -> GSCModel:
        """The model of a ``kinder train gsc`` run directory (its newest checkpoint) or of one
        checkpoint directory.

        Raises:
            FileNotFoundError: no checkpoint at ``path``, or it lacks ``model.pt``.
            CheckpointError: not a GSC checkpoint of this format.
        """
        ckpt = load_checkpoint(path, ("gsc",))
        file = ckpt.path / MODEL_FILE
        if not file.is_file():
            raise FileNotFoundError(
                f"Checkpoint {ckpt.path} is incomplete: {MODEL_FILE} is missing"
            )
        return cls.from_state_dict(torch.load(file, map_location="cpu", weights_only=True))


def atomic_torch_save(obj: Any, path: Path) -> None:
    """``torch.save`` to a temporary file, then ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


__all__ = [
    "MODEL_FILE",
    "Classifier",
    "GSCModel",
    "Layout",
    "NetConfig",
    "Scaler",
    "ScoreNet",
    "SkillSpec",
    "alpha_bar",
    "atomic_torch_save",
    "state_scaler",
    "time_embedding",
]
