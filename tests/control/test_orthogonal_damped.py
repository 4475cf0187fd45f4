"""The damped pseudo-inverse against its closed form from the SVD, near a singular posture;
its derivative against central differences; the law's two paths agree with it."""

import numpy as np
import pytest

from drake_coop.control import orthogonal
from drake_coop.control.finger import FingerLaw
from drake_coop.control.reference_layout import Reference
from drake_coop.control.params import Gains
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario.loading import default_scenario


def _near_singular(m, n, sigma_min, seed=0):
    rng = np.random.default_rng(seed)
    U, _ = np.linalg.qr(rng.normal(size=(m, m)))
    V, _ = np.linalg.qr(rng.normal(size=(n, n)))
    sigma = np.r_[np.linspace(1.0, 0.5, m - 1), sigma_min]   # the smallest: sigma_min
    return U, sigma, V[:, :m], (U * sigma) @ V[:, :m].T


@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("sigma_min", [1e-1, 1e-4, 1e-9, 0.0])
def test_damped_pinv_is_the_svd_closed_form_and_bounded(m, sigma_min):
    mu = 1e-2
    U, sigma, V, J = _near_singular(m, 6, sigma_min)
    J_pinv, Q = orthogonal.projections(J, damping=mu)
    closed = (V * (sigma / (sigma ** 2 + mu ** 2))) @ U.T
    np.testing.assert_allclose(J_pinv, closed, rtol=0, atol=1e-12)
    np.testing.assert_allclose(Q, np.eye(6) - closed @ J, rtol=0, atol=1e-12)
    assert np.linalg.norm(J_pinv, 2) <= 1.0 / (2.0 * mu) + 1e-12
    if sigma_min >= 1e-4:   # undamped, the same posture blows up as 1/σ_min
        assert np.linalg.norm(orthogonal.projections(J)[0], 2) == pytest.approx(
            1.0 / sigma_min, rel=1e-6)


def test_zero_damping_is_the_paper_pinv_bit_for_bit():
    _, _, _, J = _near_singular(2, 5, 0.3)
    for a, b in zip(orthogonal.projections(J), orthogonal.projections(J, damping=0.0)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("m", [1, 2])
def test_damped_derivatives_are_the_central_difference(m):
    mu = 3e-2
    rng = np.random.default_rng(1)
    _, _, _, J = _near_singular(m, 5, 1e-3, seed=2)
    Jd = rng.normal(size=J.shape)
    J_pinv_dot, Q_dot = orthogonal.projection_derivatives(J, Jd, damping=mu)
    e = 1e-7
    plus, minus = orthogonal.projections(J + e * Jd, mu), orthogonal.projections(J - e * Jd, mu)
    np.testing.assert_allclose(J_pinv_dot, (plus[0] - minus[0]) / (2 * e), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(Q_dot, (plus[1] - minus[1]) / (2 * e), rtol=1e-5, atol=1e-5)


def test_the_plain_float_and_numpy_paths_agree_with_damping():
    s = default_scenario()
    law = FingerLaw(arm_model(Arm(s.robots[0], s.task), closed_form=False), Gains(),
                    pinv_damping=0.05)
    assert law.fast
    rng = np.random.default_rng(7)
    q = np.array([0.1, 0.7, -0.5])
    ref = Reference(q + 1e-3, rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.1,
                    np.array([20.0]), True)
    args = (q, q + 2e-4, rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.1)
    DF = np.array([0.3])
    lam = law.force_estimate(args[0], args[1], args[3], ref, DF)
    fast = law.control(*args, lam, DF, ref)
    law.fast = False
    np.testing.assert_allclose(law.force_estimate(args[0], args[1], args[3], ref, DF), lam,
                               rtol=1e-10)
    general = law.control(*args, lam, DF, ref)
    for key in ("tau", "qdot_r", "qddot_r_hat"):
        np.testing.assert_allclose(fast[key], general[key], rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("bad", [-1.0, float("nan"), "0.1", True])
def test_bad_damping_is_refused_by_name(bad):
    s = default_scenario()
    with pytest.raises(ValueError, match="pinv_damping"):
        FingerLaw(arm_model(Arm(s.robots[0], s.task)), Gains(), pinv_damping=bad)
