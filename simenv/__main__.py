"""``python -m simenv``: the same as the ``simenv`` command."""

from simenv.cli import main

raise SystemExit(main())
