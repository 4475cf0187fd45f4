"""``serve``'s loop (:mod:`drake_coop.robot.serve_loop`, ``memq://`` only): one Simulator step
and the command per tick give the same torques as the controller side inside a Diagram
(its receiver system, its periodic publisher); ticking on the status's arrival uses a status
that arrived after the tick's grid time, the wall-clock grid one from before it; one serve
per arm: a trip in robot1 stops robot2's serve before its next tick."""

import json
import math
import time

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import rest_posture
from drake_coop.robot import pacing
from drake_coop.robot.driver_spec import driver_specs
from drake_coop.robot.drivers import COMMAND_OFFSET, add_controller_side
from drake_coop.robot.loopback import initialize_sides
from drake_coop.robot.pacing import PacingRecord
from drake_coop.robot.cell import CELL_CHANNEL, MIN_ANNOUNCEMENTS, Heartbeat
from drake_coop.robot.serve_loop import (
    STOP_CHANNEL,
    ServeLoop,
    StopListener,
    run_on_arrival,
    status_arrivals,
)
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.model_check import check_models


def status_bytes(q, utime):
    msg = lcmt_panda_status()
    msg.utime = int(utime)
    msg.num_joints = len(q)
    msg.joint_position = [float(v) for v in q]
    for f in ("joint_velocity", "joint_torque", "joint_torque_external",
              "joint_position_desired", "joint_velocity_desired",
              "joint_acceleration_desired", "joint_torque_desired"):
        setattr(msg, f, [0.0] * len(q))
    return msg.encode()


@pytest.fixture(scope="module")
def paper():
    scenario = load_scenario()
    plan = plan_run(scenario, 0.5)
    specs = driver_specs(scenario, check_models(scenario))
    q0, _ = rest_posture(plan)
    return scenario, plan, specs, [np.asarray(q, dtype=float) for q in q0]


def readings(q0, ticks, seed=0):
    """Each arm's reading at each tick: the rest posture and a slow random walk."""
    rng = np.random.default_rng(seed)
    return [[q + 1e-3 * np.cumsum(rng.normal(size=(ticks, q.size)), axis=0)[k]
             for q in q0] for k in range(ticks)]


def test_one_step_per_tick_gives_the_diagrams_torques(paper):
    """The same statuses to serve's loop (fed, one Simulator step, forced publish) and to the
    controller side with its receiver systems and periodic publisher (the loopback's wiring):
    the same commands, tick by tick, the safe one before and from a NaN reading on."""
    scenario, plan, specs, q0 = paper
    ticks = 25
    qs = readings(q0, ticks)
    bad_tick = 20
    msgs = [[status_bytes(q if not (k >= bad_tick and i == 0) else q * math.nan, k * 9000)
             for i, q in enumerate(row)] for k, row in enumerate(qs)]

    lcm = DrakeLcm("memq://")
    got = {s.command_channel: [] for s in specs}
    for channel in got:
        lcm.Subscribe(channel, lambda d, c=channel: got[c].append(
            list(lcmt_panda_command.decode(d).joint_torque)))
    loop = ServeLoop(plan, lcm, specs)
    loop.start(q0)
    for k in range(ticks):                   # no status at tick 0 (as the Diagram below)
        for i in range(len(specs)):
            if k > 0:
                loop.feed_bytes(i, msgs[k][i])
        loop.tick()
        lcm.HandleSubscriptions(0)

    lcm2 = DrakeLcm("memq://")
    ref = {s.command_channel: [] for s in specs}
    for channel in ref:
        lcm2.Subscribe(channel, lambda d, c=channel: ref[c].append(
            list(lcmt_panda_command.decode(d).joint_torque)))
    builder = DiagramBuilder()               # subscribers, receivers, periodic publishers
    side = add_controller_side(builder, plan, lcm2, specs, status_input="subscriber")
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    initialize_sides(plan, ctx, None, side, q0)
    sim.Initialize()
    for k in range(ticks):
        for i, s in enumerate(specs):
            if k > 0:      # (a message before t = 0's updates is latched only after them)
                lcm2.Publish(s.status_channel, msgs[k][i])
        lcm2.HandleSubscriptions(0)          # latched by the subscribers' next step
        sim.AdvanceTo(k * plan.h + COMMAND_OFFSET)
        lcm2.HandleSubscriptions(0)
    for s in specs:
        a, b = np.array(got[s.command_channel]), np.array(ref[s.command_channel])
        assert a.shape == b.shape == (ticks, s.n)
        np.testing.assert_array_equal(a, b)          # the same code path: the same doubles
        assert np.all(a[0] == 0.0)                    # no status yet: the safe command
        assert np.any(a[5:bad_tick] != 0.0)           # the controller's torque got through
    np.testing.assert_array_equal(np.array(got[specs[0].command_channel])[bad_tick:], 0.0)
    assert loop.tripped()["robot"] == specs[0].robot


