"""The momentum observer fed the torque actually applied (after saturation), against the
closed form of its first tick: an arm at rest whose actuators saturate."""

import numpy as np
import pytest

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.momentum import MomentumObserver
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario.loading import default_scenario

H = 0.009


def _first_tick(obs, q, tau):
    context = obs.CreateDefaultContext()
    obs.get_q_input_port().FixValue(context, q)
    obs.get_qdot_hat_input_port().FixValue(context, np.zeros(3))
    obs.get_tau_input_port().FixValue(context, tau)
    obs.get_reference_input_port().FixValue(context, np.zeros(ReferenceLayout(3, 1).size))
    update = obs.AllocateDiscreteVariables()
    obs.CalcForcedDiscreteVariableUpdate(context, update)
    context.SetDiscreteState(update)
    return obs.get_tau_ext_hat_output_port().Eval(context)


def test_a_saturated_command_is_not_read_as_external_torque():
    s = default_scenario()
    model = arm_model(Arm(s.robots[0], s.task))
    q = np.array([0.1, 0.6, -0.4])
    limits = np.array([35.0, 35.0, 35.0])
    tau_ext = np.array([1.5, -2.0, 0.7])
    applied = model.g(q) - tau_ext                   # statics under τ_ext: what the arm gets
    commanded = applied + np.array([0.0, 40.0, 0.0])  # a command beyond the limit ...
    commanded[1] = np.sign(commanded[1]) * (limits[1] + 40.0)
    applied[1] = np.sign(commanded[1]) * limits[1]    # ... clipped by the actuators
    tau_ext[1] = model.g(q)[1] - applied[1]          # the external torque that holds it still
    gain = 50.0
    clipped = MomentumObserver(model, ReferenceLayout(3, 1), H, gain, torque_limits=limits)
    plain = MomentumObserver(model, ReferenceLayout(3, 1), H, gain)
    # r(1) = h K_O τ_ext with the applied torque; the commanded one reads the excess as τ_ext.
    np.testing.assert_allclose(_first_tick(clipped, q, commanded), H * gain * tau_ext,
                               rtol=1e-12, atol=1e-12)
    wrong = _first_tick(plain, q, commanded)
    assert abs(wrong[1] - H * gain * tau_ext[1]) > 0.1
    np.testing.assert_array_equal(clipped.applied_torque(commanded),
                                  np.clip(commanded, -limits, limits))


@pytest.mark.parametrize("limits", [[1.0, 2.0], [1.0, -2.0, 3.0], [1.0, np.inf, 3.0]])
def test_bad_torque_limits_are_refused_by_name(limits):
    s = default_scenario()
    with pytest.raises(ValueError, match="torque_limits"):
        MomentumObserver(arm_model(Arm(s.robots[0], s.task)), ReferenceLayout(3, 1), H, 50.0,
                         torque_limits=limits)
