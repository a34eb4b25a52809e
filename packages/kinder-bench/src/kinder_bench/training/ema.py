"""An exponential moving average of a torch module's weights, as diffusion_policy keeps one.

Imports only the standard library at load time (torch when used), so a measurement on a machine
without this project installed can load it by file path (``benchmarks/speed/dp_gpu_cost.py``).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch


class EMA:
    """Exponential moving average of a module's parameters (diffusion_policy's ``EMAModel``
    schedule: ``decay = min(1 - (1 + step)^-0.75, 0.9999)``)."""

    def __init__(self, module: torch.nn.Module, power: float = 0.75, max_decay: float = 0.9999):
        self.module = copy.deepcopy(module).eval()
        for p in self.module.parameters():
            p.requires_grad_(False)
        self.power = power
        self.max_decay = max_decay
        self.step = 0

    def decay(self) -> float:
        return float(min(max(1.0 - (1.0 + self.step) ** -self.power, 0.0), self.max_decay))

    def update(self, module: torch.nn.Module) -> None:
        import torch

        d = self.decay()
        with torch.no_grad():
            for ema_p, p in zip(self.module.parameters(), module.parameters(), strict=True):
                ema_p.mul_(d).add_(p.detach(), alpha=1.0 - d)
            for ema_b, b in zip(self.module.buffers(), module.buffers(), strict=True):
                ema_b.copy_(b)
        self.step += 1