class FakeTime:
    """A clock that moves only when slept on: ``perf_counter`` and ``time`` read it, ``sleep``
    advances it. Patched into the loop's modules, the test runs in simulated time (a tick's
    computation takes none), whatever the machine's load."""

    def __init__(self, start: float = 1000.0):
        self.now = start

    def perf_counter(self) -> float:
        return self.now

    def monotonic(self) -> float:
        return self.now

    def time(self) -> float:
        return 1.7e9 + self.now

    def sleep(self, dt: float) -> None:
        self.now += max(dt, 0.0)


class ClockedDriver:
    """A scripted 1 kHz driver inside the LCM pump: every ``HandleSubscriptions`` first
    publishes the statuses that are due (its own clock from ``start``, stamp = cycle), so a
    status arrives when its time comes; ``log`` records each status and each grid time."""

    def __init__(self, lcm, q0, channels, start, cycle=1e-3, clock=time):
        self.lcm, self.q0, self.channels = lcm, q0, channels
        self.start, self.cycle, self.next = start, cycle, 0
        self.clock = clock
        self.log = []

    def publish_due(self):
        while self.clock.perf_counter() >= self.start + self.next * self.cycle:
            for q, c in zip(self.q0, self.channels):
                self.lcm.Publish(c, status_bytes(q, self.next * 1000))
            self.log.append(("status", self.clock.perf_counter()))
            self.next += 1

    def HandleSubscriptions(self, timeout_ms):
        self.publish_due()
        due = self.start + self.next * self.cycle
        wait = min(timeout_ms * 1e-3, due - self.clock.perf_counter())
        if wait > 0:
            self.clock.sleep(wait)
            self.publish_due()
        return self.lcm.HandleSubscriptions(0)

    def Publish(self, channel, data):
        self.lcm.Publish(channel, data)

    def Subscribe(self, channel, handler):
        return self.lcm.Subscribe(channel, handler)


@pytest.mark.parametrize("on_arrival", [True, False])
def test_ticking_on_arrival_uses_a_status_that_arrived_after_the_grid_time(paper, monkeypatch,
                                                                           on_arrival):
    scenario, plan, specs, q0 = paper
    clock = FakeTime()                      # simulated time: no dependence on the load
    from drake_coop.robot import serve_loop as serve_loop_module

    monkeypatch.setattr(pacing, "time", clock)
    monkeypatch.setattr(serve_loop_module, "time", clock)
    lcm = DrakeLcm("memq://")
    channels = [s.status_channel for s in specs]
    driver = ClockedDriver(lcm, q0, channels, clock.perf_counter(), clock=clock)
    loop = ServeLoop(plan, lcm, specs)
    arrivals = status_arrivals(lcm, specs)
    stamps = []
    feed = loop.feed

    def logged_feed(i, parsed):
        if i == 0:
            stamps.append(arrivals.parsed(channels[0])[1])
            driver.log.append(("tick", None))
        feed(i, parsed)

    monkeypatch.setattr(loop, "feed", logged_feed)
    pump = pacing.pump_until

    def logged_pump(lcm_, deadline):
        pump(lcm_, deadline)
        driver.log.append(("grid", deadline))
    monkeypatch.setattr(pacing, "pump_until", logged_pump)
    driver.HandleSubscriptions(5)
    loop.start(q0)
    record = PacingRecord(plan.h, 1e-3)
    ticks = 30
    assert run_on_arrival(loop, driver, arrivals, ticks - 1, record, lead=0.003,
                          on_arrival=on_arrival) == ""
    assert len(record.k) == ticks and loop.tripped() is None
    # on arrival: the newest status published before each tick was published after that
    # tick's grid time (the driver's own log, its perf_counter); on the grid: no wait
    fresh, grid, newest = [], None, None
    for e in driver.log:
        if e[0] == "grid":
            grid = e[1]
        elif e[0] == "status":
            newest = e[1]
        else:
            fresh.append(newest >= grid)
    assert len(fresh) == ticks
    if on_arrival:
        assert all(fresh), fresh
        assert np.all(np.diff(stamps) > 0)            # every tick a new status
    else:
        assert record.wait == [0.0] * ticks


