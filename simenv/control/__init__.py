"""Unassisted tracking control of the humanoid: sampling-based model-predictive
control over batched MuJoCo rollouts (:mod:`simenv.control.mpc`)."""

from simenv.control.costs import CostWeights, TrackingCost
from simenv.control.model import SensorLayout, planning_model
from simenv.control.mpc import FAST, MPCConfig, TrackingMPC, fast_planner
from simenv.control.reference import TrackingReference
from simenv.control.sampling import Sampler, Spline

__all__ = ["FAST", "CostWeights", "MPCConfig", "Sampler", "SensorLayout", "Spline", "fast_planner",
           "TrackingCost", "TrackingMPC", "TrackingReference", "planning_model"]
