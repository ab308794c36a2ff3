"""The `simenv` command: one entry per subcommand, and the demo."""