def test_one_serve_per_arm_a_trip_in_robot1_stops_robot2_before_its_next_tick(
        tmp_path, monkeypatch, capsys):
    """robot1's serve (``--robot robot1``) trips on a NaN status and publishes its stop; the
    message is played to robot2's serve (``--robot robot2``) at the pump that precedes the
    tick after robot1's trip: robot2 stops there, exit 1, one line naming robot1 and the stop
    channel, its last command the safe one, its run kept."""
    from drake_coop.cli import main
    from drake_coop.robot import cli

    scenario = load_scenario()
    q0, _ = rest_posture(plan_run(scenario))
    trip_pump = 30
    # pump p precedes tick p - 4 (pumps 1-3: the wait, three heartbeats announced)
    k_trip = trip_pump - 1 - MIN_ANNOUNCEMENTS

    def serve(robot, lcm, hostile=False, stop_message=None):
        calls = {"n": 0}
        partner = "robot2" if robot == "robot1" else "robot1"
        partner_beat = Heartbeat("ab" * 8, 4242, 0, "serving", [partner]).encode()

        def pump(lcm_, deadline):
            calls["n"] += 1
            n = calls["n"]
            lcm.Publish(CELL_CHANNEL, partner_beat)       # the other arm's serve, alive
            for name, q in zip(("robot1", "robot2"), q0):
                q = np.array(q, dtype=float)
                if hostile and name == "robot1" and n == trip_pump:
                    q[1] = math.nan
                lcm.Publish(f"PANDA_STATUS_{name}", status_bytes(q, n * 9000))
            if stop_message is not None and n == trip_pump + 1:
                lcm.Publish(STOP_CHANNEL, stop_message)
            lcm.HandleSubscriptions(0)
            remaining = deadline - time.perf_counter()
            if remaining > 0:
                time.sleep(remaining)

        monkeypatch.setattr(cli, "_make_lcm", lambda url: lcm)
        monkeypatch.setattr(pacing, "pump_until", pump)
        commands, stops = [], []
        lcm.Subscribe(f"PANDA_COMMAND_{robot}",
                      lambda d: commands.append(list(lcmt_panda_command.decode(d).joint_torque)))
        lcm.Subscribe(STOP_CHANNEL, lambda d: stops.append(bytes(d)))
        out = tmp_path / robot
        code = main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--robot",
                     robot, "--delay-margin", "0.002", "--quiet", "--t-end", "2"])
        lcm.HandleSubscriptions(0)
        return code, commands, stops, json.loads((out / "run.json").read_text())

    code1, commands1, stops1, meta1 = serve("robot1", DrakeLcm("memq://"), hostile=True)
    err1 = capsys.readouterr().err.strip().splitlines()
    assert code1 == 1 and len(err1) == 1 and "robot1" in err1[0]
    assert meta1["pacing"]["ticks"] == k_trip + 1 and meta1["robots"] == ["robot1"]
    assert meta1["channels"].keys() == {"robot1"}
    assert len(stops1) == 1 and stops1[0].startswith(b"robot1: ")
    assert commands1[-1] == [0.0, 0.0, 0.0]

    code2, commands2, stops2, meta2 = serve("robot2", DrakeLcm("memq://"),
                                            stop_message=stops1[0])
    err2 = capsys.readouterr().err.strip().splitlines()
    assert code2 == 1 and len(err2) == 1, err2
    assert "robot1" in err2[0] and STOP_CHANNEL in err2[0] and "non-finite" in err2[0], err2
    assert meta2["status"] == "stopped" and meta2["watchdog"]["channel"] == STOP_CHANNEL
    assert meta2["pacing"]["ticks"] == k_trip + 1       # no tick after robot1's trip
    assert len(commands2) == k_trip + 2 and commands2[-1] == [0.0, 0.0, 0.0]
    assert any(v != 0.0 for v in commands2[k_trip])     # it was commanding until then
    assert stops2 == [stops1[0]]                        # it does not echo the stop


def test_a_stop_listener_ignores_its_own_arms_and_keeps_the_first_reason():
    lcm = DrakeLcm("memq://")
    listener = StopListener(lcm, ["robot2"])
    StopListener.publish(lcm, "robot2", "own")
    lcm.HandleSubscriptions(0)
    assert listener.reason is None
    StopListener.publish(lcm, "robot1", "first\nreason")
    StopListener.publish(lcm, "robot3", "second")
    lcm.HandleSubscriptions(0)
    assert listener.reason == "robot1: first reason"


def test_serve_refuses_an_unknown_robot(tmp_path, capsys):
    from drake_coop.cli import main

    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(tmp_path / "r"),
                 "--robot", "robot9", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--robot" in err[0] and "robot1" in err[0]
