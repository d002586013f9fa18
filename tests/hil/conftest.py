"""The rig of the emulator tests: files in a temporary folder, free loopback ports, the emulator in a
background thread, and thread-safe collectors for what the interface readers deliver.

Everything runs on 127.0.0.1; every wait is on a condition with a generous bound for a loaded
2-core machine (nothing sleeps to wait for something that can be awaited).
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from sim_plant.emulator import HilEmulator, HilOptions
from sim_plant.hil_config import load_controller_wiring
from sim_plant.scenario import load_scenario

WAIT_S = 20.0


class Events:
    """Collects items from reader threads with their arrival time (``time.monotonic``)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._items: list[tuple[float, Any]] = []

    def __call__(self, item: Any) -> None:
        with self._cond:
            self._items.append((time.monotonic(), item))
            self._cond.notify_all()

    def stamped(self) -> list[tuple[float, Any]]:
        with self._cond:
            return list(self._items)

    def items(self) -> list[Any]:
        return [item for _, item in self.stamped()]

    def wait_for(self, predicate: Callable[[list[Any]], bool], timeout_s: float = WAIT_S) -> bool:
        """Block until ``predicate(items)`` holds (checked at every arrival) or the timeout passes."""
        with self._cond:
            return self._cond.wait_for(lambda: predicate([item for _, item in self._items]), timeout_s)


class EmulatorRun:
    """An emulator, opened, whose :meth:`HilEmulator.run` goes in a background thread on :meth:`start`."""

    def __init__(self, scenario: Path, controller: Path, options: HilOptions, record: Any = None) -> None:
        self.emulator = HilEmulator(load_scenario(scenario), load_controller_wiring(controller), options,
                                    record=record)
        self.emulator.open()
        self.summary: dict[str, Any] | None = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="emulator-under-test", daemon=True)

    def _run(self) -> None:
        try:
            self.summary = self.emulator.run()
        except BaseException as error:  # handed to the test in join()
            self.error = error

    def start(self) -> EmulatorRun:
        self._thread.start()
        assert self.emulator.ready.wait(WAIT_S), "the emulator loop did not start"
        return self

    def plant_time(self, monotonic_s: float) -> float:
        """Plant time at a ``time.monotonic()`` instant."""
        start = self.emulator.start_monotonic
        assert start is not None
        return (monotonic_s - start) * self.emulator.options.speed

    def join(self, timeout_s: float = WAIT_S) -> dict[str, Any]:
        self._thread.join(timeout_s)
        assert not self._thread.is_alive(), "the emulator did not end"
        if self.error is not None:
            raise self.error
        assert self.summary is not None
        return self.summary

    def close(self) -> None:
        if self._thread.is_alive():
            self.emulator.stop()
            self._thread.join(WAIT_S)
        self.emulator.close()


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port of 127.0.0.1 that was free a moment ago (TCP or UDP)."""
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def write_yaml(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


class Rig:
    """The helpers above, handed to the tests as one fixture (conftest modules are not imported by name)."""

    Events = Events
    EmulatorRun = EmulatorRun
    free_port = staticmethod(free_port)
    write_yaml = staticmethod(write_yaml)
    WAIT_S = WAIT_S


@pytest.fixture(scope="session")
def rig() -> type[Rig]:
    return Rig


@pytest.fixture(scope="module")
def closing() -> Iterator[list[Any]]:
    """Things with a ``close()`` to call at the end of the module, last opened first."""
    things: list[Any] = []
    yield things
    for thing in reversed(things):
        try:
            thing.close()
        except Exception as error:  # keep closing the rest; report at the end
            print(f"closing {thing!r} failed: {error!r}")
