"""The simulated driver's own clock (``driver.clock_phase``, ``clock_drift``): its cycles, when
its status is published and when a command reaches the arm, against times written out here."""

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import LcmSubscriberSystem

from drake import lcmt_panda_status
from drake_coop.experiment.plan import plan_run
from drake_coop.robot.drivers import add_driver_side
from drake_coop.robot.torque_driver import DriverClock
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.driver import Driver
from drake_coop.scenario.schema import ScenarioError


def _scenario(phase=0.0, drift=0.0):
    s = load_scenario()
    s.plant.time_step = 2.5e-4
    s.robots[1].driver = Driver(clock_phase=phase, clock_drift=drift)
    return load_scenario(data=dump_scenario(s))


def _status_times(scenario, t_end):
    """The stamps of robot 2's status messages published up to ``t_end``."""
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    # No LcmInterfaceSystem: the Python handler below is pumped between the steps only
    # (drake 1.58 crashes on a Python handler pumped inside AdvanceTo: add_lcm_interface).
    origin = 1_700_000_000_000_000          # the driver's epoch clock at t = 0 (µs)
    add_driver_side(builder, plan_run(scenario), lcm, clock=DriverClock("epoch", origin=origin))
    times = []
    lcm.Subscribe("PANDA_STATUS_robot2", lambda data: times.append(
        (lcmt_panda_status.decode(data).utime - origin) * 1e-6))
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.Initialize()
    t = 0.0
    while t < t_end - 1e-12:               # pump between steps (Python handlers: not inside)
        t = min(t_end, t + 2.5e-4)
        sim.AdvanceTo(t)
        lcm.HandleSubscriptions(0)
    return np.array(times)


@pytest.mark.parametrize("phase, drift", [(0.0, 0.0), (3.75e-4, 0.0), (1.25e-4, 2e-3 / 4)])
def test_status_is_published_on_the_drivers_own_clock(phase, drift):
    times = _status_times(_scenario(phase, drift), 0.0101)
    cycle = 1e-3 * (1 + drift)
    expected = phase + cycle * np.arange(len(times))
    assert len(times) == int(np.floor((0.0101 - phase) / cycle)) + 1
    np.testing.assert_allclose(times, expected, atol=2e-6)     # utime: whole microseconds


def test_clock_phase_of_a_whole_cycle_is_refused_by_name():
    s = load_scenario()
    s.robots[0].driver = Driver(clock_phase=1e-3)
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.driver\.clock_phase must be < one"):
        load_scenario(data=dump_scenario(s))
