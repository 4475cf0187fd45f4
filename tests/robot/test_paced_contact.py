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
    loop = ServeLoop(s, plan, lcm, driver_specs(s, check_models(s)))
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


def test_serve_puts_the_controller_torque_plus_the_load_feedforward_on_the_wire():
    s = compressed("known")
    T = 2.2                               # the grasp at 1.5 s, the lift to 2 s, the circle
    run = simulate(s, t_end=T)
    assert run.ok, run.meta
    wire = wire_torques(s, run.logs, T)
    for name, log in run.logs.items():
        expected = log["tau_cmd"] + log["tau_ff"]
        scale = np.max(np.abs(expected))
        assert wire[name].shape == expected.shape
        np.testing.assert_allclose(wire[name], expected, rtol=0, atol=1e-9 * scale)
        # the feedforward acts (so that a wire without it would fail here)
        assert np.max(np.abs(log["tau_ff"])) > 0.02 * scale, name


def test_serve_refuses_the_shared_object_block_naming_the_field():
    s = compressed("estimated")
    s.object_model.shared = True
    plan = plan_run(s, 1.0)
    with pytest.raises(ScenarioError, match=r"^object_model\.shared: "):
        ServeLoop(s, plan, DrakeLcm("memq://"), driver_specs(s, check_models(s)))


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
