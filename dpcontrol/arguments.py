"""Argument types shared by the ``dpcontrol`` and ``sim-plant`` command lines."""

from __future__ import annotations

import argparse
import math


def positive_number(text: str) -> float:
    """An argparse type: a finite number > 0 (durations, speeds); ``nan``, ``inf``, 0 and negatives refused.

    Raises
    ------
    argparse.ArgumentTypeError
        With what was given (argparse prints it with the option's name, exit 2).
    """
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value
