"""The controller's watchdog between its torque and an arm's driver: :class:`Watchdog`.

A real arm's controller must stop safely when its input goes bad. At every tick the watchdog
checks the driver's newest status (its age, its reading) and the force estimate (the run's
force guard), and passes the controller's torque on, clipped to the torque limits, until one
check fails; from then on it sends the driver's safe command (zero torque, or the gravity
torque that holds the arm) and reports why. Its torque output is never non-finite.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
)

from drake_coop.control.params import check_period

#: What :class:`Watchdog` sends once tripped.
SAFE_COMMANDS = ("zero_torque", "hold")
#: The watchdog's reason codes (its ``tripped`` output) and their one-line meaning.
TRIP_REASONS = {
    0: "",
    1: "status older than max_status_age",
    2: "non-finite joint position in the status",
    3: "joint position out of range",
    4: "force guard: |lambda_hat| beyond max_force",
    5: "non-finite torque from the controller",
}


class Watchdog(LeafSystem):
    """Torque limits and the safe command between one arm's controller and its driver.

    .. pydrake_system::

        name: Watchdog
        input_ports:
        - q
        - status_stamp
        - tau
        - lambda_hat
        output_ports:
        - q_checked
        - tau_safe
        - tripped

    At every tick ``t_k = k h`` (a periodic discrete update, after the controller has latched
    ``τ(k)``), with ``s`` the newest status's stamp and ``t_s`` the tick at which that stamp was
    first seen, the watchdog trips (once, for good) when

    * ``t_k − t_s > a_max`` (the status stopped arriving; ``t_s = 0`` before the first one),
    * a reading ``q_j`` is not finite, or ``q_j ∉ [q_min,j, q_max,j]``,
    * ``max_j |λ̂_j| > F_max`` or ``λ̂`` is not finite (the run's force guard),
    * ``τ(k)`` is not finite.

    Its output, at any time::

        tau_safe = clip(τ, −τ_max, τ_max)   if not tripped and τ finite
                   τ_safe                   otherwise

    with ``τ_safe = 0`` (``zero_torque``) or ``τ_safe = g(q_good)`` (``hold``: the gravity
    torque, from the caller's model, at the last reading that passed the checks), itself clipped
    and finite (0 where it is not). So the first bad tick already sends ``τ_safe``.

    The controller reads its positions through ``q_checked``: the reading itself (the same
    doubles) when it is finite, else the last good reading, so that a NaN never reaches the
    control blocks (Drake's models refuse non-finite positions); the tick that sees it trips.

    Input ports
    -----------
    q : n-vector
        The driver's measured joint positions (the reading the controller uses).
    status_stamp : 1-vector
        Any number that changes with every new status (its time stamp).
    tau : n-vector
        The controller's torque ``τ(k)``.
    lambda_hat : m-vector
        The force estimate, for the force guard.

    Output ports
    ------------
    q_checked : n-vector
        ``q`` if finite, else the last good reading (for the control blocks).
    tau_safe : n-vector
        What to send to the driver.
    tripped : 1-vector
        The reason code (0: not tripped; :data:`TRIP_REASONS`).

    Parameters
    ----------
    n, m : int
        Joints and constraint rows (> 0).
    period : float
        The control period ``h`` (s).
    max_status_age : float
        ``a_max`` (s, > 0).
    q_min, q_max : array_like, shape (n,)
        The accepted range of each reading (rad), ``q_min < q_max``.
    max_force : float
        ``F_max`` (N, > 0).
    torque_limits : array_like, shape (n,), optional
        ``τ_max`` (N·m, > 0); default none.
    safe_command : {"zero_torque", "hold"}
        ``τ_safe``.
    hold_torque : callable, optional
        ``g(q)`` for ``hold`` (required then): the gravity torque of the controller's model.
    """

    def __init__(self, n: int, m: int, period: float, *, max_status_age: float, q_min,
                 q_max, max_force: float, torque_limits=None,
                 safe_command: str = "zero_torque",
                 hold_torque: Callable[[np.ndarray], np.ndarray] | None = None):
        super().__init__()
        for name, value in (("n", n), ("m", m)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name}: a positive integer is required (got {value!r})")
        self._h = check_period(period)
        self._n, self._m = int(n), int(m)
        self._max_age = _positive(max_status_age, "max_status_age")
        self._max_force = _positive(max_force, "max_force")
        self._q_min = _vector(q_min, n, "q_min")
        self._q_max = _vector(q_max, n, "q_max")
        if np.any(np.isnan(self._q_min)) or np.any(np.isnan(self._q_max)) or np.any(
                self._q_min >= self._q_max):
            raise ValueError("q_min, q_max: q_min < q_max is required for every joint")
        if torque_limits is None:
            self._tau_max = np.full(n, np.inf)
        else:
            self._tau_max = _vector(torque_limits, n, "torque_limits")
            if not np.all(self._tau_max > 0):
                raise ValueError("torque_limits: every limit must be > 0")
        if safe_command not in SAFE_COMMANDS:
            raise ValueError(f"safe_command: one of {', '.join(SAFE_COMMANDS)} "
                             f"(got {safe_command!r})")
        if safe_command == "hold" and not callable(hold_torque):
            raise ValueError("hold_torque: a callable g(q) is required for safe_command='hold'")
        self._safe_command = safe_command
        self._hold_torque = hold_torque
        self._q = self.DeclareVectorInputPort("q", n)
        self._stamp = self.DeclareVectorInputPort("status_stamp", 1)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._lambda = self.DeclareVectorInputPort("lambda_hat", m)
        # [reason, last stamp, tick at which it was first seen]; the last good reading; τ_safe.
        self._flags = self.DeclareDiscreteState(np.array([0.0, np.nan, 0.0]))
        self._q_good = self.DeclareDiscreteState(n)
        self._safe = self.DeclareDiscreteState(n)
        self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "q_checked", n, self._calc_q,
            prerequisites_of_calc={self.xd_ticket(), self._q.ticket()})
        self.DeclareVectorOutputPort(
            "tau_safe", n, self._calc_tau,
            prerequisites_of_calc={self.xd_ticket(), self._tau.ticket()})
        self.DeclareVectorOutputPort("tripped", 1, self._calc_tripped,
                                     prerequisites_of_calc={self.xd_ticket()})

    def get_q_input_port(self):
        return self._q

    def get_status_stamp_input_port(self):
        return self._stamp

    def get_tau_input_port(self):
        return self._tau

    def get_lambda_hat_input_port(self):
        return self._lambda

    def get_q_checked_output_port(self):
        return self.GetOutputPort("q_checked")

    def get_tau_safe_output_port(self):
        return self.GetOutputPort("tau_safe")

    def get_tripped_output_port(self):
        return self.GetOutputPort("tripped")

    def set_initial_state(self, context: Context, q: np.ndarray) -> None:
        """Start untripped with ``q_good = q`` (the arm's reading at the start)."""
        q = _vector(q, self._n, "q")
        context.SetDiscreteState(self._flags, np.array([0.0, np.nan, context.get_time()]))
        context.SetDiscreteState(self._q_good, q)
        context.SetDiscreteState(self._safe, self._safe_torque(q))

    def reason(self, context: Context) -> str:
        """The one-line reason of a trip ('' if not tripped)."""
        return TRIP_REASONS[int(context.get_discrete_state(self._flags).get_value()[0])]

    def is_tripped(self, context: Context) -> bool:
        return context.get_discrete_state(self._flags).get_value()[0] != 0.0

    def _safe_torque(self, q: np.ndarray) -> np.ndarray:
        if self._safe_command == "zero_torque":
            return np.zeros(self._n)
        tau = np.asarray(self._hold_torque(q), dtype=float).reshape(self._n)
        tau = np.where(np.isfinite(tau), tau, 0.0)
        return np.clip(tau, -self._tau_max, self._tau_max)

    def _check(self, context: Context, t: float, t_seen: float) -> int:
        if t - t_seen > self._max_age * (1 + 1e-9):
            return 1
        q = self._q.Eval(context)
        if not np.all(np.isfinite(q)):
            return 2
        if np.any(q < self._q_min) or np.any(q > self._q_max):
            return 3
        lam = self._lambda.Eval(context)
        if not np.all(np.isfinite(lam)) or np.max(np.abs(lam)) > self._max_force:
            return 4
        if not np.all(np.isfinite(self._tau.Eval(context))):
            return 5
        return 0

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        reason, last, t_seen = context.get_discrete_state(self._flags).get_value()
        if reason != 0.0:
            return
        t = context.get_time()
        stamp = float(self._stamp.Eval(context)[0])
        if stamp != last:                        # a new status (NaN never equals: the first)
            last, t_seen = stamp, t
        code = self._check(context, t, t_seen)
        discrete.set_value(self._flags, np.array([float(code), last, t_seen]))
        if code == 0:
            discrete.set_value(self._q_good, self._q.Eval(context))
        else:
            q_good = context.get_discrete_state(self._q_good).get_value()
            discrete.set_value(self._safe, self._safe_torque(q_good))

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        q = self._q.Eval(context)
        output.SetFromVector(q if np.all(np.isfinite(q))
                             else context.get_discrete_state(self._q_good).get_value())

    def _calc_tau(self, context: Context, output: BasicVector) -> None:
        tau = self._tau.Eval(context)
        if context.get_discrete_state(self._flags).get_value()[0] != 0.0 or not np.all(
                np.isfinite(tau)):
            output.SetFromVector(context.get_discrete_state(self._safe).get_value())
        else:
            output.SetFromVector(np.clip(tau, -self._tau_max, self._tau_max))

    def _calc_tripped(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._flags).get_value()[:1])


def _positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
        raise TypeError(f"{name}: a number is required (got {type(value).__name__})")
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name}: a finite number > 0 is required (got {value!r})")
    return float(value)


def _vector(value, n: int, name: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: {n} numbers are required (got {value!r})") from None
    if v.size != n:
        raise ValueError(f"{name}: {n} numbers are required (got {v.size})")
    return v
