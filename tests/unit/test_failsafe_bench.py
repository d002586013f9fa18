"""The fail-safe bench runs the supply vessel as she is shipped (``deploy/config/supply.yaml``)."""

from __future__ import annotations

from pathlib import Path

from dpbase.yamlfile import read_yaml_file
from sim_plant.bench.failsafe import VESSELS, Case

SHIPPED = Path(__file__).resolve().parents[2] / "deploy" / "config" / "supply.yaml"


def test_supply_runs_her_shipped_controller_and_estimator() -> None:
    _, shipped = read_yaml_file(SHIPPED)
    assert isinstance(shipped, dict)
    bench = Case("supply", "gnss_dropout", 120.0, 60.0).scenario()["controller"]
    assert bench["control"] == shipped["control"]
    estimator = bench["estimator"]
    # the same estimator; the noise of the bench's own receiver and gyro on top
    assert {key: estimator[key] for key in shipped["estimator"]} == shipped["estimator"]
    assert set(estimator) - set(shipped["estimator"]) == {"position_noise_std_m", "heading_noise_std_rad"}
    assert VESSELS["supply"]["gnss"]["noise_m"] == estimator["position_noise_std_m"]
