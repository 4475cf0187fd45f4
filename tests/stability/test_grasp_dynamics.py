"""The grasp's dynamics check (:mod:`drake_coop.stability.grasp_dynamics`): the twin-run growth
rate against the closed form of a toy (a mass between two preloaded springs, the buckling
geometry of a squeezed grasp), and the check against the simulated truth (slow)."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import LeafSystem

from drake_coop.control.arm_plant import description_packages
from drake_coop.stability.grasp_dynamics import (PASSAGE, SETTLE, amplification, growth_rate,
                                                 passages, twin_run)

robots_extra = pytest.mark.skipif("example-robot-data" not in description_packages(),
                                  reason='example-robot-data is not installed '
                                         '(pip install -e ".[robots]")')


class _PreloadedMass(LeafSystem):
    """A mass ``m`` at ``(0, y)`` between two springs from walls at ``(±L, 0)``, each of
    stiffness ``k_s`` and rest length ``L_0 > L`` (compressed: the preload ``P = k_s (L_0 −
    L)``), held sideways by a spring ``k`` and a damper ``c``: the exact geometry, not its
    linearization."""

    def __init__(self, m, k, c, k_s, L, L0):
        super().__init__()
        self.p = (m, k, c, k_s, L, L0)
        self.DeclareContinuousState(2)

    def DoCalcTimeDerivatives(self, context, derivatives):
        m, k, c, k_s, L, L0 = self.p
        y, v = context.get_continuous_state_vector().CopyToVector()
        length = math.hypot(L, y)
        push = 2.0 * k_s * (L0 - length) * y / length      # both springs' sideways part
        derivatives.get_mutable_vector().SetFromVector([v, (push - k * y - c * v) / m])


def _sigma_closed_form(m, k, c, k_s, L, L0):
    """The largest real part of the roots of m s² + c s + (k − 2P/L), P = k_s (L0 − L)."""
    return max(np.roots([m, c, k - 2.0 * k_s * (L0 - L) / L]).real)


# k below and above the preload's 2P/L = 100 N/m (real roots both); the displacement small
# enough for the deviation to stay linear over the window
@pytest.mark.parametrize("k, y0", [(40.0, 1e-6), (150.0, 1e-3)])
def test_the_twin_run_finds_the_preloaded_mass_growth_rate_of_its_closed_form(k, y0):
    m, c, k_s, L, L0 = 0.5, 12.0, 1000.0, 0.1, 0.105
    system = _PreloadedMass(m, k, c, k_s, L, L0)
    sims = []
    for start in (0.0, y0):
        sim = Simulator(system)
        sim.get_mutable_context().SetContinuousState([start, 0.0])
        sim.get_mutable_integrator().set_target_accuracy(1e-10)
        sim.Initialize()
        sims.append(sim)
    run = twin_run(sims[0], sims[1], lambda ctx: ctx.get_continuous_state_vector()
                   .CopyToVector(), 0.0, window=1.0, samples=40)
    expected = _sigma_closed_form(m, k, c, k_s, L, L0)
    assert (expected > 0) == (k < 100.0)
    assert run.sigma == pytest.approx(expected, rel=0.02, abs=0.02)


def test_growth_rate_is_the_slope_of_the_logarithm_over_the_second_half():
    t = np.linspace(0.0, 2.0, 21)
    # a fast transient in the first half, e^{1.3 t} in the second
    d = np.where(t < 1.0, 5.0, 1.0) * np.exp(1.3 * t)
    assert growth_rate(t, d) == pytest.approx(1.3, rel=1e-12)
    assert growth_rate(t, np.full_like(t, 2e-6)) == pytest.approx(0.0, abs=1e-12)
    assert growth_rate(t, np.where(t > 1.5, 0.0, 1.0)) == math.inf
    with pytest.raises(ValueError, match="t, deviation"):
        growth_rate(t[:3], d[:3])


class _TimeVaryingTracker(LeafSystem):
    """``ẋ = σ(t) (x − r(t)) + ṙ(t)``, ``r(t) = 0.3 sin t``: the nominal from ``x(0) = r(0)``
    follows the moving reference exactly, and a twin's deviation obeys ``δ̇ = σ(t) δ``, whose
    amplification from ``t_a`` to ``t_b`` is ``exp(∫_a^b σ dt)``."""

    def __init__(self, sigma):
        super().__init__()
        self.sigma = sigma
        self.DeclareContinuousState(1)

    def DoCalcTimeDerivatives(self, context, derivatives):
        t = context.get_time()
        x = context.get_continuous_state_vector()[0]
        derivatives.get_mutable_vector().SetFromVector(
            [self.sigma(t) * (x - 0.3 * math.sin(t)) + 0.3 * math.cos(t)])


def _largest_rise(F, t):
    """``max_{a ≤ b} F(t_b) − F(t_a)`` over the samples (the closed form's integral ``F``)."""
    values = np.array([F(x) for x in t])
    return max(values[b] - values[: b + 1].min() for b in range(len(values)))


# a growth that ends (σ = 2 − t: the deviation grows until t = 2, then decays), and one that
# comes and goes (σ = 1.5 sin 2πt/2: the largest stretch is one positive half-period, however
# many there are)
@pytest.mark.parametrize("sigma, F", [
    (lambda t: 2.0 - t, lambda t: 2.0 * t - 0.5 * t * t),
    (lambda t: 1.5 * math.sin(math.pi * t), lambda t: -1.5 / math.pi * math.cos(math.pi * t))])
def test_the_amplification_along_a_moving_reference_is_the_closed_forms(sigma, F):
    system = _TimeVaryingTracker(sigma)
    sims = []
    for start in (0.0, 1e-6):
        sim = Simulator(system)
        sim.get_mutable_context().SetContinuousState([start])
        sim.get_mutable_integrator().set_target_accuracy(1e-10)
        sim.Initialize()
        sims.append(sim)
    run = twin_run(sims[0], sims[1], lambda ctx: ctx.get_continuous_state_vector()
                   .CopyToVector(), 0.0, window=4.0, samples=80)
    factor, a, b = amplification(run.deviation)
    expected = _largest_rise(F, run.t)
    assert math.log(factor) == pytest.approx(expected, rel=1e-4)
    assert F(run.t[b]) - F(run.t[a]) == pytest.approx(expected, rel=1e-9)
    # the same loop frozen at its worst instant would grow without end: the dwell decides
    assert max(sigma(t) for t in run.t) > 0.9


def test_the_amplification_is_the_largest_rise_over_any_stretch():
    assert amplification(np.array([1.0, 0.5, 2.0, 1.0, 8.0])) == (16.0, 1, 4)
    assert amplification(np.array([3.0, 2.0, 1.0]))[0] == 1.0        # never grows
    assert amplification(np.array([1.0, 4.0, 0.1, 0.2]))[:2] == (4.0, 0)
    assert amplification(np.array([1.0, math.nan]))[0] == math.inf
    with pytest.raises(ValueError, match="deviation"):
        amplification(np.zeros((2, 2)))


def test_the_stretches_followed_are_the_lift_or_the_circle_around_a_growing_posture():
    from drake_coop.scenario.schema import Task

    task = Task()                       # grasp 15 s, circle 25 … 65 s
    lift = (task.t_grasp + SETTLE, task.t_circle_start)
    assert passages(task, []) == []
    assert passages(task, [17.0]) == [lift]             # the whole lift, the box on its stand
    assert passages(task, [35.0, 45.0]) == [(35.0 - PASSAGE, 45.0 + PASSAGE)]   # joined
    assert passages(task, [17.0, 25.0, 55.0]) == [lift, (25.0, 25.0 + PASSAGE),
                                                   (55.0 - PASSAGE, 55.0 + PASSAGE)]
    assert passages(task, [65.0]) == [(65.0 - PASSAGE, 65.0)]


def test_only_a_two_pad_contact_grasp_is_checked():
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import find_scenario
    from drake_coop.stability.grasp_dynamics import check_grasp_dynamics

    for name in ("paper", "three_arms"):        # planes mode; three robots
        result = check_grasp_dynamics(load_scenario(find_scenario(name)))
        assert not result.checked and result.passes and "not checked" in result.message


def _pair(name: str, squeeze: str):
    """A pair of ``name`` as the lab-arms how-to sets it up (bench.every_arm), with the
    derived gains and the squeeze source ``squeeze``."""
    import tempfile
    from pathlib import Path

    from bench.every_arm import pair_yaml, placement
    from drake_coop.stability.gains import derive_gains, gains_for_scenario
    from drake_coop.stability.gains_cli import load_for_gains

    with tempfile.TemporaryDirectory() as folder:
        place, why = placement(name, Path(folder))
        assert place is not None, why
        path = Path(folder) / f"{name}.yaml"
        path.write_text(pair_yaml((name, name), (place, place)))
        scenario = load_for_gains(str(path))
    scenario.object_model.squeeze = squeeze
    return gains_for_scenario(scenario, derive_gains(scenario))


def _tilt_max(result) -> float:
    """The box's largest rotation from its first logged pose in a run, rad."""
    from drake_coop.kinematics.rotations import quaternion_rotations

    log = next(iter(result.logs.values()))
    R = quaternion_rotations(np.asarray(log["object_pose"])[:, :4])
    R0 = R[0]
    return float(np.arccos(np.clip((np.einsum("ij,kij->k", R0, R) - 1) / 2, -1, 1)).max())


@pytest.mark.slow
@robots_extra
@pytest.mark.parametrize("name, squeeze, points, t_end, refused", [
    # the UR3s at the task's squeeze: the frozen loop grows a quarter into the circle, the
    # moving loop through it loses the box; the run past the refusal fails on the tilt
    ("ur3", "profile", [("circle 25 %", 35.0)], 31.0, True),
    # the UR3s at the friction squeeze: nothing grows, the run carries the box
    ("ur3", "friction", [("circle 25 %", 35.0)], 31.0, False),
    # the Jaco2s at the task's squeeze: the frozen loop grows a fifth into the lift, the
    # loop lifting the box off its stand tilts it past the guard; so does the run
    ("jaco2", "profile", [("lift", 17.0)], 20.0, True),
    # the Jaco2s at the friction squeeze: the frozen loop grows at the circle's bottom, the
    # moving loop passes it with a bounded amplification; the run carries the box through it
    ("jaco2", "friction", [("circle", 45.0)], 50.0, False)])
def test_the_check_refuses_what_the_run_loses_and_passes_what_it_carries(
        name, squeeze, points, t_end, refused):
    """The simulated truth: the check at one posture (and the stretch it follows), then the
    run to ``t_end``, past the verdict."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.stability.grasp_dynamics import check_grasp_dynamics

    scenario = _pair(name, squeeze)
    check = check_grasp_dynamics(scenario, points=points)
    assert check.passes is not refused, check.message
    if refused:
        assert f"{name}_1: " in check.message and "object_model.squeeze: friction" \
            in check.message
    result = simulate(scenario, t_end=t_end)
    if refused:
        assert result.meta["status"] == "failed", result.meta
        assert "tilted" in result.meta["message"]
    else:
        assert result.meta["status"] == "ok", result.meta
        assert _tilt_max(result) < 0.05
