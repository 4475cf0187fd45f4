"""The actuators of one robot: per-joint torque saturation, and the joints' Coulomb friction.

``robotN_actuators`` is Drake's :class:`~pydrake.systems.primitives.Saturation`:
``τ = clamp(τ_cmd, −τ_max, τ_max)`` per joint (infinite limits when none are given: the
torque passes unchanged). When ``model_error.coulomb_friction`` is nonzero, the simulated
joints also feel ``τ_f = −f_c tanh(q̇ / v_s)`` (:class:`CoulombFriction`, regularized with
``v_s = 0.01 rad/s`` so that the plant's explicit 1 ms step does not chatter), added to the
saturated torque by an :class:`~pydrake.systems.primitives.Adder` named
``robotN_joint_friction_sum``. The controller knows neither.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiagramBuilder,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import Adder, Saturation

#: Velocity scale of the regularized Coulomb friction (rad/s).
FRICTION_VELOCITY = 0.01


class CoulombFriction(LeafSystem):
    """Joint Coulomb friction ``τ_f = −f_c tanh(q̇ / v_s)`` of one simulated arm.

    Parameters
    ----------
    f_c : numpy.ndarray
        The Coulomb friction torques ``f_c`` (n,), N·m.
    v_s : float
        The smoothing velocity ``v_s``, rad/s.

    Input ports
    -----------
    state : 2n-vector
        The arm's ``[q, q̇]`` from the plant.

    Output ports
    ------------
    tau_friction : n-vector
        The friction torques (N·m).
    """

    def __init__(self, f_c: np.ndarray, v_s: float = FRICTION_VELOCITY):
        super().__init__()
        self._f_c = np.asarray(f_c, dtype=float)
        self._v_s = float(v_s)
        n = self._f_c.size
        self._n = n
        self._state = self.DeclareVectorInputPort("state", 2 * n)
        self.DeclareVectorOutputPort("tau_friction", n, self._calc_tau_friction)

    def _calc_tau_friction(self, context: Context, output: BasicVector) -> None:
        v = self._state.Eval(context)[self._n:]
        output.SetFromVector(-self._f_c * np.tanh(v / self._v_s))


def add_actuators(builder: DiagramBuilder, name: str, n: int,
                  torque_limits: list[float] | None, coulomb_friction: list[float],
                  state_port: OutputPort) -> tuple[Saturation, OutputPort]:
    """Add ``<name>_actuators`` (and the friction when nonzero) to ``builder``.

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder.
    name : str
        Robot name (prefix of the systems).
    n : int
        Number of joints.
    torque_limits : list of float or None
        ``τ_max`` per joint (N·m); None: unlimited.
    coulomb_friction : list of float
        ``f_c`` per joint (N·m).
    state_port : OutputPort
        The plant's state output of this arm (read by the friction only).

    Returns
    -------
    (Saturation, OutputPort)
        The saturation (connect the commanded torque to its input; its output is the applied
        motor torque) and the port to connect to the plant's actuation input.
    """
    limit = np.full(n, np.inf) if torque_limits is None else np.asarray(torque_limits, float)
    saturation = builder.AddNamedSystem(f"{name}_actuators", Saturation(-limit, limit))
    if not np.any(np.asarray(coulomb_friction, dtype=float) > 0.0):
        return saturation, saturation.get_output_port()
    friction = builder.AddNamedSystem(f"{name}_joint_friction", CoulombFriction(coulomb_friction))
    builder.Connect(state_port, friction.get_input_port())
    adder = builder.AddNamedSystem(f"{name}_joint_friction_sum", Adder(2, n))
    builder.Connect(saturation.get_output_port(), adder.get_input_port(0))
    builder.Connect(friction.get_output_port(), adder.get_input_port(1))
    return saturation, adder.get_output_port()
