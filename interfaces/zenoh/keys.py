"""Zenoh key expressions of one vessel (docs/design.md §4.4).

Every key lives under ``dp/<vessel>/``; the vessel ID becomes one key chunk, so it must not contain
the key separator ``/``, the wildcards ``*``/``$``, the selector characters ``?``/``#`` or
whitespace. We accept a conservative positive pattern instead of black-listing characters:
``[A-Za-z0-9][A-Za-z0-9_-]{0,63}`` (e.g. ``cybership2``, ``supply-1``, ``blue_lady``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

VESSEL_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")

#: Publish/subscribe topics (payload schemas in :mod:`interfaces.zenoh.schemas`).
Topic = Literal["command", "feedback", "estimate", "mmae", "control", "status", "setpoint"]
TOPICS: tuple[str, ...] = ("command", "feedback", "estimate", "mmae", "control", "status", "setpoint")

#: Liveliness roles: the daemon declares ``controller``, the plant emulator (or drives gateway) ``plant``.
Role = Literal["controller", "plant"]
ROLES: tuple[str, ...] = ("controller", "plant")

_SUFFIX = {
    "command": "thrusters/command",
    "feedback": "thrusters/feedback",
    "estimate": "estimate",
    "mmae": "mmae",
    "control": "control",
    "status": "status",
    "setpoint": "setpoint",
}


def validate_vessel_id(vessel: object) -> str:
    """Return ``vessel`` if it is a valid vessel ID, else raise :class:`ValueError` saying why.

    Parameters
    ----------
    vessel : object
        Candidate ID (usually from a config file or the command line).

    Raises
    ------
    ValueError
        Not a string, empty, too long, or containing a character outside ``[A-Za-z0-9_-]``.
    """
    if not isinstance(vessel, str):
        raise ValueError(f"vessel id must be a string, got {type(vessel).__name__}")
    if VESSEL_ID_PATTERN.fullmatch(vessel) is None:
        raise ValueError(
            f"invalid vessel id {vessel!r}: expected 1-64 characters from [A-Za-z0-9_-], starting with a letter or "
            "digit (no '/', '*', '$', '?', '#' or spaces: it becomes one zenoh key chunk)")
    return vessel


@dataclass(frozen=True, slots=True)
class VesselKeys:
    """The key expressions of one vessel.

    Attributes
    ----------
    vessel : str
        Validated vessel ID.
    """

    vessel: str

    def __post_init__(self) -> None:
        validate_vessel_id(self.vessel)

    @property
    def prefix(self) -> str:
        """``dp/<vessel>``."""
        return f"dp/{self.vessel}"

    def topic(self, topic: str) -> str:
        """Key of a publish/subscribe topic, e.g. ``topic("command") == "dp/<vessel>/thrusters/command"``."""
        try:
            return f"dp/{self.vessel}/{_SUFFIX[topic]}"
        except KeyError:
            raise ValueError(f"unknown topic {topic!r}: expected one of {', '.join(TOPICS)}") from None

    @property
    def config(self) -> str:
        """Key of the configuration queryable."""
        return f"dp/{self.vessel}/config"

    def alive(self, role: str) -> str:
        """Key of a liveliness token, ``dp/<vessel>/alive/<role>``."""
        if role not in ROLES:
            raise ValueError(f"unknown liveliness role {role!r}: expected one of {', '.join(ROLES)}")
        return f"dp/{self.vessel}/alive/{role}"

    @property
    def everything(self) -> str:
        """Key expression matching every key of this vessel (``dp/<vessel>/**``)."""
        return f"dp/{self.vessel}/**"
