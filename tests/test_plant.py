"""The cooperative plant: constraint modes, force sensing against the statics of (1), sign.

Torques come from a small test controller: gravity compensation ``g(q)`` from the arm's model,
a squeeze ``−J_φ(q)ᵀ f`` and, for the rigid object, each arm's share of its weight. At rest, (1)
gives ``τ + J_φᵀ λ = g``, i.e. ``λ = J⁺ᵀ (g(q) − τ)``: the measured force must equal that.
"""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from drake_coop import orthogonal
from drake_coop.arm_model import ArmModel
from drake_coop.plant import add_force_sensors, build_plant, initialize_plant_context
from drake_coop.references import cartesian_reference, waypoints
from drake_coop.scenario import Task, default_scenario

G = 9.81


class TorqueSource(LeafSystem):
    """τ = g(q) − J_φᵀ f − Jᵀ w + PD, with an optional PD: in joint space to ``q_ref(t)``, or
    in Cartesian space to ``x_ref(t)`` along y and z only (tangent to the contact)."""

    def __init__(self, model, f, carry=0.0, q_ref=None, kp=0.0, kd=0.0, x_ref=None):
        super().__init__()
        self.model, self.f, self.q_ref, self.kp, self.kd = model, f, q_ref, kp, kd
        self.x_ref = x_ref
        self.w = np.array([0.0, 0.0, -carry])
        self.DeclareVectorInputPort("state", 6)
        self.DeclareVectorOutputPort("tau", 3, self._calc)

    def tau(self, q, v, t):
        J = self.model.arm.jacobian(q)
        tau = self.model.g(q) - self.model.J_phi(q)[0] * self.f - J.T @ self.w
        if self.q_ref is not None:
            tau += self.kp * (self.q_ref(t) - q) - self.kd * v
        if self.x_ref is not None:
            F = self.kp * (self.x_ref(t) - self.model.arm.fk(q)) - self.kd * (J @ v)
            F[0] = 0.0
            tau += J.T @ F
        return tau

    def _calc(self, context, out):
        x = self.get_input_port().Eval(context)
        out.SetFromVector(self.tau(x[:3], x[3:], context.get_time()))


