"""The cooperative plant: constraint modes, ground-truth force sensing against the statics of
(1), the sign convention of λ, and switching the grasp on and off.

Torques come from a small test controller (:class:`TorqueSource`): gravity compensation ``g(q)``
from the arm's own model at the current measured ``q``, a constant push ``−J_φ(q)ᵀ f``, optional
joint damping, an optional feedforward ``−Jᵀ w`` for the object's weight and an optional
joint-space PD. At rest, (1) gives ``τ + J_φᵀ λ = g``, i.e. ``λ = J⁺ᵀ (g(q) − τ)`` with
``J⁺ = J_φᵀ / (J_φ J_φᵀ)``: the force sensor must measure that.
"""

from dataclasses import dataclass

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem

from drake_coop.control.arm_model import ArmModel
from drake_coop.plant.arms import arm_model
from drake_coop.scenario.task_path import cartesian_reference, waypoints
from drake_coop.plant.arms import Arm
from drake_coop.experiment.plan import plan_run
from drake_coop.plant.cooperative import (
    CoopPlant,
    build_plant,
    initialize_plant_context,
)
from drake_coop.plant.wrist import ForceSensor, add_force_sensors
from drake_coop.scenario import Task, default_scenario

SQUEEZE = 20.0          # N, the push of the static tests
GAP = 0.8192 - 0.6      # m, b_2 − b_1: the width of the object


