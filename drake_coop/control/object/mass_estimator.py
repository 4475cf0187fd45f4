"""One arm's share of the object's mass estimated online by recursive least squares
(:class:`MassEstimator`, a LeafSystem), from the arm's model and signals, without an F/T sensor."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    OutputPort,
)

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object.grasp import contact_jacobian
from drake_coop.control.object.model import GRAVITY, _vector
from drake_coop.control.params import check_period


class MassEstimator(LeafSystem):
    r"""Recursive least squares of one arm's share ``m_i`` of the object's mass, from the
    arm's model, its measured ``q``, the commanded ``τ`` and the velocity observer — no F/T
    sensor.

    The force the object applies to the pad, from the arm's own model with the controller's
    reference acceleration and the observer's velocity (the loop tracks ``q̈̂_r``):

    .. math::
        \hat F = J_x(q)^{+T}\big(H(q)\ddot{\hat q}_r + C(q,\dot q_o)\dot q_o
                  + D\dot q_o + g(q) - \tau\big)

    (:math:`J_x^{+T}` the least-squares inverse of :math:`J_x^T`; the inverse for a 3-joint arm).
    The arm applies ``−F̂`` to the object, whose vertical part is ``m_i (g + a_d,z)``: a linear
    regression ``y = φ θ`` with ``y = −F̂_z``, ``φ = g + a_d,z``, ``θ = m_i``, solved by RLS with
    forgetting factor ``ρ`` and measurement variance ``R``:

    .. math::
        K = \frac{P\varphi}{\rho R + \varphi^2 P},\quad
        \hat\theta \leftarrow \hat\theta + K(y - \varphi\hat\theta),\quad
        P \leftarrow (P - K\varphi P)/\rho

    updated at every tick while the object is held (``held`` row of the reference), frozen
    otherwise. The squeeze (along the grasp line, horizontal here) does not enter ``F̂_z``.

    Persistence of excitation: the regressor must satisfy :math:`\sum_{\text{window}} \varphi^2
    \ge \alpha > 0` over every window of the forgetting horizon ``1/(1 − ρ)`` samples; with
    ``φ = g + a_d,z`` this holds whenever the desired vertical acceleration stays away from free
    fall (``a_d,z > −g``), i.e. always in a carrying task: gravity itself excites the mass. A
    centre-of-mass offset along the grasp line is identifiable only from both arms' shares together
    (``c = (m_1 p_1 + m_2 p_2)/(m_1 + m_2)`` on that line); each arm alone estimates what its own
    feedforward needs, its share ``m_i``.

    .. pydrake_system::

        name: MassEstimator
        input_ports:
        - q
        - qdot_o
        - qddot_r_hat
        - tau
        - acceleration_d
        - reference
        - f_couple (optional)
        output_ports:
        - mass_share
        - force_estimate

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm (identified or nominal).
    period : float
        The update period (s): the control period ``h`` or a whole multiple of it (the
        estimate is slow; :mod:`drake_coop.experiment.object_blocks` updates it every 5 ticks).
    prior : float
        ``θ̂(0)``, the prior share (kg), >= 0.
    prior_std : float
        Its standard deviation (kg), > 0: ``P(0) = prior_std²``.
    forgetting : float
        ``ρ`` in (0, 1] per update; default 0.995 (a horizon of 200 updates, 1.8 s at 9 ms:
        the stand carries the object during the first moments of the grasp, whose samples are
        then forgotten).
    noise_std : float
        ``√R`` (N), the spread of ``F̂_z``; default 1 N.
    gravity : float
        ``g`` (m/s²).
    contact_offset : array_like, shape (3,), optional
        ``r`` from E to where the object's force acts (world frame): ``F̂`` is then solved
        with ``J_c`` (:func:`contact_jacobian`) instead of ``J_x``. Without it, on a spherical
        pad the moment ``r × F`` of the carried weight about the pad's centre reads as extra
        vertical force (+3.5 % and +4.7 % for the two shipped arms at the circle's start).
    couple : bool
        Declare the input ``f_couple`` (:class:`LoadFeedforward`'s): the arm's part of the
        squeeze's couple, which is no part of the mass, is taken out of the measurement,
        ``y = −F̂_z − f_c,z``. Default False: no such port.

    Input ports
    -----------
    q : n-vector
        Measured joint positions.
    qdot_o : n-vector
        The velocity observer's ``q̇_o`` (8).
    qddot_r_hat : n-vector
        The controller's ``q̈̂_r(k)`` (11).
    tau : n-vector
        The torque commanded at the tick (the controller's plus the feedforward).
    acceleration_d : 3-vector
        The object's desired acceleration.
    reference : (3n + m + 1)-vector
        The arm's reference (its ``held`` row).
    f_couple : 3-vector, with ``couple``
        ``f_c,i`` (N).

    Output ports
    ------------
    mass_share : 1-vector
        ``θ̂ = m̂_i`` (kg), state.
    force_estimate : 3-vector
        The last ``F̂`` (N), state.
    """

    def __init__(self, model: ArmModel, period: float, prior: float, prior_std: float,
                 forgetting: float = 0.995, noise_std: float = 1.0,
                 gravity: float = GRAVITY, contact_offset=None, couple: bool = False):
        super().__init__()
        check_period(period)
        if not (np.isfinite(prior) and prior >= 0):
            raise ValueError(f"prior: a mass >= 0 is required (kg), got {prior!r}")
        if not (np.isfinite(prior_std) and prior_std > 0):
            raise ValueError(f"prior_std: a number > 0 is required (kg), got {prior_std!r}")
        if not (0 < forgetting <= 1):
            raise ValueError(f"forgetting: a number in (0, 1] is required, got {forgetting!r}")
        if not (np.isfinite(noise_std) and noise_std > 0):
            raise ValueError(f"noise_std: a number > 0 is required (N), got {noise_std!r}")
        self._model = model
        self._r = None if contact_offset is None else _vector(contact_offset, "contact_offset")
        n = model.n
        self._layout = ReferenceLayout(n, model.m)
        self._rho = float(forgetting)
        self._R = float(noise_std) ** 2
        self._g = float(gravity)
        self._q = self.DeclareVectorInputPort("q", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._qddot = self.DeclareVectorInputPort("qddot_r_hat", n)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._a_d = self.DeclareVectorInputPort("acceleration_d", 3)
        self._reference = self.DeclareVectorInputPort("reference", self._layout.size)
        self._couple = self.DeclareVectorInputPort("f_couple", 3) if couple else None
        self._theta = self.DeclareDiscreteState([float(prior)])
        self._P = self.DeclareDiscreteState([float(prior_std) ** 2])
        self._F = self.DeclareDiscreteState(np.zeros(3))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._mass_out = self.DeclareStateOutputPort("mass_share", self._theta)
        self._F_out = self.DeclareStateOutputPort("force_estimate", self._F)

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_qdot_o_input_port(self) -> InputPort:
        """The observer's ``q̇_o``."""
        return self._qdot_o

    def get_qddot_r_hat_input_port(self) -> InputPort:
        """The controller's ``q̈̂_r``."""
        return self._qddot

    def get_tau_input_port(self) -> InputPort:
        """The commanded torque."""
        return self._tau

    def get_acceleration_d_input_port(self) -> InputPort:
        """The object's desired acceleration."""
        return self._a_d

    def get_reference_input_port(self) -> InputPort:
        """The arm's reference (its ``held`` row)."""
        return self._reference

    def get_f_couple_input_port(self) -> InputPort:
        """``f_c,i`` (with ``couple`` only)."""
        if self._couple is None:
            raise ValueError("couple: the f_couple port exists only with couple=True")
        return self._couple

    def get_mass_share_output_port(self) -> OutputPort:
        """``m̂_i`` (kg)."""
        return self._mass_out

    def get_force_estimate_output_port(self) -> OutputPort:
        """``F̂`` (N)."""
        return self._F_out

    def pad_force(self, q, qdot_o, qddot_r_hat, tau) -> np.ndarray:
        r"""The object's force on the pad, from the arm's model (N):
        :math:`\hat F = J_x^{+T} (H \ddot{\hat q}_r + C(q, \dot q_o)\, \dot q_o
        + D \dot q_o + g - \tau)` (``J_c`` with a ``contact_offset``).

        Parameters
        ----------
        q : numpy.ndarray
            Measured joint positions (n,), rad.
        qdot_o : numpy.ndarray
            ``q̇_o`` of (8) (n,), rad/s.
        qddot_r_hat : numpy.ndarray
            ``q̈̂_r`` of (11) (n,), rad/s².
        tau : numpy.ndarray
            The torque applied (n,), N·m.

        Returns
        -------
        numpy.ndarray
            ``F̂`` (3,), N, world frame.
        """
        rhs = self._model.inverse_dynamics_terms(q, qdot_o, qddot_r_hat) - tau
        J = contact_jacobian(self._model, q, self._r)
        if J.shape[1] == 3:
            try:
                return np.linalg.solve(J.T, rhs)
            except np.linalg.LinAlgError:     # a singular posture: the least-squares force
                pass
        return np.linalg.lstsq(J.T, rhs, rcond=None)[0]

    def _update(self, context: Context, xd: DiscreteValues) -> None:
        if not self._layout.held(self._reference.Eval(context)):
            return
        F = self.pad_force(self._q.Eval(context), self._qdot_o.Eval(context),
                           self._qddot.Eval(context), self._tau.Eval(context))
        phi = self._g + float(self._a_d.Eval(context)[2])
        theta = float(context.get_discrete_state(self._theta).value()[0])
        P = float(context.get_discrete_state(self._P).value()[0])
        y = -F[2]
        if self._couple is not None:
            y -= float(self._couple.Eval(context)[2])
        K = P * phi / (self._rho * self._R + phi * phi * P)
        theta += K * (y - phi * theta)
        P = (P - K * phi * P) / self._rho
        xd.set_value(self._theta, [theta])
        xd.set_value(self._P, [P])
        xd.set_value(self._F, F)
