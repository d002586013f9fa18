"""Reading and exporting black-box recordings (the MCAP files of :mod:`interfaces.recorder`).

Used by ``dpcontrol log export LOG --csv DIR`` and ``dpcontrol replay``:

* :func:`read_records` iterates the records of one file or of a recording directory (rotated
  files in time order), tolerating unfinished files (a SIGKILL or power loss leaves a file without
  its summary: every complete chunk is still read, by a linear scan) and damaged chunks (skipped,
  reported); nothing here raises for a bad file — problems go to ``on_issue``;
* :func:`export_csv` writes one CSV per topic with flattened columns (nested mappings → ``a.b``,
  lists → ``a[0]`` …) and all raw inputs together in ``raw.csv`` with their bytes in hex (and as
  text when they are printable, as NMEA 0183 is);
* :func:`read_config` returns the configuration a recording was made with.

Records are read with the ``mcap`` package's stream reader, not its indexed reader: the indexed
reader needs the summary at the end of the file, which an unfinished file lacks, and a full
export reads every chunk anyway.
"""

from __future__ import annotations

import csv
import logging
import os
import re
import struct
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import orjson
from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from interfaces.recorder import list_log_files

logger = logging.getLogger(__name__)

__all__ = ["Record", "export_csv", "flatten", "log_files", "read_config", "read_records"]

# A chunk is at most ~1 MiB; anything claiming more than this is a damaged length field.
_RECORD_SIZE_LIMIT = 256 * 2**20
RAW_PREFIX = "raw/"
META_COLUMNS = ("log_time_ns", "t_s")

IssueHandler = Callable[[Path, str], None]


@dataclass(frozen=True, slots=True)
class Record:
    """One recorded message.

    Attributes
    ----------
    topic : str
        MCAP topic (``estimate``, ``raw/nmea0183``, ...).
    log_time_ns : int
        Receive/record time [ns] on the recorder's clock (UTC wall clock in the daemon).
    payload : dict
        The decoded JSON message, including the loop time ``t_s``.
    """

    topic: str
    log_time_ns: int
    payload: dict[str, Any]

    @property
    def t_s(self) -> float | None:
        """The control loop's time of the record [s] (None if absent)."""
        value = self.payload.get("t_s")
        return float(value) if isinstance(value, (int, float)) else None

    @property
    def data(self) -> bytes | None:
        """The raw bytes of a raw-input record (from ``data_hex``), else None."""
        text = self.payload.get("data_hex")
        if not isinstance(text, str):
            return None
        try:
            return bytes.fromhex(text)
        except ValueError:
            return None


def _warn(path: Path, message: str) -> None:
    logger.warning("%s: %s", path, message)


def log_files(path: str | os.PathLike[str]) -> list[Path]:
    """The files of a recording: ``[path]`` for a file, the recorder files of a directory in order.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    """
    p = Path(path)
    if p.is_dir():
        return list_log_files(p)
    if not p.exists():
        raise FileNotFoundError(f"no recording at {p}")
    return [p]


def read_records(path: str | os.PathLike[str], topics: Iterable[str] | None = None, *,
                 on_issue: IssueHandler | None = None) -> Generator[Record, None, None]:
    """Iterate the records of a recording file or directory, in recording order.

    Parameters
    ----------
    path : path-like
        One ``.mcap`` file, or a recorder directory (its ``dpcontrol-*.mcap`` files in name order,
        which is time order).
    topics : iterable of str, optional
        Only these topics (default: all).
    on_issue : callable (Path, str) -> None, optional
        Told about unfinished files, damaged chunks and undecodable messages (default: a logged
        warning). Reading goes on after every issue.

    Yields
    ------
    Record
        In the order written, which is the order of the ``record()`` calls (within a file and
        across rotated files).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    """
    wanted = None if topics is None else frozenset(topics)
    report = on_issue or _warn
    for file in log_files(path):
        yield from _read_file(file, wanted, report)