def build(mode, f, carry=0.0, time_step=0.003, held=True, q_refs=None, kp=0.0, kd=0.0,
          x_refs=None):
    s = default_scenario()
    s.plant.object_mode = mode
    s.plant.time_step = time_step
    b = DiagramBuilder()
    coop = build_plant(b, s)
    sensors = add_force_sensors(b, coop)
    ctrls = []
    for i, h in enumerate(coop.arms):
        ctrl = b.AddSystem(TorqueSource(ArmModel(h.arm), f, carry,
                                        None if q_refs is None else q_refs[i], kp, kd,
                                        None if x_refs is None else x_refs[i]))
        b.Connect(coop.plant.get_state_output_port(h.instance), ctrl.get_input_port())
        b.Connect(ctrl.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
        ctrls.append(ctrl)
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    q0 = [h.arm.ik(waypoints(s.task, s.robots[i])["grasp"]) for i, h in enumerate(coop.arms)]
    initialize_plant_context(coop, pc, q0, 0.535)
    coop.set_held(pc, held)
    sim.Initialize()
    return s, coop, sensors, ctrls, sim, ctx, pc


def measured(sensors, ctx, i):
    sc = sensors[i].GetMyContextFromRoot(ctx)
    return (sensors[i].GetOutputPort("F_meas").Eval(sc).copy(),
            float(sensors[i].GetOutputPort("lambda_meas").Eval(sc)[0]))


def static_expectation(coop, ctrls, pc, i):
    """The force at rest from the statics of (1), ``τ + Jᵀ F = g``: F and λ = n·F.

    With only the constraint force acting, ``J_φᵀ λ = g − τ`` and ``λ = J⁺ᵀ (g − τ)``.
    """
    q = coop.arm_positions(pc, i)
    model = ctrls[i].model
    tau = ctrls[i].tau(q, np.zeros(3), 0.0)
    F = np.linalg.solve(model.arm.jacobian(q).T, model.g(q) - tau)
    return F, float(coop.arms[i].arm.normal @ F)


def test_planes_mode_holds_each_end_effector_on_its_plane_and_measures_the_push():
    s, coop, sensors, ctrls, sim, ctx, pc = build("planes", f=20.0)
    sim.AdvanceTo(1.0)
    for i, h in enumerate(coop.arms):
        x = coop.ee_position(pc, i)
        assert abs(x[0] - h.arm.b) < 0.05e-3, x[0] - h.arm.b            # within 0.05 mm
        F, lam = measured(sensors, ctx, i)
        _, expected = static_expectation(coop, ctrls, pc, i)
        assert lam == pytest.approx(expected, rel=5e-3)
        q = coop.arm_positions(pc, i)
        J_pinv, _ = orthogonal.projections(ctrls[i].model.J_phi(q))
        tau = ctrls[i].tau(q, np.zeros(3), 0.0)
        assert lam == pytest.approx(float((J_pinv.T @ (ctrls[i].model.g(q) - tau))[0]),
                                    rel=5e-3)
        assert abs(F[1]) < 0.01 * abs(F[0]) and abs(F[2]) < 0.01 * abs(F[0])


def test_rigid_mode_static_squeeze_and_shared_weight():
    m = default_scenario().plant.object_mass
    s, coop, sensors, ctrls, sim, ctx, pc = build("rigid", f=20.0, carry=0.5 * m * G)
    sim.AdvanceTo(1.0)
    for i in range(2):
        F, lam = measured(sensors, ctx, i)
        F_expected, lam_expected = static_expectation(coop, ctrls, pc, i)
        assert lam == pytest.approx(lam_expected, rel=5e-3)
        np.testing.assert_allclose(F, F_expected, rtol=0, atol=5e-3 * 20.0)
        assert lam == pytest.approx(20.0, rel=5e-3)
        assert F[2] == pytest.approx(-0.5 * m * G, rel=2e-2)     # half the weight each


def test_rigid_mode_keeps_the_contact_faces_apart_around_the_circle():
    s = default_scenario()
    task = Task(t_pregrasp=0.1, t_grasp=0.2, t_circle_start=0.5, t_circle_end=4.5,
                t_release=5.5, t_end=6.0, lift_height=0.1)
    from drake_coop.arms import Arm

    def q_ref(i):
        arm = Arm(s.robots[i])
        return lambda t: arm.ik(cartesian_reference(task, s.robots[i], [t])[0][0])

    m = s.plant.object_mass
    s_, coop, sensors, ctrls, sim, ctx, pc = build(
        "rigid", f=20.0, carry=0.5 * m * G, q_refs=[q_ref(0), q_ref(1)], kp=400.0, kd=40.0)
    gaps, offsets, ys = [], [], []
    for k in range(1, 101):
        sim.AdvanceTo(0.05 * k)
        p1, p2 = coop.ee_position(pc, 0), coop.ee_position(pc, 1)
        ys.append(p1[1])
        gaps.append(p2[0] - p1[0])
        offsets.append(np.abs(p2[1:] - p1[1:]).max())
    # The object really went round and stayed one rigid body.
    assert max(abs(y) for y in ys) > 0.045
    np.testing.assert_allclose(gaps, 0.2192, atol=1e-4)
    assert max(offsets) < 1e-4


def test_positive_squeeze_is_compressive_on_both_sides_and_negative_pulls():
    for f in (15.0, -15.0):
        s, coop, sensors, ctrls, sim, ctx, pc = build("planes", f=f)
        sim.AdvanceTo(0.5)
        (F1, lam1), (F2, lam2) = measured(sensors, ctx, 0), measured(sensors, ctx, 1)
        assert lam1 == pytest.approx(f, rel=1e-2) and lam2 == pytest.approx(f, rel=1e-2)
        if f > 0:   # the object pushes robot 1 towards −x and robot 2 towards +x
            assert F1[0] < 0 < F2[0]
        else:
            assert F2[0] < 0 < F1[0]


def test_releasing_the_grasp_lets_the_push_cross_the_plane():
    s, coop, sensors, ctrls, sim, ctx, pc = build("planes", f=5.0, held=False)
    sim.AdvanceTo(0.3)
    assert not coop.is_held(pc)
    assert coop.ee_position(pc, 0)[0] - coop.arms[0].arm.b > 1e-3     # robot 1 pushed to +x
    assert coop.ee_position(pc, 1)[0] - coop.arms[1].arm.b < -1e-3


def test_none_mode_has_no_constraint_and_no_measured_force():
    s, coop, sensors, ctrls, sim, ctx, pc = build("none", f=0.0)
    assert coop.constraint_ids == []
    sim.AdvanceTo(0.5)
    for i in range(2):
        F, lam = measured(sensors, ctx, i)
        assert np.abs(F).max() < 1e-6
