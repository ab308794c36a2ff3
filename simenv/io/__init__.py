"""Readers and writers of motion files; :func:`simenv.io.load` detects the format."""
