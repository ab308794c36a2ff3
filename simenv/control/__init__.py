"""Unassisted tracking control of the humanoid: sampling-based model-predictive
control over batched MuJoCo rollouts (:mod:`simenv.control.mpc`), and a tracking policy
learned from its solutions with it as the fallback (:mod:`simenv.control.policy`)."""

from simenv.control.costs import CostWeights, TrackingCost
from simenv.control.model import SensorLayout, planning_model
from simenv.control.mpc import FAST, MPCConfig, TrackingMPC, fast_planner
from simenv.control.policy import PolicyConfig, PolicyTracker, TrackingPolicy
from simenv.control.reference import TrackingReference
from simenv.control.sampling import Sampler, Spline

__all__ = ["FAST", "CostWeights", "MPCConfig", "PolicyConfig", "PolicyTracker", "Sampler",
           "SensorLayout", "Spline", "fast_planner", "TrackingCost", "TrackingMPC",
           "TrackingPolicy", "TrackingReference", "planning_model"]
