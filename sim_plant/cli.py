"""``sim-plant`` command line (composition layer)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sim-plant`` console script."""
    del argv
    print("sim-plant: not yet implemented", file=sys.stderr)
    return 2
