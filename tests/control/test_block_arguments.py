"""The public API's edges: bad arguments to :func:`AddCooperativeController`, :class:`Gains` and
the blocks' constructors (the 58 reported and more). Each is a ``ValueError`` or ``TypeError``
whose message names the argument; none is accepted; nothing raises ``SystemExit`` (every case
catches ``BaseException`` to tell them apart)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from drake_coop.control import (
    AddCooperativeController,
    DifferenceVelocity,
    Gains,
    MeasuredVelocity,
    NoForceEstimate,
    SensedForce,
    VelocityObserver,
)
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.scenario.resources import urdf_dir

URDF = str(urdf_dir() / "crs_a465_3dof.urdf")
NAN, INF = math.nan, math.inf


def _plant(finalize=True):
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    plant.SetUseSampledOutputPorts(False)
    (arm,) = Parser(plant, "arm1").AddModels(URDF)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm),
                     RigidTransform([-0.65, 0.0, 0.0]))
    if finalize:
        plant.Finalize()
    return builder, plant, arm


def _add(**changes):
    builder, plant, arm = _plant()
    kwargs = dict(gains=Gains(), period=0.009, controller_model=URDF, ee_frame="pad",
                  normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43])
    for key, value in changes.items():
        kwargs[key] = value(builder, plant) if callable(value) else value
    return AddCooperativeController(builder, plant, arm, **kwargs)


def _momentum(gain):
    return lambda: _add(gains=Gains(momentum_gain=gain), force_source="momentum")


def _port(size):
    return lambda builder, plant: builder.AddSystem(
        ConstantVectorSource(np.zeros(size))).get_output_port()


def _twice(**second):
    def call():
        builder, plant, arm = _plant()
        kwargs = dict(gains=Gains(), period=0.009, controller_model=URDF, ee_frame="pad",
                      normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43])
        AddCooperativeController(builder, plant, arm, **kwargs)
        AddCooperativeController(builder, plant, arm, **{**kwargs, **second})
    return call


def _unfinalized():
    builder, plant, arm = _plant(finalize=False)
    AddCooperativeController(builder, plant, arm, gains=Gains(), period=0.009,
                             controller_model=URDF, ee_frame="pad",
                             normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43])


LAYOUT = ReferenceLayout(3, 1)

#: (case id, call, the argument its message must name)
CASES = [
    # gains: the type, then each field
    ("gains-dict", lambda: _add(gains={"Lambda": 35.0}), "gains"),
    ("gains-None", lambda: _add(gains=None), "gains"),
    ("Lambda-str", lambda: _add(gains=Gains(Lambda="35")), "Lambda"),
    ("Lambda-nan", lambda: _add(gains=Gains(Lambda=NAN)), "Lambda"),
    ("Lambda-neg", lambda: _add(gains=Gains(Lambda=-1.0)), "Lambda"),
    ("Lambda-inf", lambda: _add(gains=Gains(Lambda=INF)), "Lambda"),
    ("Lambda-list", lambda: _add(gains=Gains(Lambda=[35.0])), "Lambda"),
    ("K_R-abc", lambda: _add(gains=Gains(K_R="abc")), "K_R"),
    ("K_R-short", lambda: _add(gains=Gains(K_R=[1.0, 2.0])), "K_R"),
    ("K_R-2d", lambda: _add(gains=Gains(K_R=[[1.0, 2.0, 3.0]])), "K_R"),
    ("K_R-nan", lambda: _add(gains=Gains(K_R=[NAN, 1.0, 1.0])), "K_R"),
    ("K_R-zero", lambda: _add(gains=Gains(K_R=[0.0, 1.0, 1.0])), "K_R"),
    ("K_R-dict", lambda: _add(gains=Gains(K_R={"a": 1.0})), "K_R"),
    ("K_R-scalar", lambda: _add(gains=Gains(K_R=120.0)), "K_R"),
    ("K_R-strs", lambda: _add(gains=Gains(K_R=["a", "b", "c"])), "K_R"),
    ("k_d-zero", lambda: _add(gains=Gains(k_d=0.0)), "k_d"),
    ("k_d-str", lambda: _add(gains=Gains(k_d="40")), "k_d"),
    ("k_F-neg", lambda: _add(gains=Gains(k_F=-0.1)), "k_F"),
    ("k_F-nan", lambda: _add(gains=Gains(k_F=NAN)), "k_F"),
    ("zeta-None", lambda: _add(gains=Gains(zeta=None)), "zeta"),
    ("beta-neg", lambda: _add(gains=Gains(beta=-1.0)), "beta"),
    ("xi-neg", lambda: _add(gains=Gains(xi=-1.0)), "xi"),
    ("xi-str", lambda: _add(gains=Gains(xi="1e-5")), "xi"),
    ("xi-bool", lambda: _add(gains=Gains(xi=True)), "xi"),
    ("xi_matrix-shape", lambda: _add(gains=Gains(xi_matrix=[[1.0, 0.0], [0.0, 1.0]])),
     "xi_matrix"),
    ("xi_matrix-neg", lambda: _add(gains=Gains(xi_matrix=[[-1.0]])), "xi_matrix"),
    ("xi_matrix-str", lambda: _add(gains=Gains(xi_matrix="a")), "xi_matrix"),
    ("momentum_gain-str", lambda: _add(gains=Gains(momentum_gain="50")), "momentum_gain"),
    ("momentum_gain-nan", _momentum(NAN), "momentum_gain"),
    ("momentum_gain-zero", _momentum(0.0), "momentum_gain"),
    ("momentum_gain-neg", _momentum(-1.0), "momentum_gain"),
    ("momentum_gain-1e6", _momentum(1e6), "momentum_gain"),
    ("momentum_gain-inf", _momentum(INF), "momentum_gain"),
    # period
    ("period-str", lambda: _add(period="0.009"), "period"),
    ("period-None", lambda: _add(period=None), "period"),
    ("period-nan", lambda: _add(period=NAN), "period"),
    ("period-zero", lambda: _add(period=0.0), "period"),
    ("period-neg", lambda: _add(period=-0.009), "period"),
    ("period-1e-9", lambda: _add(period=1e-9), "period"),
    ("period-1e6", lambda: _add(period=1e6), "period"),
    ("period-0.0095", lambda: _add(period=0.0095), "period"),
    ("period-list", lambda: _add(period=[0.009]), "period"),
    # sources
    ("velocity_source-unknown", lambda: _add(velocity_source="tachometer"), "velocity_source"),
    ("velocity_source-None", lambda: _add(velocity_source=None), "velocity_source"),
    ("velocity_source-list", lambda: _add(velocity_source=["observer"]), "velocity_source"),
    ("force_source-unknown", lambda: _add(force_source="ft"), "force_source"),
    ("force_source-int", lambda: _add(force_source=3), "force_source"),
    ("difference_cutoff_hz-neg",
     lambda: _add(velocity_source="difference", difference_cutoff_hz=-5.0),
     "difference_cutoff_hz"),
    ("difference_cutoff_hz-str",
     lambda: _add(velocity_source="difference", difference_cutoff_hz="10"),
     "difference_cutoff_hz"),
    ("difference_cutoff_hz-nan",
     lambda: _add(velocity_source="difference", difference_cutoff_hz=NAN),
     "difference_cutoff_hz"),
    ("difference_cutoff_hz-unused", lambda: _add(difference_cutoff_hz=10.0),
     "difference_cutoff_hz"),
    # the constraint and the model
    ("normals-short", lambda: _add(normals=[[1.0, 0.0]]), "normals"),
    ("normals-nan", lambda: _add(normals=[[NAN, 0.0, 0.0]]), "normals"),
    ("normals-zero", lambda: _add(normals=[[0.0, 0.0, 0.0]]), "normals"),
    ("normals-str", lambda: _add(normals="x"), "normals"),
    ("normals-dependent", lambda: _add(normals=[[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]), "normals"),
    ("normals-dict", lambda: _add(normals={"x": 1.0}), "normals"),
    ("contact_point-short", lambda: _add(contact_point=[0.0, 0.0]), "contact_point"),
    ("contact_point-nan", lambda: _add(contact_point=[NAN, 0.0, 0.0]), "contact_point"),
    ("contact_point-str", lambda: _add(contact_point="abc"), "contact_point"),
    ("ee_frame-unknown", lambda: _add(ee_frame="no_such_frame"), "ee_frame"),
    ("ee_frame-missing", lambda: _add(ee_frame=None), "ee_frame"),
    ("ee_frame-int", lambda: _add(ee_frame=3), "ee_frame"),
    ("controller_model-int", lambda: _add(controller_model=42), "controller_model"),
    ("controller_model-missing-file", lambda: _add(controller_model="/nonexistent/arm.urdf"),
     "controller_model"),
    # wiring
    ("q-size", lambda: _add(q=_port(2)), "q"),
    ("q-not-a-port", lambda: _add(q=[0.0, 0.0, 0.0]), "q"),
    ("lambda_sensor-size", lambda: _add(force_source="sensor", lambda_sensor=_port(3)),
     "lambda_sensor"),
    ("lambda_sensor-unused", lambda: _add(lambda_sensor=_port(1)), "lambda_sensor"),
    ("lambda_sensor-foreign-builder (Drake's wiring error)",
     lambda: _add(force_source="sensor", lambda_sensor=lambda builder, plant: _port(1)(
         DiagramBuilder(), plant)), "model_instance"),
    ("name-int", lambda: _add(name=3), "name"),
    ("name-empty", lambda: _add(name=""), "name"),
    ("second-controller-on-one-arm", _twice(), "model_instance"),
    ("second-controller-same-name", _twice(connect_actuation=False), "name"),
    ("builder-None", lambda: AddCooperativeController(None, _plant()[1], _plant()[2],
                                                      gains=Gains(), period=0.009,
                                                      controller_model=URDF), "builder"),
    ("plant-unfinalized", _unfinalized, "plant"),
    ("model_instance-int", lambda: AddCooperativeController(
        *_plant()[:2], 99, gains=Gains(), period=0.009, controller_model=URDF, ee_frame="pad",
        normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43]), "model_instance"),
    # the blocks alone
    ("VelocityObserver-Lambda-str", lambda: VelocityObserver(3, "35", 40.0, 0.009), "Lambda"),
    ("VelocityObserver-k_d-nan", lambda: VelocityObserver(3, 35.0, NAN, 0.009), "k_d"),
    ("VelocityObserver-period", lambda: VelocityObserver(3, 35.0, 40.0, 0.0), "period"),
    ("VelocityObserver-n-zero", lambda: VelocityObserver(0, 35.0, 40.0, 0.009), "n"),
    ("VelocityObserver-n-float", lambda: VelocityObserver(3.5, 35.0, 40.0, 0.009), "n"),
    ("MeasuredVelocity-n", lambda: MeasuredVelocity(-1), "n"),
    ("MeasuredVelocity-n-str", lambda: MeasuredVelocity("3"), "n"),
    ("DifferenceVelocity-cutoff", lambda: DifferenceVelocity(3, 0.009, -1.0), "cutoff_hz"),
    ("DifferenceVelocity-cutoff-str", lambda: DifferenceVelocity(3, 0.009, "5"), "cutoff_hz"),
    ("DifferenceVelocity-period", lambda: DifferenceVelocity(3, "0.009"), "period"),
    ("SensedForce-period", lambda: SensedForce("0.009", LAYOUT), "period"),
    ("SensedForce-layout", lambda: SensedForce(0.009, "layout"), "layout"),
    ("NoForceEstimate-layout", lambda: NoForceEstimate(None), "layout"),
]


def test_there_are_at_least_the_58_reported_cases():
    assert len(CASES) >= 58
    assert len({case_id for case_id, _, _ in CASES}) == len(CASES)


@pytest.mark.parametrize("case_id, call, argument", CASES, ids=[c[0] for c in CASES])
def test_a_bad_argument_is_refused_naming_it(case_id, call, argument):
    try:
        call()
    except (ValueError, TypeError) as exc:
        message = str(exc)
        assert "\n" not in message
        assert message.startswith(f"{argument}:") or f"{argument}:" in message.split(" ")[0] \
            or message.split(":")[0].split(", ").count(argument), message
        return
    except BaseException as exc:          # SystemExit, RuntimeError, ...: not allowed
        pytest.fail(f"{case_id}: {type(exc).__name__}: {exc}")
    pytest.fail(f"{case_id}: accepted silently")


def test_good_arguments_are_accepted():
    """The cases above differ from accepted calls in the one argument only."""
    handles = _add()
    assert handles.system.get_name() == "arm1::crs_a465_control"
    _add(gains=Gains(momentum_gain=50.0), force_source="momentum")
    _add(velocity_source="difference", difference_cutoff_hz=10.0)
    _add(force_source="sensor", lambda_sensor=_port(1))
    VelocityObserver(3, 35.0, 40.0, 0.009)
    DifferenceVelocity(3, 0.009, 5.0)


def _two_arms(c2, n2):
    """Two CRS A465 arms in one builder: arm1 at x = −0.65 pressing on the face whose outward
    normal is −x at c1 = (0, 0, 0.43) (its inward normal +x), arm2 at x = +0.65 with the
    given contact point and outward normal."""
    import warnings

    from drake_coop.control.block import GraspWarning

    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    plant.SetUseSampledOutputPorts(False)
    arms = []
    for name, x, yaw in (("arm1", -0.65, 0.0), ("arm2", 0.65, math.pi)):
        (arm,) = Parser(plant, name).AddModels(URDF)
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm),
                         RigidTransform(RollPitchYaw(0.0, 0.0, yaw), [x, 0.0, 0.0]))
        arms.append(arm)
    plant.Finalize()
    common = dict(gains=Gains(), period=0.009, controller_model=URDF, ee_frame="pad")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        AddCooperativeController(builder, plant, arms[0], normals=[[-1.0, 0.0, 0.0]],
                                 contact_point=[-0.05, 0.0, 0.43], **common)
        AddCooperativeController(builder, plant, arms[1], normals=[n2], contact_point=c2,
                                 **common)
    return [str(w.message) for w in caught if issubclass(w.category, GraspWarning)]


def test_pads_that_pass_each_other_are_named_in_one_warning():
    """The squeeze of two opposed pads: none; arm2's pad placed beyond arm1's (the pads pass
    each other, a positive λ pulls), or its normal turned the wrong way: one warning naming
    both arms (the independent check: the sign of (c_j − c_i)·ν_i by hand below)."""
    nu1 = np.array([1.0, 0.0, 0.0])
    c1 = np.array([-0.05, 0.0, 0.43])
    good = ([0.05, 0.0, 0.43], [1.0, 0.0, 0.0])
    assert (np.array(good[0]) - c1) @ nu1 > 0 and (c1 - good[0]) @ -np.array(good[1]) > 0
    assert _two_arms(*good) == []
    passed = ([-0.10, 0.0, 0.43], [1.0, 0.0, 0.0])
    assert (np.array(passed[0]) - c1) @ nu1 < 0
    (message,) = _two_arms(*passed)
    assert "arm2" in message and "arm1" in message and "\n" not in message
    flipped = ([0.05, 0.0, 0.43], [-1.0, 0.0, 0.0])
    assert len(_two_arms(*flipped)) == 1
