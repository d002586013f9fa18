"""The shipped HIL bench (``deploy/hil/<vessel>/``): each pair of controller configuration and scenario runs
as documented (docs/hil.md) — ``sim-plant hil SCENARIO --controller-config FILE --engage`` and
``dpcontrol run --config FILE`` as two processes on 127.0.0.1 — and holds DP for 30 s with no alarm
(the pair's places on this machine moved to free ones: :mod:`hil_pair`)."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest
from hil_pair import pair_names, running_pair

from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.session_config import ZenohConfig

pytestmark = [pytest.mark.hil, pytest.mark.slow]

ENGAGE_TIMEOUT_S = 60.0  # cold interpreters, first fixes, the operator's first request on a loaded machine
HOLD_S = 30.0


@pytest.mark.parametrize("name", pair_names())
def test_shipped_pair_holds_dp_for_30_s_with_no_alarm(name: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    assert {"cybership2", "supply"} <= set(pair_names())
    run_dir = tmp_path_factory.mktemp(f"hil-{name}")
    short = Path(tmp_path_factory.mktemp("s"))
    statuses: list[tuple[float, dict[str, Any]]] = []
    lock = threading.Lock()

    class Sink:
        def put(self, item: Any) -> None:
            with lock:
                statuses.append((time.monotonic(), item.message))

    with running_pair(name, run_dir, short, ENGAGE_TIMEOUT_S + HOLD_S + 30.0) as pair:
        node = ZenohNode(ZenohConfig(mode="peer", connect=(pair.endpoint,)), pair.vessel)
        try:
            node.subscribe("status", Sink())
            deadline = time.monotonic() + ENGAGE_TIMEOUT_S
            engaged_at = None
            while engaged_at is None and time.monotonic() < deadline:
                time.sleep(0.2)  # polling the collected statuses (they arrive at 10 Hz)
                with lock:
                    engaged_at = next((t for t, s in statuses if s["mode"] == "auto_position"), None)
            assert engaged_at is not None, pair.log("dpcontrol.log")
            time.sleep(max(0.0, engaged_at + HOLD_S - time.monotonic()))  # real time: DP holds for 30 s
        finally:
            node.close()
    with lock:
        held = [s for t, s in statuses if engaged_at <= t <= engaged_at + HOLD_S]
    assert len(held) >= 0.8 * 10 * HOLD_S  # the status at ~10 Hz throughout
    assert all(s["mode"] == "auto_position" for s in held), {s["mode"] for s in held}
    raised = {(a["code"], a["severity"]) for s in held for a in s["alarms"] if a["active"]}
    assert not raised, raised
    # the daemon hears the drives the whole time (what the monitor and console show)
    assert all(s["drives"]["present"] and s["drives"]["feedback_age_s"] < 1.0 for s in held)
    assert pair.daemon_code == 0 and pair.plant_code == 0, (pair.daemon_code, pair.plant_code)
