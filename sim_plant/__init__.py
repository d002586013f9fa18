"""Plant emulator: the vessel, sea, drives and sensors that stand in for a ship (never imports the
controller).

Pure parts: :mod:`sim_plant.scenario` (scenario files → frozen :class:`~sim_plant.scenario.Scenario`),
:mod:`sim_plant.plant` (:class:`~sim_plant.plant.Plant`: command / advance / truth / feedback /
sensor_samples), :mod:`sim_plant.vessel` (nonlinear 3-DOF truth, RK4), :mod:`sim_plant.environment`
(waves, RAOs, drift, current, wind), :mod:`sim_plant.drives` (drives), :mod:`sim_plant.sensors`
(GNSS, gyrocompass), :mod:`sim_plant.faults`, :mod:`sim_plant.vessel_data` (plant-only vessel data).
"""
