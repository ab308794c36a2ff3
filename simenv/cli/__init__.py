"""The ``simenv`` command: :mod:`simenv.cli.main` assembles one module per subcommand
(``info``, ``retarget``, ``render``, ``score``, ``export``, ``demo``, ``train``,
``evaluate`` for ``eval``, ``rehearse``), each with ``add_parser(subparsers)`` and
``run(args)``; :mod:`simenv.cli.common` holds what they share."""