def _read_file(path: Path, wanted: frozenset[str] | None, report: IssueHandler) -> Iterator[Record]:
    try:
        stream = open(path, "rb")  # noqa: SIM115 - closed in the finally of this generator
    except OSError as error:
        report(path, f"cannot open: {error.strerror or error}")
        return
    channels: dict[int, str] = {}
    finished = False
    try:
        reader = StreamReader(stream, emit_chunks=True, record_size_limit=_RECORD_SIZE_LIMIT)
        try:
            for item in reader.records:
                if isinstance(item, Chunk):
                    try:
                        inner = breakup_chunk(item, validate_crc=True)
                    except Exception as error:  # CRC mismatch, bad compression: skip this chunk only
                        report(path, f"damaged chunk ({item.message_start_time}–{item.message_end_time} ns) "
                                     f"skipped: {error}")
                        continue
                    for record in inner:
                        decoded = _take(record, channels, wanted, path, report)
                        if decoded is not None:
                            yield decoded
                elif isinstance(item, DataEnd | Footer):
                    finished = True
                    break  # the summary repeats what was read
                else:
                    decoded = _take(item, channels, wanted, path, report)
                    if decoded is not None:
                        yield decoded
        except (McapError, OSError, struct.error, ValueError, MemoryError) as error:
            # McapError covers EndOfFile (a truncated last record) and a bad magic/length.
            if not finished:
                report(path, f"unfinished or damaged file, read up to byte {stream.tell()} "
                             f"({type(error).__name__}: {str(error) or 'end of file'})")
            return
        if not finished:
            report(path, "unfinished file (no summary)")
    finally:
        stream.close()


def _take(record: object, channels: dict[int, str], wanted: frozenset[str] | None, path: Path,
          report: IssueHandler) -> Record | None:
    if isinstance(record, Channel):
        channels[record.id] = record.topic
        return None
    if not isinstance(record, Message):
        return None
    topic = channels.get(record.channel_id)
    if topic is None:
        report(path, f"message on unknown channel {record.channel_id} skipped")
        return None
    if wanted is not None and topic not in wanted:
        return None
    try:
        payload = orjson.loads(record.data)
    except orjson.JSONDecodeError as error:
        report(path, f"undecodable message on {topic!r} at {record.log_time} ns skipped: {error}")
        return None
    if not isinstance(payload, dict):
        payload = {"value": payload}
    return Record(topic, record.log_time, payload)


def read_config(path: str | os.PathLike[str], *, on_issue: IssueHandler | None = None) -> dict[str, Any] | None:
    """The first ``config`` record of a recording (without ``t_s``), or None if there is none."""
    for record in read_records(path, ("config",), on_issue=on_issue):
        payload = dict(record.payload)
        payload.pop("t_s", None)
        return payload
    return None


# --------------------------------------------------------------------------------------------------
# CSV export


def flatten(value: Any, prefix: str = "", out: dict[str, Any] | None = None) -> dict[str, Any]:
    """Flatten nested mappings and lists into one level: ``{"a": {"b": [1, 2]}}`` → ``a.b[0]``, ``a.b[1]``.

    Empty mappings and lists produce no column. A scalar at the top level goes into column
    ``prefix`` (``"value"`` if empty).
    """
    if out is None:
        out = {}
    if isinstance(value, Mapping):
        for key, item in value.items():
            flatten(item, f"{prefix}.{key}" if prefix else str(key), out)
    elif isinstance(value, list | tuple):
        for index, item in enumerate(value):
            flatten(item, f"{prefix}[{index}]", out)
    else:
        out[prefix or "value"] = value
    return out


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if value is True:
        return "true"
    if value is False:
        return "false"
    return value  # floats are written with repr(): they read back exactly


def _printable(data: bytes) -> str:
    """The bytes as text when they are printable ASCII (NMEA 0183), line endings stripped; else ''."""
    text = data.rstrip(b"\r\n")
    if text and text.isascii() and all(32 <= b < 127 for b in text):
        return text.decode("ascii")
    return ""


