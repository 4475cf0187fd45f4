"""The stability map: the finite-difference monodromy matrix against a closed form,
the state bookkeeping, and ρ(Φ) of the paper's loop where the studies say stable / diverged."""

import math

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from drake_coop.cli import main
from drake_coop.scenario import default_scenario
from drake_coop.scenario.schema import Timing
from drake_coop.sensing.latency import ActuationDelay
from drake_coop.stability.one_joint import (
    crossing_period,
    observer_period_limit,
    one_joint_phi,
    one_joint_rho,
)
from drake_coop.stability.operating import operating_point
from drake_coop.stability.period_map import PeriodMap, analyse, step_sensitivity

# One joint, exact model, no gravity (vertical axis): inertia J, viscous friction D.
J, D = 0.5, 1.0
LAM, KD, KR = 35.0, 40.0, 120.0
H, DT, N = 0.009, 0.009 / 9, 9


class OneJointLoop(LeafSystem):
    """Observer (15)–(16) and controller (13) in free motion for one joint, ``q_d = 0``:
    state ``q̂, q̇̂_o`` and a latch ``[τ, k]`` (the torque of the tick, held); with
    ``measured`` the law reads the plant's velocity instead (``q̂ = q``, ``q̇̂ = q̇_o = v``)."""

    def __init__(self, measured: bool = False):
        super().__init__()
        self._measured = measured
        self._x = self.DeclareVectorInputPort("state", 2)
        self._obs = self.DeclareDiscreteState(2)
        self._latch = self.DeclareDiscreteState(np.array([0.0, -1.0]))
        self.DeclarePeriodicDiscreteUpdateEvent(H, 0.0, self._update)
        self.DeclareVectorOutputPort("tau", 1, self._calc_tau)

    def _law(self, context):
        q, v = self._x.Eval(context)
        q_hat, o = context.get_discrete_state(self._obs).value()
        if self._measured:
            q_hat, o = q, v
        z = q - q_hat
        qdot_hat = o + (LAM + KD) * z
        qdot_o = o + KD * z
        qdot_r = -LAM * q_hat
        qddot_r = -LAM * qdot_hat
        tau = J * qddot_r + D * qdot_r - KR * (qdot_o - qdot_r)
        return tau, q_hat + H * qdot_hat, o + H * (qddot_r + KD * LAM * z)

    def _calc_tau(self, context, output: BasicVector):
        k = round(context.get_time() / H)
        latch = context.get_discrete_state(self._latch).value()
        at_tick = abs(context.get_time() - k * H) < 1e-12
        output.SetAtIndex(0, self._law(context)[0] if at_tick and latch[1] != k else latch[0])

    def _update(self, context, discrete_state):
        tau, q_hat, o = self._law(context)
        discrete_state.set_value(self._obs, np.array([q_hat, o]))
        discrete_state.set_value(self._latch, np.array([tau, round(context.get_time() / H)]))


def one_joint_map(sampled: bool = False, measured: bool = False, delay: float = 0.0):
    b = DiagramBuilder()
    plant = b.AddNamedSystem("plant", MultibodyPlant(DT))
    plant.SetUseSampledOutputPorts(sampled)   # False as the project's plant: q(t_k) at t_k
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, 0.0])
    body = plant.AddRigidBody("link", SpatialInertia(1.0, np.zeros(3),
                                                     UnitInertia(J, J, J)))
    joint = plant.AddJoint(RevoluteJoint("joint", plant.world_frame(), body.body_frame(),
                                         [0.0, 0.0, 1.0], D))
    plant.AddJointActuator("motor", joint)
    plant.Finalize()
    law = b.AddNamedSystem("law", OneJointLoop(measured))
    b.Connect(plant.get_state_output_port(), law.get_input_port(0))
    if delay:
        lat = b.AddNamedSystem("latency", ActuationDelay(1, H, DT, Timing(computation_delay=delay)))
        b.Connect(law.get_output_port(0), lat.get_tau_cmd_input_port())
        b.Connect(lat.get_tau_output_port(), plant.get_actuation_input_port())
    else:
        b.Connect(law.get_output_port(0), plant.get_actuation_input_port())
    diagram = b.Build()
    context = diagram.CreateDefaultContext()
    if delay:       # start after a first tick (the block applies the very first torque at once)
        simulator = Simulator(diagram, context)
        simulator.AdvanceTo(H)
        context = simulator.get_context()
    return PeriodMap(diagram, context, H)


def closed_form_phi(measured: bool = False) -> np.ndarray:
    return one_joint_phi(J, D, LAM, KD, KR, H, DT, "measured" if measured else "observer")


