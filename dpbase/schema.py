"""Validation of configuration mappings into frozen dataclasses.

Pure: works on already-parsed mappings (YAML is read at the composition layer), so the numeric
core, the runtime and the plant share one way of reporting bad configuration. Every error names
the file (when known), the key path and what was expected::

    deploy/config/supply.yaml: sensors[1].rate_hz: expected a number > 0, got 'fast'
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


class ConfigError(ValueError):
    """Invalid configuration: carries the file, the key path and what was expected."""

    def __init__(self, path: str, expected: str, got: object = None, *, file: str | None = None,
                 show_got: bool = True) -> None:
        self.path = path
        self.expected = expected
        self.got = got
        self.file = file
        self.show_got = show_got
        super().__init__(self._message())

    def _message(self) -> str:
        where = f"{self.file}: " if self.file else ""
        key = self.path or "<root>"
        got = f", got {self.got!r}" if self.show_got else ""
        return f"{where}{key}: expected {self.expected}{got}"

    def with_file(self, file: str) -> ConfigError:
        """Return a copy of this error that names ``file``."""
        return ConfigError(self.path, self.expected, self.got, file=file, show_got=self.show_got)


_MISSING = object()


@dataclass(frozen=True)
class KeyRecord:
    """One configuration key as a parser read it (see :func:`recording_keys`).

    Attributes
    ----------
    path : str
        Key path with list indices folded: ``sensors[].rate_hz``.
    type : str
        ``number``, ``integer``, ``string``, ``boolean``, ``mapping``, ``list``, ``vector``, ``matrix``, or
        ``value`` (read raw: the parser checks it itself).
    default : object
        The default, :data:`REQUIRED` when the key must be given.
    detail : str
        Bounds or choices (``> 0``, ``one of a, b``); empty when none.
    when : str
        ``kind = mmae`` when the key is read only for that kind of its section; empty otherwise.
    """

    path: str
    type: str
    default: object
    detail: str
    when: str


REQUIRED = _MISSING
"""The default of a :class:`KeyRecord` whose key is required."""


class VesselDefault(str):
    """A default that depends on the vessel (``control.kind``): the value is this vessel's, and the configuration
    reference writes ``per vessel`` for it instead (a string like any other to the parsers)."""

    __slots__ = ()

class _KeyLog:
    """What :func:`recording_keys` collects: the records, and the discriminator (``kind``, ``protocol``) read in
    each section so far, by the section's full path (``transports[2]``)."""

    DISCRIMINATORS = ("kind", "protocol")

    def __init__(self) -> None:
        self.records: list[KeyRecord] = []
        self.chosen: dict[str, str] = {}

    def note(self, section_path: str, key: str, type_: str, default: object, detail: str,  # noqa: PLR0917
             value: object) -> None:  # (one call site, Section._note)
        when = "" if key in self.DISCRIMINATORS else self.chosen.get(section_path, "")
        if key in self.DISCRIMINATORS and type_ == "string" and isinstance(value, str):
            self.chosen[section_path] = f"{key} = {value}"
        self.records.append(KeyRecord(_INDEX.sub("[]", join(section_path, key)), type_, default, detail, when))


_KEY_LOG: ContextVar[_KeyLog | None] = ContextVar("dpbase_schema_key_log", default=None)
_INDEX = re.compile(r"\[\d+\]")


@contextmanager
def recording_keys() -> Iterator[list[KeyRecord]]:
    """Record every key the parsers read while the block runs (for the generated configuration reference).

    Outside such a block nothing is recorded (one context-variable look-up per key read).
    """
    log = _KeyLog()
    token = _KEY_LOG.set(log)
    try:
        yield log.records
    finally:
        _KEY_LOG.reset(token)


def _bounds(minimum: float | None, maximum: float | None, exclusive_minimum: bool = False) -> str:
    parts = []
    if minimum is not None:
        parts.append(f"{'>' if exclusive_minimum else '>='} {minimum:g}")
    if maximum is not None:
        parts.append(f"<= {maximum:g}")
    return ", ".join(parts)


