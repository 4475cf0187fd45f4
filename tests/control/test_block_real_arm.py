"""The real-arm options reach the blocks through ``AddCooperativeController``."""

import numpy as np
import pytest

from drake_coop.control import AddCooperativeController, Gains
from tests.control.test_block import URDF, _user_plant


def test_damping_and_torque_limits_reach_the_law_and_the_momentum_observer():
    builder, plant, arms = _user_plant(n_arms=1)
    limits = [35.0, 35.0, 20.0]
    block = AddCooperativeController(
        builder, plant, arms[0], gains=Gains(), period=0.009, controller_model=URDF,
        ee_frame="pad", normals=[1.0, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43],
        force_source="momentum", pinv_damping=0.05, momentum_torque_limits=limits)
    assert block.law.pinv_damping == 0.05
    tau = np.array([50.0, -50.0, 10.0])
    np.testing.assert_array_equal(block.force_source.applied_torque(tau), [35.0, -35.0, 10.0])


def test_the_defaults_are_the_papers():
    builder, plant, arms = _user_plant(n_arms=1)
    block = AddCooperativeController(
        builder, plant, arms[0], gains=Gains(), period=0.009, controller_model=URDF,
        ee_frame="pad", normals=[1.0, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43],
        force_source="momentum")
    assert block.law.pinv_damping == 0.0 and block.law.model.coulomb is None
    tau = np.array([50.0, -50.0, 10.0])
    np.testing.assert_array_equal(block.force_source.applied_torque(tau), tau)
    builder, plant, arms = _user_plant(n_arms=1)
    with pytest.raises(ValueError, match="pinv_damping"):
        AddCooperativeController(
            builder, plant, arms[0], gains=Gains(), period=0.009, controller_model=URDF,
            ee_frame="pad", normals=[1.0, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43],
            pinv_damping=-1.0)
