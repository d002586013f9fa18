"""Persisted estimator/controller state for a bumpless restart (docs/design.md §10).

When the daemon restarts (crash, watchdog, update), it should resume with the wave filter's and the
controller's state instead of re-converging from zero — but only from a state that is complete,
recent and made with the same configuration. :class:`StateStore` keeps one JSON file:

``{"format": "dpcontrol.state", "version": V, "saved_wall_s": t, "config_sha256": h, "state": {...}}``

* **Atomic save**: the JSON is written to a temporary file in the same directory, ``fsync`` ed,
  renamed over the old file with ``os.replace`` (atomic on POSIX), and the directory is
  ``fsync`` ed so the rename itself survives a power loss. A SIGKILL at any instant leaves either
  the old or the new complete file (and at worst a stray temporary file, removed by the next save).
* **Checked load**: :meth:`StateStore.check` returns the state only if the file exists, is valid
  JSON of this format, has the expected ``version`` and configuration hash, and is younger than
  ``max_age_s``; otherwise ``None`` with a :class:`LoadStatus` reason (missing, unreadable,
  corrupt, wrong version, wrong config, too old, from the future) and a sentence to log.

Cost and threading: serialising a typical state (an 8-model bank with 15 states: ~2 000 floats)
with orjson takes tens of µs, but ``fsync`` takes milliseconds on a good disk and can take seconds
on a busy or failing one, which a 10 Hz control loop must never wait for. So the loop uses
:class:`BackgroundSaver`: :meth:`BackgroundSaver.submit` serialises the state *in the calling
thread* (the serialised bytes are the copy: later in-place updates of the loop's arrays cannot tear
the snapshot) and hands the bytes to a helper thread that does the atomic write. Only the newest
snapshot waits; one still waiting when a newer one arrives is replaced (counted). :meth:`StateStore.save`
is the synchronous version (shutdown, tests, tools).

Times are wall-clock seconds (``time.time()``) so the age survives a reboot; the age limit is what
keeps a state from a different situation (hours old) from being applied.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import tempfile
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import orjson

from interfaces.recorder import fsync_directory, json_default

if TYPE_CHECKING:
    from dpcontrol.runtime.config import StateSettings

logger = logging.getLogger(__name__)

__all__ = ["FORMAT", "BackgroundSaver", "LoadResult", "LoadStatus", "StateStore", "StateStoreError"]

FORMAT = "dpcontrol.state"
_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


class StateStoreError(RuntimeError):
    """A state file could not be written (the message names the file and the OS error)."""


class LoadStatus(str, Enum):
    """Why a persisted state was (not) returned."""

    OK = "ok"
    MISSING = "missing"
    UNREADABLE = "unreadable"  # exists but cannot be read (permissions, I/O error)
    CORRUPT = "corrupt"  # not JSON, not this format, or fields of the wrong type
    WRONG_VERSION = "wrong_version"
    WRONG_CONFIG = "wrong_config"
    TOO_OLD = "too_old"
    FUTURE = "future"  # saved later than now: the wall clock stepped back


@dataclass(frozen=True)
class LoadResult:
    """Outcome of :meth:`StateStore.check`.

    Attributes
    ----------
    state : dict or None
        The persisted state when ``status`` is OK.
    status : LoadStatus
    detail : str
        One sentence for the log ("state file /var/lib/... is 42.0 s old (limit 30.0 s)").
    saved_wall_s : float or None
        When it was saved (wall clock [s]) if the file could be parsed.
    age_s : float or None
        ``now - saved_wall_s`` [s] if the file could be parsed.
    """

    state: dict[str, Any] | None
    status: LoadStatus
    detail: str
    saved_wall_s: float | None = None
    age_s: float | None = None

    @property
    def ok(self) -> bool:
        return self.status is LoadStatus.OK


class StateStore:
    """One atomically replaced JSON file holding the state for a bumpless restart.

    Parameters
    ----------
    path : path-like
        The state file (its directory is created on the first save).
    period_s : float
        Save interval the loop keeps (:meth:`due`) [s].
    max_age_s : float
        Oldest state :meth:`load` accepts [s].
    version : int
        Version of the state layout; bump it when the layout changes, and older files are refused
        (``WRONG_VERSION``).
    config_hash : str, optional
        SHA-256 of the running configuration; a file saved under another configuration is refused
        (``WRONG_CONFIG``). ``None`` skips the check.
    fsync : bool
        ``fsync`` file and directory (durability across power loss; atomicity does not need it).
    future_tolerance_s : float
        How far in the future ``saved_wall_s`` may be before the file is refused (clock steps) [s].
    """

    def __init__(self, path: str | os.PathLike[str], period_s: float = 1.0, max_age_s: float = 30.0, *,
                 version: int = 1, config_hash: str | None = None, fsync: bool = True,
                 future_tolerance_s: float = 5.0) -> None:
        if period_s <= 0 or not math.isfinite(period_s):
            raise ValueError(f"state period_s must be positive, got {period_s}")
        if max_age_s < 0 or not math.isfinite(max_age_s):
            raise ValueError(f"state max_age_s must be non-negative, got {max_age_s}")
        self._path = Path(path)
        self.period_s = float(period_s)
        self.max_age_s = float(max_age_s)
        self.version = int(version)
        self.config_hash = config_hash
        self._fsync = fsync
        self._future_tolerance_s = float(future_tolerance_s)
        self._last_due_s: float | None = None
        self._cleaned = False
        self.last_result: LoadResult | None = None

    @classmethod
    def from_settings(cls, settings: StateSettings, *, version: int = 1,
                      config_hash: str | None = None) -> StateStore | None:
        """A store for the daemon's ``state:`` section, or None when no path is configured."""
        if settings.path is None:
            return None
        return cls(settings.path, settings.period_s, settings.max_age_s, version=version, config_hash=config_hash)

    @property
    def path(self) -> Path:
        return self._path

    # ---------------------------------------------------------------- saving

    def due(self, t_wall_s: float) -> bool:
        """True if ``period_s`` has passed since the last save/submission (or the clock stepped back)."""
        last = self._last_due_s
        return last is None or not 0.0 <= t_wall_s - last < self.period_s

    def encode(self, t_wall_s: float, state: Mapping[str, Any]) -> bytes:
        """Serialise a state with its envelope (the snapshot :class:`BackgroundSaver` hands over).

        Numpy arrays and scalars are allowed (stored as lists/numbers; non-finite floats as null).

        Raises
        ------
        TypeError
            If ``state`` is not a mapping or holds values JSON cannot represent.
        ValueError
            If ``t_wall_s`` is not finite.
        """
        if not isinstance(state, Mapping):
            raise TypeError(f"a persisted state is a mapping, not {type(state).__name__}")
        if not math.isfinite(t_wall_s):
            raise ValueError(f"t_wall_s must be finite, got {t_wall_s}")
        self._last_due_s = float(t_wall_s)
        envelope = {"format": FORMAT, "version": self.version, "saved_wall_s": float(t_wall_s),
                    "config_sha256": self.config_hash, "state": state}
        return orjson.dumps(envelope, default=json_default, option=_OPTIONS)

    def save(self, t_wall_s: float, state: Mapping[str, Any]) -> None:
        """Serialise and atomically write ``state`` (synchronous: includes the fsyncs).

        Raises
        ------
        TypeError, ValueError
            For a state that cannot be serialised (nothing is written, the old file stays).
        StateStoreError
            If the file cannot be written (the old file stays).
        """
        self.write(self.encode(t_wall_s, state))

    def write(self, data: bytes) -> None:
        """Atomically replace the state file with ``data`` (from :meth:`encode`).

        Raises
        ------
        StateStoreError
            If the file cannot be written (the old file stays untouched).
        """
        directory = self._path.parent
        try:
            directory.mkdir(parents=True, exist_ok=True)
            if not self._cleaned:
                self._remove_stale_temporaries()
            fd, tmp_name = tempfile.mkstemp(prefix=f".{self._path.name}.", suffix=".tmp", dir=directory)
        except FileExistsError as error:  # mkdir's word for "the folder is a file": say that
            raise StateStoreError(f"cannot write state file {self._path}: {directory} is a file, not a folder") \
                from error
        except OSError as error:
            raise StateStoreError(f"cannot write state file {self._path}: {error.strerror or error}") from error
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                if self._fsync:
                    os.fsync(handle.fileno())
            os.replace(tmp_name, self._path)
        except BaseException as error:
            with contextlib.suppress(OSError):
                os.unlink(tmp_name)
            if isinstance(error, OSError):
                raise StateStoreError(f"cannot write state file {self._path}: {error.strerror or error}") from error
            raise
        if self._fsync:
            fsync_directory(directory)

    def _remove_stale_temporaries(self) -> None:
        """Remove temporary files a killed save left behind (only this store's own name pattern)."""
        self._cleaned = True
        prefix, directory = f".{self._path.name}.", self._path.parent
        for name in os.listdir(directory):
            if name.startswith(prefix) and name.endswith(".tmp"):
                with contextlib.suppress(OSError):
                    os.unlink(directory / name)

    # ---------------------------------------------------------------- loading

    def load(self, now_wall_s: float) -> dict[str, Any] | None:
        """The persisted state if it is valid, current and from this configuration, else None.

        The reason is in :attr:`last_result` (``.status``, ``.detail``).
        """
        return self.check(now_wall_s).state

    def check(self, now_wall_s: float) -> LoadResult:
        """Read and validate the state file; see :class:`LoadStatus` for the outcomes."""
        result = self._check(now_wall_s)
        self.last_result = result
        return result

    def _check(self, now_wall_s: float) -> LoadResult:  # noqa: PLR0911 - one return per reason a saved state is refused
        path = self._path
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return LoadResult(None, LoadStatus.MISSING, f"no state file at {path}")
        except OSError as error:
            return LoadResult(None, LoadStatus.UNREADABLE, f"cannot read state file {path}: {error.strerror or error}")
        try:
            doc = orjson.loads(data)
        except orjson.JSONDecodeError as error:
            return LoadResult(None, LoadStatus.CORRUPT, f"state file {path} is not valid JSON: {error}")
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            return LoadResult(None, LoadStatus.CORRUPT, f"state file {path} is not a {FORMAT} file")
        saved = doc.get("saved_wall_s")
        if isinstance(saved, bool) or not isinstance(saved, (int, float)) or not math.isfinite(saved):
            return LoadResult(None, LoadStatus.CORRUPT, f"state file {path} has no valid saved_wall_s")
        saved = float(saved)
        age = now_wall_s - saved
        version = doc.get("version")
        if version != self.version:
            return LoadResult(None, LoadStatus.WRONG_VERSION,
                              f"state file {path} has version {version!r}, expected {self.version}", saved, age)
        stored_hash = doc.get("config_sha256")
        if self.config_hash is not None and stored_hash != self.config_hash:
            return LoadResult(None, LoadStatus.WRONG_CONFIG,
                              f"state file {path} was saved with configuration {str(stored_hash)[:12]}…, "
                              f"running {self.config_hash[:12]}…", saved, age)
        state = doc.get("state")
        if not isinstance(state, dict):
            return LoadResult(None, LoadStatus.CORRUPT, f"state file {path} has no state mapping", saved, age)
        if age > self.max_age_s:
            return LoadResult(None, LoadStatus.TOO_OLD,
                              f"state file {path} is {age:.1f} s old (limit {self.max_age_s:.1f} s)", saved, age)
        if age < -self._future_tolerance_s:
            return LoadResult(None, LoadStatus.FUTURE,
                              f"state file {path} was saved {-age:.1f} s in the future (clock stepped back?)",
                              saved, age)
        return LoadResult(state, LoadStatus.OK, f"state file {path} loaded ({age:.1f} s old)", saved, age)


