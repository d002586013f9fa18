"""Black-box recorder: every input, decision and command of the control loop, in MCAP (docs/design.md §10).

"Nothing lost": after an incident a DP engineer must be able to reconstruct every raw input (with
its receive time, rejected ones with the reason), every estimate, reference, control and allocation
result, every published command, mode change and alarm, and the configuration that produced them.

Format
------
`MCAP <https://mcap.dev>`_ — open, indexed, append-only, read by Foxglove, the ``mcap`` CLI and the
``mcap`` Python package. One channel per topic, ``json`` message encoding with a ``jsonschema``
schema per topic, so every file can be opened and plotted without dpcontrol. Messages are grouped
into zstd-compressed chunks. Every message is one JSON object holding the control loop's ``t_s``
(the time the loop stamped it) and the payload; the MCAP ``log_time`` is the receive/record time
[ns] from the injected ``clock`` (by default the UTC wall clock, ``time.time_ns``).

Topics are data-driven (:class:`TopicSpec`, :func:`default_topics`): ``raw/<transport>``,
``estimate``, ``mmae``, ``reference``, ``control``, ``allocation``, ``command``, ``mode``,
``alarm``, ``status``, ``config``, ``replay`` and the recorder's own ``recorder`` topic. A record
on a topic that was not declared is still recorded (on a channel registered on first use, with an
open schema) and logged once as a warning — nothing is lost for a missing declaration.

Threading and the loop's guarantees
-----------------------------------
:meth:`Recorder.record` is called from the control loop (and from transport threads): it never
blocks and never raises. It puts ``(topic, t_s, payload, log_time_ns)`` into a bounded queue
(``queue.SimpleQueue`` — C-implemented, ~0.1 µs per put — bounded by checking ``qsize()``) and
returns; when the queue is full the record is dropped and counted. One writer thread serialises
(orjson), writes MCAP messages, rotates and deletes files, and reports errors. The writer polls the
queue (every ``min(50 ms, flush_s / 4)``) instead of blocking on it, so that no ``put`` ever has
to wake a thread: waking it cost the loop 10 µs and more per cycle on this kind of machine.
Ownership of the payload passes to the recorder: the caller must not mutate it (or the arrays in
it) afterwards — pass copies of buffers that the loop reuses.

Durability
----------
The writer closes the open chunk, hands it to the OS and ``fsync`` s it as soon as the oldest
record not yet flushed has waited ``flush_s / 2``. A record therefore reaches the OS within
``flush_s / 2`` plus the poll period (plus the queue delay, nil while the writer keeps up) of its
``record()`` call, so a SIGKILL of the daemon loses at most the records of the last ``flush_s``
≤ 1 s, the gap between two records included. A killed file has no summary/index (it is
*unfinished*) but every chunk written before the kill is complete and readable by a linear scan
(:func:`dpcontrol.logtools.read_records` does that, and so does ``mcap recover``). Files are
finished (summary + chunk/metadata indexes + statistics) on rotation and on :meth:`Recorder.close`.

Rotation and disk use
---------------------
A file is rotated when it reaches ``max_file_mb`` (checked after every chunk, so a file exceeds it
by at most one chunk and its summary) or when a record's ``log_time`` is ``rotate_s`` past that of
the file's first record. Every file starts with the ``config`` record (and an MCAP metadata record), so each
is self-contained. Before a file is opened, the oldest recorder files in the directory (this run's
and earlier runs') are deleted while their total plus ``max_file_mb`` (room for the new file)
would exceed ``max_total_mb``. 1 MB = 10⁶ bytes. File names are ``dpcontrol-YYYYmmddTHHMMSSZ-
NNNN.mcap`` (UTC wall time of opening; ``NNNN`` disambiguates files opened in the same second);
names are made strictly increasing even if the wall clock steps back, so sorting names sorts files
by time.

Errors
------
An unwritable directory, a full disk (ENOSPC), no permission (EACCES), a read-only file system
(EROFS), a path under a regular file (ENOTDIR/EEXIST): the writer abandons the current file (what
was flushed stays readable), reports the error through ``on_error`` (called from the writer
thread — keep it short and thread-safe) and :attr:`Recorder.health`, keeps draining the queue and
counting the records it cannot write as dropped (so ``record()`` stays fast), and retries opening
a new file every ``retry_s``. When the path becomes writable again, recording resumes in a new
file whose first ``recorder`` record lists what was dropped.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import math
import os
import queue
import re
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import orjson
from mcap.writer import CompressionType, IndexType, Writer

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecorderSettings:
    """Black-box recorder settings (docs/design.md §10): ``path`` is a directory (None: recording off); sizes in
    MB (10⁶ bytes); ``flush_s`` ≤ 1 bounds what a SIGKILL loses."""

    path: str | None = None
    max_file_mb: float = 256.0
    max_total_mb: float = 4096.0
    rotate_s: float = 3600.0
    flush_s: float = 1.0
    queue_size: int = 10000

__all__ = [
    "FILE_PATTERN",
    "RAW_TRANSPORTS",
    "RECORDER_LIBRARY",
    "Recorder",
    "RecorderError",
    "RecorderHealth",
    "TopicSpec",
    "default_topics",
    "encode_record",
    "json_default",
    "list_log_files",
    "log_file_name",
    "raw_topic",
    "raw_topic_spec",
]

RECORDER_LIBRARY = "dpcontrol-recorder/1"
MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
BYTES_PER_MB = 1_000_000
RAW_TRANSPORTS = ("nmea0183", "nmea2000", "mavlink")
FILE_PATTERN = re.compile(r"^dpcontrol-(\d{8}T\d{6}Z)-(\d{4,})\.mcap$")

_ORJSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS
_BYTES_TYPES = (bytes, bytearray, memoryview)
_MAX_CHUNK_BYTES = 1 << 20
_MIN_CHUNK_BYTES = 4096


# --------------------------------------------------------------------------------------------------
# Topics


@dataclass(frozen=True)
class TopicSpec:
    """One recorded topic (MCAP channel) and its JSON schema.

    Attributes
    ----------
    topic : str
        MCAP topic, e.g. ``"estimate"`` or ``"raw/nmea0183"``.
    schema_name : str
        Schema name (topics may share one, as the raw topics do).
    description : str
        What the topic holds (goes into the schema's ``description``).
    properties : Mapping
        JSON-schema ``properties`` of the payload fields (informative: the schema allows further
        fields, so adding a field to a payload never needs a schema change). ``t_s`` is added.
    """

    topic: str
    schema_name: str
    description: str
    properties: Mapping[str, Any] = field(default_factory=dict)

    def json_schema(self) -> bytes:
        """The channel's JSON schema (draft 2020-12), UTF-8 encoded."""
        properties = {"t_s": {"type": ["number", "null"],
                              "description": "control-loop time of the record [s] (the loop's clock)"}}
        properties.update(self.properties)
        return orjson.dumps({"$schema": "https://json-schema.org/draft/2020-12/schema", "title": self.schema_name,
                             "description": self.description, "type": "object", "properties": properties,
                             "required": ["t_s"]})


def _num(description: str) -> dict[str, Any]:
    return {"type": ["number", "null"], "description": description}


def _vec(description: str) -> dict[str, Any]:
    return {"type": "array", "items": {"type": ["number", "null"]}, "description": description}


def _str(description: str) -> dict[str, Any]:
    return {"type": ["string", "null"], "description": description}


def raw_topic(transport: str) -> str:
    """Topic of the raw inputs of one transport: ``raw/<transport>``."""
    return f"raw/{transport}"


def raw_topic_spec(transport: str) -> TopicSpec:
    """Topic spec of one transport's raw inputs (accepted and rejected)."""
    return TopicSpec(raw_topic(transport), "dpcontrol.raw",
                     f"Raw inputs received on {transport}: one record per NMEA line / CAN frame / MAVLink packet, "
                     "log_time = receive time; rejected ones carry the reason.",
                     {"data_hex": {"type": "string", "description": "the bytes as received, hexadecimal"},
                      "rejected": _str("why the codec rejected the input; null when accepted"),
                      "transport": _str("configured transport name"),
                      "source": _str("sensor the input was routed to, when known"),
                      "can_id": {"type": ["integer", "null"], "description": "CAN arbitration ID (NMEA 2000)"}})


GENERIC_SCHEMA = "dpcontrol.record"

_CORE_TOPICS = (
    TopicSpec("config", "dpcontrol.config",
              "The running configuration and its SHA-256; the first message of every file.",
              {"vessel_id": _str("vessel ID"), "config_sha256": _str("SHA-256 of the configuration text"),
               "config": {"type": ["object", "null"], "description": "the parsed configuration"},
               "text": _str("the configuration file as written")}),
    TopicSpec("replay", "dpcontrol.replay",
              "Replay metadata: software versions, seeds, initial state, anything `dpcontrol replay` needs.", {}),
    TopicSpec("estimate", "dpcontrol.estimate",
              "Wave-filter output: LF pose and velocity, bias, WF motion, covariance diagonal (NED / body).",
              {"eta_n": _vec("LF pose [north_m, east_m, psi_rad]"), "nu_b": _vec("LF body velocity [mps, mps, radps]"),
               "bias_b": _vec("bias force estimate [n, n, nm]"), "eta_wf_n": _vec("WF motion estimate"),
               "P_diag": _vec("covariance diagonal of the state estimate")}),
    TopicSpec("mmae", "dpcontrol.mmae", "MMAE bank: model frequencies, weights, estimated peak frequency.",
              {"omegas_rad_s": _vec("model wave frequencies [rad/s]"), "weights": _vec("model weights [-]"),
               "omega_hat_rad_s": _num("weighted peak-frequency estimate [rad/s]")}),
    TopicSpec("reference", "dpcontrol.reference", "Reference model output and the operator setpoint.",
              {"eta_ref_n": _vec("reference pose [north_m, east_m, psi_rad]"),
               "nu_ref_b": _vec("reference body velocity"), "setpoint_n": _vec("target pose")}),
    TopicSpec("control", "dpcontrol.control", "Controller output: commanded generalised force and MRAC parameters.",
              {"tau_b": _vec("commanded force [surge_n, sway_n, yaw_nm]"),
               "wave_band": {"type": ["object", "null"],
                             "description": "wave-band std of the commanded force and the LF estimate: force_n, "
                                            "moment_nm, lf_position_m, lf_heading_rad (null outside DP)"}}),
    TopicSpec("allocation", "dpcontrol.allocation",
              "Thrust allocation result: per-thruster thrust/azimuth, achieved force, slack, solver status.",
              {"thrust_n": _vec("thrust per thruster [N]"), "azimuth_rad": _vec("azimuth per thruster [rad]"),
               "tau_achieved_b": _vec("force the solution produces [n, n, nm]")}),
    TopicSpec("command", "dpcontrol.command", "Thruster command as published on dp/<vessel>/thrusters/command.", {}),
    TopicSpec("mode", "dpcontrol.mode", "Mode change: new mode, previous mode, reason; or an operator request "
              "refused (rejected_request, with the role and identity it came in under when one was refused by role).",
              {"mode": _str("new mode"), "previous": _str("previous mode"), "reason": _str("why")}),
    TopicSpec("alarm", "dpcontrol.alarm", "Alarm transition: raised or cleared.",
              {"code": _str("alarm code"), "severity": _str("info/warning/alarm/critical"),
               "text": _str("alarm text"), "raised": {"type": ["boolean", "null"]}}),
    TopicSpec("status", "dpcontrol.status", "Daemon status: mode, sensor health, alarms, cycle timing.", {}),
    TopicSpec("recorder", "dpcontrol.recorder",
              "The recorder's own state: records written and dropped (by reason), errors; explains any gap.",
              {"written": {"type": "integer"}, "dropped": {"type": "integer"},
               "dropped_by_reason": {"type": "object"}, "last_error": _str("last write error")}),
)


def default_topics(raw_transports: Iterable[str] = RAW_TRANSPORTS,
                   extra: Iterable[TopicSpec] = ()) -> tuple[TopicSpec, ...]:
    """The recorded topics: one ``raw/<transport>`` per transport, the core topics, and ``extra``.

    Parameters
    ----------
    raw_transports : iterable of str
        Transport names (protocol names by default; the daemon may pass its configured transport
        names instead).
    extra : iterable of TopicSpec
        Further topics; a spec with the topic of an existing one replaces it.
    """
    specs: dict[str, TopicSpec] = {}
    for spec in (*(raw_topic_spec(t) for t in raw_transports), *_CORE_TOPICS, *extra):
        specs[spec.topic] = spec
    return tuple(specs.values())


# --------------------------------------------------------------------------------------------------
# Files


def log_file_name(wall_ns: int, index: int) -> str:
    """``dpcontrol-YYYYmmddTHHMMSSZ-NNNN.mcap`` for a UTC wall time [ns since the Unix epoch]."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(wall_ns // 1_000_000_000))
    return f"dpcontrol-{stamp}-{index:04d}.mcap"


def _name_key(name: str) -> tuple[str, int]:
    match = FILE_PATTERN.match(name)
    return (match.group(1), int(match.group(2))) if match else ("", -1)


def list_log_files(directory: str | os.PathLike[str]) -> list[Path]:
    """Recorder files in ``directory``, oldest first (by name: UTC stamp, then index).

    Only names matching :data:`FILE_PATTERN` are listed; a missing directory lists nothing.
    """
    try:
        names = [n for n in os.listdir(directory) if FILE_PATTERN.match(n)]
    except (FileNotFoundError, NotADirectoryError):
        return []
    return [Path(directory, n) for n in sorted(names, key=_name_key)]


def _next_name(wall_ns: int, existing: list[Path]) -> str:
    """A name after every existing one: the wall-clock stamp, or the last stamp with index + 1."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(wall_ns // 1_000_000_000))
    if existing:
        last_stamp, last_index = _name_key(existing[-1].name)
        if stamp <= last_stamp:
            return f"dpcontrol-{last_stamp}-{last_index + 1:04d}.mcap"
    return f"dpcontrol-{stamp}-0000.mcap"


def _open_output(path: Path) -> IO[bytes]:
    """Create a new recorder file (never overwrites). A seam for fault-injection tests."""
    return open(path, "xb")  # the writer thread owns and closes it


def fsync_directory(directory: Path) -> None:
    """Make a created, renamed or deleted directory entry durable (best effort: not every file system supports
    fsync on a directory). Used by the recorder and the daemon's state store."""
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def json_default(value: Any) -> Any:
    """orjson ``default`` hook: arrays (any layout) and numpy scalars → lists/numbers, bytes → hex.

    orjson serialises C-contiguous numpy arrays itself (``OPT_SERIALIZE_NUMPY``); this handles the
    rest. Non-finite floats are written as ``null`` by orjson (missing data is never NaN).
    """
    if isinstance(value, _BYTES_TYPES):
        return bytes(value).hex()
    tolist = getattr(value, "tolist", None)  # numpy arrays and scalars, without importing numpy
    if tolist is not None:
        return tolist()
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=repr)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"cannot record a value of type {type(value).__name__}")


