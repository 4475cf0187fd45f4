"""The ``contact`` mode: a box held only by friction at two hydroelastic pads.

A simple position/force controller (joint PD to the inverse kinematics of the path, gravity
compensation, a 32 N squeeze and half the box's weight per arm) lifts the box 0.1 m off its
stand, carries it once around the circle of (28) and holds it: it must stay in the grasp.
"""

import numpy as np
import pytest

from drake_coop.references import cartesian_reference
from drake_coop.scenario import Task, default_scenario
from tests.test_plant import G, build

SQUEEZE = 32.0


def _box_state(coop, pc):
    X = coop.plant.EvalBodyPoseInWorld(pc, coop.object_body)
    mid = 0.5 * (coop.ee_position(pc, 0) + coop.ee_position(pc, 1))
    R_pads = [coop.plant.EvalBodyPoseInWorld(pc, h.ee_body).rotation().matrix()
              for h in coop.arms]
    return X.translation() - mid, X.rotation().ToAngleAxis().angle(), X.translation(), R_pads


def _slip(coop, state, state0):
    """Tangential slip of the box on the pads.

    The pads are spheres fixed to links whose orientation changes along the path, so a box
    that sticks to them rolls with them: the material point of pad i that touched the box at
    the grasp, ``c_i = −r n_i`` from the pad's centre, is now at ``R_i R_i0ᵀ c_i``. Slip is the
    box's displacement relative to the pads' centres minus that rolling.
    """
    offset, _, _, R = state
    offset0, _, _, R0 = state0
    r = coop.arms[0].arm.geometry.r_pad
    rolling = np.mean([R[i] @ R0[i].T @ (-r * h.arm.normal) + r * h.arm.normal
                       for i, h in enumerate(coop.arms)], axis=0)
    return np.linalg.norm(offset - offset0 - rolling)


def test_box_rests_on_its_stand_untouched():
    s, coop, sensors, ctrls, sim, ctx, pc = build("contact", f=0.0)
    z0 = coop.plant.EvalBodyPoseInWorld(pc, coop.object_body).translation()[2]
    sim.AdvanceTo(1.0)
    X = coop.plant.EvalBodyPoseInWorld(pc, coop.object_body)
    assert abs(X.translation()[2] - z0) < 1e-3
    assert X.rotation().ToAngleAxis().angle() < 1e-3
    for i in range(2):
        assert np.abs(sensors[i].GetOutputPort("F_meas").Eval(
            sensors[i].GetMyContextFromRoot(ctx))).max() < 1e-6


@pytest.mark.slow
def test_simple_controller_lifts_and_carries_the_box_around_the_circle():
    s = default_scenario()
    task = Task(t_pregrasp=0.1, t_grasp=0.2, t_circle_start=3.0, t_circle_end=11.0,
                t_release=13.0, t_end=14.0)

    def x_ref(i):
        def f(t):
            t = max(t, task.t_grasp)       # hold the grasp point first, then lift and circle
            if t >= task.t_circle_end:
                t = task.t_circle_end - 1e-9
            return cartesian_reference(task, s.robots[i], [t])[0][0]
        return f

    m = s.plant.object_mass
    # Cartesian PD along y and z only, so that the squeeze along x is exactly f at rest.
    s_, coop, sensors, ctrls, sim, ctx, pc = build(
        "contact", f=SQUEEZE, carry=0.5 * m * G, x_refs=[x_ref(0), x_ref(1)], kp=3000.0,
        kd=300.0, held=False)
    sim.AdvanceTo(task.t_grasp + 0.3)             # squeeze established, box still on the stand
    state0 = _box_state(coop, pc)
    p0 = state0[2]
    slip, rot, z = [], [], []
    t = task.t_grasp + 0.3
    while t < task.t_circle_end + 1.0:
        t += 0.05
        sim.AdvanceTo(t)
        state = _box_state(coop, pc)
        slip.append(_slip(coop, state, state0))
        rot.append(state[1])
        z.append(state[2][2])
    print(f"max rotation {max(rot):.4f} rad, max slip {1e3 * max(slip):.3f} mm")
    assert max(rot) < 0.05
    assert max(slip) < 2e-3
    assert max(z) - p0[2] == pytest.approx(0.1, abs=5e-3)        # really lifted 0.1 m
    # Static at the end: measured squeeze ≈ 32 N and equal to the contact results.
    results = coop.plant.get_contact_results_output_port().Eval(pc)
    for i in range(2):
        F, lam = (sensors[i].GetOutputPort(p).Eval(sensors[i].GetMyContextFromRoot(ctx))
                  for p in ("F_meas", "lambda_meas"))
        assert lam[0] == pytest.approx(SQUEEZE, rel=0.05)
        pad = coop.arms[i].ee_body
        total = np.zeros(3)
        for k in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(k)
            f = info.F_Ac_W().translational()
            ids = {coop.scene_graph.model_inspector().GetFrameId(info.contact_surface().id_M()),
                   coop.scene_graph.model_inspector().GetFrameId(info.contact_surface().id_N())}
            pad_frame = coop.plant.GetBodyFrameIdOrThrow(pad.index())
            if pad_frame in ids:
                # F_Ac_W acts on body A (geometry M's body); make it the force on the pad.
                on_pad = f if coop.scene_graph.model_inspector().GetFrameId(
                    info.contact_surface().id_M()) == pad_frame else -f
                total += on_pad
        np.testing.assert_allclose(F, total, rtol=0, atol=0.01 * np.linalg.norm(total))
