"""``python -m hybridteam.cli``: the same as the ``hybridteam`` command.

Guarded, so importing the module (as the API reference's generator does with every
module) runs nothing."""

from hybridteam.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