class BackgroundSaver:
    """Writes a :class:`StateStore` from a helper thread so the control loop never waits for fsync.

    Parameters
    ----------
    store : StateStore
    on_error : callable (str) -> None, optional
        Called from the helper thread with a message when a write fails (keep it short and
        thread-safe); :attr:`last_error` holds the same message until the next successful write.
    """

    def __init__(self, store: StateStore, on_error: Callable[[str], None] | None = None) -> None:
        self.store = store
        self._on_error = on_error
        self._condition = threading.Condition()
        self._pending: bytes | None = None
        self._busy = False
        self._closing = False
        self.saved = 0
        self.superseded = 0
        self.failed = 0
        self.last_error: str | None = None
        self._thread = threading.Thread(target=self._run, name="dpcontrol-state-saver", daemon=True)
        self._thread.start()

    def submit(self, t_wall_s: float, state: Mapping[str, Any]) -> bool:
        """Snapshot ``state`` now (serialised in this thread) and have it written in the background.

        Never raises and never waits for I/O: returns False (and records the reason in
        :attr:`last_error`) for an unserialisable state or a closed saver.
        """
        try:
            data = self.store.encode(t_wall_s, state)
        except Exception as error:  # TypeError/ValueError for bad states; the loop must not see any
            self.last_error = f"state not serialisable: {error}"
            self.failed += 1
            return False
        with self._condition:
            if self._closing:
                return False
            if self._pending is not None:
                self.superseded += 1
            self._pending = data
            self._condition.notify()
        return True

    def maybe_submit(self, t_wall_s: float, make_state: Callable[[], Mapping[str, Any]]) -> bool:
        """Submit ``make_state()`` if the store's period has passed (the state is only built then)."""
        if not self.store.due(t_wall_s):
            return False
        try:
            state = make_state()
        except Exception as error:
            self.last_error = f"building the state failed: {error!r}"
            self.failed += 1
            return False
        return self.submit(t_wall_s, state)

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until every submitted snapshot is written (True) or ``timeout_s`` passes (False)."""
        with self._condition:
            return self._condition.wait_for(lambda: self._pending is None and not self._busy, timeout_s)

    def close(self, timeout_s: float = 5.0) -> bool:
        """Write the last snapshot and stop the thread; True if done within ``timeout_s``."""
        with self._condition:
            self._closing = True
            self._condition.notify_all()
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def _run(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._pending is not None or self._closing)
                data, self._pending = self._pending, None
                if data is None:  # closing with nothing left to write
                    self._condition.notify_all()
                    return
                self._busy = True
            try:
                self.store.write(data)
            except Exception as error:
                message = str(error)
                self.failed += 1
                if message != self.last_error:
                    logger.error("%s", message)
                self.last_error = message
                if self._on_error is not None:
                    try:
                        self._on_error(message)
                    except Exception:
                        logger.exception("state saver: on_error callback failed")
            else:
                self.saved += 1
                self.last_error = None
            finally:
                with self._condition:
                    self._busy = False
                    self._condition.notify_all()