def test_finite_difference_monodromy_matches_the_hand_derived_one_joint_loop():
    F = one_joint_map()
    report = analyse(F)
    labels = report.dynamic_labels()
    assert labels[0].endswith("joint_q") and labels[1].endswith("joint_w")
    assert labels[2:] == ["law[0][0]", "law[0][1]"]      # the observer's q̂, q̇̂_o
    expected = closed_form_phi()
    np.testing.assert_allclose(report.Phi, expected, rtol=1e-6, atol=1e-8)
    rho = max(abs(np.linalg.eigvals(expected)))
    assert report.rho == pytest.approx(rho, rel=1e-7)
    assert 0.5 < rho < 1.0


def test_finite_difference_monodromy_matches_the_closed_form_with_measured_velocity():
    report = analyse(one_joint_map(measured=True))
    assert len(report.dynamic) == 2          # the observer's state is overwritten: q̂ = q
    np.testing.assert_allclose(report.Phi, closed_form_phi(measured=True), rtol=1e-6,
                               atol=1e-8)


def test_closed_form_limit_of_measured_velocity_is_h_K_R_over_J_about_2():
    # a sampled velocity loop: h K_R / J < 2 (ref. estimate of the studies); exact limit here
    h = crossing_period(0.478, 0.0, 35.0, 40.0, 100.0, 0.001, "measured")
    assert 1.6 < h * 100.0 / 0.478 < 2.2
    # the observer's filtering moves the limit out (the studies: 20 ms vs 9 ms)
    assert crossing_period(0.478, 0.0, 35.0, 40.0, 100.0, 0.001, "observer") > 1.5 * h


def test_observer_limit_is_forward_euler_on_its_fast_pole():
    # s² + (2Λ + k_d) s + Λ k_d, Λ = 35, k_d = 40: poles −14.7 and −95.3 → h < 2/95.3 = 21 ms
    assert observer_period_limit(35.0, 40.0) == pytest.approx(0.02098, abs=2e-5)
    # against the full one-joint map: a heavy joint (the arm barely moves within a sample)
    h = observer_period_limit(35.0, 40.0)
    assert one_joint_rho(50.0, 0.0, 35.0, 40.0, 120.0, 0.97 * h, h / 100, "observer") < 1.0
    assert one_joint_rho(50.0, 0.0, 35.0, 40.0, 120.0, 1.03 * h, h / 100, "observer") > 1.0


@pytest.mark.parametrize("delay, steps", [(0.001, 1), (0.0025, 3)])
def test_map_with_a_computation_delay_matches_the_closed_form(delay, steps):
    F = one_joint_map(delay=delay)
    report = analyse(F)
    assert report.dynamic_labels()[-1] == "latency[0][3]"     # τ(k−1) held into the period
    expected = one_joint_phi(J, D, LAM, KD, KR, H, DT, "observer", delay_steps=steps)
    np.testing.assert_allclose(report.Phi, expected, rtol=1e-6, atol=1e-8)


def test_latched_torque_is_overwritten_and_the_tick_index_is_a_counter():
    report = analyse(one_joint_map())
    assert [report.labels[i] for i in report.overwritten] == ["law[1][0]"]   # τ latched
    assert [report.labels[i] for i in report.counters] == ["law[1][1]"]      # tick index


@pytest.mark.parametrize("sampled", [False, True])
def test_the_map_is_a_fresh_simulation_from_the_state(sampled):
    # sampled output ports keep the plant's step results as abstract state: Initialize()
    # recomputes them from the written state, as a fresh simulation does
    F = one_joint_map(sampled)
    assert (F.nominal.num_abstract_states() > 0) == sampled
    x0 = F.x0
    x0[:4] = [0.01, -0.2, 0.0, 0.05]
    F(F.x0)                                 # an evaluation before must leave no trace
    sim = Simulator(F.diagram, F.diagram.CreateDefaultContext())
    F.state.set(sim.get_mutable_context(), x0)
    sim.AdvanceTo(3 * H)
    np.testing.assert_array_equal(F(x0, periods=3), F.state.get(sim.get_context()))


def test_central_differences_of_the_one_joint_loop_are_exact_over_step_sizes():
    # the map is linear: truncation error zero, only rounding (~ u |F| / ε)
    F = one_joint_map()
    report = analyse(F)
    rows = step_sensitivity(F, F.x0, report.dynamic, (1e-2, 1e-4, 1e-6))
    assert max(r[2] for r in rows) < 1e-7


@pytest.fixture(scope="module")
def paper_free():
    return analyse(operating_point(default_scenario(), "free").map)


def test_paper_loop_at_9ms_is_stable_in_free_motion(paper_free):
    assert paper_free.residual < 1e-10                  # at its equilibrium
    assert 0.85 < paper_free.rho < 0.95                 # measured 0.896
    assert paper_free.slowest.frequency_hz > 10.0       # a lightly damped oscillation