def encode_record(t_s: float | None, payload: Mapping[str, Any] | bytes | bytearray | memoryview) -> bytes:
    """The JSON message of one record: ``{"t_s": t_s, **payload}``.

    A bytes payload becomes ``{"t_s", "data_hex"}``; a bytes ``data`` field becomes ``data_hex``;
    other bytes values become hex strings. ``t_s`` from the argument wins over a payload ``t_s``.

    Raises
    ------
    TypeError
        For a payload that is neither a mapping nor bytes, or holds unserialisable values.
    """
    if isinstance(payload, _BYTES_TYPES):
        doc: dict[Any, Any] = {"t_s": t_s, "data_hex": bytes(payload).hex()}
    elif isinstance(payload, Mapping):
        doc = {"t_s": t_s}
        doc.update(payload)
        doc["t_s"] = t_s
        data = doc.get("data")
        if isinstance(data, _BYTES_TYPES):
            del doc["data"]
            doc["data_hex"] = bytes(data).hex()
    else:
        raise TypeError(f"a record payload is a mapping or bytes, not {type(payload).__name__}")
    return orjson.dumps(doc, default=json_default, option=_ORJSON_OPTIONS)


# --------------------------------------------------------------------------------------------------
# Health


@dataclass(frozen=True)
class RecorderError:
    """A recorder failure, as passed to ``on_error``.

    Attributes
    ----------
    kind : str
        ``"open"``, ``"write"``, ``"flush"``, ``"finish"``, ``"delete"``, ``"payload"`` (a record
        that cannot be serialised; the file is fine) or ``"internal"``.
    message : str
        Human-readable, names the path and the OS error.
    path : str or None
    errno_name : str or None
        ``"ENOSPC"``, ``"EACCES"``, ``"EROFS"``, ``"ENOTDIR"``, ... for OS errors.
    wall_ns : int
        When it happened (UTC wall clock [ns]).
    """

    kind: str
    message: str
    path: str | None = None
    errno_name: str | None = None
    wall_ns: int = 0


