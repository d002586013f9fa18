"""Logging of the command-line tools: on a terminal, or in the systemd journal with each line's priority.

Under systemd the services' stderr is a stream to journald (``JOURNAL_STREAM`` names it). journald stamps
every line itself, and reads a ``<N>`` syslog-priority prefix from it (``SyslogLevelPrefix=``, on by
default), so there each line carries its level as a priority instead of a timestamp: ``journalctl -u
dpcontrol@osv1 -p warning`` then lists the alarms and errors alone, and the journal colours them.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import TextIO

#: syslog priorities (RFC 5424) of the logging levels
SYSLOG_PRIORITIES = ((logging.CRITICAL, 2), (logging.ERROR, 3), (logging.WARNING, 4), (logging.INFO, 6))
DEBUG_PRIORITY = 7
#: libraries logged from WARNING up only, whatever the tools' level
QUIET_LIBRARIES = ("matplotlib", "PIL", "numba")


def syslog_priority(levelno: int) -> int:
    """The syslog priority of a logging level (``logging.ERROR`` → 3; below INFO → 7, debug)."""
    for level, priority in SYSLOG_PRIORITIES:
        if levelno >= level:
            return priority
    return DEBUG_PRIORITY


class JournalFormatter(logging.Formatter):
    """``<priority>name: message`` — journald keeps the priority and adds the time."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        prefix = f"<{syslog_priority(record.levelno)}>"
        # a multi-line message (a traceback) is one journal entry per line: each keeps the priority
        return "\n".join(prefix + line for line in text.split("\n"))


def stream_is_journal(stream: TextIO, environ: dict[str, str] | None = None) -> bool:
    """Whether ``stream`` is the journal stream systemd connected (``JOURNAL_STREAM=<device>:<inode>``).

    systemd sets the variable for the service's stdout/stderr; a child whose stderr was redirected
    elsewhere inherits it, so the device and inode are compared with the stream's own (``systemd.exec(5)``).
    """
    value = (os.environ if environ is None else environ).get("JOURNAL_STREAM", "")
    device, _, inode = value.partition(":")
    if not (device.isdigit() and inode.isdigit()):
        return False
    try:
        status = os.fstat(stream.fileno())
    except (OSError, ValueError, AttributeError):  # closed, or not a real file (a test's capture)
        return False
    return (status.st_dev, status.st_ino) == (int(device), int(inode))


def configure_logging(level: int, *, terminal_format: str = "%(asctime)s %(levelname)s %(name)s: %(message)s",
                      stream: TextIO | None = None) -> None:
    """Log at ``level`` to ``stream`` (stderr): with priorities in the journal, timestamps elsewhere."""
    stream = sys.stderr if stream is None else stream
    handler = logging.StreamHandler(stream)
    if stream_is_journal(stream):
        handler.setFormatter(JournalFormatter("%(name)s: %(message)s"))
    else:
        handler.setFormatter(logging.Formatter(terminal_format))
    logging.basicConfig(level=level, handlers=[handler])
    # Libraries' own progress notes are not the operator's business: matplotlib's "generated new
    # fontManager" (the first plot on a fresh machine) ended the demo's output, between its results.
    for library in QUIET_LIBRARIES:
        logging.getLogger(library).setLevel(max(level, logging.WARNING))
