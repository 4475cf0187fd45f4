"""Three arms (and l ≥ 3 pads) holding one object by friction.

* The l-pad load split (:func:`~drake_coop.control.object.load_distribution`) against a hand
  static balance: the contact forces sum to ``m (a − g)``, their moment about the centre of mass
  is zero, and what is added to them by the squeeze lies in the null space of a grasp matrix
  built here from the cross products; for three pads 120° apart the split is the closed form
  ``m (a − g) / 3`` per pad.
* The prism of :func:`~drake_coop.plant.prism.prism_section` against the equilateral triangle's
  closed form, its inertia against the solid prism's, and the refusals.
* The prism's pad forces (:meth:`~drake_coop.plant.grasp.ContactObject.pad_forces`, from the
  plant's contact results) against the plant's generalized contact forces on the object (the
  discrete solver's, another route) and the faces' normals.
* The slip on each pad's own face (:mod:`drake_coop.results.object_metrics`) on constructed
  motions of three pads whose slide is known in closed form.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from drake_coop.control.object import (
    ObjectModel,
    internal_part,
    load_distribution,
    mass_shares,
    squeeze_for_grasp,
)
from drake_coop.experiment.plan import grasp_object, plan_run
from drake_coop.kinematics.rotations import pad_contact_components
from drake_coop.plant.prism import prism_section
from drake_coop.results.object_metrics import SLIP_DISTANCE, object_signals
from drake_coop.scenario import load_scenario, validate
from drake_coop.scenario.resources import scenarios_dir
from drake_coop.scenario.schema import ScenarioError

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])


def _three_arms():
    return load_scenario(scenarios_dir() / "three_arms_contact.yaml")


def _hand_grasp_matrix(points: np.ndarray, com: np.ndarray) -> np.ndarray:
    """``[f_1; …; f_l] -> [Σ f_i; Σ (p_i − c) × f_i]``, column by column from cross products."""
    cols = []
    for p in points:
        for e in np.eye(3):
            cols.append(np.concatenate([e, np.cross(p - com, e)]))
    return np.array(cols).T


# ------------------------------------------------------------------------- load split


@pytest.mark.parametrize("a", [np.zeros(3), np.array([0.3, -0.2, 1.1])])
def test_three_pad_load_split_is_a_third_of_m_a_minus_g_each(a):
    model = grasp_object(_three_arms(), 0.8)
    f = load_distribution(model, a)
    np.testing.assert_allclose(f, np.tile(0.8 * (a - GRAVITY) / 3.0, (3, 1)), atol=1e-12)
    np.testing.assert_allclose(mass_shares(model), [0.8 / 3.0] * 3, atol=1e-12)


def test_l_pad_load_split_against_a_hand_static_balance():
    """Four pads at unequal angles and heights, the centre of mass off their mean."""
    rng = np.random.default_rng(1)
    angles = np.array([0.1, 1.9, 3.3, 4.6])
    points = np.column_stack([0.12 * np.cos(angles), 0.1 * np.sin(angles),
                              [0.0, 0.02, -0.01, 0.015]])
    normals = -np.column_stack([np.cos(angles), np.sin(angles), np.zeros(4)])
    com = np.array([0.01, -0.005, 0.003])
    model = ObjectModel(mass=1.3, com=com, grasp_points=points, grasp_normals=normals)
    a = np.array([0.4, 0.1, -0.7])
    f = load_distribution(model, a)
    G_hand = _hand_grasp_matrix(points, com)
    # The balance: the forces sum to m (a − g), no moment about the centre of mass.
    np.testing.assert_allclose(f.sum(axis=0), 1.3 * (a - GRAVITY), atol=1e-12)
    np.testing.assert_allclose(sum(np.cross(p - com, fi) for p, fi in zip(points, f)),
                               0.0, atol=1e-12)
    # Minimum norm: orthogonal to every internal force (the null space of G, from its SVD).
    _, sv, vt = np.linalg.svd(G_hand)
    null = vt[np.sum(sv > 1e-9):]
    assert null.shape[0] == 3 * 4 - 6
    np.testing.assert_allclose(null @ f.reshape(-1), 0.0, atol=1e-12)
    # Any force = the split + its internal part: the internal part moves nothing.
    extra = rng.normal(size=(4, 3))
    internal = internal_part(model, f + extra)
    np.testing.assert_allclose(G_hand @ internal.reshape(-1), 0.0, atol=1e-12)
    np.testing.assert_allclose(internal.reshape(-1), null.T @ (null @ extra.reshape(-1)),
                               atol=1e-12)


@pytest.mark.parametrize("mass, mu, a", [(0.2, 1.0, np.zeros(3)),
                                         (1.5, 0.5, np.array([0.0, 0.0, 0.8])),
                                         (1.0, 0.6, np.array([0.5, -0.4, -0.3]))])
def test_friction_squeeze_of_three_pads_holds_every_cone_and_moves_nothing(mass, mu, a):
    model = grasp_object(_three_arms(), mass)
    loads = load_distribution(model, a)
    n = model.grasp_normals / np.linalg.norm(model.grasp_normals, axis=1)[:, None]
    lam, ok = squeeze_for_grasp(loads, n, mu, margin=1.0)
    assert ok
    total = loads + lam * n
    # The squeeze is internal: the totals still balance the object (hand balance).
    np.testing.assert_allclose(total.sum(axis=0), mass * (a - GRAVITY), atol=1e-10)
    points = model.grasp_points - model.com
    np.testing.assert_allclose(sum(np.cross(p, fi) for p, fi in zip(points, total)), 0.0,
                               atol=1e-10)
    f_n = np.einsum("ij,ij->i", total, n)
    f_t = np.linalg.norm(total - f_n[:, None] * n, axis=1)
    assert np.all(f_t <= mu * f_n * (1 + 1e-9))
    assert np.max(f_t - mu * f_n) == pytest.approx(0.0, abs=1e-9)   # the least: one at the edge


# ------------------------------------------------------------------------- the prism


def test_prism_section_of_three_arms_is_the_equilateral_triangle():
    s = _three_arms()
    points = np.array([r.contact_xy for r in s.robots])
    normals = np.array([r.normals[0][:2] for r in s.robots])
    section = prism_section(points, normals, 0.015)
    np.testing.assert_allclose(section.offsets, 0.085, atol=1e-12)
    sides = np.linalg.norm(section.vertices - np.roll(section.vertices, 1, axis=0), axis=1)
    np.testing.assert_allclose(sides, 2 * np.sqrt(3) * 0.085, rtol=1e-12)    # inradius a
    np.testing.assert_allclose(np.linalg.norm(section.vertices, axis=1), 2 * 0.085, rtol=1e-12)
    # Every vertex on its two faces, inside the third.
    d = section.vertices @ section.normals[:, :2].T - section.offsets
    assert np.sum(np.abs(d) < 1e-12) == 6 and np.all(d < 1e-12)


def test_prism_section_refuses_normals_that_do_not_enclose_an_object():
    with pytest.raises(ValueError, match="surround"):
        prism_section(np.array([[0.1, 0.0], [0.0, 0.1], [-0.1, 0.0]]),
                      np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]), 0.015)
    with pytest.raises(ValueError, match="pad radius"):       # a contact point near a corner
        prism_section(np.array([[0.1, 0.15], [-0.05, 0.0866], [-0.05, -0.0866]]),
                      np.array([[1.0, 0.0], [-0.5, 0.8660254], [-0.5, -0.8660254]]), 0.015)


def test_validation_accepts_the_shipped_three_arms_and_refuses_unbalanced_squeezes():
    s = _three_arms()
    validate(s)
    s.robots[0].force_weights = [2.0]
    with pytest.raises(ScenarioError, match="balance"):
        validate(s)
    s = _three_arms()
    s.robots[1].normals = [[-0.5, 0.8, 0.3]]
    with pytest.raises(ScenarioError, match="horizontal"):
        validate(s)


@pytest.fixture(scope="module")
def pressed():
    """The three-arm contact plant, each pad 1 mm into its face, the object 2 mm above its
    stand (held only by the pads)."""
    from pydrake.math import RigidTransform

    from drake_coop.plant.cooperative import build_plant, initialize_plant_context

    s = _three_arms()
    builder = DiagramBuilder()
    coop = build_plant(builder, plan_run(s))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    pc = coop.plant.GetMyMutableContextFromRoot(context)
    z = s.task.circle_top_z - s.task.lift_height
    depth = 1e-3
    q0 = []
    for h, r in zip(coop.arms, s.robots):
        N = np.asarray(r.normals[0], dtype=float)
        q0.append(h.arm.ik(np.array([*r.contact_xy, z]) - depth * N))
    initialize_plant_context(coop, pc, q0, z)
    X = coop.grasp.X_WBox0
    coop.plant.SetFreeBodyPose(pc, coop.grasp.box, RigidTransform(
        X.rotation(), X.translation() + np.array([0.0, 0.0, 2e-3])))
    for h in coop.arms:
        coop.plant.get_actuation_input_port(h.instance).FixValue(pc, np.zeros(3))
    return s, coop, pc


def test_prism_mass_and_inertia_are_the_solid_prisms(pressed):
    s, coop, pc = pressed
    box = coop.grasp.box
    m, a, height = 0.5, 0.085, 0.10
    side = 2 * np.sqrt(3) * a
    assert box.default_mass() == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(box.default_com(), 0.0, atol=1e-12)
    I = box.default_rotational_inertia().CopyToFullMatrix3()
    # Equilateral triangle of side s: polar m s²/12, in-plane m s²/24; plus m h²/12.
    np.testing.assert_allclose(np.diag(I), [m * side ** 2 / 24 + m * height ** 2 / 12] * 2
                               + [m * side ** 2 / 12], rtol=1e-9)


def test_prism_pad_forces_match_the_plants_contact_forces_on_the_object(pressed):
    s, coop, pc = pressed
    plant, grasp = coop.plant, coop.grasp
    results = plant.get_contact_results_output_port().Eval(pc)
    forces = grasp.pad_forces(results)
    # The discrete solver's generalized contact forces on the free object: [torque, force].
    generalized = plant.get_generalized_contact_forces_output_port(
        grasp.box.model_instance()).Eval(pc)
    np.testing.assert_allclose(-np.sum(forces, axis=0), generalized[3:], atol=1e-6)
    X = plant.EvalBodyPoseInWorld(pc, grasp.box)
    pose = np.array([[*X.rotation().ToQuaternion().wxyz(), *X.translation()]])
    normals = []
    for i, (F, r) in enumerate(zip(forces, s.robots)):
        N = np.asarray(r.normals[0], dtype=float)
        # The box pushes each pad out along its face's normal; the tangential force, inside
        # the friction cone, is the pad's share of the object's weight (below).
        assert N @ F > 1.0
        assert np.linalg.norm(F - (N @ F) * N) < s.plant.friction * (N @ F)
        E = plant.EvalBodyPoseInWorld(pc, plant.GetBodyByName("pad", coop.arms[i].instance))
        f_n, f_t, _ = pad_contact_components(F[None, :], E.translation()[None, :], pose,
                                             grasp.face_normals[i])
        assert f_n[0] == pytest.approx(N @ F, rel=1e-9)
        normals.append(f_n[0])
    # Three equal presses: equal normal forces (the pads' meshes differ in orientation only).
    assert np.ptp(normals) < 0.1 * np.mean(normals)
    # The object off its stand hangs in the three grips: each pad's friction holds it up
    # (SAP's regularized friction lets it start to slide within the step: not all its weight).
    weight = s.plant.object_mass * G
    assert np.all(-np.array(forces)[:, 2] > 0.1 * weight / 3)
    assert -np.sum(forces, axis=0)[2] < weight


# ------------------------------------------------------------------------- slip per face


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _three_pad_run(slide: float, yaw: float = 0.4):
    """Three pads on the prism's faces (normals 120° apart in the object's frame, the object
    turned by ``yaw``); pad 2 slides ``slide`` along its face, horizontally, during 5–6 s;
    the pads roll (turn about their face's horizontal tangent) without sliding."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    K = t.size
    R_B = _rz(yaw)
    p = np.column_stack([0.05 * np.sin(t), 0.02 * t, 0.5 + 0.01 * t])
    pose = np.column_stack([np.tile([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)], (K, 1)), p])
    offset, depth = 0.085, 0.014
    faces = []
    logs = {}
    alpha = 0.2 * np.sin(0.7 * t)
    s = slide * np.clip(t - 5.0, 0.0, 1.0)
    for i in range(3):
        th = 2 * np.pi * i / 3
        n_B = np.array([np.cos(th), np.sin(th), 0.0])
        faces.append([*n_B, offset])
        u_B = np.cross([0.0, 0.0, 1.0], n_B)                 # the face's horizontal tangent
        n, u = R_B @ n_B, R_B @ u_B
        # Rolling about u by α: the centre moves d α along z (the contact point at −d n).
        E = (p + (offset + depth) * n + np.outer(depth * alpha, [0.0, 0.0, 1.0])
             + (np.outer(s, u) if i == 1 else 0.0))
        R_P = np.array([R_B @ _rot(u_B, -a) for a in alpha])
        f_n = np.where((t >= 1.0) & (t < 9.0), 20.0, 0.0)
        F = np.outer(f_n, n) + np.outer(0.3 * f_n, [0.0, 0.0, 1.0])
        f_n_log, f_t_log, p_B = pad_contact_components(F, E, pose, n_B)
        logs[f"robot{i + 1}"] = {"t": t, "x": E, "x_d": E - (np.outer(s, u) if i == 1 else 0),
                                 "F_meas": F, "object_pose": pose,
                                 "pad_normal_force": f_n_log,
                                 "pad_tangential_force": f_t_log, "pad_in_object": p_B,
                                 "pad_rotation": R_P}
    meta = {"phases": [["free", 0.0, 1.0], ["lift", 1.0, 4.0], ["circle", 4.0, 8.0],
                       ["put_down", 8.0, 9.0], ["return", 9.0, 10.0]],
            "friction": 0.8, "object_size": [0.255, 0.294, 0.1], "object_faces": faces}
    return t, logs, meta


