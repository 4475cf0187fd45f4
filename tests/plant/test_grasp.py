"""The ``contact`` object mode of the plant: a box held only by friction at two hydroelastic pads.

A simple position/force controller written here (not the paper's controller; it reads the true
joint velocities): Cartesian PD on the tangent directions y and z, gravity compensation
``g(q)``, a squeeze ``−J_φᵀ f`` along the object's normal and a feedforward for half the box's
weight per arm. The box must stay in the grasp while it is lifted 0.1 m, carried once around the
circle (28) and held.

Slip is the box centre's displacement relative to the midpoint of the end-effector points (the
pads' centres) since the grasp, net of rolling: the pads are spheres fixed to links whose
orientation changes along the path, so a box that sticks to them rolls with them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem

from drake_coop.control.arm_model import ArmModel
from drake_coop.plant.arms import arm_model
from drake_coop.scenario.task_path import cartesian_reference, quintic, waypoints
from drake_coop.experiment.plan import plan_run
from drake_coop.plant.cooperative import (
    CoopPlant,
    build_plant,
    initialize_plant_context,
)
from drake_coop.plant.wrist import add_force_sensors
from drake_coop.scenario import Robot, Task, default_scenario

G = 9.81
SQUEEZE = 32.0        # N, the paper's mean squeeze
TIME_STEP = 0.003     # s
T_RAMP = 1.0          # squeeze (and carry feed-forward) ramp, s
# Shortened task: squeeze [0, 1] s, settle, lift [1.5, 3.5] s, circle [3.5, 11.5] s, hold.
TASK = Task(t_pregrasp=0.5, t_grasp=1.5, t_circle_start=3.5, t_circle_end=11.5,
            t_release=13.5, t_end=15.0)
T_HOLD_END = TASK.t_circle_end + 1.0


def _ramp(t: float) -> float:
    """0 → 1 over ``[0, T_RAMP]`` with the quintic time scaling."""
    return float(quintic(np.array([t / T_RAMP]))[0][0])


class GraspController(LeafSystem):
    """τ = g(q) − J_φᵀ f(t) − Jᵀ w(t) + Jᵀ F_PD, with F_PD = K_p (x_r − x) − K_d ẋ on y, z only.

    ``f(t) = SQUEEZE · ramp(t)`` and ``w = (0, 0, −½ m g) · ramp(t)``: with the PD acting only
    along y and z, the end effector pushes the object with exactly ``f`` along its normal at
    rest.

    Input port ``state`` (the arm's ``[q, v]``), output port ``tau``.
    """

    def __init__(self, model: ArmModel, x_ref, carry: float, squeeze: float = SQUEEZE,
                 kp: float = 3000.0, kd: float = 300.0):
        super().__init__()
        self.model, self.x_ref, self.squeeze, self.kp, self.kd = model, x_ref, squeeze, kp, kd
        self.w = np.array([0.0, 0.0, -carry])
        self.DeclareVectorInputPort("state", 6)
        self.DeclareVectorOutputPort("tau", 3, self._calc)

    def tau(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        arm = self.model.kinematics
        J = arm.jacobian(q)
        s = _ramp(t)
        F = self.kp * (self.x_ref(t) - arm.fk(q)) - self.kd * (J @ v)
        F[0] = 0.0
        F -= s * self.w
        return self.model.g(q) - self.model.J_phi(q)[0] * (s * self.squeeze) + J.T @ F

    def _calc(self, context: Context, out) -> None:
        x = self.get_input_port().Eval(context)
        out.SetFromVector(self.tau(x[:3], x[3:], context.get_time()))


def x_reference(task: Task, robot: Robot):
    """Grasp point until ``t_grasp``, lift and circle (28), then hold at the circle's start."""
    w = waypoints(task, robot)

    def x_ref(t: float) -> np.ndarray:
        if t <= task.t_grasp:
            return w["grasp"]
        if t >= task.t_circle_end:
            return w["circle_start"]
        return cartesian_reference(task, robot, [t])[0][0]
    return x_ref


@dataclass
class Rig:
    coop: CoopPlant
    sensors: list
    controllers: list
    simulator: Simulator
    context: Context
    plant_context: Context

    def box_pose(self):
        return self.coop.plant.EvalBodyPoseInWorld(self.plant_context, self.coop.object_body)

    def contact_results(self):
        return self.coop.plant.get_contact_results_output_port().Eval(self.plant_context)

    def measured_lambda(self, i: int) -> float:
        s = self.sensors[i]
        return float(s.GetOutputPort("lambda_meas").Eval(s.GetMyContextFromRoot(self.context))[0])

    def measured_force(self, i: int) -> np.ndarray:
        s = self.sensors[i]
        return s.GetOutputPort("F_meas").Eval(s.GetMyContextFromRoot(self.context)).copy()

    def contact_lambda(self, i: int) -> float:
        """The box's force on pad i from the contact results, along the outward normal."""
        grasp = self.coop.grasp
        F = grasp.pad_force(self.contact_results(), grasp.pad_geometries[i])
        return float(self.coop.arms[i].arm.normal @ F)


def build_rig(task: Task, at: str = "grasp", squeeze: float = SQUEEZE,
              time_step: float = TIME_STEP) -> Rig:
    scenario = default_scenario()
    scenario.plant.object_mode = "contact"
    scenario.plant.time_step = time_step
    scenario.task = task
    builder = DiagramBuilder()
    coop = build_plant(builder, plan_run(scenario))
    sensors = add_force_sensors(builder, coop)
    carry = 0.5 * scenario.plant.object_mass * G if squeeze > 0 else 0.0
    controllers = []
    for i, h in enumerate(coop.arms):
        robot = scenario.robots[i]
        x_ref = x_reference(task, robot) if at == "grasp" else (
            lambda t, p=waypoints(task, robot)[at]: p)
        ctrl = builder.AddSystem(GraspController(arm_model(h.arm), x_ref, carry, squeeze))
        builder.Connect(coop.plant.get_state_output_port(h.instance), ctrl.get_input_port())
        builder.Connect(ctrl.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
        controllers.append(ctrl)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(context)
    q0 = [h.arm.ik(waypoints(task, scenario.robots[i])[at]) for i, h in enumerate(coop.arms)]
    initialize_plant_context(coop, pc, q0, task.circle_top_z - task.lift_height)
    simulator.Initialize()
    return Rig(coop, sensors, controllers, simulator, context, pc)


def pad_contacts(rig: Rig) -> list:
    """Contact entries (hydroelastic and point) that involve a pad."""
    pads = set(rig.coop.grasp.pad_geometries)
    res = rig.contact_results()
    found = []
    for k in range(res.num_hydroelastic_contacts()):
        surface = res.hydroelastic_contact_info(k).contact_surface()
        if {surface.id_M(), surface.id_N()} & pads:
            found.append(surface)
    for k in range(res.num_point_pair_contacts()):
        pp = res.point_pair_contact_info(k).point_pair()
        if {pp.id_A, pp.id_B} & pads:
            found.append(pp)
    return found


# ------------------------------------------------------------------------------ geometry


def test_contact_object_geometry_and_collision_filters():
    rig = build_rig(TASK, at="pregrasp", squeeze=0.0)
    coop, grasp = rig.coop, rig.coop.grasp
    plant = coop.plant
    assert plant.GetModelInstanceName(grasp.box.model_instance()) == "object"
    assert grasp.box.default_mass() == pytest.approx(0.5)
    r = coop.arms[0].arm.geometry.r_pad
    b1, b2 = (h.arm.b for h in coop.arms)
    X = grasp.X_WBox0
    faces = X.translation()[0] + np.array([-0.5, 0.5]) * grasp.size[0]
    np.testing.assert_allclose(faces, [b1 + r, b2 - r], atol=1e-12)
    assert X.translation()[2] == pytest.approx(0.535)
    # The stand: under the box, narrower, its top at the box's bottom face.
    inspector = coop.scene_graph.model_inspector()
    (stand_geometry,) = plant.GetCollisionGeometriesForBody(grasp.stand)
    stand = inspector.GetShape(stand_geometry)
    X_WS = plant.EvalBodyPoseInWorld(rig.plant_context, grasp.stand)
    assert X_WS.translation()[2] + stand.height() / 2 == pytest.approx(0.535 - grasp.size[2] / 2)
    assert stand.width() < grasp.size[0] - 4 * r
    # Only pad–box, box–stand and box–floor pairs are ever checked.
    names = {frozenset(inspector.GetName(g).split("::")[-1] for g in pair)
             for pair in inspector.GetCollisionCandidates()}
    assert names == {frozenset({"pad_collision", "box_collision"}),
                     frozenset({"box_collision", "stand_collision"}),
                     frozenset({"box_collision", "floor_collision"})}
    assert len(inspector.GetCollisionCandidates()) == 4


def test_box_rests_on_its_stand_untouched():
    rig = build_rig(TASK, at="pregrasp", squeeze=0.0)
    z0 = rig.box_pose().translation()[2]
    z, contacts = [], 0
    for t in np.arange(0.05, 1.0 + 1e-9, 0.05):
        rig.simulator.AdvanceTo(t)
        z.append(rig.box_pose().translation()[2])
        contacts += len(pad_contacts(rig))
    assert np.abs(np.array(z) - z0).max() < 1e-3
    assert rig.box_pose().rotation().ToAngleAxis().angle() < 1e-4
    assert contacts == 0
    for i in range(2):
        assert np.abs(rig.measured_force(i)).max() < 1e-6
    # The stand carries the box's weight through a pressure patch.
    res = rig.contact_results()
    grasp = rig.coop.grasp
    inspector = rig.coop.scene_graph.model_inspector()
    (stand_geometry,) = rig.coop.plant.GetCollisionGeometriesForBody(grasp.stand)
    on_box = np.zeros(3)
    for k in range(res.num_hydroelastic_contacts()):
        info = res.hydroelastic_contact_info(k)
        s = info.contact_surface()
        if {s.id_M(), s.id_N()} == {grasp.box_geometry, stand_geometry}:
            f = info.F_Ac_W().translational()
            on_box += f if s.id_M() == grasp.box_geometry else -f
    assert inspector.GetName(stand_geometry).endswith("stand_collision")
    np.testing.assert_allclose(on_box, [0.0, 0.0, 0.5 * G], atol=0.01 * 0.5 * G)


# ----------------------------------------------------------------------- grasp and carry


@dataclass
class Run:
    t: list = field(default_factory=list)
    rotation: list = field(default_factory=list)
    offset: list = field(default_factory=list)      # box centre − midpoint of E_1, E_2
    rolling: list = field(default_factory=list)     # the part of it due to the pads rolling
    z: list = field(default_factory=list)
    offset0: np.ndarray | None = None
    z0: float = 0.0
    static: dict = field(default_factory=dict)      # name → (λ_meas, λ_contact) per robot
    patches: list = field(default_factory=list)     # pad–box contact surfaces at the end
    wall_per_second: float = 0.0

    def displacement(self) -> np.ndarray:
        """‖offset − offset at the grasp‖: the box's motion relative to the pads' centres."""
        return np.linalg.norm(np.array(self.offset) - self.offset0, axis=1)

    def slip(self) -> np.ndarray:
        """The same net of rolling: what the box slid on the pads."""
        return np.linalg.norm(np.array(self.offset) - self.offset0 - np.array(self.rolling),
                              axis=1)


@pytest.fixture(scope="module")
def carry_run() -> Run:
    rig = build_rig(TASK)
    run = Run()

    coop, pc = rig.coop, rig.plant_context
    R0, c0 = None, None

    def pads():
        return [coop.plant.EvalBodyPoseInWorld(pc, h.ee_body).rotation().matrix()
                for h in coop.arms]

    def record() -> None:
        X = rig.box_pose()
        E = [coop.ee_position(pc, i) for i in range(2)]
        run.t.append(rig.context.get_time())
        run.rotation.append(X.rotation().ToAngleAxis().angle())
        run.offset.append(X.translation() - 0.5 * (E[0] + E[1]))
        run.z.append(X.translation()[2])
        # Rolling: the pads are spheres on links whose orientation changes along the path.
        # Sticking to the box, pad i carries the material point c_i (from its centre to the
        # box's face, the effective rolling radius r − penetration) to R_i R_i0ᵀ c_i.
        if R0 is None:
            run.rolling.append(np.zeros(3))
        else:
            R = pads()
            run.rolling.append(np.mean([R[i] @ R0[i].T @ c0[i] - c0[i] for i in range(2)],
                                       axis=0))

    def static(name: str) -> None:
        run.static[name] = [(rig.measured_lambda(i), rig.contact_lambda(i)) for i in range(2)]

    start = time.perf_counter()
    # Squeeze ramp on the stand, then settle: the grasp is established.
    for t in np.arange(0.03, TASK.t_grasp + 1e-9, 0.03):
        rig.simulator.AdvanceTo(t)
        record()
    static("grasped")
    run.offset0 = run.offset[-1].copy()
    run.z0 = run.z[-1]
    R0 = pads()
    X = rig.box_pose()
    c0 = []
    for i, h in enumerate(coop.arms):
        n_W = X.rotation().matrix() @ h.arm.normal          # the face's outward normal
        E = coop.ee_position(pc, i)
        depth = n_W @ (E - X.translation()) - 0.5 * coop.grasp.size[0]   # centre to face
        c0.append(-depth * n_W)
    # Lift, circle, hold.
    for t in np.arange(TASK.t_grasp + 0.03, T_HOLD_END + 1e-9, 0.03):
        rig.simulator.AdvanceTo(t)
        record()
    static("lifted")
    run.wall_per_second = (time.perf_counter() - start) / rig.context.get_time()
    run.patches = pad_contacts(rig)
    run.t, run.rotation, run.z = (np.array(a) for a in (run.t, run.rotation, run.z))
    after = run.t >= TASK.t_grasp - 1e-9
    print(f"\ncontact mode, dt = {TIME_STEP * 1e3:g} ms: wall {run.wall_per_second:.3f} s per "
          f"simulated s; max rotation {run.rotation.max():.4f} rad, max slip "
          f"{1e3 * run.slip()[after].max():.3f} mm (displacement relative to the pads' centres "
          f"{1e3 * run.displacement()[after].max():.3f} mm, rolling included), lift "
          f"{run.z.max() - run.z0:.4f} m; λ (meas, contact) {run.static}")
    return run


@pytest.mark.slow
def test_box_does_not_rotate_in_the_grasp(carry_run: Run):
    # Measured ≈ 0.04 rad, about the pad axis x, nearly all of it kinematic: the wrists are
    # locked, and on the circle the pads spin about x by ∫ω_x = −0.029 and −0.067 rad (a
    # geometric phase of the joint path, ω_x = −sin q1 · d(q2 + q3)/dt). The two patches'
    # torsional friction saturates against each other (±0.11 N·m) and the box turns at about
    # their mean; brushing the stand at the circle's bottom takes back ≈ 0.01 rad.
    assert carry_run.rotation.max() < 0.05


@pytest.mark.slow
def test_box_does_not_slip_between_the_pads(carry_run: Run):
    after = carry_run.t >= TASK.t_grasp - 1e-9
    assert carry_run.slip()[after].max() < 2e-3
    # Relative to the pads' centres the box moves by the rolling (≈ 3.5 mm: the pads pitch by
    # 0.22 and 0.30 rad on the lift, at a rolling radius r − δ ≈ 13.6 mm), not more.
    assert carry_run.displacement()[after].max() < 5e-3


@pytest.mark.slow
def test_box_is_lifted_by_the_lift_height(carry_run: Run):
    # ≈ 0.1034 m: the pads' rolling on the lift raises the box 3.5 mm relative to them.
    lifted = carry_run.z[carry_run.t >= TASK.t_circle_start].max() - carry_run.z0
    assert lifted == pytest.approx(TASK.lift_height, abs=5e-3)
    # Held at the circle's start at the end, not dropped.
    assert carry_run.z[-1] - carry_run.z0 == pytest.approx(TASK.lift_height, abs=5e-3)


@pytest.mark.slow
def test_static_squeeze_is_measured_and_matches_the_contact_results(carry_run: Run):
    for name, forces in carry_run.static.items():
        for measured, contact in forces:
            assert measured == pytest.approx(SQUEEZE, rel=0.05), name
            assert measured == pytest.approx(contact, rel=0.01), name


@pytest.mark.slow
def test_pads_touch_the_box_through_pressure_patches(carry_run: Run):
    """Hydroelastic patches (torsional friction), not point contacts."""
    assert len(carry_run.patches) == 2
    for surface in carry_run.patches:
        assert hasattr(surface, "num_faces") and surface.num_faces() > 10
        assert surface.total_area() > 5e-5          # m², a patch of ≈ 4 mm radius or more