@dataclass(frozen=True)
class RecorderHealth:
    """What the status shows and what the daemon raises an alarm on.

    ``state``: ``"starting"`` (first file not opened yet), ``"recording"``, ``"unwritable"``
    (retrying), ``"disabled"`` (no path configured), ``"closed"``, ``"failed"`` (writer thread
    died — a bug). ``ok`` is False for ``unwritable`` and ``failed``.
    """

    state: str
    error: RecorderError | None
    dropped: int

    @property
    def ok(self) -> bool:
        return self.state not in ("unwritable", "failed")


# --------------------------------------------------------------------------------------------------
# Recorder


class _Stop:
    __slots__ = ()


class _Sync:
    __slots__ = ("done", "ok")

    def __init__(self) -> None:
        self.done = threading.Event()
        self.ok = False


class _Config:
    __slots__ = ("payload",)

    def __init__(self, payload: Mapping[str, Any]) -> None:
        self.payload = payload


_STOP = _Stop()


class _OpenFile:
    """The file being written and its per-file MCAP state (writer thread only)."""

    __slots__ = ("channels", "messages", "path", "pending", "pending_count", "schemas", "start_ns", "stream", "writer")

    def __init__(self, path: Path, stream: IO[bytes], writer: Writer) -> None:
        self.path = path
        self.stream = stream
        self.writer = writer
        self.start_ns: int | None = None  # log_time of the first loop record: time rotation counts from it
        self.channels: dict[str, int] = {}
        self.schemas: dict[str, int] = {}
        self.pending: dict[str, int] = {}  # records added since the last successful flush, by topic
        self.pending_count = 0
        self.messages = 0  # records of the loop's topics in this file (not config/recorder)


