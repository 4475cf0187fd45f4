"""The alternatives to the observers (:mod:`drake_coop.control.sources`), each alone, against closed
forms: the backward difference and its low-pass, the sensed force's integral (6), the
implicit force control's constant outputs, the measured-velocity baseline."""

import math

import numpy as np
import pytest

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.sources import (
    DifferenceVelocity,
    MeasuredVelocity,
    NoForceEstimate,
    SensedForce,
)

H = 0.009


def _reference(lam_d, held):
    return np.concatenate([np.zeros(9), [lam_d], [float(held)]])


def _difference_outputs(q_of_k, ticks, cutoff=None):
    dv = DifferenceVelocity(3, H, cutoff)
    ctx = dv.CreateDefaultContext()
    dv.set_initial_state(ctx, q_of_k(0))
    out = []
    for k in range(ticks):
        ctx.SetTime(k * H)
        dv.GetInputPort("q").FixValue(ctx, q_of_k(k))
        out.append([dv.GetOutputPort(p).Eval(ctx).copy() for p in ("q_hat", "qdot_hat",
                                                                     "qdot_o")])
        ctx.SetDiscreteState(dv.EvalUniquePeriodicDiscreteUpdate(ctx))
    return np.array(out)        # (ticks, 3 ports, 3 joints)


def test_raw_difference_of_a_sine_is_the_closed_form():
    w = np.array([1.0, 5.0, 20.0])
    q = lambda k: np.sin(w * k * H)
    out = _difference_outputs(q, 50)
    k = np.arange(1, 50)[:, None]
    # (sin ω t_k − sin ω t_{k−1}) / h = (2/h) cos(ω (k − 1/2) h) sin(ω h / 2)
    expected = 2 / H * np.cos(w * (k - 0.5) * H) * np.sin(w * H / 2)
    np.testing.assert_allclose(out[1:, 1], expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(out[0, 1], np.zeros(3))        # q(−1) = q(0)
    np.testing.assert_array_equal(out[:, 2], out[:, 1])          # q̇_o = d/dt q̂
    np.testing.assert_array_equal(out[:, 0], [q(k) for k in range(50)])   # q̂ = q


def test_low_passed_difference_of_a_ramp_is_the_first_order_step_response():
    a, f_c = np.array([0.2, -0.1, 0.05]), 8.0
    out = _difference_outputs(lambda k: 0.3 + a * k * H, 40, cutoff=f_c)
    k = np.arange(40)[:, None]
    # The difference is the step a·1(k ≥ 1); the exactly sampled first-order lag answers
    # y(k) = a (1 − (1 − α)^k) = a (1 − exp(−2π f_c k h)).
    expected = a * (1 - np.exp(-2 * math.pi * f_c * k * H))
    np.testing.assert_allclose(out[:, 1], expected, rtol=1e-12, atol=1e-15)


def test_sensed_force_uses_the_sensor_and_integrates_6_while_held():
    sf = SensedForce(H, ReferenceLayout(3, 1))
    ctx = sf.CreateDefaultContext()
    sf.GetInputPort("lambda_sensor").FixValue(ctx, [30.0])
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0, True))
    DF = 0.0
    for _ in range(4):
        assert sf.GetOutputPort("lambda_hat").Eval(ctx)[0] == 30.0
        assert sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == pytest.approx(DF, abs=1e-15)
        ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
        DF += H * (30.0 - 25.0)
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0, False))
    assert sf.GetOutputPort("lambda_hat").Eval(ctx)[0] == 0.0        # free motion
    ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
    assert sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == 0.0     # reset on release


@pytest.mark.parametrize("held, expected", [(True, 17.5), (False, 0.0)])
def test_no_force_estimate_is_the_desired_force_and_no_integral(held, expected):
    nf = NoForceEstimate(ReferenceLayout(3, 1))
    ctx = nf.CreateDefaultContext()
    nf.GetInputPort("reference").FixValue(ctx, _reference(17.5, held))
    assert nf.GetOutputPort("lambda_hat").Eval(ctx)[0] == expected
    assert nf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == 0.0
    assert not nf.HasDirectFeedthrough(0, 1)      # ΔF̃ depends on nothing


