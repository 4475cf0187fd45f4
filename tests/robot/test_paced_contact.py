"""The controller side over the cable with an object model: ``serve``'s
blocks (:class:`~drake_coop.robot.serve_loop.ServeLoop`) build the object model's load
feedforward as the simulated diagram does. Checked against the simulated run itself: fed the
run's own readings as statuses, the torque ``serve`` puts on the wire is, tick by tick, the
simulated controller's torque plus its load feedforward (``tau_cmd + tau_ff`` of the run's
logs) — on the paper's arms holding contact.yaml's box, through the grasp and the lift."""

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm

from bench.lab_arms_object import contact_scenario
from bench.serve_tick import _status_bytes
from drake import lcmt_panda_command
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import simulate
from drake_coop.robot.driver_spec import driver_specs
from drake_coop.robot.serve_loop import ServeLoop
from drake_coop.robot.status import check_panda_status
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.model_check import check_models
from drake_coop.scenario.driver import Driver
from drake_coop.scenario.schema import ScenarioError


def compressed(mode: str):
    s = contact_scenario("contact")
    s.object_model.mode = mode
    t = s.task
    t.t_pregrasp, t.t_grasp, t.t_circle_start = 1.0, 1.5, 2.0
    t.t_circle_end, t.t_release, t.t_end = 4.0, 4.5, 6.0
    t.force_omega = 3 * np.pi / 2.0
    return load_scenario(data=dump_scenario(s))


def wire_torques(s, logs, t_end):
    """``serve``'s commands when fed the run's readings ``logs[robot]["q"]`` tick by tick."""
    plan = plan_run(s, t_end)
    lcm = DrakeLcm("memq://")
    loop = ServeLoop(plan, lcm, driver_specs(s, check_models(s)))
    got = {spec.command_channel: [] for spec in loop.specs}
    for channel, out in got.items():
        lcm.Subscribe(channel, lambda d, out=out: out.append(
            np.array(lcmt_panda_command.decode(d).joint_torque)))
    names = list(logs)
    loop.start([logs[r]["q"][0] for r in names])
    for k in range(len(logs[names[0]]["t"])):
        for i, (r, spec) in enumerate(zip(names, loop.specs)):
            loop.feed(i, check_panda_status(_status_bytes(logs[r]["q"][k], int(k * 9000)),
                                            spec.n))
        loop.tick()
        lcm.HandleSubscriptions(0)
    assert loop.tripped() is None
    return {r: np.array(got[spec.command_channel]) for r, spec in zip(names, loop.specs)}


@pytest.mark.parametrize("mode", ["known", "estimated",
                                  pytest.param("none", marks=pytest.mark.slow)])
def test_serve_puts_the_controller_torque_plus_the_load_feedforward_on_the_wire(mode):
    """Every object mode, tick by tick on identical readings. ``estimated`` departed by
    0.24–0.32 N·m from ~10 ticks after the grasp when ``serve`` stepped to exactly ``k h``:
    the mass estimator's event at ``m (5h)``, an ulp before the tick ``5m h``, then ran on the
    previous reading, where the simulated diagram's encoders give the tick's."""
    s = compressed(mode)
    for robot in s.robots:           # the wire carries τ itself (no robot adding g(q))
        robot.driver = Driver(gravity="none")
    s = load_scenario(data=dump_scenario(s))
    T = 2.2                               # the grasp at 1.5 s, the lift to 2 s, the circle
    run = simulate(s, t_end=T)
    assert run.ok, run.meta
    wire = wire_torques(s, run.logs, T)
    for name, log in run.logs.items():
        expected = log["tau_cmd"] + (log["tau_ff"] if mode != "none" else 0.0)
        scale = np.max(np.abs(expected))
        assert wire[name].shape == expected.shape
        np.testing.assert_allclose(wire[name], expected, rtol=0, atol=1e-9 * scale)
        if mode == "none":
            continue
        # the feedforward acts (so that a wire without it would fail here)
        assert np.max(np.abs(log["tau_ff"])) > 0.02 * scale, name
        if mode == "estimated":     # the estimator moved the mass share (it is on the wire)
            share = np.asarray(log["mass_share"]).ravel()
            assert np.ptp(share) > 0.05 * share[0], name


def test_serve_refuses_the_shared_object_block_naming_the_field():
    s = compressed("estimated")
    s.object_model.shared = True
    plan = plan_run(s, 1.0)
    with pytest.raises(ScenarioError, match=r"^object_model\.shared: "):
        ServeLoop(plan, DrakeLcm("memq://"), driver_specs(s, check_models(s)))


@pytest.mark.parametrize("name, existing", [("truth.txt", False), ("truth.npz", True),
                                            ("missing/truth.npz", False)])
def test_sim_driver_log_is_refused_naming_it(tmp_path, capsys, name, existing):
    from drake_coop.cli import main

    path = tmp_path / name
    if existing:
        path.write_bytes(b"not ours")
    assert main(["sim-driver", "paper", "--lcm-url", "memq://", "--command-wait", "0.1",
                 "--log", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--log" in err and len([x for x in err.splitlines() if x.strip()]) == 1
    assert path.read_bytes() == b"not ours" if existing else not path.exists()


def test_a_step_ends_short_of_a_tick_only_where_an_event_falls_a_rounding_before_it():
    from drake_coop.control.params import checked_period
    from drake_coop.robot.serve_loop import step_end

    h = plan_run(compressed("estimated"), 1.0).h   # 9 ms on a 3 ms plant step's grid
    period = checked_period(5 * h)                # the mass estimator's
    early = [k for k in range(0, 2000, 5) if (k // 5) * period < k * h]
    assert early                      # the rounding happens (m (5h) < (5m) h now and then)
    for k in range(0, 2000):
        end = step_end(k, h, (period,))
        if k in early:
            assert (k // 5) * period > end and k * h - end <= 1e-9 * max(1.0, k * h)
        else:
            assert end == k * h
        assert step_end(k, h) == k * h
