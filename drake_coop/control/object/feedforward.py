"""One arm's share of the object's load fed forward as joint torques (:class:`LoadFeedforward`,
a LeafSystem)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    Context,
    InputPort,
    LeafSystem,
    OutputPort,
    State,
)

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object.grasp import contact_jacobian
from drake_coop.control.object.model import GRAVITY, _vector
from drake_coop.control.params import check_period, check_positive


class LoadFeedforward(LeafSystem):
    r"""One arm's share of the object's load, fed forward as joint torques.

    .. math::
        \tau_{ff} = J_x(q)^T f_i, \qquad f_i = m_i\,(a_d - g) \quad\text{while held,}
        \qquad \tau_{ff} = 0 \text{ otherwise}

    with ``m_i`` the arm's share of the object's mass (:func:`mass_shares`, or
    :class:`MassEstimator`'s estimate, clamped at ``m_i >= 0``: a negative mass is never fed
    forward), ``a_d`` the object's desired acceleration along the
    shared path and ``g = (0, 0, −g)``. Add ``tau_ff`` to the controller's ``τ`` (13) before
    the actuators; the force observer (22) is left as it is (see the module docstring).

    .. pydrake_system::

        name: LoadFeedforward
        input_ports:
        - q
        - reference
        - acceleration_d
        - mass_share
        - f_couple (optional)
        output_ports:
        - tau_ff
        - f_load

    The mass share is clamped at zero, not held at its prior until trusted: right after the
    grasp the stand still carries part of the object while the squeeze ramps up, so the
    estimate of a share can pass below zero for a moment (the two shares of a 0.5 kg box
    summed to -0.057 kg on two Jaco2s); fed forward, a negative mass would push the object
    down, against the pads' friction. Zero feeds nothing forward, which is what the arm carries
    at that instant; holding the prior instead would feed forward its error (+50 % by default)
    through the time the estimate needs to be trusted, a time with no measured bound.

    Latched by a periodic unrestricted update at ``t_k`` (as the controller's ``τ(k)``), so
    the plant's step at ``t_k`` applies it; both outputs are state output ports.

    Parameters
    ----------
    model : ArmModel
        The arm's model (``J_x``).
    period : float
        ``h`` (s).
    gravity : float
        ``g`` (m/s²).
    contact_offset : array_like, shape (3,), optional
        ``r`` from the end-effector point E to where the load acts (world frame; for a
        spherical pad the radius along the inward normal): ``τ_ff = J_cᵀ f_i``
        (:func:`contact_jacobian`). Default: the load acts at E (``J_x``).
    friction : float, optional
        ``μ`` of a grasp held by friction: a pad can pass the object no more tangential force
        than its friction cone at the commanded squeeze holds, so the part of ``f_i`` across
        the constraint normals ``N`` is limited to ``μ ‖λ_d‖``,

        .. math::
            f_t = (I - N^+ N) f_i, \qquad f_i \leftarrow f_i - f_t
            + \min\!\big(1, \mu\,\|\lambda_d\| / \|f_t\|\big)\, f_t .

        While the squeeze ramps up at the grasp the feedforward follows it (the rest of the
        weight stays on whatever supports the object) instead of sliding the pad up the
        object's face. Default: no limit (a rigid grasp).
    couple : bool
        Declare the input ``f_couple``: a force added to ``f_i`` (before the friction limit),
        the arm's part of the squeeze's couple when the two pads' normal forces act along
        offset lines (:func:`~drake_coop.control.couple.squeeze_couple`). Default
        False: no such port.

    Input ports
    -----------
    q : n-vector
        Measured joint positions.
    reference : (3n + m + 1)-vector
        The arm's reference (its ``held`` row; ``λ_d`` with ``friction``).
    acceleration_d : 3-vector
        The object's desired acceleration ``a_d`` (world frame, m/s²).
    mass_share : 1-vector
        ``m_i`` (kg).
    f_couple : 3-vector, with ``couple``
        ``f_c,i`` (N), added to ``f_i``.

    Output ports
    ------------
    tau_ff : n-vector
        ``J_xᵀ f_i`` (N·m).
    f_load : 3-vector
        ``f_i`` (N), the force the arm applies to the object for its motion.
    """

    def __init__(self, model: ArmModel, period: float, gravity: float = GRAVITY,
                 contact_offset=None, friction: float | None = None, couple: bool = False):
        super().__init__()
        check_period(period)
        self._model = model
        self._r = None if contact_offset is None else _vector(contact_offset, "contact_offset")
        self._mu = None if friction is None else check_positive(friction, "friction")
        N = np.asarray(model.N, dtype=float)
        #: Projector onto the directions across the constraint normals (``I − N⁺N``).
        self._across = np.eye(3) - np.linalg.pinv(N) @ N
        n = model.n
        self._layout = ReferenceLayout(n, model.m)
        self._lambda_d = self._layout.slices()["lambda_d"]
        self._g = np.array([0.0, 0.0, -float(gravity)])
        self._q = self.DeclareVectorInputPort("q", n)
        self._reference = self.DeclareVectorInputPort("reference", self._layout.size)
        self._a_d = self.DeclareVectorInputPort("acceleration_d", 3)
        self._mass = self.DeclareVectorInputPort("mass_share", 1)
        self._couple = self.DeclareVectorInputPort("f_couple", 3) if couple else None
        self._tau_state = self.DeclareDiscreteState(np.zeros(n))
        self._f_state = self.DeclareDiscreteState(np.zeros(3))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self._tau_out = self.DeclareStateOutputPort("tau_ff", self._tau_state)
        self._f_out = self.DeclareStateOutputPort("f_load", self._f_state)

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_reference_input_port(self) -> InputPort:
        """The arm's reference (its ``held`` row)."""
        return self._reference

    def get_acceleration_d_input_port(self) -> InputPort:
        """The object's desired acceleration ``a_d``."""
        return self._a_d

    def get_mass_share_input_port(self) -> InputPort:
        """The arm's share ``m_i`` of the object's mass."""
        return self._mass

    def get_f_couple_input_port(self) -> InputPort:
        """``f_c,i``, the arm's part of the squeeze's couple (with ``couple`` only)."""
        if self._couple is None:
            raise ValueError("couple: the f_couple port exists only with couple=True")
        return self._couple

    def get_tau_ff_output_port(self) -> OutputPort:
        """``τ_ff = J_xᵀ f_i``."""
        return self._tau_out

    def get_f_load_output_port(self) -> OutputPort:
        """``f_i = m_i (a_d − g)``."""
        return self._f_out

    def load(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """``(τ_ff, f_i)`` at the current inputs (what a tick latches): the feed-forward torque
        (n,), N·m, and the load the arm applies to the object (3,), N, world frame.

        Parameters
        ----------
        context : Context
            This system's context.
        """
        reference = self._reference.Eval(context)
        if not self._layout.held(reference):
            return np.zeros(self._model.n), np.zeros(3)
        q = self._q.Eval(context)
        f = max(float(self._mass.Eval(context)[0]), 0.0) * (self._a_d.Eval(context) - self._g)
        if self._couple is not None:
            f = f + self._couple.Eval(context)
        if self._mu is not None:
            f = self.friction_limited(f, reference[self._lambda_d])
        return contact_jacobian(self._model, q, self._r).T @ f, f

    def friction_limited(self, f: np.ndarray, lambda_d: np.ndarray) -> np.ndarray:
        """``f`` with its part across the constraint normals limited to ``μ ‖λ_d‖`` (the
        ``friction`` parameter; ``f`` unchanged without it).

        Parameters
        ----------
        f : numpy.ndarray
            The load (3,), N, world frame.
        lambda_d : numpy.ndarray
            The desired squeeze ``λ_d`` (m,), N.

        Returns
        -------
        numpy.ndarray
            The limited load (3,), N.
        """
        f = np.asarray(f, dtype=float)
        if self._mu is None:
            return f
        f_t = self._across @ f
        size = float(np.linalg.norm(f_t))
        limit = self._mu * float(np.linalg.norm(np.clip(lambda_d, 0.0, None)))
        if size <= limit:
            return f
        return f - f_t + (limit / size) * f_t

    def _update(self, context: Context, state: State) -> None:
        tau, f = self.load(context)
        xd = state.get_mutable_discrete_state()
        xd.set_value(self._tau_state, tau)
        xd.set_value(self._f_state, f)
