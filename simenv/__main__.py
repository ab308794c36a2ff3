"""``python -m simenv``: the same as the ``simenv`` command."""

from simenv.cli.main import main

raise SystemExit(main())
