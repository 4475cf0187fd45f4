"""The ``contact`` mode's ground truth (drake_coop.plant.grasp.PadForces) against Newton's law
on the wrist sensor's bodies from the plant's reaction forces, and the pads' normal and
tangential forces against the contact surfaces in the plant's contact results; the stand's
clearance and the pads' material."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ZeroOrderHold

from drake_coop.plant.arms import arm_model
from drake_coop.plant.cooperative import build_plant, initialize_plant_context
from drake_coop.plant.grasp import PadForces, pad_contact_components
from drake_coop.plant.wrist import add_force_sensors
from drake_coop.experiment.references import waypoints
from drake_coop.scenario import default_scenario
from tests.plant.test_grasp import TASK, TIME_STEP, GraspController, x_reference

H = 3 * TIME_STEP          # a control period of three plant steps


def _contact_scenario(clearance: float = 0.0):
    scenario = default_scenario()
    scenario.plant.object_mode = "contact"
    scenario.plant.time_step = TIME_STEP
    scenario.plant.stand_clearance = clearance
    scenario.task = TASK
    return scenario


@pytest.fixture(scope="module")
def squeezed():
    """Both arms squeeze the box on its stand (32 N) and lift it: Newton's-law sensors
    (:func:`add_force_sensors` without a period) beside :class:`PadForces`."""
    scenario = _contact_scenario()
    builder = DiagramBuilder()
    coop = build_plant(builder, scenario)
    newton = add_force_sensors(builder, coop)
    pads = builder.AddSystem(PadForces(coop.grasp, [h.arm.name for h in coop.arms],
                                       [h.arm.N for h in coop.arms], H))
    results = coop.plant.get_contact_results_output_port()
    builder.Connect(results, pads.get_contact_results_input_port())
    held = builder.AddSystem(ZeroOrderHold(TIME_STEP, AbstractValue.Make(ContactResults())))
    builder.Connect(results, held.get_input_port())
    builder.Connect(held.get_output_port(), pads.get_contact_results_last_step_input_port())
    for i, h in enumerate(coop.arms):
        ctrl = builder.AddSystem(GraspController(arm_model(h.arm), x_reference(
            TASK, scenario.robots[i]), 0.5 * 0.5 * 9.81))
        builder.Connect(coop.plant.get_state_output_port(h.instance), ctrl.get_input_port())
        builder.Connect(ctrl.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(context)
    q0 = [h.arm.ik(waypoints(TASK, scenario.robots[i])["grasp"])
          for i, h in enumerate(coop.arms)]
    initialize_plant_context(coop, pc, q0, TASK.circle_top_z - TASK.lift_height)
    simulator.Initialize()
    return coop, newton, pads, simulator


def _port(system, name, context):
    return system.GetOutputPort(name).Eval(system.GetMyContextFromRoot(context)).copy()


def test_pad_forces_match_newtons_law_and_latch_the_ticks(squeezed):
    coop, newton, pads, simulator = squeezed
    context = simulator.get_mutable_context()
    names = [h.arm.name for h in coop.arms]
    k = int(round(2.4 / H))                  # a tick while lifting, the squeeze established
    simulator.AdvanceTo(k * H)
    live = [_port(pads, f"{n}_wrist", context) for n in names]
    for i, n in enumerate(names):
        F_newton = _port(newton[i], "F_meas", context)
        assert np.linalg.norm(live[i]) > 20.0
        np.testing.assert_allclose(live[i], F_newton, atol=1e-3 * np.linalg.norm(F_newton))
    # The tick's update latches the step from t_k (the one just read live) ...
    simulator.AdvanceTo(k * H + 0.5 * TIME_STEP)
    for i, n in enumerate(names):
        tol = 1e-9 * np.linalg.norm(live[i])     # the same step, solved again
        np.testing.assert_allclose(_port(pads, f"{n}_F_step", context), live[i], atol=tol)
        N = coop.arms[i].arm.N
        np.testing.assert_allclose(_port(pads, f"{n}_lambda_step", context), N @ live[i],
                                   atol=tol)
    # ... and holds it between ticks.
    simulator.AdvanceTo(k * H + 1.5 * TIME_STEP)
    for i, n in enumerate(names):
        tol = 1e-9 * np.linalg.norm(live[i])
        np.testing.assert_allclose(_port(pads, f"{n}_F_step", context), live[i], atol=tol)
    # Not checked: <robot>_lambda_last_step (the contact results held by a C++ ZeroOrderHold at
    # every plant step) differs from a live read of the same step by up to 2 % on the steps
    # after a tick; the cause was not found.


def test_normal_and_tangential_forces_match_the_contact_surfaces(squeezed):
    coop, _, pads, simulator = squeezed
    context = simulator.get_mutable_context()
    simulator.AdvanceTo(simulator.get_context().get_time() + 0.3)
    plant = coop.plant
    pc = plant.GetMyContextFromRoot(context)
    results = plant.get_contact_results_output_port().Eval(pc)
    X = plant.EvalBodyPoseInWorld(pc, coop.grasp.box)
    q = X.rotation().ToQuaternion()
    pose = np.array([[q.w(), q.x(), q.y(), q.z(), *X.translation()]])
    seen = 0
    for i, h in enumerate(coop.arms):
        pad = coop.grasp.pad_geometries[i]
        for k in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(k)
            surface = info.contact_surface()
            if {surface.id_M(), surface.id_N()} != {pad, coop.grasp.box_geometry}:
                continue
            # The surface's own normal (it points out of N into M) and the pad's total force.
            sign = 1.0 if surface.id_M() == pad else -1.0
            F = sign * info.F_Ac_W().translational()
            normal = surface.face_normal(0)
            f_n = abs(normal @ F)
            f_t = np.linalg.norm(F - (normal @ F) * normal)
            E = coop.ee_position(pc, i)
            got_n, got_t, _ = pad_contact_components(F[None], E[None], pose)
            assert got_n[0] == pytest.approx(f_n, rel=1e-6)
            assert got_t[0] == pytest.approx(f_t, rel=1e-4, abs=1e-6)
            assert f_n > 20.0 and f_t > 1.0             # squeezed, carrying the weight
            seen += 1
    assert seen == 2


def test_stand_clearance_lowers_the_stand_only_when_asked():
    d = 0.004
    scenario = _contact_scenario(d)
    scenario.plant.friction = 0.5
    scenario.plant.pad_modulus = 2e6
    builder = DiagramBuilder()
    coop = build_plant(builder, scenario)
    z_grasp = TASK.circle_top_z - TASK.lift_height
    assert coop.grasp.X_WBox0.translation()[2] == pytest.approx(z_grasp)
    assert coop.grasp.stand.model_instance() != coop.grasp.box.model_instance()
    plant = coop.plant
    context = plant.CreateDefaultContext()
    q0 = [h.arm.ik(waypoints(TASK, scenario.robots[i])["grasp"])
          for i, h in enumerate(coop.arms)]
    initialize_plant_context(coop, context, q0, z_grasp)
    (stand,) = plant.GetCollisionGeometriesForBody(coop.grasp.stand)
    height = coop.scene_graph.model_inspector().GetShape(stand).height()

    def top() -> float:
        return plant.EvalBodyPoseInWorld(context, coop.grasp.stand).translation()[2] + height / 2

    assert top() == pytest.approx(z_grasp - coop.grasp.size[2] / 2)     # under the box
    assert coop.grasp.stand_slide.is_locked(context)
    coop.grasp.set_stand_lowered(context, True)
    assert top() == pytest.approx(z_grasp - coop.grasp.size[2] / 2 - d)
    coop.grasp.set_stand_lowered(context, False)
    assert top() == pytest.approx(z_grasp - coop.grasp.size[2] / 2)
    inspector = coop.scene_graph.model_inspector()
    for pad in coop.grasp.pad_geometries:
        props = inspector.GetProximityProperties(pad)
        assert props.GetProperty("material", "coulomb_friction").static_friction() == 0.5
        assert props.GetProperty("hydroelastic", "hydroelastic_modulus") == 2e6