class Recorder:
    """Black-box MCAP recorder with a non-blocking bounded queue and a writer thread.

    Parameters
    ----------
    settings : RecorderSettings
        ``path`` (directory; ``None`` disables recording: ``record()`` returns False and counts
        nothing), ``max_file_mb``, ``max_total_mb``, ``rotate_s``, ``flush_s`` (≤ 1), ``queue_size``.
    clock : callable () -> int
        Receive/record time [ns] used as MCAP ``log_time`` and for time rotation; by default the
        UTC wall clock ``time.time_ns``. Called from the recording threads: must be thread-safe.
    on_error : callable (RecorderError) -> None, optional
        Called from the writer thread when recording fails (entering the unwritable state, a
        changed error while retrying, a failed deletion, an unserialisable payload — once per
        topic). Keep it short and thread-safe; polling :attr:`health` from the loop also works.
    topics : iterable of TopicSpec, optional
        Declared topics (default :func:`default_topics`); ``config`` and ``recorder`` are always
        declared.
    config : mapping, optional
        The configuration record (e.g. ``{"vessel_id", "config_sha256", "config", "text"}``),
        written first in every file. See :meth:`set_config`.
    retry_s : float
        Interval between attempts to open a file while unwritable [s].
    fsync : bool
        ``fsync`` each flushed chunk (durability across power loss, not only process death).
    on_recovered : callable () -> None, optional
        Called from the writer thread when recording resumes after an error.
    wall_clock : callable () -> int
        UTC wall clock [ns] for file names (default ``time.time_ns``).
    index_messages : bool
        Also write MCAP message indexes (per message time/offset within each chunk). Chunk indexes,
        statistics and metadata indexes are always written; message indexes add about 16 bytes per
        message, uncompressed, and only speed up per-topic seeks inside a chunk.

    Notes
    -----
    Call :meth:`close` on shutdown (it finishes the file). The payload passed to :meth:`record`
    belongs to the recorder from then on: do not mutate it afterwards.
    """

    def __init__(self, settings: RecorderSettings, clock: Callable[[], int] = time.time_ns,
                 on_error: Callable[[RecorderError], None] | None = None, *,
                 topics: Iterable[TopicSpec] | None = None, config: Mapping[str, Any] | None = None,
                 retry_s: float = 5.0, fsync: bool = True, on_recovered: Callable[[], None] | None = None,
                 wall_clock: Callable[[], int] = time.time_ns, index_messages: bool = False) -> None:
        self._enabled = settings.path is not None
        self._directory = Path(settings.path) if settings.path is not None else None
        if not hasattr(Writer, "flush"):  # closing a chunk on demand is what bounds the loss on a crash
            raise RuntimeError("the recorder needs mcap >= 1.6 (Writer.flush); upgrade the mcap package")
        if not 0.0 < settings.flush_s <= 1.0:
            raise ValueError(f"recorder flush_s must be in (0, 1] s, got {settings.flush_s}")
        if settings.queue_size < 1:
            raise ValueError(f"recorder queue_size must be at least 1, got {settings.queue_size}")
        if settings.max_file_mb <= 0 or settings.max_total_mb <= 0 or settings.rotate_s <= 0:
            raise ValueError("recorder max_file_mb, max_total_mb and rotate_s must be positive")
        self._capacity = int(settings.queue_size)
        self._max_total_bytes = int(settings.max_total_mb * BYTES_PER_MB)
        self._max_file_bytes = min(int(settings.max_file_mb * BYTES_PER_MB), self._max_total_bytes)
        self._chunk_bytes = max(_MIN_CHUNK_BYTES, min(_MAX_CHUNK_BYTES, self._max_file_bytes // 16))
        self._rotate_ns = int(settings.rotate_s * 1e9)
        self._flush_after_s = 0.5 * settings.flush_s
        self._retry_s = float(retry_s)
        self._fsync = fsync
        self._clock = clock
        self._wall_clock = wall_clock
        self._on_error = on_error
        self._on_recovered = on_recovered
        self._index_types = IndexType.ALL if index_messages else IndexType.ALL & ~IndexType.MESSAGE
        specs = default_topics() if topics is None else tuple(topics)
        self._topics: dict[str, TopicSpec] = {s.topic: s for s in specs}
        for spec in _CORE_TOPICS:
            if spec.topic in ("config", "recorder"):
                self._topics.setdefault(spec.topic, spec)
        self._config: Mapping[str, Any] | None = config

        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._local = threading.local()
        self._tallies: list[dict[tuple[str, str], int]] = []
        self._accepting = self._enabled
        self._close_lock = threading.Lock()
        self._closed = False
        self._stop_deadline: float | None = None
        self._ready = threading.Event()
        # The writer polls the queue every _poll_s instead of blocking on it: a blocking get() would
        # make the loop's first put() of every cycle wake the writer thread (a futex wake and often
        # a context switch: 10–40 µs measured), and the loop must not pay for that. Requests that
        # wait for the writer (sync, close, set_config) set _wakeup.
        self._wakeup = threading.Event()
        self._poll_s = min(0.05, 0.25 * settings.flush_s)

        # writer-thread state (read from other threads only as whole attribute values)
        self._state = "starting" if self._enabled else "disabled"
        self._error: RecorderError | None = None
        self._errors = 0
        self._file: _OpenFile | None = None
        self._file_name: str | None = None
        self._file_bytes = 0
        self._files_opened = 0
        self._files_deleted = 0
        self._written = 0
        self._seq = 0
        self._flush_due: float | None = None
        self._retry_due: float | None = None
        self._last_t_s: float | None = None
        self._reported_dropped = 0
        self._payload_errors_reported: set[str] = set()
        self._unknown_topics: set[str] = set()
        self._finished_clean = False

        self._thread: threading.Thread | None = None
        if self._enabled:
            self._thread = threading.Thread(target=self._run, name="dpcontrol-recorder", daemon=True)
            self._thread.start()
        else:
            self._ready.set()

    # ---------------------------------------------------------------- producer side (control loop)

    def record(self, topic: str, t_s: float | None, payload: Mapping[str, Any] | bytes,
               log_time_ns: int | None = None) -> bool:
        """Queue one record; never blocks, never raises.

        Parameters
        ----------
        topic : str
            A declared topic (an undeclared one is recorded too, see the module notes).
        t_s : float or None
            The control loop's time of the record [s]; stored in the message as ``t_s``.
        payload : mapping or bytes
            JSON-serialisable mapping (numpy arrays and scalars allowed; a bytes ``data`` field is
            stored as ``data_hex``) or raw bytes. Not to be mutated after the call.
        log_time_ns : int, optional
            Receive time [ns] on the recorder's clock when it was taken earlier (raw inputs);
            default: ``clock()`` now.

        Returns
        -------
        bool
            True if queued; False if dropped (queue full, recorder closed or disabled).
        """
        try:
            if not self._accepting:
                if self._enabled:
                    self._count_drop(topic, "closed")
                return False
            if self._queue.qsize() >= self._capacity:
                self._count_drop(topic, "queue_full")
                return False
            self._queue.put((topic, t_s, payload, self._clock() if log_time_ns is None else log_time_ns))
            return True
        except Exception:  # the control loop must never see a recorder exception
            with contextlib.suppress(Exception):
                self._count_drop(str(topic), "error")
            return False

    def record_raw(self, transport: str, t_s: float | None, data: bytes, *, rejected: str | None = None,
                   log_time_ns: int | None = None, **fields: Any) -> bool:
        """Record one raw input (NMEA line, CAN frame, MAVLink packet) on ``raw/<transport>``.

        Parameters
        ----------
        transport : str
            Transport name (the ``<transport>`` of the topic).
        t_s : float or None
            Loop time [s].
        data : bytes
            The bytes as received (stored as ``data_hex``).
        rejected : str, optional
            Why the codec rejected the input; ``None`` when it was accepted.
        log_time_ns : int, optional
            Receive time [ns] on the recorder's clock.
        **fields
            Further JSON-serialisable fields (``source``, ``can_id``, ...).
        """
        try:
            payload = {"data": data, "rejected": rejected, **fields}
            return self.record(f"raw/{transport}", t_s, payload, log_time_ns)
        except Exception:
            return False

    def set_config(self, config: Mapping[str, Any]) -> None:
        """Record a (new) configuration now and write it first in every later file.

        Queued in order with the records, never dropped for a full queue.
        """
        if self._accepting:
            self._queue.put(_Config(config))
            self._wakeup.set()

    # ---------------------------------------------------------------- control

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait until the first file is open (or failed to open); True if recording."""
        self._ready.wait(timeout_s)
        return self._state == "recording"

    def sync(self, timeout_s: float = 5.0) -> bool:
        """Wait until everything recorded before this call is written and flushed to the OS.

        Returns True if it was written (False: unwritable, timed out, closed or disabled).
        """
        if not self._accepting:
            return False
        request = _Sync()
        self._queue.put(request)
        self._wakeup.set()
        return request.done.wait(timeout_s) and request.ok

    def close(self, timeout_s: float = 5.0) -> bool:
        """Stop recording: write what is queued, finish the file (summary + index), stop the thread.

        Bounded in time: after 80 % of ``timeout_s`` the remaining queued records are dropped
        (counted) and the file is finished. Idempotent.

        Returns
        -------
        bool
            True if the writer finished cleanly within ``timeout_s`` (always True when disabled).
        """
        if self._thread is None:
            self._accepting = False
            return True
        with self._close_lock:
            if not self._closed:
                self._closed = True
                self._accepting = False
                self._stop_deadline = time.monotonic() + 0.8 * max(timeout_s, 0.0)
                self._queue.put(_STOP)
                self._wakeup.set()
        if threading.current_thread() is self._thread:
            return False  # called from a callback on the writer thread: it stops after this item
        self._thread.join(max(timeout_s, 0.0))
        return not self._thread.is_alive() and self._finished_clean

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- state for the status

    @property
    def directory(self) -> Path | None:
        """The recording directory (None when disabled)."""
        return self._directory

    @property
    def current_file(self) -> Path | None:
        """The file being written (None while unwritable, closed or disabled)."""
        current = self._file
        return current.path if current is not None else None

    @property
    def dropped(self) -> int:
        """Records not recorded, all reasons (queue full, unwritable, invalid, closed, shutdown)."""
        return sum(self._drop_counts().values())

    @property
    def health(self) -> RecorderHealth:
        """Current health (``ok`` is False while unwritable or failed)."""
        state = self._state
        if state in ("starting", "recording", "unwritable") and self._thread is not None \
                and not self._thread.is_alive():
            state = "failed"
        error = self._error if state in ("unwritable", "failed") else None
        return RecorderHealth(state, error, self.dropped)

    def stats(self) -> dict[str, Any]:
        """JSON-ready counters for the daemon status (``dp/<vessel>/status``)."""
        counts = self._drop_counts()
        by_reason: dict[str, int] = {}
        by_topic: dict[str, int] = {}
        for (reason, topic), n in counts.items():
            by_reason[reason] = by_reason.get(reason, 0) + n
            by_topic[topic] = by_topic.get(topic, 0) + n
        health = self.health
        error = self._error
        return {"state": health.state, "ok": health.ok, "file": self._file_name, "file_bytes": self._file_bytes,
                "files_opened": self._files_opened, "files_deleted": self._files_deleted,
                "written": self._written, "queued": self._queue.qsize(), "queue_size": self._capacity,
                "dropped": sum(by_reason.values()), "dropped_by_reason": by_reason, "dropped_by_topic": by_topic,
                "errors": self._errors, "last_error": error.message if error is not None else None}

    # ---------------------------------------------------------------- drop accounting

    def _count_drop(self, topic: str, reason: str, n: int = 1) -> None:
        # One dict per producing thread: exact counts without a lock on the hot path (a shared
        # counter would lose increments between threads; a lock could block the loop).
        try:
            tally = self._local.tally
        except AttributeError:
            tally = self._local.tally = {}
            self._tallies.append(tally)
        key = (reason, topic)
        tally[key] = tally.get(key, 0) + n

    def _drop_counts(self) -> dict[tuple[str, str], int]:
        total: dict[tuple[str, str], int] = {}
        for tally in list(self._tallies):
            for key, n in tally.copy().items():
                total[key] = total.get(key, 0) + n
        return total

    # ---------------------------------------------------------------- writer thread

    def _run(self) -> None:
        try:
            self._guarded(self._open_or_fail)
            self._ready.set()
            stop = False
            while not stop:
                self._wakeup.clear()  # before draining: a request queued after the drain sets it again
                while True:
                    try:
                        item = self._queue.get_nowait()
                    except queue.Empty:
                        break
                    if item is _STOP:
                        stop = True
                        break
                    self._guarded(self._handle, item)
                    self._guarded(self._service)
                if not stop:
                    self._guarded(self._service)
                    self._wakeup.wait(self._wait_s())
            self._shutdown()
        except BaseException as error:
            logger.exception("recorder: writer thread failed")
            self._error = RecorderError("internal", f"recorder writer failed: {error!r}", wall_ns=time.time_ns())
            self._state = "failed"
            self._notify_error(self._error)
            raise
        finally:
            self._ready.set()

    def _now_ns(self) -> int:
        try:
            return int(self._clock())
        except Exception:
            return time.time_ns()

    def _guarded(self, step: Callable[..., object], *args: Any) -> None:
        try:
            step(*args)
        except Exception as error:  # a bug must not stop recording for good
            logger.exception("recorder: unexpected error")
            self._fail("internal", error, self._file.path if self._file else self._directory)

    def _wait_s(self) -> float:
        """How long the writer may sleep: the poll period, or less until a flush or retry is due."""
        wait = self._poll_s
        due = self._flush_due if self._file is not None else self._retry_due
        if due is not None:
            wait = min(wait, max(0.0, due - time.monotonic()))
        return wait

    def _handle(self, item: Any) -> None:
        if type(item) is tuple:
            self._write(*item)
        elif isinstance(item, _Sync):
            try:
                item.ok = self._file is not None and self._flush()
            finally:
                item.done.set()
        elif isinstance(item, _Config):
            self._config = item.payload
            self._write("config", None, item.payload, self._now_ns())

    def _service(self) -> None:
        now = time.monotonic()
        if self._file is not None:
            if self._flush_due is not None and now >= self._flush_due:
                self._flush()
        elif self._retry_due is not None and now >= self._retry_due:
            self._open_or_fail()

    def _write(self, topic: Any, t_s: Any, payload: Any, log_time_ns: Any) -> None:
        if not isinstance(topic, str) or not topic:
            self._count_drop(str(topic), "invalid")
            self._report_payload_error(str(topic), f"invalid topic {topic!r}")
            return
        if self._stop_deadline is not None and time.monotonic() > self._stop_deadline:
            self._count_drop(topic, "shutdown")
            return
        if self._file is None:
            self._count_drop(topic, "unwritable")
            return
        try:
            data = encode_record(t_s, payload)
            log_time = int(log_time_ns)
            if not 0 <= log_time < 1 << 64:
                raise ValueError(f"log_time_ns {log_time} out of range")
        except (TypeError, ValueError, OverflowError) as error:
            self._count_drop(topic, "invalid")
            self._report_payload_error(topic, f"record on {topic!r} not recordable: {error}")
            return
        if isinstance(t_s, (int, float)) and math.isfinite(t_s):
            self._last_t_s = float(t_s)
        current = self._file
        loop_record = topic not in ("config", "recorder")
        if loop_record and current.start_ns is not None and log_time - current.start_ns >= self._rotate_ns:
            if not self._rotate():
                self._count_drop(topic, "unwritable")
                return
            current = self._file
            assert current is not None
        if not self._add(current, topic, data, log_time):
            self._count_drop(topic, "unwritable")
            return
        if loop_record:
            current.messages += 1
            if current.start_ns is None:
                current.start_ns = log_time
            if current.stream.tell() >= self._max_file_bytes:
                self._rotate()

    def _add(self, current: _OpenFile, topic: str, data: bytes, log_time: int) -> bool:
        """Add one message to the open chunk; on an OS error abandon the file and return False."""
        try:
            self._add_unchecked(current, topic, data, log_time)
        except OSError as error:  # a full chunk was finalised and its write failed
            self._fail("write", error, current.path)
            return False
        return True

    def _add_unchecked(self, current: _OpenFile, topic: str, data: bytes, log_time: int) -> None:
        channel = current.channels.get(topic)
        if channel is None:
            channel = self._register(current, topic)
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        current.writer.add_message(channel, log_time, data, log_time, self._seq)
        current.pending[topic] = current.pending.get(topic, 0) + 1
        current.pending_count += 1
        if self._flush_due is None:
            self._flush_due = time.monotonic() + self._flush_after_s

    def _register(self, current: _OpenFile, topic: str) -> int:
        spec = self._topics.get(topic)
        if spec is None:
            spec = TopicSpec(topic, GENERIC_SCHEMA, "A topic the recorder was not told about (open schema).")
            if topic not in self._unknown_topics:
                self._unknown_topics.add(topic)
                logger.warning("recorder: topic %r was not declared; recording it with an open schema", topic)
        schema = current.schemas.get(spec.schema_name)
        if schema is None:
            schema = current.writer.register_schema(spec.schema_name, SCHEMA_ENCODING, spec.json_schema())
            current.schemas[spec.schema_name] = schema
        channel = current.writer.register_channel(topic, MESSAGE_ENCODING, schema)
        current.channels[topic] = channel
        return channel

    def _flush(self) -> bool:
        """Close the open chunk, hand it to the OS, fsync; rotate if the file is full."""
        current = self._file
        if current is None:
            return False
        if self.dropped != self._reported_dropped and not self._add(
                current, "recorder", self._recorder_status(current), self._now_ns()):
            return False
        try:
            current.writer.flush()
            if self._fsync:
                os.fsync(current.stream.fileno())
            size = current.stream.tell()
        except OSError as error:
            self._fail("flush", error, current.path)
            return False
        self._written += current.pending_count
        current.pending.clear()
        current.pending_count = 0
        self._flush_due = None
        self._file_bytes = size
        if size >= self._max_file_bytes and current.messages > 0:
            return self._rotate()
        return True

    def _recorder_status(self, current: _OpenFile) -> bytes:
        """The ``recorder`` record: counters and the last error (explains gaps in the log)."""
        by_reason: dict[str, int] = {}
        for (reason, _), n in self._drop_counts().items():
            by_reason[reason] = by_reason.get(reason, 0) + n
        total = sum(by_reason.values())
        self._reported_dropped = total
        error = self._error
        payload = {"written": self._written + current.pending_count, "dropped": total, "dropped_by_reason": by_reason,
                   "errors": self._errors, "last_error": error.message if error is not None else None,
                   "file": current.path.name}
        return encode_record(self._last_t_s, payload)

    def _rotate(self) -> bool:
        self._finish_file()
        if self._state == "unwritable":
            return False  # finishing failed: the retry timer opens the next file
        return self._open_or_fail()

    def _open_or_fail(self) -> bool:
        assert self._directory is not None
        try:
            self._open_file()
        except OSError as error:
            self._fail("open", error, getattr(error, "filename", None) or self._directory)
            return False
        recovered = self._state == "unwritable"
        self._state = "recording"
        self._retry_due = None
        if recovered:
            logger.warning("recorder: recording again in %s", self._file_name)
            if self._on_recovered is not None:
                try:
                    self._on_recovered()
                except Exception:
                    logger.exception("recorder: on_recovered callback failed")
        return True

    def _open_file(self) -> None:
        assert self._directory is not None
        directory = self._directory
        directory.mkdir(parents=True, exist_ok=True)
        existing = list_log_files(directory)
        name = _next_name(self._wall_clock(), existing)
        self._prune(existing)
        path = directory / name
        stream = _open_output(path)
        try:
            writer = Writer(stream, chunk_size=self._chunk_bytes, compression=CompressionType.ZSTD,
                            index_types=self._index_types)
            writer.start(profile="", library=RECORDER_LIBRARY)
            current = _OpenFile(path, stream, writer)
            config = self._config or {}
            writer.add_metadata("dpcontrol", {
                "recorder": RECORDER_LIBRARY, "file": name, "file_index": str(self._files_opened),
                "vessel_id": str(config.get("vessel_id", "")), "config_sha256": str(config.get("config_sha256", ""))})
            for spec in self._topics.values():  # every declared channel up front: self-describing files
                self._register(current, spec.topic)
            now_ns = self._now_ns()
            if self._config is not None:
                try:
                    config_data = encode_record(None, self._config)
                except (TypeError, ValueError) as error:
                    self._report_payload_error("config", f"configuration record not recordable: {error}")
                else:
                    self._add_unchecked(current, "config", config_data, now_ns)
            self._add_unchecked(current, "recorder", self._recorder_status(current), now_ns)
            writer.flush()
            if self._fsync:
                os.fsync(stream.fileno())
        except BaseException:
            with contextlib.suppress(OSError):
                stream.close()
            with contextlib.suppress(OSError):
                path.unlink()  # a file with nothing recorded in it
            raise
        if self._fsync:
            fsync_directory(directory)
        self._file = current
        self._file_name = name
        self._file_bytes = stream.tell()
        self._files_opened += 1
        self._written += current.pending_count
        current.pending.clear()
        current.pending_count = 0
        self._flush_due = None

    def _prune(self, existing: list[Path]) -> None:
        """Delete the oldest files while they and a new full file would exceed ``max_total_mb``."""
        sizes = []
        for path in existing:
            try:
                sizes.append(path.stat().st_size)
            except OSError:
                sizes.append(0)
        total = sum(sizes)
        budget = self._max_total_bytes - self._max_file_bytes
        index = 0
        while total > budget and index < len(existing):
            path = existing[index]
            try:
                path.unlink()
                self._files_deleted += 1
                logger.info("recorder: deleted %s to stay within max_total_mb", path.name)
            except FileNotFoundError:
                pass
            except OSError as error:
                self._errors += 1
                self._notify_error(self._error_of("delete", error, path))
                break
            total -= sizes[index]
            index += 1

    def _finish_file(self) -> None:
        current = self._file
        if current is None:
            return
        if not self._add(current, "recorder", self._recorder_status(current), self._now_ns()):
            return  # abandoned: the flushed part stays readable
        try:
            current.writer.finish()
            current.stream.flush()
            if self._fsync:
                os.fsync(current.stream.fileno())
            size = current.stream.tell()
            current.stream.close()
        except OSError as error:
            self._fail("finish", error, current.path)
            return
        self._written += current.pending_count
        self._file = None
        self._file_name = None
        self._file_bytes = size
        self._flush_due = None

    def _shutdown(self) -> None:
        self._finish_file()
        clean = self._state == "recording"
        while True:  # records queued after the stop request
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if type(item) is tuple:
                self._count_drop(str(item[0]), "closed")
            elif isinstance(item, _Sync):
                item.done.set()
        self._state = "closed"
        self._finished_clean = clean

    def _error_of(self, kind: str, error: BaseException, path: object) -> RecorderError:
        code = getattr(error, "errno", None)
        errno_name = errno.errorcode.get(code) if isinstance(code, int) else None
        reason = getattr(error, "strerror", None) or str(error) or type(error).__name__
        where = f" {path}" if path is not None else ""
        code_text = f" ({errno_name})" if errno_name else ""
        return RecorderError(kind, f"recorder cannot {kind}{where}: {reason}{code_text}",
                             str(path) if path is not None else None, errno_name, time.time_ns())

    def _fail(self, kind: str, error: BaseException, path: object) -> None:
        """Abandon the current file (its flushed part stays readable), enter the unwritable state."""
        current = self._file
        self._file = None
        self._file_name = None
        self._flush_due = None
        if current is not None:
            for topic, n in current.pending.items():
                self._count_drop(topic, "unwritable", n)
            with contextlib.suppress(OSError):  # the buffered bytes that failed are lost; the fd is closed anyway
                current.stream.close()
        report = self._error_of(kind, error, path)
        previous = self._error
        changed = (self._state != "unwritable" or previous is None
                   or (previous.kind, previous.errno_name, previous.path)
                   != (report.kind, report.errno_name, report.path))
        self._error = report
        self._errors += 1
        self._state = "unwritable"
        self._retry_due = time.monotonic() + self._retry_s
        if changed:
            logger.error("%s; retrying every %.1f s", report.message, self._retry_s)
            self._notify_error(report)

    def _report_payload_error(self, topic: str, message: str) -> None:
        if topic in self._payload_errors_reported:
            return
        self._payload_errors_reported.add(topic)
        logger.error("recorder: %s", message)
        self._notify_error(RecorderError("payload", message, wall_ns=time.time_ns()))

    def _notify_error(self, report: RecorderError) -> None:
        if self._on_error is None:
            return
        try:
            self._on_error(report)
        except Exception:
            logger.exception("recorder: on_error callback failed")