def _row(record: Record, with_topic: bool) -> dict[str, Any]:
    row: dict[str, Any] = {"log_time_ns": record.log_time_ns, "t_s": record.payload.get("t_s")}
    if with_topic:
        row["topic"] = record.topic
    flat = flatten({k: v for k, v in record.payload.items() if k != "t_s"})
    if record.topic.startswith(RAW_PREFIX):
        data = record.data
        if data is not None:
            flat["data_text"] = _printable(data)
    for key, value in flat.items():
        row[key if key not in row else f"payload.{key}"] = value
    return row


def export_csv(log: str | os.PathLike[str], out_dir: str | os.PathLike[str], topics: Iterable[str] | None = None,
               *, on_issue: IssueHandler | None = None) -> list[Path]:
    """Export a recording to CSV: one file per topic, plus ``raw.csv`` with every raw input.

    Columns: ``log_time_ns``, ``t_s``, then the flattened payload fields in order of first
    appearance over the whole recording (``raw.csv`` adds ``topic``; raw topics add
    ``data_text``, the bytes as text when printable). Missing values are empty cells; booleans
    are ``true``/``false``; floats are written so that they read back exactly. A topic ``a/b``
    goes to ``a_b.csv``.

    The recording is read twice (once for the columns, once for the rows), so memory stays
    bounded for recordings of any length.

    Parameters
    ----------
    log : path-like
        Recording file or directory.
    out_dir : path-like
        Output directory (created).
    topics : iterable of str, optional
        Only these topics.
    on_issue : callable (Path, str) -> None, optional
        See :func:`read_records` (issues are reported on the first pass only).

    Returns
    -------
    list of Path
        The CSV files written, sorted.
    """
    wanted = None if topics is None else list(topics)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    names: dict[str, str] = {}  # topic → CSV file name (unique, "raw.csv" reserved)
    columns: dict[str, dict[str, None]] = {}  # CSV file name → ordered set of columns
    count = 0
    for record in read_records(log, wanted, on_issue=on_issue):
        count += 1
        for name, with_topic in _targets(record.topic, names):
            known = columns.setdefault(name, {})
            for key in _row(record, with_topic):
                known.setdefault(key, None)

    handles: dict[str, Any] = {}
    writers: dict[str, csv.DictWriter[str]] = {}
    records = read_records(log, wanted, on_issue=lambda path, message: None)
    try:
        for name, known in columns.items():
            handle = open(out / name, "w", newline="", encoding="utf-8")  # noqa: SIM115 - closed below
            handles[name] = handle
            # "ignore": a recording still being written may have grown since the first pass
            writer = csv.DictWriter(handle, fieldnames=list(known), restval="", extrasaction="ignore")
            writer.writeheader()
            writers[name] = writer
        for _, record in zip(range(count), records, strict=False):
            for name, with_topic in _targets(record.topic, names):
                target = writers.get(name)
                if target is not None:
                    target.writerow({k: _cell(v) for k, v in _row(record, with_topic).items()})
    finally:
        records.close()
        for handle in handles.values():
            handle.close()
    return sorted(out / name for name in columns)


def _targets(topic: str, names: dict[str, str]) -> list[tuple[str, bool]]:
    """CSV files a record goes to: its topic's (``a/b`` → ``a_b.csv``), and ``raw.csv`` for raw inputs."""
    name = names.get(topic)
    if name is None:
        base = re.sub(r"[^A-Za-z0-9_.-]", "_", topic) or "topic"
        taken = set(names.values()) | {"raw.csv"}
        name, suffix = f"{base}.csv", 2
        while name in taken:
            name, suffix = f"{base}-{suffix}.csv", suffix + 1
        names[topic] = name
    targets = [(name, False)]
    if topic.startswith(RAW_PREFIX):
        targets.append(("raw.csv", True))
    return targets
