"""Delay compensation on the one-period map, and the plant step's half-step bias, against
independent computations: the continuous joint integrated exactly (matrix exponential, checked
against the closed-form solution) and the Drake loop's map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drake_coop.stability.continuous import continuous_rho, continuous_rows
from drake_coop.stability.one_joint import (
    _expm,
    _plant_steps,
    one_joint_predicted_rho,
    one_joint_rho,
)

# robot 2's slow joint (the free loop's binding mode), the paper's gains
J, D, LAMBDA, K_D, K_R, H = 0.478, 1.0, 26.0, 40.0, 100.0, 0.009


def test_exact_joint_solution_is_the_closed_form():
    t, tau, q0, v0 = 0.004, 3.0, 0.2, -0.5
    A, B = _plant_steps(J, D, t, None)
    q, v = A @ [q0, v0] + B * tau
    e = math.exp(-D * t / J)
    v_ref = v0 * e + tau / D * (1 - e)
    q_ref = q0 + tau / D * t + (v0 - tau / D) * J / D * (1 - e)
    assert v == pytest.approx(v_ref, rel=1e-12)
    assert q == pytest.approx(q_ref, rel=1e-12)
    np.testing.assert_allclose(_expm(np.array([[0.0, 2.0], [0.0, 0.0]])), [[1, 2], [0, 1]])


def test_one_joint_without_predictor_is_the_existing_closed_form():
    for steps in range(0, 9):
        assert one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, steps * 1e-3, None,
                                       dt=1e-3) == pytest.approx(
            one_joint_rho(J, D, LAMBDA, K_D, K_R, H, 1e-3, "observer", steps), rel=1e-12)


@pytest.mark.parametrize("delay", [0.0, 0.002, 0.004])
def test_fine_plant_step_converges_to_the_continuous_joint(delay):
    cont = one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, None, dt=None)
    fine = one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, None, dt=H / 360)
    assert abs(fine - cont) < 2e-3


@pytest.mark.parametrize("delay", [0.001, 0.002, 0.003, 0.004, 0.006])
def test_one_ms_plant_acts_half_a_step_early(delay):
    """The 1 ms plant at delay d is the continuous joint at d − 0.5 ms, not at d."""
    disc = one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, None, dt=1e-3)
    assert abs(disc - one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay - 5e-4, None)) \
        < 3e-3
    assert one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, None) - disc > 0.01


@pytest.mark.parametrize("horizon", [None, 0.003])
@pytest.mark.parametrize("delay", [0.0, 0.002, 0.004, 0.006])
def test_richardson_of_two_plant_steps_is_the_continuous_joint(delay, horizon):
    rho = [one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, horizon, dt=dt)
           for dt in (1e-3, 5e-4)]
    cont = one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, delay, horizon, dt=None)
    # 1e-3 where one mode dominates at both steps; where the largest eigenvalue changes mode
    # between them (4 ms with the predictor) the extrapolation is off by 0.004
    assert abs(continuous_rho(*rho) - cont) < (5e-3 if (delay, horizon) == (0.004, 0.003)
                                               else 1e-3)
    assert abs(rho[0] - cont) > abs(continuous_rho(*rho) - cont)


@pytest.mark.parametrize("scale", [0.7, 1.0, 1.3])
def test_one_joint_predictor_keeps_the_continuous_joint_stable_to_8ms(scale):
    for d in np.arange(0.0, 0.0081, 0.0005):
        assert one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, d, 0.003,
                                       model_scale=scale) < 1.0
    assert one_joint_predicted_rho(J, D, LAMBDA, K_D, K_R, H, 0.002, None) > 1.0


def test_continuous_rows_pairs_the_plant_steps():
    rows = [{"d": 0.002, "plant.time_step": dt, "point": "free", "rho": rho, "status": "stable"}
            for dt, rho in ((0.001, 0.98), (0.0005, 0.99))]
    (row,) = continuous_rows(rows, ["d", "plant.time_step"])
    assert row["rho_continuous"] == pytest.approx(1.0)
    assert row["d"] == 0.002 and row["time_step"] == 0.001
    with pytest.raises(ValueError, match="plant.time_step"):
        continuous_rows(rows, ["d"])


# --- the Drake loop's own map ----------------------------------------------------------------

def _paper(delay: float, horizon=None):
    from drake_coop.scenario import default_scenario

    s = default_scenario()
    for robot in s.robots:
        robot.timing.computation_delay = delay
        robot.timing.prediction_horizon = horizon
    return s


@pytest.mark.slow
def test_held_map_default_step_is_on_the_solvers_plateau():
    """At 4 ms of delay the held loop is unstable: ρ 1.0636 on the plateau 1e-3 … 1e-2; at
    ε = 1e-5 the plant's solver does not move and the map read 0.9995 (what the old default
    reported)."""
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse, step_sensitivity

    F = operating_point(_paper(0.004), "held").map
    report = analyse(F)
    assert report.step_agrees and report.epsilon_check == pytest.approx(3 * report.epsilon)
    assert report.rho > 1.05
    (_, rho_big, _), (_, rho_small, _) = step_sensitivity(F, F.x0, report.dynamic, (1e-2, 1e-5))
    assert abs(rho_big - report.rho) < 1e-4
    assert rho_small < 1.0                   # the unresolved step's wrong answer


@pytest.mark.slow
@pytest.mark.parametrize("point", ["free", "held"])
def test_compensation_makes_the_6ms_loop_stable(point):
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse

    off = analyse(operating_point(_paper(0.006), point).map)
    on = analyse(operating_point(_paper(0.006, 0.003), point).map)
    assert off.step_agrees and on.step_agrees
    assert off.rho > 1.05 and on.rho < 1.0


@pytest.mark.slow
def test_encoder_delayed_held_map_is_checked_below_the_default_step():
    """The held loop with one sample of encoder delay: ε = 1e-5 … 1e-3 agree (1.17674), 3e-3
    leaves that plateau (1.1700); the check then takes ε/3 and the point is resolved."""
    from drake_coop.scenario.resources import find_scenario
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse, step_sensitivity

    s = load_scenario(find_scenario("realistic"))
    for robot in s.robots:
        robot.encoders.delay_samples = 1
    F = operating_point(s, "held").map
    report = analyse(F)
    assert report.step_agrees and report.epsilon_check == pytest.approx(report.epsilon / 3)
    (_, rho_small, _), (_, rho_big, _) = step_sensitivity(F, F.x0, report.dynamic, (1e-5, 3e-3))
    assert abs(rho_small - report.rho) < 1e-4 < abs(rho_big - report.rho)
    assert report.rho > 1.1
