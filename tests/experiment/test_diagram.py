"""The controller (13) and the observers (15)-(16), (22) as Drake systems in the diagram.

* the control block reads measured joint positions only (velocities, constraint state and
  forces in the plant's context do not change the next torque sample);
* (21), evaluated with the torque the controller outputs at a sample, equals (22);
* events fire at k·h, the plant makes no spurious tiny steps (only the F/T read splits the
  step before a tick in halves), logs are at the ticks;
* no algebraic loop, state-only outputs declared as such;
* a plain NumPy loop written here from the paper's equations (docs/guide/paper.md), fed the
  logged q(k), reproduces the diagram's τ(k), q̂(k) and λ̂(k) to 1e-11 of each signal's scale.
"""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator

from drake_coop.experiment.diagram import build_experiment

from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.ticks import grasp_ticks
from drake_coop.experiment.simulate import initialize, simulate
from drake_coop.scenario import aligned_periods
from tests.conftest import advance_to_tick, short_scenario


@pytest.fixture(scope="module")
def short_run():
    """0–3 s of the compressed scenario: free motion, grasp at 1.008 s, lift."""
    scenario = short_scenario("planes", 0.003)
    return scenario, simulate(scenario, t_end=3.0)


def test_next_torque_ignores_plant_velocities_and_constraint_state():
    scenario = short_scenario("planes", 0.003)
    k_grasp, _ = grasp_ticks(scenario.task, scenario.control_period)
    # The live ground truth: its ports show that the perturbation reaches the plant's force.
    exp, sim, ctx = advance_to_tick(scenario, k_grasp + 40, live_ground_truth=True)
    plant = exp.coop.plant
    pc = plant.GetMyMutableContextFromRoot(ctx)
    # τ(k) of the tick the simulator stopped at, before its events: what the tick's update
    # latches (the tau port is state and still holds τ(k−1): comparing it would prove nothing).
    taus = [rs.controller.next_tau(rs.controller.GetMyContextFromRoot(ctx)).copy()
            for rs in exp.robots]
    forces = [rs.force_sensor.GetOutputPort("F_meas").Eval(
        rs.force_sensor.GetMyContextFromRoot(ctx)).copy() for rs in exp.robots]
    assert np.linalg.norm(forces[0]) > 1.0       # the object is squeezed at this tick
    # Change everything the controller must not see: velocities, constraint, forces.
    rng = np.random.default_rng(0)
    plant.SetVelocities(pc, rng.normal(size=plant.num_velocities()))
    exp.coop.set_held(pc, False)
    for rs, tau in zip(exp.robots, taus):
        new = rs.controller.next_tau(rs.controller.GetMyContextFromRoot(ctx))
        np.testing.assert_array_equal(new, tau)
    # ...while the plant's ground truth did change (the sensor's ports are live).
    assert not exp.coop.is_held(pc)
    changed = exp.robots[0].force_sensor.GetOutputPort("F_meas").Eval(
        exp.robots[0].force_sensor.GetMyContextFromRoot(ctx))
    assert np.linalg.norm(changed - forces[0]) > 1.0
    # The tick's update latches exactly that torque, which the plant then applies.
    sim.AdvanceTo(ctx.get_time() + scenario.plant.time_step / 2)
    for rs, tau in zip(exp.robots, taus):
        np.testing.assert_array_equal(
            rs.control.GetOutputPort("tau").Eval(rs.control.GetMyContextFromRoot(ctx)), tau)


def test_force_observer_22_equals_21_with_the_controllers_torque():
    scenario = short_scenario("planes", 0.003)
    k_grasp, _ = grasp_ticks(scenario.task, scenario.control_period)
    for k in (k_grasp + 5, k_grasp + 60):
        exp, sim, ctx = advance_to_tick(scenario, k)
        for rs in exp.robots:
            cc = rs.control.GetMyContextFromRoot(ctx)
            lam_22 = rs.control.GetOutputPort("lambda_hat").Eval(cc)[0]
            terms = rs.controller.terms(rs.controller.GetMyContextFromRoot(ctx))
            tau = terms["tau"]     # τ(k): what the tick's update latches (the port holds τ(k−1))
            q = exp.coop.arm_positions(exp.coop.plant.GetMyContextFromRoot(ctx),
                                       exp.robots.index(rs))
            lam_21 = rs.law.force_estimate_21(q, terms["qdot_r"], terms["qddot_r_hat"], tau,
                                              True)
            assert abs(lam_21 - lam_22) < 1e-9, (lam_21, lam_22)
            assert lam_22 > 0.1    # a real squeeze estimate, not a trivial zero


