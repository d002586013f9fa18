"""The step hands the MRAC's inertia estimate to an estimator only when that estimator has the vessel's force model."""

from __future__ import annotations

import dataclasses

import numpy as np

from dpcontrol.bench import bench_config
from dpcontrol.runtime.config import EstimatorSettings
from dpcontrol.runtime.estimators import KalmanBucyEstimator, MassAdaptiveEstimator
from dpcontrol.runtime.step import DpController


def test_a_wave_filter_takes_the_mrac_mass_and_a_kinematic_filter_does_not() -> None:
    config = bench_config()  # MRAC (adapting) with the MMAE wave filter
    controller = DpController(config)
    assert isinstance(controller.estimator, MassAdaptiveEstimator) and controller.estimator.force_model
    kinematic = dataclasses.replace(config, estimator=EstimatorSettings(kind="kalman_bucy", wave_filter=None))
    controller = DpController(kinematic)
    assert isinstance(controller.estimator, KalmanBucyEstimator) and not controller.estimator.force_model
    controller.estimator.reset(np.zeros(3))  # and it runs as before
    assert controller.estimator.step(np.zeros(3), np.zeros(3)).eta_hat_ned.shape == (3,)
