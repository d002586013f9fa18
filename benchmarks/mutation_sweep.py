"""Which safety behaviour of the sensor hub and the thruster monitor does no unit test guard? A targeted mutation sweep.

Each mutant removes one behaviour (a test switched off, a guard dropped, a fall-back skipped) in a copy of the tracked
tree; the hub's and the monitor's unit tests run against it. A mutant the tests pass is a behaviour nothing checks:
write the test that fails without it (docs/fault-handling.md). A mutant whose code is no longer found is reported as
not applied (the code moved on: update its text here).

Usage::

    nice -n 10 .venv/bin/python benchmarks/mutation_sweep.py            # every mutant (~15 min on 2 cores)
    nice -n 10 .venv/bin/python benchmarks/mutation_sweep.py 0 10 14    # those by index

Prints one line per mutant: killed (with the first failing test) or SURVIVED; exits 1 when any survived.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HUB = "dpcontrol/runtime/hub.py"
MON = "dpcontrol/runtime/thruster_monitor.py"
TESTS = ["tests/unit/test_hub.py", "tests/unit/test_hub_rate_check.py", "tests/unit/test_hub_rate_of_turn.py",
         "tests/unit/test_hub_velocity_check.py", "tests/unit/test_hub_noisy_reference.py",
         "tests/unit/test_thruster_monitor_failsafe.py",
         "tests/unit/test_runtime_fast_paths.py", "tests/unit/test_allocation_kernels.py"]
#: (what is removed, file, the code as it is, the code without the behaviour)
MUTANTS: list[tuple[str, str, str, str]] = [
 ("freeze test off", HUB, "if frozen_since is not None and t_s - frozen_since >= self._freeze_limit_s:", "if False:"),
 ("prediction test off", HUB, "            if distance > limit:\n                track.rejected_samples += 1", "            if False:\n                track.rejected_samples += 1"),
 ("a repeated value corrects the estimator", HUB, "        if frozen_since is not None:\n            # A value repeated exactly", "        if False:\n            # A value repeated exactly"),
 ("jump persistence judged on the grown variance", HUB, "            variance = self._base_variance\n", "            pass\n"),
 ("variance test not measured", HUB, "                track.residual_variance = own if measured is None else (1.0 - alpha) * measured + alpha * own", "                track.residual_variance = None"),
 ("noisy alarm off", HUB, "        if state is not SensorState.OK:\n            return False\n        variance = self._settled_variance(track)", "        if True:\n            return False\n        variance = self._settled_variance(track)"),
 ("median test off", HUB, "                if distance > max(limit, 3.0 * self._nominal_sigma(track)):", "                if False:"),
 ("two-reference disagreement alarm off", HUB, "            disagree = distance > max(limit, 3.0 * math.hypot(self._nominal_sigma(a), self._nominal_sigma(b)))", "            disagree = False"),
 ("stale detection off", HUB, "            elif t_s - last > track.stale_s:\n                state = SensorState.STALE", "            elif False:\n                state = SensorState.STALE"),
 ("lone reference accepted at once", HUB, "        if t_s - since >= accept_s:\n            return True", "        if True:\n            return True"),
 ("all-rejecting ignores a recently accepted reference", HUB, "            if any(t.last_accepted_t_s is not None and t_s - t.last_accepted_t_s < persist for t in tracks):\n                return False", "            pass"),
 ("no readmit delay", HUB, "        track.usable_from_t_s = t_s + self.config.readmit_s if others else -math.inf", "        track.usable_from_t_s = -math.inf"),
 ("no bumpless switch between reference sets", HUB, "                offset[0] += old_level[0] - new_level[0]\n                offset[1] += old_level[1] - new_level[1]", "                pass"),
 ("no anchor after a position loss", HUB, "                offset[0] += weight * (anchor[0] - north - offset[0])\n                offset[1] += weight * (anchor[1] - east - offset[1])", "                pass"),
 ("no heading anchor after a loss", HUB, "                self._heading_offset += ssa(anchor[2] - heading - self._heading_offset) / self._heading_anchor_samples", "                pass"),
 ("inverse-variance weights equal", HUB, "        return [1.0 / max(s * s, 1e-12) for s in map(self._sigma, tracks)]", "        return [1.0 for s in map(self._sigma, tracks)]"),
 ("slow reference not moved to the present", HUB, "            north += weight * (value[0] + vn * age)\n            east += weight * (value[1] + ve * age)", "            north += weight * value[0]\n            east += weight * value[1]"),
 ("dead-reckoning variance does not grow", HUB, "    def _dead_reckoning_variance(self, t_s: float, variance: Sequence[float]) -> tuple[float, float, float]:\n", "    def _dead_reckoning_variance(self, t_s: float, variance: Sequence[float]) -> tuple[float, float, float]:\n        return (variance[0], variance[1], variance[2])\n"),
 ("monitor: mismatch never latches", MON, "                    if t_s - drive[i, D_MISMATCH_SINCE] >= persist_s:\n                        failed[i] = True", "                    if False:\n                        failed[i] = True"),
 ("monitor: no absolute floor", MON, "    return min(fraction * rating_n, max(RELATIVE_MISMATCH * abs(expected_n), floor_fraction * rating_n))", "    return min(fraction * rating_n, RELATIVE_MISMATCH * abs(expected_n))"),
 ("monitor: a drive back after a loss keeps its old expectation", MON, "                drive[i, D_LOST] = 0.0\n                expected = delivered\n", "                drive[i, D_LOST] = 0.0\n"),
 ("monitor: no hysteresis", MON, "if drive[i, D_ERROR] > limit or (not math.isnan(since) and drive[i, D_ERROR] > 0.5 * limit):", "if drive[i, D_ERROR] > limit:"),
 ("monitor: stale feedback not flagged", MON, "                event |= E_STALE\n", "                pass\n"),
 ("monitor: not-ready drive stays in the allocation", MON, "        usable = not (not_ready[i] or failed[i])", "        usable = not failed[i]"),
 ("monitor: readmitted at once", MON, "                if t_s - drive[i, D_READY_SINCE] >= readmit_s:", "                if True:"),
 ("monitor: repeated sample judged again", MON, "and sample_t != drive[i, D_JUDGED_SAMPLE]:", ":"),
 ("velocity check verdict off", HUB, "            if distance > check.limit:\n                self._velocity_verdict(track, check, distance, t_s)", "            if False:\n                self._velocity_verdict(track, check, distance, t_s)"),
 ("velocity-rejected receiver never taken back", HUB, "                    elif t_s - check.agree_since_t_s >= cfg.velocity_check_return_s:", "                    elif False:"),
 ("no dead reckoning on the receiver velocity", HUB, "        if self._position_used or predicted is None:\n            return\n        for track in self._position:", "        if True:\n            return\n        for track in self._position:"),
 ("velocity dead reckoning keeps the lever arm", HUB, "                north -= d_north\n                east -= d_east", "                pass"),
 ("velocity check runs on a frozen receiver", HUB, "                    track.disconnected or track.frozen_since_t_s is not None or \\\n", "                    track.disconnected or \\\n"),
 ("rate check verdict off", HUB, "if abs(check.disagreement) > check.limit and self._check_verdict is None:", "if False:"),
 ("rate verdict ignores another agreeing gyro", HUB, "        if any(c.agree_since_t_s is not None for c in others):", "        if False:"),
 ("rate verdict ignores a turn", HUB, "        elif turn > 3.0 * abs(check.disagreement):", "        elif False:"),
 ("no heading dead reckoning on the rate", HUB, "        self._feed_dead_reckoning(source, t_s, predicted)\n", "        pass\n"),
 ("rate bias not subtracted in dead reckoning", HUB, "            self._dr_heading += (source.value - source.bias) * dt", "            self._dr_heading += source.value * dt"),
 ("dead reckoning starts from the drifted gyro", HUB, "                self._dr_heading = ssa(check.previous - check.disagreement)", "                self._dr_heading = check.previous"),
 ("a blamed rate still carries the heading", HUB, "            if source is None and rate.bias_time_s > 0.0 and not rate.blamed:", "            if source is None and rate.bias_time_s > 0.0:"),
 ("noisy receiver not de-weighted", HUB, "        if pos_new and excess > 0.0:\n", "        if False:\n"),
 ("noisy receiver judged on its configured noise", HUB, "                if track.recent_variance is not None:  # (a receiver whose noise just grew: its recent noise)", "                if False:"),
 ("noisy receiver taken back without the fade", HUB, "                if self._position_used and self._position_lost_since is None:\n                    self._position_anchor_samples = 0", "                if False:\n                    self._position_anchor_samples = 0"),
]


def _copy_tree(to: Path) -> None:
    """The tracked files (as in the working tree) into ``to``: mutants never touch the checkout."""
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    for rel in files:
        source = ROOT / rel
        if source.is_file():
            target = to / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)


def _run(tree: Path, index: int) -> bool | None:
    """Mutant ``index`` in ``tree``: True killed, False survived, None not applied."""
    name, rel, old, new = MUTANTS[index]
    path = tree / rel
    original = path.read_text(encoding="utf-8")
    if original.count(old) != 1:
        print(f"{index:2d} NOT APPLIED ({original.count(old)} matches): {name}", flush=True)
        return None
    path.write_text(original.replace(old, new), encoding="utf-8")
    try:
        start = time.monotonic()
        env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
        result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *TESTS],
                                cwd=tree, capture_output=True, text=True, timeout=900, env=env, check=False)
        failed = [line for line in result.stdout.splitlines() if line.startswith("FAILED")]
        killed = result.returncode != 0
        print(f"{index:2d} {'killed' if killed else 'SURVIVED':8s} {time.monotonic() - start:5.0f}s {name}  "
              f"{failed[:1]}", flush=True)
        return killed
    finally:
        path.write_text(original, encoding="utf-8")


def main() -> int:
    chosen = [int(a) for a in sys.argv[1:]] or list(range(len(MUTANTS)))
    with tempfile.TemporaryDirectory(prefix="dp-mutants-") as tmp:
        tree = Path(tmp)
        _copy_tree(tree)
        verdicts = [_run(tree, k) for k in chosen]
    survived = sum(v is False for v in verdicts)
    print(f"{sum(v is True for v in verdicts)} killed, {survived} survived, "
          f"{sum(v is None for v in verdicts)} not applied of {len(chosen)}")
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