def test_control_block_has_no_direct_feedthrough_on_state_outputs():
    scenario = short_scenario()
    exp = build_experiment(plan_run(scenario), log=False)
    rs = exp.robots[0]
    vel, force = rs.velocity_observer, rs.force_observer
    q_in = vel.GetInputPort("q").get_index()
    qdd_in = vel.GetInputPort("qddot_r_hat").get_index()
    assert not vel.HasDirectFeedthrough(q_in, vel.GetOutputPort("q_hat").get_index())
    assert not vel.HasDirectFeedthrough(qdd_in, vel.GetOutputPort("qdot_o").get_index())
    assert vel.HasDirectFeedthrough(q_in, vel.GetOutputPort("qdot_o").get_index())
    for port in ("q", "q_hat", "qdot_o", "reference"):
        assert not force.HasDirectFeedthrough(
            force.GetInputPort(port).get_index(), force.GetOutputPort("Delta_F_tilde").get_index())


def test_events_fire_at_ticks_and_the_ft_read_without_tiny_steps():
    scenario = short_scenario("planes", 0.001)
    # The live ground truth and F/T sensor model: their reads are what this test times (the
    # offline ground truth's holds are timed by tests/plant/test_ground_truth.py).
    exp = build_experiment(plan_run(scenario), log=False, live_ground_truth=True)
    sim = Simulator(exp.diagram)
    ctx = sim.get_mutable_context()
    initialize(exp, ctx)
    times = []
    sim.set_monitor(lambda c: times.append(c.get_time()) or None)
    sim.Initialize()
    sim.AdvanceTo(0.5)
    steps = np.diff(times)
    steps = steps[steps > 0]
    # No ~1e-17 s steps from 0.009 vs 0.001: every step is one plant step (1 ms), except that
    # the ground truth's C++ hold at t_k − 1.5 ms and the F/T sensor's read at t_k − 0.5 ms
    # (each mid-way between two plant updates) split the plant's last two steps
    # before each tick into halves.
    half = np.abs(steps - 0.0005) < 0.0005 * 1e-9
    assert np.all(half | (np.abs(steps - 0.001) < 0.001 * 1e-9)), steps.min()
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    ends = np.asarray(times[1:])[np.diff(times) > 0][half]

    def at(lead):
        return ends[np.abs((ends + lead) / h - np.round((ends + lead) / h)) < 1e-9]

    holds, reads = at(1.5 * dt), at(0.5 * dt)
    # One hold and one read per tick, and only there.
    assert holds.size == reads.size == half.sum() // 4 >= 50
    np.testing.assert_allclose(reads - holds, dt, rtol=1e-9)
    # The controller latched one torque per tick: last latched tick is that of t = 0.495 s.
    ctrl = exp.robots[0].controller
    assert ctrl.latched_tick(ctrl.GetMyContextFromRoot(ctx)) == 55


def test_logs_are_sampled_at_the_ticks(short_run):
    scenario, result = short_run
    t = result.logs["robot1"]["t"]
    k = np.arange(t.size)
    np.testing.assert_allclose(t, k * scenario.control_period, rtol=0, atol=1e-12)
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    np.testing.assert_array_equal(t, k * h)   # exactly the event times


# ------------------------------------------------------------------------ replay
def _dynamics_plant(robot):
    """A fresh single-arm plant for H, C, g (independent of drake_coop.control.arm_model)."""
    from drake_coop.plant.arms import Arm

    arm = Arm(robot)
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(arm.urdf_path))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"),
                     RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base))
    plant.Finalize()
    return arm, plant, plant.CreateDefaultContext()


