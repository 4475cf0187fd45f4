"""The squeeze's buckling of a two-pad grasp (:mod:`drake_coop.stability.grasp`): the bound
against closed forms (springs in series, a Schur complement) and against the simulated truth
(two Kinova Jaco2s, whose soft wrists buckle under the task's squeeze and hold a squeeze below
the bound)."""

import numpy as np
import pytest

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.resources import find_scenario
from drake_coop.stability.grasp import (
    buckling_squeeze,
    check_grasp_buckling,
    pad_stiffness,
)

robots_extra = pytest.mark.skipif("example-robot-data" not in description_packages(),
                                  reason='example-robot-data is not installed '
                                         '(pip install -e ".[robots]")')


def test_equal_isotropic_pads_buckle_at_k_L_over_2():
    k, L = 250.0, 0.14
    lam, mode = buckling_squeeze(k * np.eye(2), k * np.eye(2), L)
    assert lam == pytest.approx(k * L / 2, rel=1e-12)
    # the mode moves the pads in opposite directions (the line between them turns)
    np.testing.assert_allclose(mode[:2], -mode[2:], atol=1e-12)


def test_unequal_pads_buckle_as_springs_in_series_along_the_softer_axis():
    # Energy k1 d1² + k2 d2² − (λ/L)(d1 − d2)² along each axis: the least over d1 − d2 fixed
    # is k1 k2/(k1 + k2) (d1 − d2)², so λ_b = L k1 k2/(k1 + k2) on the softer axis.
    L = 0.2
    K1, K2 = np.diag([300.0, 80.0]), np.diag([500.0, 120.0])
    lam, mode = buckling_squeeze(K1, K2, L)
    assert lam == pytest.approx(L * 80 * 120 / 200, rel=1e-12)
    assert abs(mode[0]) < 1e-12 and abs(mode[2]) < 1e-12      # the stiff axis stays


def test_pad_stiffness_is_the_schur_complement_of_the_cartesian_stiffness():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(3, 3))
    Kq = np.array([40.0, 7.0, 0.9])
    K = np.linalg.inv(J).T @ np.diag(Kq) @ np.linalg.inv(J)      # the pad's full stiffness
    # the plane normal to x: its motion along x free, the Schur complement on (y, z)
    schur = K[1:, 1:] - np.outer(K[1:, 0], K[0, 1:]) / K[0, 0]
    P = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(pad_stiffness(J, Kq, P), schur, rtol=1e-10)


def test_the_paper_arms_grasp_is_far_from_buckling():
    result = check_grasp_buckling(load_scenario(find_scenario("contact")))
    assert result.checked and result.passes
    assert result.worst_ratio < 0.1          # λ_d 50 N against λ_b near 1 kN


@pytest.mark.parametrize("squeeze, advice", [
    ("profile", "task.force_mean, force_amplitude; object_model.squeeze: friction"),
    ("friction", "a lighter box or a higher friction, plant.object_mass, plant.friction")])
def test_a_refusal_advises_a_lower_squeeze_its_squeeze_source_can_give(squeeze, advice):
    """A margin below the paper grasp's ratio makes it a refusal; already at the friction
    squeeze, the advice is the box, not that field again."""
    scenario = load_scenario(find_scenario("contact"))
    scenario.object_model.mode, scenario.object_model.squeeze = "known", squeeze
    result = check_grasp_buckling(scenario, margin=1e-4)
    assert not result.passes and f"{advice}), widen the grasp" in result.message


def test_three_robots_are_not_checked():
    result = check_grasp_buckling(load_scenario(find_scenario("three_arms")))
    assert not result.checked and result.passes and "not checked" in result.message


def _jaco2_pair(squeeze="profile", mu=None):
    """Two Jaco2s as the how-to sets them up (bench.every_arm), with the derived gains."""
    from bench.every_arm import pair_yaml, placement
    from drake_coop.stability.gains import derive_gains, gains_for_scenario
    from drake_coop.stability.gains_cli import load_for_gains

    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        place, why = placement("jaco2", Path(folder))
        assert place is not None, why
        path = Path(folder) / "jaco2.yaml"
        path.write_text(pair_yaml(("jaco2", "jaco2"), (place, place)))
        scenario = load_for_gains(str(path))
    scenario = gains_for_scenario(scenario, derive_gains(scenario))
    scenario.object_model.squeeze = squeeze
    if mu is not None:
        scenario.plant.friction = mu
    return scenario


@pytest.mark.slow
@robots_extra
@pytest.mark.parametrize("squeeze, mu, buckles", [("profile", None, True),
                                                  ("friction", 2.0, False)])
def test_the_jaco2_grasp_buckles_above_the_bound_and_holds_below_it(squeeze, mu, buckles):
    """The simulated truth: the task's squeeze (29) is several times the bound and the box
    turns about the vertical through tens of degrees during the lift, the pads sliding
    sideways; the friction squeeze on a grippier box stays below it and the box stays put."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.kinematics.rotations import quaternion_rotations

    t_end = 24.0
    scenario = _jaco2_pair(squeeze, mu)
    bound = check_grasp_buckling(scenario, t_end=t_end)
    assert (bound.worst_ratio > 2.0) if buckles else (bound.worst_ratio < 1.0)
    g = scenario.guards         # the truth past the failure guards (the tilt's ends the run)
    g.max_object_tilt_deg, g.max_pad_error, g.max_object_position_error = 180.0, 10.0, 10.0
    g.max_squeeze_error, g.grasp_lost = 1e5, False
    result = simulate(scenario, t_end=t_end)
    log = next(iter(result.logs.values()))
    R = quaternion_rotations(np.asarray(log["object_pose"])[:, :4])
    angle = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
    late = np.asarray(log["t"]) > t_end - 1.0
    if buckles:
        assert angle[late].min() > 0.2, angle[late].min()           # > 11°
    else:
        assert angle[late].max() < 0.01, angle[late].max()           # < 0.6°
        assert angle.max() < 0.05, angle.max()       # the grasp's settling, not a buckle


@pytest.mark.slow
@robots_extra
def test_the_jaco2_pair_carries_the_box_or_is_refused_with_the_reason():
    """The Jaco2 pair set up as the how-to says: ``drake-coop gains`` (its derivation and the
    task's checks) refuses it before any run, naming the grasp's dynamics in the lift (where
    its run loses the box) and what to change; had it passed, the run would have to meet
    the bars."""
    from bench.every_arm import run_row

    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        case = run_row("jaco2", Path(folder) / "every_arm.json")
    if "refusal" in case:
        refusal = case["refusal"]
        assert "grasp dynamics: the grasp is unstable along the task" in refusal
        assert "lift" in refusal and "1/s" in refusal                # where it is lost
        assert "object_model.squeeze: friction" in refusal
        assert case["gains"]["task_checks"]["grasp"]["passes"] is False
    else:
        assert case["verdict"]["passes"], case["verdict"]