class TorqueSource(LeafSystem):
    """``τ = g(q) − J_φ(q)ᵀ f − J(q)ᵀ w − d v + kp (q_ref(t) − q) − kd v``.

    ``w = (0, 0, −carry)`` is the force the held object's weight puts on the end effector
    (``carry`` = this arm's share, N); the PD is on only when ``q_ref`` is given.
    """

    def __init__(self, model: ArmModel, f: float, carry: float = 0.0, damping: float = 0.0,
                 q_ref=None, kp: float = 0.0, kd: float = 0.0):
        super().__init__()
        self.model, self.f, self.damping = model, f, damping
        self.q_ref, self.kp, self.kd = q_ref, kp, kd
        self.w = np.array([0.0, 0.0, -carry])
        self.DeclareVectorInputPort("state", 6)
        self.DeclareVectorOutputPort("tau", 3, self._calc)

    def tau(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        model = self.model
        tau = (model.g(q) - model.J_phi(q)[0] * self.f - model.kinematics.jacobian(q).T @ self.w
               - self.damping * v)
        if self.q_ref is not None:
            tau += self.kp * (self.q_ref(t) - q) - self.kd * v
        return tau

    def _calc(self, context: Context, out) -> None:
        x = self.get_input_port().Eval(context)
        out.SetFromVector(self.tau(x[:3], x[3:], context.get_time()))


@dataclass
class Rig:
    """A simulated cooperative plant with force sensors and one TorqueSource per arm."""

    coop: CoopPlant
    sensors: list[ForceSensor]
    ctrls: list[TorqueSource]
    sim: Simulator
    context: Context          # the diagram's
    pc: Context               # the plant's

    def measured(self, i: int) -> tuple[np.ndarray, float]:
        """``F_meas`` and ``lambda_meas`` of arm i."""
        sc = self.sensors[i].GetMyContextFromRoot(self.context)
        return (self.sensors[i].GetOutputPort("F_meas").Eval(sc).copy(),
                float(self.sensors[i].GetOutputPort("lambda_meas").Eval(sc)[0]))

    def tau(self, i: int) -> np.ndarray:
        """The torque the test controller applies to arm i now."""
        q = self.coop.arm_positions(self.pc, i)
        v = self.coop.plant.GetVelocities(self.pc, self.coop.arms[i].instance)
        return self.ctrls[i].tau(q, v, self.context.get_time())

    def static_lambda(self, i: int) -> float:
        """``λ = J⁺ᵀ (g(q) − τ)`` at the current q: the statics of (1) along the constraint."""
        q = self.coop.arm_positions(self.pc, i)
        model = self.ctrls[i].model
        J_phi = model.J_phi(q)                                   # 1×3
        J_pinv = J_phi.T / (J_phi @ J_phi.T)[0, 0]               # 3×1
        return float((J_pinv.T @ (model.g(q) - self.tau(i)))[0])

    def static_force(self, i: int) -> np.ndarray:
        """``F = J⁻ᵀ (g(q) − τ)``: the whole Cartesian force at rest, from ``τ + Jᵀ F = g``."""
        q = self.coop.arm_positions(self.pc, i)
        model = self.ctrls[i].model
        return np.linalg.solve(model.kinematics.jacobian(q).T, model.g(q) - self.tau(i))


def build(mode: str, f: float, carry: float = 0.0, damping: float = 0.0, held: bool = True,
          time_step: float = 0.003, q_refs=None, kp: float = 0.0, kd: float = 0.0) -> Rig:
    """Both arms at rest at their grasp postures, the grasp on (``held``), the test controller
    pushing with ``f``."""
    s = default_scenario()
    s.plant.object_mode = mode
    s.plant.time_step = time_step
    builder = DiagramBuilder()
    coop = build_plant(builder, plan_run(s))
    sensors = add_force_sensors(builder, coop)
    ctrls = []
    for i, h in enumerate(coop.arms):
        ctrl = builder.AddSystem(TorqueSource(
            arm_model(h.arm), f, carry, damping, None if q_refs is None else q_refs[i], kp, kd))
        builder.Connect(coop.plant.get_state_output_port(h.instance), ctrl.get_input_port())
        builder.Connect(ctrl.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
        ctrls.append(ctrl)
    sim = Simulator(builder.Build())
    context = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(context)
    grasp = [waypoints(s.task, robot)["grasp"] for robot in s.robots]
    q0 = [h.arm.ik(grasp[i]) for i, h in enumerate(coop.arms)]
    initialize_plant_context(coop, pc, q0, z_grasp=grasp[0][2])
    coop.set_held(pc, held)
    sim.Initialize()
    return Rig(coop, sensors, ctrls, sim, context, pc)


def object_weight(share: float = 0.5) -> float:
    """``share`` of the rigid object's weight (N)."""
    s = default_scenario()
    return share * s.plant.object_mass * 9.81      # Drake's default gravity


# ---------------------------------------------------------------------------- planes mode
@pytest.fixture(scope="module")
def planes_at_rest() -> Rig:
    rig = build("planes", f=SQUEEZE)
    rig.sim.AdvanceTo(1.0)
    return rig


def test_planes_mode_holds_each_end_effector_on_its_plane(planes_at_rest):
    rig = planes_at_rest
    for i, h in enumerate(rig.coop.arms):
        error = rig.coop.ee_position(rig.pc, i)[0] - h.arm.b
        assert abs(error) < 0.05e-3, f"{h.arm.name}: {error * 1e3:.4f} mm off the plane"


def test_planes_mode_measured_force_equals_the_statics_of_equation_1(planes_at_rest):
    rig = planes_at_rest
    for i in range(2):
        _, lam = rig.measured(i)
        expected = rig.static_lambda(i)
        assert expected == pytest.approx(SQUEEZE, rel=1e-9)     # the model is exact
        assert lam == pytest.approx(expected, rel=5e-3)


def test_planes_mode_force_is_along_the_plane_normal(planes_at_rest):
    rig = planes_at_rest
    for i in range(2):
        F, _ = rig.measured(i)
        assert abs(F[1]) < 0.01 * abs(F[0]) and abs(F[2]) < 0.01 * abs(F[0]), F


# ----------------------------------------------------------------------------- rigid mode
def test_rigid_mode_measured_force_equals_the_statics_and_each_arm_carries_half_the_weight():
    half = object_weight(0.5)
    rig = build("rigid", f=SQUEEZE, carry=half)
    rig.sim.AdvanceTo(1.0)
    for i in range(2):
        F, lam = rig.measured(i)
        F_expected = rig.static_force(i)
        np.testing.assert_allclose(F_expected, rig.coop.arms[i].arm.normal * SQUEEZE
                                   + [0.0, 0.0, -half], atol=1e-9)
        np.testing.assert_allclose(F, F_expected, atol=5e-3 * SQUEEZE)
        assert lam == pytest.approx(rig.coop.arms[i].arm.normal @ F_expected, rel=5e-3)
        assert F[2] == pytest.approx(-half, rel=1e-2)


def test_rigid_mode_keeps_the_contact_faces_apart_around_the_circle():
    s = default_scenario()
    # Lift over 1 s, then the circle (28) over 4 s; the test starts at the grasp (t_grasp).
    task = Task(t_pregrasp=0.5, t_grasp=1.0, t_circle_start=2.0, t_circle_end=6.0,
                t_release=7.0, t_end=8.0)

    def q_ref(robot):
        arm = Arm(robot)
        return lambda t: arm.ik(cartesian_reference(task, robot, [task.t_grasp + t])[0][0])

    rig = build("rigid", f=SQUEEZE, carry=object_weight(0.5),
                q_refs=[q_ref(r) for r in s.robots], kp=400.0, kd=40.0)
    gaps, offsets, ys, zs = [], [], [], []
    for k in range(1, 111):
        rig.sim.AdvanceTo(0.05 * k)
        p1, p2 = rig.coop.ee_position(rig.pc, 0), rig.coop.ee_position(rig.pc, 1)
        gaps.append(p2[0] - p1[0])
        offsets.append(np.abs(p2[1:] - p1[1:]).max())
        ys.append(p1[1])
        zs.append(p1[2])
    # The object really went up and round ...
    assert max(ys) > 0.045 and min(ys) < -0.045 and max(zs) > 0.63 and min(zs) < 0.54
    # ... and stayed one rigid body between the two end-effector points.
    np.testing.assert_allclose(gaps, GAP, atol=1e-4)
    assert max(offsets) < 1e-4


# ----------------------------------------------------------------------------------- sign
def test_positive_squeeze_is_compressive_on_both_robots():
    f = 15.0
    rig = build("planes", f=f)
    rig.sim.AdvanceTo(0.5)
    (F1, lam1), (F2, lam2) = rig.measured(0), rig.measured(1)
    assert lam1 == pytest.approx(f, rel=1e-2) and lam2 == pytest.approx(f, rel=1e-2)
    # The object pushes robot 1 towards −x and robot 2 towards +x.
    assert F1[0] < 0 < F2[0]


def test_negative_squeeze_pulls_on_both_robots():
    f = -15.0
    rig = build("planes", f=f)
    rig.sim.AdvanceTo(0.5)
    (F1, lam1), (F2, lam2) = rig.measured(0), rig.measured(1)
    assert lam1 == pytest.approx(f, rel=1e-2) and lam2 == pytest.approx(f, rel=1e-2)
    assert F2[0] < 0 < F1[0]


# --------------------------------------------------------------------------- grasp switch
def test_releasing_the_grasp_lets_the_push_cross_the_plane():
    rig = build("planes", f=5.0, held=True)
    rig.sim.AdvanceTo(0.2)
    assert rig.coop.is_held(rig.pc)
    x_held = [rig.coop.ee_position(rig.pc, i)[0] for i in range(2)]
    rig.coop.set_held(rig.pc, False)
    rig.sim.AdvanceTo(0.5)
    assert not rig.coop.is_held(rig.pc)
    x = [rig.coop.ee_position(rig.pc, i)[0] for i in range(2)]
    b = [h.arm.b for h in rig.coop.arms]
    assert abs(x_held[0] - b[0]) < 0.05e-3 and abs(x_held[1] - b[1]) < 0.05e-3
    assert x[0] - b[0] > 1e-3          # robot 1 pushes towards +x, now through its plane
    assert x[1] - b[1] < -1e-3         # robot 2 towards −x


# ------------------------------------------------------------------------------ none mode
def test_none_mode_has_no_constraints():
    rig = build("none", f=0.0)
    assert rig.coop.constraint_ids == [] and rig.coop.slider_joints == []
    assert not rig.coop.is_held(rig.pc)


def test_none_mode_measures_no_force_on_an_arm_at_rest():
    rig = build("none", f=0.0, damping=1.0)
    rig.sim.AdvanceTo(0.5)
    for i in range(2):
        v = rig.coop.plant.GetVelocities(rig.pc, rig.coop.arms[i].instance)
        assert np.abs(v).max() < 1e-9                      # gravity compensation holds it
        F, lam = rig.measured(i)
        assert np.abs(F).max() < 1e-6 and abs(lam) < 1e-6, F


def test_wrist_dynamics_ground_truth_equals_the_reaction_force_chain():
    """planes mode: the force from each arm's own equations of motion and the plant's
    acceleration port (``WristDynamics``, SAP's implicit damping) equals Newton's law on the
    carried bodies from Drake's reaction forces (``WristKinematics``), at every plant step of
    free motion, the grasp and the lift. On the live path (``live_ground_truth=True``): the
    offline path evaluates the same equation (``ArmForces``) from held data and is checked
    against the live one in ``tests/plant/test_ground_truth.py``."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.plant.wrist import WristKinematics
    from drake_coop.plant.wrist_dynamics import WristDynamics
    from tests.conftest import short_scenario

    scenario = short_scenario("planes", 0.001)
    pairs = []

    def before_build(builder, coop):
        kin = builder.AddSystem(WristKinematics(coop.plant, coop.arms))
        for name in ("reaction_forces", "body_poses", "body_spatial_velocities",
                     "body_spatial_accelerations"):
            builder.Connect(coop.plant.GetOutputPort(name), kin.GetInputPort(name))
        for h in coop.arms:
            sensor = builder.AddSystem(ForceSensor(coop.plant, h))
            builder.Connect(kin.GetOutputPort(f"{h.arm.name}_wrist"),
                            sensor.GetInputPort("wrist"))
            pairs.append((h.arm.name, sensor))

    diffs, peak = [], [0.0]

    def on_start(exp, simulator):
        assert isinstance(exp.diagram.GetSubsystemByName("wrist_dynamics"), WristDynamics)
        live = {rs.name: rs.force_sensor for rs in exp.robots}

        def compare(context):
            for name, reference in pairs:
                a = live[name].GetOutputPort("F_meas").Eval(
                    live[name].GetMyContextFromRoot(context))
                b = reference.GetOutputPort("F_meas").Eval(
                    reference.GetMyContextFromRoot(context))
                diffs.append(np.abs(a - b).max())
                peak[0] = max(peak[0], np.abs(b).max())
        simulator.set_monitor(compare)

    result = simulate(scenario, t_end=1.5, before_build=before_build, on_start=on_start,
                      live_ground_truth=True)
    assert result.ok
    assert peak[0] > 10.0                  # the grasp's squeeze is in the comparison
    assert max(diffs) < 1e-9, max(diffs)   # N (measured ~5e-13)
