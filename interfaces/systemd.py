"""systemd service notification (``sd_notify``) for ``Type=notify`` units.

The protocol is a few newline-separated ``KEY=VALUE`` lines in one datagram sent to the
``AF_UNIX`` socket named by ``$NOTIFY_SOCKET`` (a path, or an abstract-namespace name written
with a leading ``@``). It is about twenty lines of socket code, written here by hand instead of
adding a dependency (``python-systemd`` needs libsystemd headers to build; ``sdnotify`` is a
thin, unmaintained wrapper of the same twenty lines).

This module only *sends*. When to send is the control loop's decision, and the rule is strict
(docs/design.md §5): ``WATCHDOG=1`` only from a healthy control loop, never from a side thread — a
thread that pings systemd while the loop hangs keeps a dead controller "alive". Send it every
``watchdog_interval_s() / 2`` at most.

Outside systemd (no ``$NOTIFY_SOCKET``) every call is a cheap no-op returning ``False``. Sending
never blocks (the socket is non-blocking: a full queue at PID 1 drops the notification rather
than stall a control cycle) and never raises; failures are counted and logged once.

Stdlib only: the plant emulator may need it too, and it must not depend on the controller.
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Mapping, MutableMapping

log = logging.getLogger(__name__)

_ENV_KEYS = ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID")


def socket_address(value: str | None) -> str | bytes | None:
    """The ``AF_UNIX`` address for a ``$NOTIFY_SOCKET`` value, or ``None`` if unusable.

    ``@name`` is the abstract namespace (``b"\\0name"``); a path must be absolute. Other forms
    (e.g. ``vsock:`` addresses used for virtual machines) are not supported here.
    """
    if not value:
        return None
    if value.startswith("@"):
        return b"\0" + value[1:].encode()
    if value.startswith("/"):
        return value
    return None


class SystemdNotifier:
    """Sends ``sd_notify`` messages to the service manager.

    Parameters
    ----------
    environ : mapping, optional
        Where to read ``NOTIFY_SOCKET``, ``WATCHDOG_USEC`` and ``WATCHDOG_PID`` (default
        ``os.environ``; tests pass their own).
    pid : int, optional
        This process's PID for the ``WATCHDOG_PID`` check (default ``os.getpid()``).
    """

    def __init__(self, environ: Mapping[str, str] | None = None, *, pid: int | None = None) -> None:
        env = os.environ if environ is None else environ
        self._pid = os.getpid() if pid is None else pid
        raw = env.get("NOTIFY_SOCKET")
        self._address = socket_address(raw)
        if raw and self._address is None:
            log.warning("NOTIFY_SOCKET=%r is not an absolute path or @abstract name: systemd notification off", raw)
        self._watchdog_usec = env.get("WATCHDOG_USEC")
        self._watchdog_pid = env.get("WATCHDOG_PID")
        self._socket: socket.socket | None = None
        self.sent = 0
        self.failures = 0

    @property
    def enabled(self) -> bool:
        """True when running under a service manager that listens for notifications."""
        return self._address is not None

    def notify(self, *fields: str) -> bool:
        """Send ``fields`` (each ``KEY=VALUE``) as one datagram; ``True`` if it was sent."""
        if self._address is None:
            return False
        message = "\n".join(fields).encode("utf-8", "replace")
        try:
            if self._socket is None:
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
                sock.setblocking(False)
                self._socket = sock
            self._socket.sendto(message, self._address)
        except OSError as exc:  # queue full (BlockingIOError), socket gone, permission ...
            self.failures += 1
            if self.failures == 1:
                log.warning("sd_notify to %r failed: %s", self._address, exc)
            return False
        self.sent += 1
        return True

    def ready(self, status: str | None = None) -> bool:
        """``READY=1`` (start-up finished: configuration loaded, transports open, loop running)."""
        fields = ["READY=1"]
        if status is not None:
            fields.append("STATUS=" + _one_line(status))
        return self.notify(*fields)

    def status(self, text: str) -> bool:
        """``STATUS=…``: a one-line human-readable state shown by ``systemctl status``."""
        return self.notify("STATUS=" + _one_line(text))

    def watchdog(self) -> bool:
        """``WATCHDOG=1`` — call only from the healthy control loop (see module docstring)."""
        return self.notify("WATCHDOG=1")

    def stopping(self, status: str | None = None) -> bool:
        """``STOPPING=1`` (shutdown began: thrusters being brought to standby)."""
        fields = ["STOPPING=1"]
        if status is not None:
            fields.append("STATUS=" + _one_line(status))
        return self.notify(*fields)

    def extend_timeout(self, seconds: float) -> bool:
        """``EXTEND_TIMEOUT_USEC=…``: ask for more start-up/shutdown time than ``TimeoutStartSec=``."""
        return self.notify(f"EXTEND_TIMEOUT_USEC={max(0, round(seconds * 1e6))}")

    def watchdog_interval_s(self) -> float | None:
        """The watchdog timeout [s] from ``$WATCHDOG_USEC``, or ``None`` if no watchdog applies.

        ``None`` when the variable is absent or not a positive integer, or when ``$WATCHDOG_PID``
        names another process (the variables were inherited, not meant for us). Ping at half of it.
        """
        if not self._watchdog_usec:
            return None
        if self._watchdog_pid:
            try:
                if int(self._watchdog_pid) != self._pid:
                    return None
            except ValueError:
                return None
        try:
            usec = int(self._watchdog_usec)
        except ValueError:
            return None
        return usec / 1e6 if usec > 0 else None

    def close(self) -> None:
        """Close the socket (further calls reopen it)."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def __enter__(self) -> SystemdNotifier:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def unset_environment(environ: MutableMapping[str, str] | None = None) -> None:
    """Remove the notification variables so child processes do not inherit them (like
    ``sd_notify(unset_environment=1)``): e.g. before ``sim-plant demo`` starts a daemon."""
    env = os.environ if environ is None else environ
    for key in _ENV_KEYS:
        env.pop(key, None)


def _one_line(text: str) -> str:
    # A newline would start a new KEY=VALUE field: keep STATUS to one line.
    return " ".join(str(text).split())
