"""GSC's chained sampler: one joint diffusion over a whole skeleton's states and parameters.

For a skeleton ``π₁(o₁) … π_K(o_K)`` and the observed state ``s₀``, the chain vector is
``X = [s₀, a₁, s₁, a₂, s₂, …, a_K, s_K]`` (states as normalised Box-view vectors), a batch of
``num_samples`` chains started from Gaussian noise. For ``k = N … 1`` (``t = k/N``):

1. each skill ``i`` reads its window ``[s_{i−1}, a_i, s_i]`` (objects reordered for its grounding),
   predicts ε, forms ``x̂₀ = (x − √(1−ᾱ)·ε)/√ᾱ``, clips it to [-1, 1] and recomputes ε from the
   clipped ``x̂₀``;
2. the chain's ε is skill ``i``'s on ``a_i``; on a shared state ``s_i`` (``0 < i < K``) it is
   ``γ_i·ε_i[s′] + (1 − γ_i)·ε_{i+1}[s]`` (γ = 1: forward chaining, the effect of skill i
   decides ``s_i``; γ = 0: backward, the next skill's precondition pulls it); ``s_K`` takes
   ``ε_K[s′]`` and ``s₀`` ``ε₁[s]``;
3. the chain's ``x̂₀`` is formed, clipped, and **inpainted**: ``s₀`` is set to the observed state,
   and in every ``s_i`` the *fixed* entries (the model's static features and every feature of the
   objects no skill of the skeleton takes as an argument) are copied from ``s₀``;
4. ``x_{t−1} = √ᾱ(t−1/N)·x̂₀ + √(1 − ᾱ(t−1/N))·z`` with fresh noise ``z`` (GSC's DDPM-style
   re-noising); the last step returns ``x̂₀``.

Afterwards the states are mapped back to features, ``s₀`` and the fixed entries are set to the
observed values *exactly* (no round trip through the normalisation), parameters are clipped to
each controller's bounds, and every sample is scored by the product over skills of the
feasibility classifier on ``(s_{i−1}, a_i)``; :attr:`ChainSamples.order` lists samples best first.

Left open by the public code and chosen here: ``N`` (GSC: 256; default 50 here for CPU time),
the batch (GSC: 40), γ (GSC: 1 except one backward step in hook-reach; default 0.5 here on every
shared state, so a skill's parameters also adapt to what the next skill needs), no constraint
guidance (KinDER has no differentiable constraint to guide with; the ranking does that job).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import torch
from numpy.typing import NDArray

from kinder_bench.baselines.gsc.model import GSCModel, alpha_bar

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


@dataclasses.dataclass(frozen=True)
class ChainStep:
    """One skeleton step: a lifted operator and the object names it is grounded on."""

    operator: str
    objects: tuple[str, ...]


@dataclasses.dataclass
class ChainSamples:
    """``num_samples`` sampled chains for one skeleton."""

    states: FloatArray
    """``(B, K + 1, D)`` Box-view state vectors; ``states[:, 0]`` is the observed state."""
    params: list[FloatArray]
    """Per skeleton step, ``(B, p_i)`` parameters (within the controller's bounds)."""
    log_scores: FloatArray
    """``(B,)`` sum over steps of the log feasibility probability."""
    order: IntArray
    """Sample indices, best score first."""

    def best_params(self) -> list[FloatArray]:
        """The parameters of the top-ranked sample, one array per step."""
        b = int(self.order[0])
        return [p[b].copy() for p in self.params]


def fixed_entries(model: GSCModel, skeleton: Sequence[ChainStep]) -> NDArray[np.bool_]:
    """The Box-view entries held at their initial value in every state of the chain: the
    model's static features and every feature of the objects the skeleton never names."""
    fixed: NDArray[np.bool_] = np.array(model.static, dtype=bool)
    touched = {o for step in skeleton for o in step.objects}
    for name in model.layout.names:
        if name not in touched:
            fixed[model.layout.object_dims(name)] = True
    return fixed


@torch.no_grad()
def sample_chain(
    model: GSCModel,
    s0: FloatArray,
    skeleton: Sequence[ChainStep],
    num_samples: int = 40,
    steps: int = 50,
    gamma: float | Sequence[float] = 0.5,
    seed: int = 0,
) -> ChainSamples:
    """Sample ``num_samples`` chains for ``skeleton`` from ``s0`` (module docstring).

    Args:
        model: The trained per-skill models of ``s0``'s env.
        s0: The observed state (Box-view vector).
        skeleton: The steps; every operator must have a model.
        num_samples: Chains sampled jointly (the batch).
        steps: Denoising steps ``N``.
        gamma: The forward/backward weight on each shared state (one value for all, or
            ``K − 1`` values).
        seed: Seeds the sampler's noise.
    """
    layout = model.layout
    d = layout.dim
    s0 = np.asarray(s0, dtype=np.float64).reshape(-1)
    if s0.shape != (d,):
        raise ValueError(f"s0 has {s0.shape[0]} entries; {model.env_id}'s states have {d}")
    if not skeleton:
        raise ValueError("sample_chain: empty skeleton")
    missing = sorted({st.operator for st in skeleton} - set(model.skills))
    if missing:
        raise ValueError(
            f"No trained model for operator(s) {missing}; the checkpoint has {sorted(model.skills)}"
        )
    if num_samples < 1 or steps < 1:
        raise ValueError(f"num_samples and steps must be >= 1, got {num_samples}, {steps}")
    k = len(skeleton)
    gammas = [float(gamma)] * (k - 1) if isinstance(gamma, (int, float)) else list(gamma)
    if len(gammas) != k - 1 or not all(0.0 <= g <= 1.0 for g in gammas):
        raise ValueError(f"gamma must be one value or {k - 1} values in [0, 1], got {gamma}")

    # Offsets of s_0, a_1, s_1, ..., a_K, s_K in the chain vector.
    specs = [model.skills[st.operator] for st in skeleton]
    off_s, off_a = [0], []
    pos = d
    for spec in specs:
        off_a.append(pos)
        pos += spec.param_dim
        off_s.append(pos)
        pos += d
    total = pos
    perms = [torch.as_tensor(layout.order(st.objects), dtype=torch.long) for st in skeleton]
    windows = []
    for i, spec in enumerate(specs):
        windows.append(
            torch.cat(
                [
                    off_s[i] + perms[i],
                    torch.arange(off_a[i], off_a[i] + spec.param_dim),
                    off_s[i + 1] + perms[i],
                ]
            )
        )
    s0n = torch.as_tensor(model.state.norm(s0), dtype=torch.float32)
    fixed = torch.as_tensor(fixed_entries(model, skeleton))
    known = torch.zeros(total, dtype=torch.bool)
    known_val = torch.zeros(total)
    known[:d] = True
    known_val[:d] = s0n
    for i in range(1, k + 1):
        sl = slice(off_s[i], off_s[i] + d)
        known[sl] = fixed
        known_val[sl] = torch.where(fixed, s0n, torch.zeros(d))

    gen = torch.Generator().manual_seed(int(seed))
    x = torch.randn(num_samples, total, generator=gen)
    nets = [model.score_nets[st.operator] for st in skeleton]
    for step in range(steps, 0, -1):
        ab = alpha_bar(torch.tensor(step / steps))
        ab_prev = alpha_bar(torch.tensor((step - 1) / steps)) if step > 1 else torch.tensor(1.0)
        t = torch.full((num_samples,), step / steps)
        sa, s1a = ab.sqrt(), (1 - ab).sqrt()
        eps_total = torch.zeros_like(x)
        prev_next: torch.Tensor | None = None  # skill i-1's ε on s_{i-1} (global order)
        for i, (spec, net) in enumerate(zip(specs, nets, strict=True)):
            w = x[:, windows[i]]
            eps = net(w, t)
            x0 = ((w - s1a * eps) / sa).clamp(-1.0, 1.0)
            eps = (w - sa * x0) / s1a
            eps_s = torch.zeros(num_samples, d)
            eps_s[:, perms[i]] = eps[:, :d]
            eps_next = torch.zeros(num_samples, d)
            eps_next[:, perms[i]] = eps[:, d + spec.param_dim :]
            if prev_next is None:
                eps_total[:, :d] = eps_s
            else:
                g = gammas[i - 1]
                eps_total[:, off_s[i] : off_s[i] + d] = g * prev_next + (1 - g) * eps_s
            eps_total[:, off_a[i] : off_a[i] + spec.param_dim] = eps[:, d : d + spec.param_dim]
            prev_next = eps_next
        assert prev_next is not None
        eps_total[:, off_s[k] : off_s[k] + d] = prev_next
        x0 = ((x - s1a * eps_total) / sa).clamp(-1.0, 1.0)
        x0 = torch.where(known, known_val, x0)
        if step > 1:
            z = torch.randn(x.shape, generator=gen)
            x = ab_prev.sqrt() * x0 + (1 - ab_prev).sqrt() * z
        else:
            x = x0

    xn = x.double().numpy()
    fixed_np = fixed.numpy()
    states = np.empty((num_samples, k + 1, d))
    for i in range(k + 1):
        s = model.state.denorm(xn[:, off_s[i] : off_s[i] + d])
        s[:, fixed_np] = s0[fixed_np]
        states[:, i] = s
    states[:, 0] = s0
    params = []
    for i, spec in enumerate(specs):
        a = spec.scaler.denorm(xn[:, off_a[i] : off_a[i] + spec.param_dim])
        params.append(np.clip(a, spec.param_lo, spec.param_hi))

    # Rank by the product of the feasibility classifiers on (s_{i-1}, a_i).
    log_scores = torch.zeros(num_samples, dtype=torch.float64)
    for i, st in enumerate(skeleton):
        spec = specs[i]
        s_prev = torch.as_tensor(model.state.norm(states[:, i])[:, layout.order(st.objects)])
        a_n = torch.as_tensor(spec.scaler.norm(params[i]))
        inp = torch.cat([s_prev, a_n], dim=1).float()
        logit = model.classifiers[st.operator](inp).double()
        log_scores += torch.nn.functional.logsigmoid(logit)
    scores = log_scores.numpy()
    order = np.argsort(-scores, kind="stable").astype(np.intp)
    return ChainSamples(states, params, scores, order)


__all__ = ["ChainSamples", "ChainStep", "fixed_entries", "sample_chain"]
