"""The data model: motions, skeletons, errors, configuration and the SRVF representation."""
