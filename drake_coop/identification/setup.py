"""Where identifying one robot starts: its nominal model, parameter layout, simulated truth and
limits (:func:`identification_setup`), and its excitation (:func:`design_for`) — shared by the
simulated experiment (:func:`~drake_coop.identification.report.identify_robot`) and the one
driven over the wire (:mod:`~drake_coop.robot.wire_identify`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.identification.excitation import (
    ExcitationLimits,
    FourierExcitation,
    design_excitation,
)
from drake_coop.identification.regressor import (
    ArmStructure,
    Regressor,
    load_structure,
    true_parameters,
)
from drake_coop.scenario.schema import Scenario

__all__ = ["IdentificationSetup", "IdentifyInputError", "design_for", "identification_setup"]


class IdentifyInputError(ValueError):
    """Bad input of ``identify`` (one-line message)."""


def _velocity_limits(structure: ArmStructure) -> np.ndarray:
    plant = structure.plant
    return np.array([min(10.0, plant.GetJointByName(j).velocity_upper_limits()[0])
                     for j in structure.joints])


@dataclass
class IdentificationSetup:
    """What identifying one robot starts from (:func:`identification_setup`).

    Attributes
    ----------
    index : int
        The robot (0-based).
    arm : Arm
        Its resolved arm.
    nominal : ArmModel
        The nominal model (the controller's model of the scenario).
    structure : ArmStructure
        Its parameter layout.
    regressor : Regressor
        Its regressor.
    theta_true, theta_nominal : numpy.ndarray
        The simulated truth's and the nominal model's parameters (p,).
    limits : ExcitationLimits
        The excitation's limits (the URDF's positions and velocities, the torque limits).
    """

    index: int
    arm: object
    nominal: object
    structure: ArmStructure
    regressor: Regressor
    theta_true: np.ndarray
    theta_nominal: np.ndarray
    limits: ExcitationLimits

    def nominal_torque(self, q, v, a) -> np.ndarray:
        """The nominal model's inverse dynamics along samples.

        Parameters
        ----------
        q, v, a : numpy.ndarray
            Positions, velocities, accelerations (N, n).

        Returns
        -------
        numpy.ndarray
            The torques (N, n), N·m.
        """
        return np.array([self.nominal.inverse_dynamics_terms(q[k], v[k], a[k])
                         for k in range(len(q))])


def identification_setup(scenario: Scenario, index: int) -> IdentificationSetup:
    """The nominal model, parameter layout, truth and limits of robot ``index``.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    index : int
        The robot (0-based).

    Returns
    -------
    IdentificationSetup
        The setup.
    """
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.model_error import controller_arm_model

    robot = scenario.robots[index]
    arm = Arm(robot, scenario.task)
    nominal = controller_arm_model(arm, robot.model_error)
    structure = load_structure(arm.urdf_path, arm.base_frame,
                               payload_mass=robot.model_error.payload_mass,
                               sensor_joint=robot.sensor_joint)
    theta_true = true_parameters(structure)
    if robot.model_error.coulomb_friction:
        theta_true[structure.joint_slice("coulomb")] = robot.model_error.coulomb_friction
    n = structure.n
    limits = ExcitationLimits(
        q_min=arm.q_min, q_max=arm.q_max,
        torque_limits=(np.full(n, np.inf) if robot.actuators.torque_limits is None
                       else np.asarray(robot.actuators.torque_limits, float)),
        velocity_limits=_velocity_limits(structure))
    return IdentificationSetup(index, arm, nominal, structure, Regressor(structure), theta_true,
                               true_parameters(structure, nominal.plant), limits)


def design_for(setup: IdentificationSetup, duration: float, seed: int = 0,
               q0: np.ndarray | None = None, name: str = "") -> FourierExcitation:
    """The excitation of ``duration`` s about ``q0`` (default: the middle of the joint range).

    Parameters
    ----------
    setup : IdentificationSetup
        The robot's setup.
    duration : float
        The excitation's length, s.
    seed : int
        Seeds its random candidates.
    q0 : numpy.ndarray or None
        Where it starts and ends (n,), rad.
    name : str
        The robot's name, for the refusal.

    Returns
    -------
    FourierExcitation
        The excitation.

    Raises
    ------
    IdentifyInputError
        No excitation fits the arm's limits.
    """
    from drake_coop.identification.excitation import ExcitationError

    q0 = 0.5 * (setup.arm.q_min + setup.arm.q_max) if q0 is None else np.asarray(q0, float)
    try:
        excitation, _ = design_excitation(duration, q0, setup.limits, setup.nominal_torque,
                                          setup.regressor.matrix, seed=seed)
    except ExcitationError as exc:
        raise IdentifyInputError(f"{name or 'robot'}: {exc}") from None
    return excitation
