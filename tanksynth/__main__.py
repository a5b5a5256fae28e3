"""``python -m tanksynth``: the command line, the same as the ``tanksynth`` command."""

from __future__ import annotations

import sys

from tanksynth.cli import main

__all__: list[str] = []

if __name__ == "__main__":
    sys.exit(main())
