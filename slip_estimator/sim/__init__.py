"""Seeded skid-steer rover simulator (truth, IMU, wheel encoders, GNSS).

:mod:`.scenario` (configuration), :mod:`.drives` (the seeded scenarios), :mod:`.truth`,
:mod:`.sensors` and :mod:`.rover` (:func:`simulate`) import only numpy and the standard
library; :mod:`.bag` writes a run to an MCAP bag with ROS messages and is imported
explicitly (``from slip_estimator.sim.bag import write_sim_bag``) so that this package stays
ROS-free.
"""
from slip_estimator.sim.drives import (
                                       default_scenario,
                                       mixed_scenario,
                                       patch_scenario,
                                       short_scenario,
)
from slip_estimator.sim.rover import SimResult, simulate, slip_class, slip_ratio
from slip_estimator.sim.scenario import (
                                         WHEEL_JOINT_NAMES,
                                         GnssConfig,
                                         HillSpec,
                                         ImuErrorConfig,
                                         RoverConfig,
                                         ScenarioConfig,
                                         Segment,
                                         SiteConfig,
                                         TerrainConfig,
                                         VibrationConfig,
)

__all__ = ['SimResult', 'simulate', 'slip_class', 'slip_ratio', 'WHEEL_JOINT_NAMES',
           'GnssConfig', 'HillSpec', 'ImuErrorConfig', 'RoverConfig', 'ScenarioConfig',
           'Segment', 'SiteConfig', 'TerrainConfig', 'VibrationConfig', 'default_scenario',
           'mixed_scenario', 'patch_scenario', 'short_scenario']