def join(path: str, *keys: str | int) -> str:
    """Extend a key path: ``join("sensors", 1) == "sensors[1]"``, ``join("a", "b", "c") == "a.b.c"``."""
    for key in keys:
        if isinstance(key, int):
            path = f"{path}[{key}]"
        elif path:
            path = f"{path}.{key}"
        else:
            path = key
    return path


class Section:
    """A mapping being validated, with its key path; remembers which keys were read.

    Call :meth:`finish` after reading every key to reject unknown keys (typos).
    """

    __slots__ = ("_read", "data", "path")

    def __init__(self, data: Mapping[str, Any], path: str = "") -> None:
        self.data = data
        self.path = path
        self._read: set[str] = set()

    def _note(self, key: str, type_: str, default: object, detail: str = "") -> None:
        """Tell a running :func:`recording_keys` that ``key`` was read."""
        log = _KEY_LOG.get()
        if log is not None:
            log.note(self.path, key, type_, default, detail, self.data.get(key, default))

    @staticmethod
    def of(value: object, path: str = "") -> Section:
        """Wrap ``value`` (must be a mapping with string keys; ``None`` is an empty mapping)."""
        if value is None:
            value = {}
        if not isinstance(value, Mapping):
            raise ConfigError(path, "a mapping", value)
        for key in value:
            if not isinstance(key, str):
                raise ConfigError(path, "string keys", key)
        return Section(dict(value), path)

    def _mark(self, key: str) -> None:
        self._read.add(key)

    def has(self, key: str) -> bool:
        self._note(key, "value", None)
        return key in self.data

    def raw(self, key: str, default: object = _MISSING) -> Any:
        """The raw value of ``key`` (required when no default is given)."""
        self._note(key, "value", default)
        self._mark(key)
        if key not in self.data:
            if default is _MISSING:
                raise ConfigError(join(self.path, key), "a value (required key is missing)", show_got=False)
            return default
        return self.data[key]

    def number(self, key: str, default: object = _MISSING, *, minimum: float | None = None,
               maximum: float | None = None, exclusive_minimum: bool = False) -> float:
        """A finite real number, optionally bounded."""
        self._note(key, "number", default, _bounds(minimum, maximum, exclusive_minimum))
        value = self.raw(key, default)
        return check_number(value, join(self.path, key), minimum=minimum, maximum=maximum,
                            exclusive_minimum=exclusive_minimum)

    def optional_number(self, key: str, **bounds: Any) -> float | None:
        self._note(key, "number", None, _bounds(bounds.get("minimum"), bounds.get("maximum"),
                                                bounds.get("exclusive_minimum", False)))
        value = self.raw(key, None)
        if value is None:
            return None
        return check_number(value, join(self.path, key), **bounds)

    def integer(self, key: str, default: object = _MISSING, *, minimum: int | None = None,
                maximum: int | None = None) -> int:
        self._note(key, "integer", default, _bounds(minimum, maximum))
        value = self.raw(key, default)
        where = join(self.path, key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(where, "an integer", value)
        if minimum is not None and value < minimum:
            raise ConfigError(where, f"an integer >= {minimum}", value)
        if maximum is not None and value > maximum:
            raise ConfigError(where, f"an integer <= {maximum}", value)
        return value

    def string(self, key: str, default: object = _MISSING, *, choices: Iterable[str] | None = None) -> str:
        if choices is not None:
            choices = list(choices)
        self._note(key, "string", default, "" if choices is None else "one of " + ", ".join(choices))
        value = self.raw(key, default)
        where = join(self.path, key)
        if not isinstance(value, str) or not value:
            raise ConfigError(where, "a non-empty string", value)
        if choices is not None:
            options = list(choices)
            if value not in options:
                raise ConfigError(where, "one of " + ", ".join(options), value)
        return value

    def boolean(self, key: str, default: object = _MISSING) -> bool:
        self._note(key, "boolean", default)
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise ConfigError(join(self.path, key), "true or false", value)
        return value

    def section(self, key: str, *, required: bool = False) -> Section:
        self._note(key, "mapping", _MISSING if required else None)
        value = self.raw(key, _MISSING if required else None)
        return Section.of(value, join(self.path, key))

    def items(self, key: str, *, required: bool = False, min_items: int = 0) -> list[tuple[str, Any]]:
        """A list value: returns ``(path, element)`` pairs."""
        self._note(key, "list", _MISSING if required else [],
                   f"at least {min_items} item(s)" if min_items else "")
        value = self.raw(key, _MISSING if required else [])
        where = join(self.path, key)
        if value is None:
            value = []
        if not isinstance(value, list):
            raise ConfigError(where, "a list", value)
        if len(value) < min_items:
            raise ConfigError(where, f"a list of at least {min_items} item(s)", value)
        return [(join(where, i), element) for i, element in enumerate(value)]

    def vector(self, key: str, length: int | None = None, default: object = _MISSING) -> np.ndarray:
        self._note(key, "vector", default, "" if length is None else f"{length} numbers")
        value = self.raw(key, default)
        return check_vector(value, join(self.path, key), length)

    def matrix(self, key: str, shape: tuple[int, int], default: object = _MISSING) -> np.ndarray:
        self._note(key, "matrix", default, f"{shape[0]}x{shape[1]}")
        value = self.raw(key, default)
        return check_matrix(value, join(self.path, key), shape)

    def finish(self, also_valid: Iterable[str] = ()) -> None:
        """Reject keys that were never read (typos name the key and list the valid ones: those read, and
        ``also_valid``, the keys of a section whose parser reads only the keys present)."""
        read = self._read
        unknown = [key for key in self.data if key not in read]
        if unknown:
            valid = ", ".join(sorted(set(read) | set(also_valid))) or "none"
            raise ConfigError(join(self.path, unknown[0]), f"a known key (valid keys here: {valid})",
                              show_got=False)


def check_number(value: object, where: str, *, minimum: float | None = None, maximum: float | None = None,
                 exclusive_minimum: bool = False) -> float:
    """Validate a finite real number within optional bounds."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(where, "a number", value)
    number = float(value)
    if not math.isfinite(number):
        raise ConfigError(where, "a finite number", value)
    if minimum is not None:
        if exclusive_minimum and number <= minimum:
            raise ConfigError(where, f"a number > {minimum:g}", value)
        if not exclusive_minimum and number < minimum:
            raise ConfigError(where, f"a number >= {minimum:g}", value)
    if maximum is not None and number > maximum:
        raise ConfigError(where, f"a number <= {maximum:g}", value)
    return number


def check_vector(value: object, where: str, length: int | None = None) -> np.ndarray:
    """Validate a list of finite numbers (optionally of a given length)."""
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise ConfigError(where, "a list of numbers", value)
    if length is not None and len(value) != length:
        raise ConfigError(where, f"a list of {length} numbers", value)
    return np.array([check_number(v, join(where, i)) for i, v in enumerate(value)], dtype=float)


def check_matrix(value: object, where: str, shape: tuple[int, int]) -> np.ndarray:
    """Validate a nested list of finite numbers with the given shape."""
    rows, cols = shape
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != rows:
        raise ConfigError(where, f"a {rows}x{cols} matrix (list of {rows} rows)", value)
    return np.vstack([check_vector(row, join(where, i), cols) for i, row in enumerate(value)])


def parse_list(section: Section, key: str, parse: Callable[[Section], T], *, required: bool = False,
               min_items: int = 0) -> tuple[T, ...]:
    """Parse a list of mappings with ``parse`` (each element gets its own key path)."""
    return tuple(parse(Section.of(element, where))
                 for where, element in section.items(key, required=required, min_items=min_items))
