"""The grasp's dynamics check (:mod:`drake_coop.stability.grasp_dynamics`): the twin-run growth
rate against the closed form of a toy (a mass between two preloaded springs, the buckling
geometry of a squeezed grasp), and the check against the simulated truth (slow)."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, LeafSystem

from drake_coop.control.arm_plant import description_packages
from drake_coop.stability.grasp_dynamics import growth_rate, twin_run

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