def test_measured_velocity_takes_q_from_the_encoders_and_the_velocity_from_the_plant():
    mv = MeasuredVelocity(3)
    ctx = mv.CreateDefaultContext()
    mv.GetInputPort("state").FixValue(ctx, [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    mv.GetInputPort("q").FixValue(ctx, [1.001, 2.001, 3.001])
    np.testing.assert_array_equal(mv.GetOutputPort("q_hat").Eval(ctx), [1.001, 2.001, 3.001])
    np.testing.assert_array_equal(mv.GetOutputPort("qdot_hat").Eval(ctx), [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(mv.GetOutputPort("qdot_o").Eval(ctx), [0.1, 0.2, 0.3])


# ---------------------------------------------------------------- the sources' registry

def _law():
    from pydrake.math import RigidTransform, RotationMatrix

    from drake_coop.control import ArmModel, FingerLaw, Gains
    from drake_coop.control.arm_plant import make_arm_controller_plant
    from drake_coop.scenario.resources import urdf_dir

    plant = make_arm_controller_plant(str(urdf_dir() / "crs_a465_3dof.urdf"), "base_link",
                                      RigidTransform(RotationMatrix.MakeZRotation(0.0),
                                                     [-0.65, 0.0, 0.0]))
    model = ArmModel.from_plant(plant, "pad", [[-1.0, 0.0, 0.0]], [0.0, 0.0, 0.43])
    return FingerLaw(model, Gains())


def test_every_registered_source_is_built_with_the_ports_it_declares():
    """Each entry of the registry builds its system, of the kind it says, whose input ports
    are exactly the inputs it declares (each a signal of the block or an input from outside)
    and whose outputs hold its kind's and its own."""
    from drake_coop.control.interfaces import ForceSource, VelocitySource
    from drake_coop.control.registry import (
        BLOCK_SIGNALS,
        EXTERNAL_INPUTS,
        KIND_OUTPUTS,
        SOURCES,
    )

    law = _law()
    options = {"difference_cutoff_hz": 20.0, "momentum_torque_limits": None}
    assert len({(s.kind, s.name) for s in SOURCES}) == len(SOURCES)
    assert len({s.suffix for s in SOURCES}) == len(SOURCES)
    for spec in SOURCES:
        system = spec.make(law, H, options)
        assert isinstance(system, {"velocity": VelocitySource, "force": ForceSource}[spec.kind])
        assert type(system).__name__ == spec.class_name
        inputs = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
        assert sorted(inputs) == sorted(spec.inputs), spec.name
        assert set(spec.inputs) <= set(BLOCK_SIGNALS) | set(EXTERNAL_INPUTS)
        outputs = {system.get_output_port(i).get_name()
                   for i in range(system.num_output_ports())}
        assert set(KIND_OUTPUTS[spec.kind]) | set(spec.outputs) <= outputs, spec.name


def test_the_names_exports_and_docs_of_the_sources_are_the_registrys():
    """The accepted names, ``drake_coop.control``'s exports, and for each source an API
    entry (docs/api/control.md) and a line in the sensing guide's table of
    ``velocity_source`` / ``force_source`` (docs/guide/sensing.md)."""
    from pathlib import Path

    import drake_coop.control as control
    from drake_coop.control.params import FORCE_SOURCES, VELOCITY_SOURCES
    from drake_coop.control.registry import SOURCES, names

    assert VELOCITY_SOURCES == names("velocity") == tuple(
        s.name for s in SOURCES if s.kind == "velocity")
    assert FORCE_SOURCES == names("force")
    docs = Path(__file__).resolve().parents[2] / "docs"
    api = (docs / "api" / "control.md").read_text(encoding="utf-8")
    guide = (docs / "guide" / "sensing.md").read_text(encoding="utf-8")
    for spec in SOURCES:
        assert spec.class_name in control.__all__
        assert getattr(control, spec.class_name) is spec.system_class()
        assert f"\n   {spec.class_name}\n" in api, f"{spec.class_name}: no API entry"
        row = next(line for line in guide.splitlines()
                   if line.startswith(f"| `{spec.kind}_source` |"))
        assert f"`{spec.name}`" in row, f"{spec.kind}_source: {spec.name} not in the guide"
        assert spec.label and spec.role
