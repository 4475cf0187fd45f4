"""The reference table's rows that no scenario field selects (the applied-torque residual and
the online identification): what the worker builds, and their cells against the simulated
truth computed here from the logs of an independent run."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from drake_coop.scenario.loading import load_scenario
from drake_coop.studies.reference_table import _source, compress, expand_table
import drake_coop.studies.reference_variants as variants
from drake_coop.studies.reference_variants import variant_built, variant_matters

T_TINY = 5.3     # 0.3 s of the circle
PEAKS = {"robot1": {"lift": [10.0, 20.0, 5.0], "other": [1.0, 30.0, 1.0]},
         "robot2": {"lift": [8.0, 8.0, 8.0], "other": [1.0, 1.0, 1.0]}}


def test_the_residual_is_the_momentum_case_without_limits_and_its_own_with():
    cases = expand_table(load_scenario(), ["momentum", "applied_torque"],
                         ["exact", "saturation"], 1, t_end=T_TINY, peaks=PEAKS)
    h = {(c.params["row"], c.params["column"]): c.hash for c in cases}
    assert h[("momentum", "exact")] == h[("applied_torque", "exact")]
    assert h[("momentum", "saturation")] != h[("applied_torque", "saturation")]
    with pytest.raises(ValueError, match="variant: unknown 'nope'"):
        variant_matters(load_scenario(), "nope")


def _momentum_scenario(limits=None):
    s = compress(load_scenario())
    _source("momentum")(s, 0)
    for robot in s.robots:
        robot.actuators.torque_limits = limits
    return s


def test_the_residual_integrates_the_clipped_torque_and_the_swap_is_undone():
    from drake_coop.control.momentum import MomentumObserver
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run

    s = _momentum_scenario([4.0, 5.0, 6.0])
    tau = np.array([10.0, -10.0, 1.0])
    with variant_built(s, "applied_torque"):
        exp = build_experiment(plan_run(s), log=False)
    for rs in exp.robots:
        np.testing.assert_array_equal(rs.force_observer.applied_torque(tau), [4.0, -5.0, 1.0])
    plain = build_experiment(plan_run(s), log=False)    # outside: the commanded torque
    assert isinstance(plain.robots[0].force_observer, MomentumObserver)
    np.testing.assert_array_equal(plain.robots[0].force_observer.applied_torque(tau), tau)


def test_the_online_row_builds_the_online_block_from_the_controllers_model():
    from drake_coop.control.momentum import MomentumObserver
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.identification.online import OnlineIdentification, momentum_rows

    s = _momentum_scenario()
    s.robots[0].model_error.mass_scale = 1.2
    with variant_built(s, "online"):
        exp = build_experiment(plan_run(s), log=False)
    block = exp.robots[0].force_observer
    assert isinstance(block, OnlineIdentification)
    theta0 = block.CreateDefaultContext().get_discrete_state(0).value()
    # its prior is the controller's (20 % heavy) model: Y_p θ0 = Ĥ q̇ of that model, an
    # independent computation (Drake's mass matrix of the controller's plant)
    model = exp.robots[0].law.model
    q, v = np.array([0.3, -0.4, 0.8]), np.array([0.5, 0.2, -0.3])
    Y_p, _ = momentum_rows(block._regressor, q, v)
    np.testing.assert_allclose(Y_p @ theta0, model.H(q) @ v, rtol=1e-6, atol=1e-9)
    after = build_experiment(plan_run(s), log=False)
    assert isinstance(after.robots[0].force_observer, MomentumObserver)


def _circle_rms(scenario, t_end, variant):
    """λ − λ_d and λ̂ − λ over the circle, RMS, worst robot, from the logs of a run (not the
    metrics the table reads)."""
    from drake_coop.experiment.simulate import simulate

    with variant_built(scenario, variant):
        result = simulate(scenario, t_end=t_end)
    assert result.ok
    squeeze, estimate = [], []
    for log in result.logs.values():
        circle = log["t"] >= scenario.task.t_circle_start - 1e-9
        lam, lam_d, lam_hat = (np.asarray(log[k])[circle] for k in
                               ("lambda_meas", "lambda_d", "lambda_hat"))
        squeeze.append(np.sqrt(np.mean((lam - lam_d) ** 2)))
        estimate.append(np.sqrt(np.mean((lam_hat - lam) ** 2)))
    return max(squeeze), max(estimate)


@pytest.mark.slow
def test_the_residual_case_matches_an_independent_run_and_differs_under_saturation():
    """Robot 1's elbow limited to 11.5 N·m (its lift peak is 11.7, its approach's 11.8 on
    the short segment; saturated on 96 of the lift's ticks): the residual's case (what the table's worker runs) against the run
    built here, its numbers read from the logs; and the residual integrates what the arm got,
    so it differs from the momentum observer on the same limits (which reads the clipped
    torque as contact force) during the lift."""
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.studies.reference_table import per_draw
    from drake_coop.studies.reference_variants import run_variant_case

    s = _momentum_scenario()
    s.robots[0].actuators.torque_limits = [100.0, 100.0, 11.5]
    squeeze, estimate = _circle_rms(s, T_TINY, "applied_torque")
    numbers = per_draw(run_variant_case(dump_scenario(s), T_TINY, "applied_torque"))
    assert numbers["squeeze"] == pytest.approx(squeeze, rel=1e-6)
    assert numbers["estimate"] == pytest.approx(estimate, rel=1e-6)
    momentum = per_draw(run_variant_case(dump_scenario(s), T_TINY, None))
    assert momentum["squeeze_lift"] != pytest.approx(numbers["squeeze_lift"], rel=1e-6)


@pytest.mark.slow
def test_online_row_against_the_truth_beats_the_wrong_model(tmp_path):
    """A controller model 15 % heavy: the online block's estimate of the contact force is
    closer to the simulated truth than the momentum observer's on the same model, and the
    table's cell is the run's (numbers from the logs here)."""
    s = _momentum_scenario()
    for robot in s.robots:
        robot.model_error.mass_scale = robot.model_error.inertia_scale = 1.15
    _, momentum = _circle_rms(s, T_TINY, None)
    squeeze, online = _circle_rms(s, T_TINY, "online")
    assert online < 0.7 * momentum
    from drake_coop.studies.reference_variants import run_variant_case
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.studies.reference_table import per_draw

    record = run_variant_case(dump_scenario(s), T_TINY, "online")
    numbers = per_draw(record)
    assert numbers["squeeze"] == pytest.approx(squeeze, rel=1e-6)
    assert numbers["estimate"] == pytest.approx(online, rel=1e-6)


def test_open_loop_refuses_what_it_cannot_build():
    from drake_coop.studies.reference_open_loop import open_loop_built

    s = _momentum_scenario()
    with pytest.raises(ValueError, match="row: 'sensor_3' does not run beside"):
        with open_loop_built(s, "sensor_3"):
            pass
    with pytest.raises(ValueError, match="scenario: the open-loop column closes"):
        with open_loop_built(s, "observer"):
            pass


def test_open_loop_cases_share_the_sensor_loop_and_the_f_t_rows_are_their_own():
    cases = expand_table(load_scenario(), ["observer", "applied_torque", "momentum",
                                           "sensor_3"], ["open_loop", "exact"], 1,
                         t_end=T_TINY)
    by = {(c.params["row"], c.params["column"]): c for c in cases}
    assert by[("observer", "open_loop")].values["variant"] == "open_loop:observer"
    # the residual without torque limits is the momentum observer beside the loop
    assert by[("applied_torque", "open_loop")].hash == by[("momentum", "open_loop")].hash
    assert by[("sensor_3", "open_loop")].hash == by[("sensor_3", "exact")].hash
    loop = load_scenario(data=by[("observer", "open_loop")].scenario_yaml)
    assert all(r.force_source == "sensor" and r.force_sensor.noise_std == 0.3
               for r in loop.robots)


@pytest.mark.slow
def test_open_loop_against_the_truth():
    """Beside the F/T loop: every estimator leaves the loop as it is (the squeeze error of
    each open-loop case is the plain σ = 0.3 N sensor run's, run here without any swap), and
    λ̂ = λ_d beside it has the loop's own squeeze error as its estimate error (λ_d − λ)."""
    from drake_coop.studies.reference_table import per_draw
    from drake_coop.studies.reference_variants import run_variant_case

    cases = expand_table(load_scenario(), ["observer", "none", "sensor_0p3"],
                         ["open_loop", "exact"], 1, t_end=T_TINY)
    by = {(c.params["row"], c.params["column"]): c for c in cases}
    plain = _circle_rms(load_scenario(data=by[("sensor_0p3", "exact")].scenario_yaml),
                        T_TINY, None)
    numbers = {row: per_draw(run_variant_case(by[(row, "open_loop")].scenario_yaml, T_TINY,
                                              by[(row, "open_loop")].values["variant"]))
               for row in ("observer", "none")}
    for v in numbers.values():
        assert v["squeeze"] == pytest.approx(plain[0], rel=1e-9)
    assert numbers["none"]["estimate"] == pytest.approx(plain[0], rel=1e-9)
    assert numbers["observer"]["estimate"] < 0.5 * numbers["none"]["estimate"]


@pytest.mark.slow
def test_online_row_after_10_s_within_2x_of_the_batch_on_the_same_segment(monkeypatch):
    """±30 %-class model error (both arms 25 % heavy, inertia 20 % light): the online row's
    squeeze error over 10–13 s against a run whose controller model and force estimate are
    the batch MAP estimate of the same first 10 s of the online run (its rows built here from
    the logs, solved by ``numpy.linalg.lstsq``), fixed from the start; and both far below the
    unrefined model's."""
    import drake_coop.studies.reference_variants as variants
    from drake_coop.experiment.simulate import simulate
    from drake_coop.identification.online import momentum_rows
    from drake_coop.identification.regressor import Regressor, load_structure, true_parameters
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.model_error import controller_arm_model

    s = _momentum_scenario()
    for robot in s.robots:
        robot.model_error.mass_scale, robot.model_error.inertia_scale = 1.25, 0.8
    s.guards.max_squeeze_error = 100.0     # the unrefined model leaves its squeeze by 20 N+

    def squeeze(result):
        out = []
        for log in result.logs.values():
            t, e = log["t"], log["lambda_meas"] - log["lambda_d"]
            out.append(np.sqrt(np.mean(e[(t >= 10.0 - 1e-9) & (t < 13.0 + 1e-9)] ** 2)))
        return max(out)

    with variant_built(s, "online"):
        online = simulate(s, t_end=13.0)
    nominal = simulate(s, t_end=13.0)
    assert online.ok and nominal.ok
    h, batch = s.control_period, {}
    for robot in s.robots:
        log = online.logs[robot.name]
        arm = Arm(robot, s.task)
        model = controller_arm_model(arm, robot.model_error)
        structure = load_structure(arm.urdf_path, arm.base_frame,
                                   sensor_joint=robot.sensor_joint)
        regressor = Regressor(structure)
        theta0 = true_parameters(structure, model.plant)
        q = log["q"]
        vc = np.full_like(q, np.nan)
        vc[1:-1] = (q[2:] - q[:-2]) / (2 * h)        # the encoder's central difference
        rows, ys = [], []
        for k in range(2, int(np.searchsorted(log["t"], 10.0 + 1e-9))):
            if np.linalg.norm(vc[k]) < 0.01:
                continue
            (Yp1, _), (Yp0, Yb0) = (momentum_rows(regressor, q[k], vc[k]),
                                    momentum_rows(regressor, q[k - 1], vc[k - 1]))
            J = model.J_phi(q[k - 1])
            Pi = (np.eye(3) - J.T @ np.linalg.solve(J @ J.T, J) if log["lambda_d"][k - 1]
                  else np.eye(3))
            rows.append(Pi @ (Yp1 - Yp0 + h * Yb0) / (0.03 * h))
            ys.append(Pi @ (h * log["tau"][k - 1]) / (0.03 * h))
        scale = np.abs(theta0) + 1e-5 * max(np.abs(theta0).max(), 1.0)
        batch[robot.name] = np.linalg.lstsq(np.vstack([*rows, np.diag(1.0 / scale)]),
                                            np.concatenate([*ys, theta0 / scale]),
                                            rcond=None)[0]

    # the row's own builder with the batch θ as each robot's prior, held (no update)
    monkeypatch.setattr(variants, "_online_builder", functools.partial(
        variants._online_builder, prior=batch, options={"v_min": np.inf}))
    with variant_built(s, "online"):
        fixed = simulate(s, t_end=13.0)
    assert fixed.ok
    errors = {"online": squeeze(online), "batch": squeeze(fixed), "nominal": squeeze(nominal)}
    print(errors)
    assert errors["online"] < 2.0 * errors["batch"]
    assert errors["online"] < 0.1 * errors["nominal"]


def test_the_online_row_refines_the_controllers_model_and_beside_the_sensor_loop_does_not():
    """In its row the online block holds the control law's own model (it writes its
    parameters into it); beside the F/T loop (the open-loop column) it holds none, so the
    loop stays the sensor's."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.studies.reference_open_loop import open_loop_built

    s = _momentum_scenario()
    with variant_built(s, "online"):
        exp = build_experiment(plan_run(s), log=False)
    for rs in exp.robots:
        assert rs.force_observer._model is rs.law.model
    cases = expand_table(load_scenario(), ["online"], ["open_loop"], 1, t_end=T_TINY)
    loop = load_scenario(data=cases[0].scenario_yaml)
    with open_loop_built(loop, "online", variants._online_builder(loop, feed_controller=False)):
        exp = build_experiment(plan_run(loop), log=False)
    from pydrake.systems.framework import Diagram
    from drake_coop.identification.online import OnlineIdentification

    def systems(diagram):
        for system in diagram.GetSystems():
            yield system
            if isinstance(system, Diagram):
                yield from systems(system)
    blocks = [b for b in systems(exp.diagram) if isinstance(b, OnlineIdentification)]
    assert len(blocks) == len(loop.robots)
    assert all(block._model is None for block in blocks)


def test_the_online_builders_prior_and_options_reach_each_robots_block(monkeypatch):
    """``_online_builder``'s per-robot prior and block options (what the batch comparison
    passes): robot 1's block starts from the given θ and holds it (``v_min = inf``); robot 2,
    left out of the prior, starts from its controller model's parameters."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.identification.regressor import load_structure, true_parameters
    from drake_coop.plant.arms import Arm

    s = _momentum_scenario()
    arm = Arm(s.robots[0], s.task)
    structure = load_structure(arm.urdf_path, arm.base_frame,
                               sensor_joint=s.robots[0].sensor_joint)
    given = 1.1 * true_parameters(structure)
    monkeypatch.setattr(variants, "_online_builder", functools.partial(
        variants._online_builder, prior={"robot1": given}, options={"v_min": np.inf}))
    with variant_built(s, "online"):
        exp = build_experiment(plan_run(s), log=False)
    first, second = (rs.force_observer for rs in exp.robots)
    np.testing.assert_array_equal(first._theta0, given)
    assert first._v_min == second._v_min == np.inf
    np.testing.assert_array_equal(second._theta0, true_parameters(
        structure, exp.robots[1].law.model.plant))


def test_the_online_prior_row_is_the_online_row_with_the_friction_prior_only():
    """The optional row ``online_prior``: its cases are the online row's scenarios, draw by
    draw (the clock column's drawn clock too), under their own hashes; its blocks are the
    online row's but for the prior's friction entries (at least 0.5 N·m where the online
    row's are ``r|f_c0|``, zero on this friction-free model) and the friction written into the
    model. Not a default row; refused with the open-loop column (it has no case there)."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.studies.reference_table import ROWS

    assert "online_prior" not in [r.name for r in ROWS]
    cols = ["exact", "model_30", "coulomb", "clock"]
    cases = expand_table(load_scenario(), ["online", "online_prior"], cols, 2, t_end=T_TINY)
    online, prior = cases[:len(cases) // 2], cases[len(cases) // 2:]
    for a, b in zip(online, prior):
        assert {**a.params, "row": "online_prior"} == b.params
        assert a.scenario_yaml == b.scenario_yaml
        assert b.values["variant"] == a.values["variant"].replace("online", "online_prior")
        assert a.hash != b.hash
    with pytest.raises(ValueError, match="columns: open_loop has no case of the optional row"):
        expand_table(load_scenario(), ["online_prior"], ["open_loop"], 1, t_end=T_TINY)

    s = _momentum_scenario()
    blocks = {}
    for variant in ("online", "online_prior"):
        with variant_built(s, variant):
            blocks[variant] = [rs.force_observer for rs in
                               build_experiment(plan_run(s), log=False).robots]
    for a, b in zip(blocks["online"], blocks["online_prior"]):
        coulomb = a._regressor.structure.joint_slice("coulomb")
        p0_a, p0_b = np.diag(a._P0), np.diag(b._P0)
        np.testing.assert_array_equal(np.sqrt(p0_b[coulomb]), 0.5)
        assert np.all(np.sqrt(p0_a[coulomb]) < 1e-3)
        others = np.ones(p0_a.size, bool)
        others[coulomb] = False
        np.testing.assert_array_equal(p0_a[others], p0_b[others])
        assert (a._free_friction, b._free_friction) == (False, True)
        np.testing.assert_array_equal(a._theta0, b._theta0)
        for attr in ("_h", "_gain", "_mu", "_v_min", "_R"):
            assert getattr(a, attr) == getattr(b, attr)
        assert a._model is not None and b._model is not None