def _replay(scenario, index, q_log):
    """Equations (4), (8), (11), (13), (15)-(16), (22) as a plain loop (docs/guide/paper.md)."""
    robot = scenario.robots[index]
    g = robot.gains
    h = scenario.control_period
    arm, plant, pc = _dynamics_plant(robot)
    D = np.diag([plant.get_joint(j).default_damping() for j in plant.GetJointIndices()
                 if plant.get_joint(j).num_velocities() == 1])
    Lam, KR, kd, kF, xi, zeta, beta = (g.Lambda, np.diag(g.K_R), g.k_d, g.k_F, g.xi, g.zeta,
                                       g.beta)
    _, ref = plan_run(scenario).robots[index].samples
    q_hat = q_log[0].copy()
    qdot_hat_o = np.zeros(3)
    DF = 0.0
    out = {"tau": [], "q_hat": [], "lambda_hat": []}
    for k, q in enumerate(q_log):
        q_d, qdot_d, qddot_d, lam_d, held = ref[k, 0:3], ref[k, 3:6], ref[k, 6:9], ref[k, 9], \
            ref[k, 10] > 0.5
        z = q - q_hat
        qdot_hat = qdot_hat_o + Lam * z + kd * z              # (15)
        qdot_o = qdot_hat - Lam * z                           # (8)
        if held:
            J = arm.s * arm.jacobian(q)[0]                    # J_φ, 1×3 as a vector
            phi = arm.s * (arm.fk(q)[0] - arm.b)
            nJ = J @ J
            Jp = J / nJ                                       # J⁺ for m = 1
            Q = np.eye(3) - np.outer(Jp, J)
            qdot_r = Q @ (qdot_d - Lam * (q_hat - q_d)) + Jp * (-beta * phi + xi * DF)   # (4)
            lam_hat = ((Jp @ KR @ (qdot_o - qdot_r)) - kF * DF) / (1 + zeta) + lam_d     # (22)
            dlt = lam_hat - lam_d
            Jd = arm.s * arm.jacobian_dot(q, qdot_o)[0]       # J̇_φ along q̇_o
            Jpd = Jd / nJ - J * 2 * (Jd @ J) / nJ ** 2
            Qd = -(np.outer(Jpd, J) + np.outer(Jp, Jd))
            qddot_r = (Q @ (qddot_d - Lam * (qdot_hat - qdot_d)) + Jp * (xi * dlt)
                       + Qd @ (qdot_d - Lam * (q_hat - q_d)) + Jpd * (-beta * phi + xi * DF))  # (11)
            force_term = J * (lam_d - kF * DF - zeta * dlt)
        else:
            qdot_r = qdot_d - Lam * (q_hat - q_d)
            qddot_r = qddot_d - Lam * (qdot_hat - qdot_d)
            lam_hat, force_term = 0.0, np.zeros(3)
        plant.SetPositions(pc, q)
        plant.SetVelocities(pc, qdot_r)
        H = plant.CalcMassMatrix(pc)
        Cv = plant.CalcBiasTerm(pc)
        grav = -plant.CalcGravityGeneralizedForces(pc)
        tau = H @ qddot_r + Cv + D @ qdot_r + grav - KR @ (qdot_o - qdot_r) - force_term  # (13)
        out["tau"].append(tau)
        out["q_hat"].append(q_hat.copy())
        out["lambda_hat"].append(lam_hat)
        # Forward-Euler updates of (15), (16) and (6).
        q_hat = q_hat + h * qdot_hat
        qdot_hat_o = qdot_hat_o + h * (qddot_r + kd * Lam * z)
        DF = DF + h * (lam_hat - lam_d) if held else 0.0
    return {k: np.array(v) for k, v in out.items()}


@pytest.mark.parametrize("index", [0, 1], ids=["robot1", "robot2"])
def test_numpy_replay_reproduces_logged_torque_and_estimates(short_run, index):
    scenario, result = short_run
    log = result.logs[scenario.robots[index].name]
    replay = _replay(scenario, index, log["q"])
    held = plan_run(scenario).robots[index].samples[1][: log["t"].size, 10] > 0.5
    assert held.sum() > 100 and (~held).sum() > 100      # both forms are exercised
    # 1e-11 of each signal's largest magnitude: the replay and the systems are the same
    # equations in other operation orders (closed form vs Drake, NumPy vs plain floats), which
    # differ by a few hundred roundings at most (measured ~2e-13 of the scale).
    for key in ("q_hat", "lambda_hat", "tau"):
        scale = np.abs(log[key]).max()
        np.testing.assert_allclose(replay[key], log[key], rtol=0, atol=1e-11 * scale,
                                   err_msg=key)


