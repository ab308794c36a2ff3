"""What every training loop of the models shares: one CPU thread and seeded generators,
the cosine learning-rate decay (with an optional linear warm-up), and a CPU-time budget.

Training runs on one CPU thread and counts CPU time, not wall time: the machine is
shared, and both keep a run reproducible and its budget fair.
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch


def seeded(seed: int) -> np.random.Generator:
    """Set torch to one CPU thread and seed its global generator (the networks' initial
    weights, dropout) with ``seed``; returns NumPy's generator of the same seed (crops,
    augmentation, batch order)."""
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    return np.random.default_rng(seed)


def cosine_factor(step: int, total: int, *, floor: float = 0.0,
                  warmup_steps: int = 0) -> float:
    """Learning-rate factor at optimiser step ``step`` (0-based): ``(step + 1) /
    warmup_steps`` during the warm-up, then ``floor + (1 - floor) (1 + cos(π t)) / 2``
    with ``t = min(step / total, 1)``, from 1 down to ``floor`` at ``total`` steps."""
    if step < warmup_steps:
        return (step + 1) / warmup_steps
    t = min(step / max(total, 1), 1.0)
    return floor + (1 - floor) * 0.5 * (1 + math.cos(math.pi * t))


def cosine_lr(base: float, step: int, total: int) -> float:
    """Cosine decay from ``base`` to ``base / 100`` over ``total`` steps."""
    return base * cosine_factor(step, total, floor=0.01)


def cosine_schedule(optimizer: torch.optim.Optimizer, total: int, *, floor: float = 0.0,
                    warmup_steps: int = 0) -> torch.optim.lr_scheduler.LambdaLR:
    """Scheduler multiplying the optimiser's learning rate by :func:`cosine_factor`
    (``scheduler.step()`` once per optimiser step)."""
    return torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda step: cosine_factor(step, total, floor=floor,
                                              warmup_steps=warmup_steps))


class CpuBudget:
    """CPU time of this process since construction, against a budget.

    Args:
        minutes: the budget in CPU minutes; None: no limit.
    """

    def __init__(self, minutes: float | None = None) -> None:
        self.minutes = minutes
        self.start = time.process_time()

    def seconds(self) -> float:
        """CPU seconds spent since construction."""
        return time.process_time() - self.start

    def exceeded(self) -> bool:
        """True once more than the budget is spent (never without one)."""
        return self.minutes is not None and self.seconds() > 60 * self.minutes


__all__ = ["CpuBudget", "cosine_factor", "cosine_lr", "cosine_schedule", "seeded"]
