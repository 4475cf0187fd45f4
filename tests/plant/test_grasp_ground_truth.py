"""The ``contact`` mode's ground truth (drake_coop.plant.grasp.PadForces, held and logged at
every plant step by drake_coop.plant.ground_truth.add_pad_force_log) against the plant's contact
results read at every step and Newton's law on the wrist sensor's bodies from the plant's
reaction forces; the F/T sensor model after the run against the live model; the pads' normal
and tangential forces against the contact surfaces in the plant's contact results; the stand's
clearance and the pads' material."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from drake_coop.kinematics.rotations import pad_contact_components
from drake_coop.plant.arms import arm_model
from drake_coop.experiment.plan import plan_run
from drake_coop.plant.cooperative import build_plant, initialize_plant_context
from drake_coop.plant.ground_truth import add_pad_force_log
from drake_coop.plant.wrist import add_force_sensors
from drake_coop.scenario.task_path import waypoints
from drake_coop.scenario import default_scenario
from drake_coop.scenario.schema import ForceSensorModel
from drake_coop.sensing.force_sensor import FTModel, add_ft_sensor
from tests.plant.test_grasp import TASK, TIME_STEP, GraspController, x_reference

STEPS = 3                  # plant steps per control period
H = STEPS * TIME_STEP
#: Robot 1's F/T sensor model: low-pass, bias and seeded noise (robot 2's is ideal).
FT_SETTINGS = ForceSensorModel(noise_std=0.2, bias=0.5, cutoff_hz=20.0, seed=3)


def _contact_scenario(clearance: float = 0.0):
    scenario = default_scenario()
    scenario.plant.object_mode = "contact"
    scenario.plant.time_step = TIME_STEP
    scenario.plant.stand_clearance = clearance
    scenario.task = TASK
    return scenario


def _plan(scenario):
    """The scenario's plan on this test's own grid: plant steps of exactly ``TIME_STEP``."""
    return replace(plan_run(scenario), dt=TIME_STEP)


@pytest.fixture(scope="module")
def squeezed():
    """Both arms squeeze the box on its stand (32 N) and lift it: Newton's-law sensors
    (:func:`add_force_sensors` without a period) beside the pads' ground truth; robot 1's
    non-ideal F/T sensor model read live at ``t_k − Δt/2`` from the hold, its reading
    logged."""
    scenario = _contact_scenario()
    builder = DiagramBuilder()
    coop = build_plant(builder, _plan(scenario))
    newton = add_force_sensors(builder, coop)
    models = [FTModel.from_settings(FT_SETTINGS, H, 0, 1), FTModel.from_settings(None, H, 1, 1)]
    truth = add_pad_force_log(builder, coop, H, models)
    name = coop.arms[0].arm.name
    last_step = truth.add_lambda_last_step(builder, 0, name)
    _, reading = add_ft_sensor(builder, name, H, TIME_STEP, FT_SETTINGS, 0, 1, last_step,
                               last_step)
    reading_log = LogVectorOutput(reading, builder, publish_period=H)
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
    return coop, newton, truth, simulator, reading_log


def _port(system, name, context):
    return system.GetOutputPort(name).Eval(system.GetMyContextFromRoot(context)).copy()


def _contact_forces(coop, context) -> list[np.ndarray]:
    """The box's force on each pad from the plant's contact results, now."""
    plant = coop.plant
    results = plant.get_contact_results_output_port().Eval(plant.GetMyContextFromRoot(context))
    return [coop.grasp.pad_force(results, pad) for pad in coop.grasp.pad_geometries]


def test_pad_forces_of_every_tick_match_the_contact_results_and_newtons_law(squeezed):
    """Tick ``k``'s ``F_meas`` is the step taken from ``t_k`` and its F/T reading the step
    before ``t_k``: the plant's contact results read at every plant step before its updates
    (the step the plant then takes: its own solve, so exactly) and, to 1e-3, Newton's law on
    the reaction forces; the guards' reading at a tick (before its updates) is the step
    before it."""
    coop, newton, truth, simulator, _ = squeezed
    context = simulator.get_mutable_context()
    k0, k1 = int(round(2.4 / H)), int(round(2.4 / H)) + 12   # lifting, the squeeze established
    steps = {}
    for j in range(k0 * STEPS - 1, k1 * STEPS + 2):
        simulator.AdvanceTo(j * TIME_STEP)
        steps[j] = _contact_forces(coop, context)
        if j % STEPS == 0:
            for i, F in enumerate(truth.force_before_tick(context)):
                np.testing.assert_array_equal(F, steps[j - 1][i])
        if j == k0 * STEPS:
            for i, sensor in enumerate(newton):
                F = steps[j][i]
                assert np.linalg.norm(F) > 20.0
                np.testing.assert_allclose(_port(sensor, "F_meas", context), F,
                                           atol=1e-3 * np.linalg.norm(F))
    rows = truth.evaluate(context, k1 + 1, False)
    for i, h in enumerate(coop.arms):
        N = np.atleast_2d(h.arm.N)
        F_meas = rows[i]["F_meas"]
        for k in range(k0, k1 + 1):
            np.testing.assert_array_equal(F_meas[k], steps[k * STEPS][i])
            np.testing.assert_array_equal(rows[i]["lambda_meas"][k], N @ steps[k * STEPS][i])
        if i == 1:           # the ideal model: λ of the step before the tick itself
            for k in range(k0, k1 + 1):
                np.testing.assert_allclose(rows[i]["lambda_sensor"][k],
                                           N @ steps[k * STEPS - 1][i], rtol=0, atol=1e-12)
        # the step from the tick and the step before it differ: the test tells them apart
        assert np.linalg.norm(steps[k0 * STEPS][i] - steps[k0 * STEPS - 1][i]) > 1e-6


def test_f_t_model_after_the_run_equals_the_live_model(squeezed):
    """The F/T model evaluated after the run (:meth:`PadForceLog.evaluate`, what a
    ``contact`` run logs) gives the live model's readings at every tick (the live model reads
    ``λ`` of the hold at ``t_k − Δt/2``)."""
    coop, _, truth, simulator, reading_log = squeezed
    context = simulator.get_mutable_context()
    simulator.AdvanceTo(int(np.ceil(context.get_time() / H)) * H + 20 * H)
    reading = reading_log.FindLog(context).data()[0]            # published at t_k: tick k
    K = reading.size - 1
    offline = truth.evaluate(context, K, False)[0]["lambda_sensor"][:, 0]
    assert K > 250 and np.ptp(reading[:K]) > 20.0
    np.testing.assert_allclose(offline, reading[:K], rtol=0, atol=1e-9)


def test_normal_and_tangential_forces_match_the_contact_surfaces(squeezed):
    coop, _, _, simulator, _ = squeezed
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
    coop = build_plant(builder, _plan(scenario))
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
