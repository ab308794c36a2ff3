"""Training and evaluation of the networks in simenv.models."""
