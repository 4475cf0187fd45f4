"""``bench.franka_emulation.wire_check``: what it reads from an emulated driver's log, on a
log written here (two Pandas, the robot's g(q) from Drake's C++ gravity compensation, the
driver's own route), with gravity counted once, twice, and a command expired."""

import numpy as np
import pytest
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder

from drake_coop.control.arm_plant import description_packages

pytestmark = pytest.mark.skipif("example-robot-data" not in description_packages(),
                                reason='example-robot-data is not installed')


def log(tmp_path, gravity_times=1.0, expired_utime=None):
    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.cooperative import build_plant
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.scenario.resources import find_scenario

    scenario = load_scenario(find_scenario("two_pandas"))
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    coop = build_plant(DiagramBuilder(), plan_run(scenario, 0.1))
    rng = np.random.default_rng(0)
    data = {}
    for i in range(2):
        model = controller_arm_model(coop.arms[i].arm, None)
        gc = InverseDynamics(model.plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation)
        ctx = gc.CreateDefaultContext()
        rows = []
        for k in range(5):
            q = rng.uniform(-1, 1, 7)
            gc.get_input_port(0).FixValue(ctx, np.concatenate([q, np.zeros(7)]))
            g = gc.get_output_port(0).Eval(ctx)
            wire = rng.uniform(-5, 5, 7)
            rows.append(np.concatenate([[1000 * k + 7, 1000 * k], wire, wire, g,
                                        wire + gravity_times * g, q]))
        data[f"arm{i}_journal"] = np.array(rows)
        data[f"arm{i}_counts"] = np.array([0 if expired_utime is None else 1, 0])
        data[f"arm{i}_expiries"] = (np.zeros((0, 2)) if expired_utime is None
                                    else np.array([[expired_utime + 100_001, expired_utime]]))
    np.savez(tmp_path / "truth.npz", **data)
    return tmp_path / "truth.npz", path


def test_gravity_counted_once_passes_and_twice_fails(tmp_path):
    from bench.franka_emulation import wire_check

    once = wire_check(*log(tmp_path))
    assert all(a["gravity_once_max_Nm"] <= 1e-9 and a["commands_taken"] == 5
               for a in once.values())
    twice = wire_check(*log(tmp_path, gravity_times=2.0))
    for robot, a in twice.items():
        assert a["gravity_once_max_Nm"] == pytest.approx(a["gravity_max_Nm"], rel=1e-9)
        assert a["gravity_once_max_Nm"] > 1.0


def test_an_expiry_in_the_run_is_told_from_the_last_commands(tmp_path):
    from bench.franka_emulation import wire_check

    inside = wire_check(*log(tmp_path, expired_utime=2000))
    assert all(a["commands_expired_in_run"] == 1 for a in inside.values())
    last = wire_check(*log(tmp_path, expired_utime=4000))      # the last command taken
    assert all(a["commands_expired_in_run"] == 0 and a["commands_expired"] == 1
               and a["last_command_expired_after_s"] == pytest.approx(0.100001)
               for a in last.values())


def test_the_driver_cpu_measurement_runs_each_driver_alone_in_alternated_pairs(monkeypatch):
    """``driver_cpu`` runs the driver's side alone to its end with no fault, plain and
    emulated, alternating which goes first; the figures are CPU seconds per simulated
    second of each run (here on a few cycles: the numbers themselves are the bench's)."""
    import bench.franka_emulation as bench

    order, real = [], bench._driver_side_cpu

    def recorded(scenario, t_end, emulate):
        run = real(scenario, t_end, emulate)
        order.append(emulate)
        assert run["t_end_s"] == pytest.approx(t_end) and run["fault"] == ""
        return run
    monkeypatch.setattr(bench, "_driver_side_cpu", recorded)
    result = bench.driver_cpu(t_end=0.01, pairs=2)
    emulated = "drake-franka-driver"
    assert order == [None, emulated, None, emulated, emulated, None]   # warm-ups, then pairs
    for key in ("plain", "emulated"):
        assert len(result[key]["per_run"]) == 2 and result[key]["faults"] == ["", ""]
        assert all(v > 0 for v in result[key]["per_run"])
        assert result[key]["median"] == pytest.approx(np.median(result[key]["per_run"]))
