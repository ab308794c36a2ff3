"""simenv.models package."""
