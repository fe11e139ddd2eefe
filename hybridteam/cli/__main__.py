"""``python -m hybridteam.cli``: the same as the ``hybridteam`` command."""

from hybridteam.cli import main

raise SystemExit(main())