def _interrupted_at(scenario, t_stop):
    """The run interrupted (KeyboardInterrupt from a monitor) after the step reaching t_stop."""

    def on_start(exp, simulator):
        def monitor(context):
            if context.get_time() >= t_stop - 1e-12:
                raise KeyboardInterrupt
        simulator.set_monitor(monitor)

    return simulate(scenario, t_end=3.0, on_start=on_start)


@pytest.mark.parametrize("offset_steps, rows", [(4, 0), (0, -1)],
                         ids=["off_a_tick", "before_a_ticks_updates"])
def test_logs_of_a_run_stopped_early_end_at_the_last_latched_tick(offset_steps, rows):
    """Stopped 4 plant steps after tick k (its updates ran): the logs keep tick k, whose
    torque comes from the latched port. Stopped at tick k itself, before its updates: the logs
    end at tick k − 1. Either way every logged torque is the law at its logged q (replay)."""
    scenario = short_scenario("planes", 0.001)
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    k = 150                                        # held from k_grasp = 112
    result = _interrupted_at(scenario, k * h + offset_steps * dt)
    assert result.meta["status"] == "interrupted"
    log = result.logs["robot1"]
    assert log["t"].size == k + 1 + rows
    np.testing.assert_array_equal(log["t"], np.arange(k + 1 + rows) * h)
    replay = _replay(scenario, 0, log["q"])
    scale = np.abs(log["tau"]).max()
    np.testing.assert_allclose(replay["tau"], log["tau"], rtol=0, atol=1e-11 * scale)
    assert all(v.shape[0] == log["t"].size for v in log.values())


def test_the_block_diagram_of_every_source_combination_is_labelled():
    """Each registered velocity source with each registered force source (two robots a
    diagram): every block drawn has its own label (none falls back to its system's name), and
    each source's box reads its registry entry's label and role (the momentum observer had
    none)."""
    import itertools
    import re

    from drake_coop.control.registry import SOURCES
    from drake_coop.results.block_diagram import BLOCK_LABELS, paper_block_diagram
    from drake_coop.scenario import default_scenario

    velocity = [s for s in SOURCES if s.kind == "velocity"]
    force = [s for s in SOURCES if s.kind == "force"]
    pairs = list(itertools.product(velocity, force))
    seen = set()
    for k in range(0, len(pairs), 2):
        scenario = default_scenario()
        chosen = pairs[k:k + 2] + pairs[:max(0, k + 2 - len(pairs))]
        for robot, (v, f) in zip(scenario.robots, chosen):
            robot.velocity_source, robot.force_source = v.name, f.name
        exp = build_experiment(plan_run(scenario), log=False)
        dot = paper_block_diagram(exp.diagram)
        labels = {}
        for label in re.findall(r"\[label=<(.*)>, fillcolor", dot):
            title = re.search(r"<B>(.*?)</B>", label).group(1)
            role = re.search(r"</B><BR/>(.*?)<BR/><FONT", label)
            system = re.search(r'COLOR="#667788">(.*?)</FONT>', label).group(1)
            labels[system] = (title, re.sub(r"<[^>]+>", "", role.group(1)) if role else "")
            assert title != system, f"{system} has no label in the block diagram"
        for robot, (v, f) in zip(scenario.robots, chosen):
            for spec in (v, f):
                system = f"{robot.name}_{spec.suffix}"
                assert labels[system][0] == spec.label
                assert labels[system][1] == spec.role.replace("λ_d", "λd")
                assert BLOCK_LABELS[spec.class_name][:2] == (spec.label, spec.role)
            seen.add((v.name, f.name))
    assert seen == {(v.name, f.name) for v, f in pairs}
