"""simenv.assets package."""
