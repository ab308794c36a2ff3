"""Simulation guards: divergence and MuJoCo warnings.

A policy, or a motion no body can perform, can drive a simulation into states the
integrator cannot handle (huge velocities, interpenetration resolved with enormous
forces). Whoever steps MuJoCo checks after its step(s) with :func:`physics_problem`: the
environments end the episode as *truncated* (the state is not a task outcome) with the
reason in ``info["truncation_reason"]``; physics tracking
(:mod:`simenv.plausibility.tracking`) stops and reports a failed result naming the frame.
Neither returns NaN or crashes.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: Largest generalized acceleration accepted (rad/s^2 or m/s^2); beyond it the state is
#: taken as diverged (a person's limbs peak around 1e3).
MAX_QACC = 1e6

#: MuJoCo warnings that mean the simulation can no longer be trusted.
WARNINGS: tuple[mujoco.mjtWarning, ...] = (
    mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADCTRL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL, mujoco.mjtWarning.mjWARN_CONTACTFULL,
)


_WATCHED = np.array([int(w) for w in WARNINGS])


def warning_counts(data: mujoco.MjData) -> np.ndarray:
    """(len(WARNINGS),) how often each watched warning has fired in ``data`` so far."""
    return data.warning.number[_WATCHED]


def physics_problem(model: mujoco.MjModel, data: mujoco.MjData,
                    counts_before: np.ndarray) -> str | None:
    """Why the simulation cannot go on, or None.

    Args:
        counts_before: :func:`warning_counts` taken before the step(s) being checked.
    """
    fired = warning_counts(data) - counts_before
    if fired.any():
        return f"MuJoCo warning {WARNINGS[int(np.flatnonzero(fired)[0])].name}"
    if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
        return "non-finite state (qpos/qvel)"
    peak = float(np.abs(data.qacc).max()) if model.nv else 0.0
    if not np.isfinite(peak) or peak > MAX_QACC:
        return f"generalized acceleration {peak:.3g} beyond {MAX_QACC:.0e}"
    return None