def test_free_point_leaves_out_the_locked_sliders(paper_free):
    locked = [paper_free.labels[i] for i in paper_free.locked]
    assert len(locked) == 8 and all("slider" in label for label in locked)
    assert not any("slider" in label for label in paper_free.dynamic_labels())


def test_step_size_plateau_of_the_papers_free_map(paper_free):
    F = operating_point(default_scenario(), "free").map
    report = analyse(F)
    rows = step_sensitivity(F, F.x0, report.dynamic, (1e-4, 1e-5, 1e-6))
    assert max(abs(r[1] - report.rho) for r in rows) < 1e-6


def test_paper_loop_at_9ms_is_stable_held_with_the_slow_force_mode():
    report = analyse(operating_point(default_scenario(), "held").map)
    assert report.residual < 1e-6
    assert report.rho < 1.0
    # the force integral's mode: decay k_F / (1 + ζ) ≈ 0.05 /s → |μ| ≈ 1 − 0.05 h
    assert report.slowest.time_constant == pytest.approx(1 / 0.05, rel=0.2)
    assert any("force_observer" in s for s in report.slowest.dominant)


def test_observer_loop_diverges_in_free_motion_at_25ms():
    s = default_scenario()
    s.control_period = 0.025
    assert analyse(operating_point(s, "free").map).rho > 1.5      # measured 2.18


def test_k_d_320_is_unstable_in_free_motion():
    s = default_scenario()
    s.plant.time_step = 0.003
    for robot in s.robots:
        robot.gains.k_d = 320.0
    assert analyse(operating_point(s, "free").map).rho > 2.0       # measured 5.4


def test_computation_delay_enters_the_map():
    s = default_scenario()
    base = analyse(operating_point(s, "free").map)
    for robot in s.robots:
        robot.timing.computation_delay = 0.004
    delayed = analyse(operating_point(s, "free").map)
    assert len(delayed.dynamic) == len(base.dynamic) + 2 * 3      # τ(k−1) held, per robot
    assert delayed.rho > base.rho


def test_cli_bad_grid_path_exits_2_with_one_line(tmp_path, capsys):
    code = main(["stability", "paper", "--out", str(tmp_path / "o"),
                 "--grid", "robots.*.gains.k_x=1,2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "k_x" in err[0]


def test_cli_refuses_a_folder_that_is_not_ours(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["stability", "paper", "--out", str(tmp_path)]) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_cli_writes_a_row_per_grid_point_and_operating_point(tmp_path):
    out = tmp_path / "map"
    assert main(["stability", "paper", "--out", str(out), "--quiet", "--workers", "2",
                 "--grid", "control_period=0.009,0.025"]) == 0
    import csv
    rows = list(csv.DictReader((out / "stability.csv").open()))
    assert [(r["control_period"], r["point"], r["status"]) for r in rows] == [
        ("0.009", "free", "stable"), ("0.025", "free", "unstable")]
    assert math.isclose(float(rows[0]["rho"]), 0.896, abs_tol=0.01)
    assert list(out.glob("stability_*.png"))


def test_contact_mode_is_refused_in_one_line():
    from drake_coop.scenario import ScenarioError

    s = default_scenario()
    s.plant.object_mode = "contact"
    with pytest.raises(ScenarioError, match="plant.object_mode"):
        operating_point(s, "free")


def test_overlay_matches_a_studys_per_joint_gain_to_the_grids_value(tmp_path):
    """A study's results.csv writes a ``*`` path into a per-joint list as the list
    (``K_R`` = ``"30.0 30.0 30.0"``); the map's grid sweeps the scalar 30."""
    from drake_coop.stability.output import read_outcomes

    path = tmp_path / "results.csv"
    path.write_text("robots.*.gains.k_d,robots.*.gains.K_R,status\n"
                    "10,30.0 30.0 30.0,ok\n10,30.0 60.0 30.0,diverged\n")
    assert read_outcomes(path, ["robots.*.gains.k_d", "robots.*.gains.K_R"]) == {
        ("10", "30"): "ok", ("10", "30.0 60.0 30.0"): "diverged"}


def test_cli_overlay_matching_no_grid_point_exits_2_naming_overlay(tmp_path, capsys):
    path = tmp_path / "results.csv"
    path.write_text("control_period,status\n0.005,ok\n")
    code = main(["stability", "paper", "--out", str(tmp_path / "o"), "--overlay", str(path),
                 "--grid", "control_period=0.009,0.025"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--overlay" in err[0]
    assert not (tmp_path / "o").exists()