def _rot(axis: np.ndarray, a: float) -> np.ndarray:
    """Rotation by ``a`` about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


def test_three_pads_rolling_is_not_slip_and_a_slide_on_its_face_is_counted():
    t, logs, meta = _three_pad_run(0.0)
    sig = object_signals(logs, meta)
    held = (t >= 1.0) & (t < 9.0)
    for name in logs:
        np.testing.assert_allclose(logs[name]["pad_normal_force"][held], 20.0, rtol=1e-12)
        np.testing.assert_allclose(logs[name]["pad_tangential_force"][held], 6.0, rtol=1e-12)
        assert np.nanmax(sig[name]["slip"]) < 1e-6, name
        assert sig[name]["slip_events"].size == 0 and sig[name]["drop_events"].size == 0
    slide = 2.5 * SLIP_DISTANCE
    t, logs, meta = _three_pad_run(slide)
    sig = object_signals(logs, meta)
    assert np.nanmax(sig["robot2"]["slip"]) == pytest.approx(slide, rel=1e-3)
    assert np.nanmax(sig["robot1"]["slip"]) < 1e-6 and np.nanmax(sig["robot3"]["slip"]) < 1e-6
    events = t[sig["robot2"]["slip_events"]]
    assert events.size == 2 and (events > 5.0).all() and (events <= 6.0).all()


# ------------------------------------------------------------------------- the run's plan


def test_the_plan_of_three_arms_splits_the_mass_in_thirds_without_the_couple():

    s = _three_arms()
    s.object_model.mode, s.object_model.squeeze = "estimated", "friction"
    validate(s)
    plan = plan_run(s)
    assert not plan.uses_couple                       # a two-arm term
    np.testing.assert_allclose(plan.object.shares, [plan.object.mass / 3] * 3, rtol=1e-12)
    # The friction squeeze in the lift: the least that holds a third of m (a − g) in each
    # cone (its part across pad i's normal N_i against μ λ, its part along N_i adding to or
    # taking from λ), times the margin; a from the desired path.
    from drake_coop.scenario.task_path import cartesian_reference

    m, mu = plan.object.mass, plan.object.mu
    for t in (s.task.t_grasp + 2.0, s.task.t_grasp + 5.0):
        a = cartesian_reference(s.task, s.robots[0], np.array([t]))[2][0]
        f = m * (a - GRAVITY) / 3
        need = []
        for r in s.robots:
            n = -np.asarray(r.normals[0], dtype=float)      # inward
            need.append(np.linalg.norm(f - (f @ n) * n) / mu - f @ n)
        hand = max(s.object_model.squeeze_min, s.object_model.margin * max(need))
        assert plan.squeeze(np.array([t]))[0] == pytest.approx(hand, rel=1e-9)
    assert [r.pad_point_control for r in plan.robots] == ["contact"] * 3
