"""Which planner a physics verdict is computed with: the named choices, their cost, and the
record a result carries of it.

``simenv score --planner`` and ``simenv rehearse --planner`` choose among :data:`PLANNERS`:
``default``, the scorer's own :class:`~simenv.control.MPCConfig`, and ``fast``,
:data:`simenv.control.FAST` with the scorer's seeds, attempts and retry horizon
(:func:`simenv.control.fast_planner`; docs/tracking_speed.md has what each costs and how
closely it tracks). A smaller search can only fail to find a way a larger one finds: a clip
the fast planner tracks is one the body can perform on its own; a failure it reports may be
the search's.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from simenv.control import MPCConfig, fast_planner
from simenv.plausibility.metric import ScoreConfig

#: The planners the commands offer, by name.
PLANNERS: tuple[str, ...] = ("default", "fast")


def with_planner(config: ScoreConfig, name: str) -> ScoreConfig:
    """``config`` planning with the planner ``name`` (one of :data:`PLANNERS`): ``default``
    leaves it as it is, ``fast`` plans with FAST's search and ``config``'s seeds.

    Raises:
        ValueError: ``name`` is not one of :data:`PLANNERS`.
    """
    if name not in PLANNERS:
        raise ValueError(f"planner {name!r}: expected one of {', '.join(PLANNERS)}")
    return config if name == "default" else replace(config, mpc=fast_planner(config.mpc))


def planning_cost(mpc: MPCConfig) -> float:
    """Planning-model steps a planner rolls out per physics step, first attempt (samples x
    horizon steps per replan / physics steps between replans)."""
    return mpc.n_samples * mpc.horizon_s / mpc.timestep_factor / mpc.replan_steps


def planner_record(config: ScoreConfig) -> dict[str, Any]:
    """What physics verdicts were computed with: the planner's settings, whether the
    assisted PD run was reported, and the same in words (``text``) for a page, compared
    with the planner ``simenv score`` uses by default."""
    from simenv.plausibility.report import DEFAULT_SCORE_CONFIG

    mpc = config.mpc
    retry = mpc.horizon_s if mpc.retry_horizon_s is None else mpc.retry_horizon_s
    seeds = (f"up to {mpc.attempts} seeds (the further ones over {retry:g} s)"
             if mpc.attempts > 1 else "one seed")
    shipped = DEFAULT_SCORE_CONFIG.mpc
    text = (f"unassisted MPC with {mpc.n_samples} samples per replan"
            f"{' in mirrored pairs' if mpc.antithetic else ''} over {mpc.horizon_s:g} s, "
            f"planning step {mpc.timestep_factor} physics steps, {seeds}; simenv score plans "
            f"with {shipped.n_samples} samples, planning step {shipped.timestep_factor} "
            f"physics steps ({planning_cost(shipped) / planning_cost(mpc):.0f}x the "
            "rolled-out steps)")
    return {"n_samples": mpc.n_samples, "antithetic": mpc.antithetic,
            "timestep_factor": mpc.timestep_factor, "horizon_s": mpc.horizon_s,
            "attempts": mpc.attempts, "retry_horizon_s": retry, "seed": mpc.seed,
            "assisted_detail": config.tracking_assisted_detail, "text": text}


__all__ = ["PLANNERS", "planner_record", "planning_cost", "with_planner"]
