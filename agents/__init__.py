"""simenv.agents package."""
