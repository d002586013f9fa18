"""Argument types shared by the ``dpcontrol`` and ``sim-plant`` command lines."""

from __future__ import annotations

import argparse
import math

from interfaces.zenoh.security import add_tls_arguments
from interfaces.zenoh.session_config import LOCAL_DAEMON_CONNECT


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def positive_number(text: str) -> float:
    """An argparse type: a finite number > 0 (durations, speeds); ``nan``, ``inf``, 0 and negatives refused.

    Raises
    ------
    argparse.ArgumentTypeError
        With what was given (argparse prints it with the option's name, exit 2).
    """
    value = _number(text)
    if not 0.0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def finite_number(text: str) -> float:
    """An argparse type: a finite number (positions, moves, angles); ``nan`` and ``inf`` refused (as above)."""
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def add_zenoh_arguments(parser: argparse.ArgumentParser) -> None:
    """``--vessel``, ``--connect``, ``--listen`` and the TLS options (``--tls-dir``, ``--identity``): how an
    operator's tool finds a vessel's controller over zenoh. :func:`interfaces.zenoh.session_config.tool_config` turns
    them into the tool's session configuration."""
    parser.add_argument("--vessel", required=True, help="vessel ID (zenoh keys dp/<vessel>/...)")
    parser.add_argument("--connect", action="append", metavar="ENDPOINT",
                        help=f"zenoh endpoint of the daemon (repeatable; default {LOCAL_DAEMON_CONNECT[0]})")
    parser.add_argument("--listen", action="append", metavar="ENDPOINT", default=[],
                        help="zenoh endpoint to listen on (default: none)")
    add_tls_arguments(parser)
