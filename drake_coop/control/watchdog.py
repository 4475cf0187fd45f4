"""The controller's watchdog between its torque and an arm's driver: :class:`Watchdog`.

A real arm's controller must stop safely when its input goes bad. At every tick the watchdog
checks the driver's newest status (its arrival, its shape, its age, its reading, how far the
reading moved since the last one) and the force estimate (the run's force guard), and passes
the controller's torque on, always clipped to the torque limits, once a valid status has
arrived and until one check fails; from then on it sends the driver's safe command (zero
torque, or the gravity torque that holds the arm) and reports why. Its torque output is never
non-finite and never beyond the limits.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
)

from drake_coop.control.params import check_period

#: What :class:`Watchdog` sends once tripped (and before the first valid status).
SAFE_COMMANDS = ("zero_torque", "hold")

#: The ``status`` input's fault codes (its second entry), set by whatever decodes the driver's
#: messages: ``STATUS_OK`` a valid status, ``STATUS_NONE`` none has arrived yet (not a fault:
#: the watchdog waits, sending the safe command, at most ``max_status_age``); the others are
#: faults that trip the watchdog at the tick they arrive. The third entry is a number the
#: one-line reason quotes (``{v}``; ``{n}`` is the arm's joint count).
STATUS_OK, STATUS_NONE = 0, 1
STATUS_FAULTS = {
    2: "not a status message (another message type, {v:.0f} bytes)",
    3: "truncated status ({v:.0f} bytes)",
    4: "status of {v:.0f} joints, the arm has {n}",
    5: "status of the wrong size ({v:.0f} bytes)",
    6: "non-finite joint position in the status",
}

#: The watchdog's reason codes (its ``tripped`` output) and their one-line meaning.
TRIP_REASONS = {
    0: "",
    1: "status older than max_status_age",
    2: "non-finite joint position in the status",
    3: "joint position out of range",
    4: "force guard: |lambda_hat| beyond max_force",
    5: "non-finite torque from the controller",
    6: "non-finite status stamp (a stale status)",
    7: "malformed status",
    8: "joint position jumped faster than the velocity limits allow",
}

#: Entries of the watchdog's flags before ``q_g`` in its memory state.
_FLAGS = 8

#: No details (a trip's reason quotes none).
_NONE = (0.0, 0.0, 0.0)

#: Readings may differ by this much (rad) beyond what the velocity limits allow (noise floor).
JUMP_TOLERANCE = 1e-6


class Watchdog(LeafSystem):
    """Torque limits and the safe command between one arm's controller and its driver.

    .. pydrake_system::

        name: Watchdog
        input_ports:
        - q
        - status
        - tau
        - lambda_hat
        output_ports:
        - q_checked
        - tau_safe
        - tripped
        - tau_latched

    The ``status`` input is ``[s, f, v]``: the newest status's stamp ``s`` (s, the driver's
    clock), its fault code ``f`` (:data:`STATUS_OK`, :data:`STATUS_NONE` before the first one,
    or a key of :data:`STATUS_FAULTS`) and a number ``v`` the fault's reason quotes.

    At every tick ``t_k = k h`` (a periodic discrete update, after the controller has latched
    ``τ(k)``), with ``t_s`` the tick at which the newest stamp was first seen (the start
    before the first status), ``q_g`` and ``s_g`` the last reading that passed the checks and
    its stamp, the watchdog trips (once, for good) when

    * ``f`` is a fault (a malformed status: wrong type, truncated, another joint count, the
      wrong size, a non-finite position),
    * ``s`` is not finite while ``f = STATUS_OK`` (counts as stale),
    * ``t_k − t_s > a_max`` (the status stopped arriving, or none arrived),
    * a reading ``q_j`` is not finite, or ``q_j ∉ [q_min,j, q_max,j]``,
    * ``|q_j − q_g,j| > v_max,j · max(s − s_g, 0) + ε`` (a jump the arm cannot make in the time
      between the two statuses; ``ε`` = :data:`JUMP_TOLERANCE`; checked from the second valid
      status on),
    * ``max_j |λ̂_j| > F_max`` or ``λ̂`` is not finite (the run's force guard),
    * ``τ(k)`` is not finite.

    Its output, at any time::

        tau_safe = clip(τ, −τ_max, τ_max)   if a valid status has arrived, not tripped,
                                            and τ finite
                   τ_safe                   otherwise

    with ``τ_safe = 0`` (``zero_torque``) or ``τ_safe = clip(g(q_g))`` (``hold``: the gravity
    torque, from the caller's model, at the last good reading; 0 where not finite). So the
    controller's torque never leaves before a valid status, and the first bad tick already
    sends ``τ_safe``; ``τ_max`` is required and finite: ``tau_safe`` is always within it.

    ``tau_latched`` is ``tau_safe`` as the tick's update saw it, latched into state (the same
    doubles): in a Diagram where ``τ`` changes only at the ticks (a controller that latches
    ``τ(k)`` before the watchdog's update at ``t_k``) it equals ``tau_safe`` from the tick on,
    and reading it costs no Python call. ``tripped`` is a state output too: the watchdog's one
    Python callback per tick is its update, computed on plain floats. Built with
    ``periodic=False`` it has no event: whoever runs the loop calls :meth:`tick` after the
    tick's step with the inputs' values (the same checks and state; ``drake-coop serve``).

    The controller reads its positions through ``q_checked``: the reading itself (the same
    doubles) when the status is valid and finite, else the last good reading, so that no
    NaN or stale zero (before the first status) reaches the control blocks.

    Input ports
    -----------
    q : n-vector
        The driver's measured joint positions (the reading the controller uses).
    status : 3-vector
        ``[s, f, v]`` above.
    tau : n-vector
        The controller's torque ``τ(k)``.
    lambda_hat : m-vector
        The force estimate, for the force guard.

    Output ports
    ------------
    q_checked : n-vector
        ``q`` if valid, else the last good reading (for the control blocks).
    tau_safe : n-vector
        What to send to the driver.
    tripped : 1-vector
        The reason code (0: not tripped; :data:`TRIP_REASONS`).
    tau_latched : n-vector
        ``tau_safe`` latched at the last tick (the safe command before the first).

    Parameters
    ----------
    n, m : int
        Joints and constraint rows (> 0).
    period : float
        The control period ``h`` (s).
    max_status_age : float
        ``a_max`` (s, ≥ h: a shorter one would trip whenever a tick sees no new status).
    q_min, q_max : array_like, shape (n,)
        The accepted range of each reading (rad), ``q_min < q_max``.
    max_force : float
        ``F_max`` (N, > 0).
    torque_limits : array_like, shape (n,)
        ``τ_max`` (N·m, finite, > 0): the arm's effort limits, or tighter ones.
    velocity_limits : array_like, shape (n,), optional
        ``v_max`` (rad/s, > 0; ``inf`` leaves a joint unchecked); default none: no jump check.
    safe_command : {"zero_torque", "hold"}
        ``τ_safe``.
    hold_torque : callable, optional
        ``g(q)`` for ``hold`` (required then): the gravity torque of the controller's model.
    periodic : bool
        Whether the tick's checks are a periodic discrete update (default). ``False``: the
        watchdog has no event; whoever runs the loop calls :meth:`tick` once per tick with
        the tick's inputs as plain floats (``drake-coop serve``'s loop: no Python event, no
        ``Eval`` of the inputs), with the same checks, state and outputs.
    """

    def __init__(self, n: int, m: int, period: float, *, max_status_age: float, q_min,
                 q_max, max_force: float, torque_limits, velocity_limits=None,
                 safe_command: str = "zero_torque",
                 hold_torque: Callable[[np.ndarray], np.ndarray] | None = None,
                 periodic: bool = True):
        super().__init__()
        for name, value in (("n", n), ("m", m)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name}: a positive integer is required (got {value!r})")
        self._h = check_period(period)
        self._n, self._m = int(n), int(m)
        self._max_age = _positive(max_status_age, "max_status_age")
        if self._max_age < self._h * (1 - 1e-9):
            raise ValueError(f"max_status_age: at least one control period ({self._h:g} s) is "
                             f"required (got {max_status_age!r})")
        self._max_force = _positive(max_force, "max_force")
        self._q_min = _vector(q_min, n, "q_min")
        self._q_max = _vector(q_max, n, "q_max")
        if np.any(np.isnan(self._q_min)) or np.any(np.isnan(self._q_max)) or np.any(
                self._q_min >= self._q_max):
            raise ValueError("q_min, q_max: q_min < q_max is required for every joint")
        if torque_limits is None:
            raise ValueError("torque_limits: n finite limits > 0 are required (the arm's "
                             "effort limits, or tighter ones)")
        self._tau_max = _vector(torque_limits, n, "torque_limits")
        if not np.all((self._tau_max > 0) & np.isfinite(self._tau_max)):
            raise ValueError("torque_limits: every limit must be finite and > 0")
        if velocity_limits is None:
            self._v_max = None
        else:
            self._v_max = _vector(velocity_limits, n, "velocity_limits")
            if not np.all(self._v_max > 0):       # NaN fails too
                raise ValueError("velocity_limits: every limit must be > 0 (inf: unchecked)")
        if safe_command not in SAFE_COMMANDS:
            raise ValueError(f"safe_command: one of {', '.join(SAFE_COMMANDS)} "
                             f"(got {safe_command!r})")
        if safe_command == "hold" and not callable(hold_torque):
            raise ValueError("hold_torque: a callable g(q) is required for safe_command='hold'")
        self._safe_command = safe_command
        self._hold_torque = hold_torque
        self._q = self.DeclareVectorInputPort("q", n)
        self._status = self.DeclareVectorInputPort("status", 3)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._lambda = self.DeclareVectorInputPort("lambda_hat", m)
        # _memory: [reason, last stamp, tick at which it was first seen, a valid status seen,
        #           s_g, detail 0, detail 1, detail 2, q_g (the last good reading, n)] (one
        #           group: read and written once a tick); τ_safe; the reason code alone (the
        #           tripped port); tau_latched.
        self._memory = self.DeclareDiscreteState(np.concatenate(
            [[0.0, math.nan, 0.0, 0.0, math.nan, 0.0, 0.0, 0.0], np.zeros(n)]))
        self._safe = self.DeclareDiscreteState(n)
        self._code = self.DeclareDiscreteState(1)
        self._latched = self.DeclareDiscreteState(n)
        # plain floats for the tick's arithmetic (no NumPy on n-vectors at every tick)
        self._q_min_l, self._q_max_l = self._q_min.tolist(), self._q_max.tolist()
        self._tau_max_l = self._tau_max.tolist()
        self._v_max_l = None if self._v_max is None else self._v_max.tolist()
        if periodic:
            self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "q_checked", n, self._calc_q,
            prerequisites_of_calc={self.xd_ticket(), self._q.ticket(), self._status.ticket()})
        self.DeclareVectorOutputPort(
            "tau_safe", n, self._calc_tau,
            prerequisites_of_calc={self.xd_ticket(), self._tau.ticket()})
        self.DeclareStateOutputPort("tripped", self._code)
        self.DeclareStateOutputPort("tau_latched", self._latched)

    def get_q_input_port(self):
        return self._q

    def get_status_input_port(self):
        return self._status

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

    def get_tau_latched_output_port(self):
        return self.GetOutputPort("tau_latched")

    @property
    def torque_limits(self) -> np.ndarray:
        """``τ_max`` (a copy)."""
        return self._tau_max.copy()

    def set_initial_state(self, context: Context, q: np.ndarray) -> None:
        """Start untripped, no status seen yet, with ``q_g = q`` (the arm's expected reading
        at the start: what ``q_checked`` gives and ``hold`` holds until the first status).

        Parameters
        ----------
        context : Context
            This system's context.
        q : numpy.ndarray
            The arm's expected reading at the start (n,), rad.
        """
        q = _vector(q, self._n, "q")
        context.SetDiscreteState(self._memory, np.concatenate(
            [[0.0, math.nan, context.get_time(), 0.0, math.nan, 0.0, 0.0, 0.0], q]))
        safe = self._safe_torque(q)
        context.SetDiscreteState(self._safe, safe)
        context.SetDiscreteState(self._code, np.zeros(1))
        context.SetDiscreteState(self._latched, safe)

    def reason(self, context: Context) -> str:
        """The one-line reason of a trip ('' if not tripped).

        Parameters
        ----------
        context : Context
            This system's context.
        """
        flags = context.get_discrete_state(self._memory).get_value()
        code = int(flags[0])
        if code == 7:
            fault, value = int(flags[5]), flags[6]
            text = STATUS_FAULTS.get(fault, "unknown status fault {f}")
            return f"{TRIP_REASONS[7]}: " + text.format(v=value, n=self._n, f=fault)
        if code == 8:
            j, jump, dt = flags[5:8]
            return (f"{TRIP_REASONS[8]}: joint {int(j)} moved {jump:.4g} rad in {dt:.4g} s "
                    f"(limit {self._v_max[int(j)]:.4g} rad/s)")
        return TRIP_REASONS[code]

    def is_tripped(self, context: Context) -> bool:
        """Whether the watchdog has tripped (it then commands the safe torque until reset).

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return context.get_discrete_state(self._memory).get_value()[0] != 0.0

    def last_good_position(self, context: Context) -> np.ndarray:
        """``q_g``: the last reading that passed the checks (the start's before the first).

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return context.get_discrete_state(self._memory).get_value()[_FLAGS:].copy()

    def _safe_torque(self, q: np.ndarray) -> np.ndarray:
        if self._safe_command == "zero_torque":
            return np.zeros(self._n)
        tau = np.asarray(self._hold_torque(q), dtype=float).reshape(self._n)
        tau = np.where(np.isfinite(tau), tau, 0.0)
        return np.clip(tau, -self._tau_max, self._tau_max)

    def _check(self, status, q_in, lam, flags: list, t: float, q_good: list):
        """``(code, details, q)`` of this tick (``q`` the new valid reading, else None);
        updates ``flags``' stamp. ``status`` the ``[s, f, v]`` floats; ``q_in()`` and
        ``lam()`` give the reading and ``λ̂`` as lists of floats (called only when needed).
        Plain floats throughout."""
        stamp, fault, value = status
        if fault != STATUS_OK and fault != STATUS_NONE:
            return 7, (fault, value, 0.0), None
        valid = fault == STATUS_OK
        if valid:
            if not math.isfinite(stamp):
                return 6, _NONE, None
            if stamp != flags[1]:                   # a new status
                flags[1], flags[2] = stamp, t
        if t - flags[2] > self._max_age * (1 + 1e-9):
            return 1, _NONE, None
        q = None
        if valid:
            q = q_in()
            isfinite = math.isfinite
            for qj in q:
                if not isfinite(qj):
                    return 2, _NONE, None
            for qj, lo, hi in zip(q, self._q_min_l, self._q_max_l):
                if qj < lo or qj > hi:
                    return 3, _NONE, None
            if self._v_max_l is not None and flags[3] != 0.0:
                dt = max(stamp - flags[4], 0.0)
                worst, j_worst = 0.0, -1
                for j, (qj, gj, vj) in enumerate(zip(q, q_good, self._v_max_l)):
                    excess = abs(qj - gj) - (vj * dt + JUMP_TOLERANCE)
                    if excess > worst:
                        worst, j_worst = excess, j
                if j_worst >= 0:
                    return 8, (float(j_worst), abs(q[j_worst] - q_good[j_worst]), dt), None
        biggest = 0.0
        for lj in lam():
            if not math.isfinite(lj):
                return 4, _NONE, None
            biggest = max(biggest, abs(lj))
        if biggest > self._max_force:
            return 4, _NONE, None
        return 0, _NONE, q

    def _update(self, context: Context, discrete: DiscreteValues) -> None:
        memory = context.get_discrete_state(self._memory).get_value().tolist()
        if memory[0] != 0.0:
            return
        new = self._step(
            memory, context.get_time(), self._status.Eval(context).tolist(),
            lambda: self._q.Eval(context).tolist(),
            lambda: self._lambda.Eval(context).tolist(),
            lambda: self._tau.Eval(context).tolist())
        for group, value in zip((self._memory, self._safe, self._latched, self._code), new):
            if value is not None:
                discrete.set_value(group, value)

    def tick(self, context: Context, t: float, status, q, lambda_hat, tau) -> bool:
        """The checks of the tick at ``t = t_k``, for a watchdog built with
        ``periodic=False``: what its periodic update at ``t_k`` does, on the given inputs,
        written into ``context``'s state (the outputs follow: ``tau_latched`` is the command
        to send).

        ``status`` the ``[s, f, v]`` floats; ``q`` the reading (floats; read only when ``f``
        is :data:`STATUS_OK`); ``lambda_hat`` ``λ̂(k)``; ``tau`` ``τ(k)``: the values the
        ``q``, ``lambda_hat`` and ``tau`` inputs would have at the update.

        Parameters
        ----------
        context : Context
            This system's context (its state is updated).
        t : float
            The tick's time ``t_k``, s.
        status : sequence of float
            ``[s, f, v]``: the status's stamp (s), its fault code and the fault's value.
        q : sequence of float
            The arm's reading (n,), rad.
        lambda_hat : sequence of float
            ``λ̂(k)`` (m,), N.
        tau : sequence of float
            The controller's ``τ(k)`` (n,), N·m.

        Returns
        -------
        bool
            Whether the watchdog is tripped after the tick.
        """
        memory = context.get_discrete_state(self._memory).get_value().tolist()
        if memory[0] != 0.0:
            return True
        new = self._step(memory, t, status, lambda: list(q), lambda: list(lambda_hat),
                         lambda: list(tau))
        for group, value in zip((self._memory, self._safe, self._latched, self._code), new):
            if value is not None:
                context.SetDiscreteState(group, np.array(value, dtype=float))
        return new[0][0] != 0.0

    def _step(self, memory: list, t: float, status, q_in, lam, tau_in):
        """The tick's new ``(memory, τ_safe, tau_latched, code)`` (None: unchanged) from
        ``memory`` (flags and ``q_g``, as a list)."""
        flags, q_good = memory[:_FLAGS], memory[_FLAGS:]
        code, details, q = self._check(status, q_in, lam, flags, t, q_good)
        tau = None
        if code == 0:
            tau = tau_in()
            if not all(map(math.isfinite, tau)):
                code, tau = 5, None
        flags[0] = float(code)
        flags[5:8] = details
        safe = latched = code_out = None
        if q is not None:
            flags[3], flags[4] = 1.0, flags[1]
            q_good = q
        if code != 0:
            safe = latched = self._safe_torque(np.array(q_good))
            code_out = [float(code)]
        elif flags[3] != 0.0:
            latched = [min(max(tj, -mj), mj) for tj, mj in zip(tau, self._tau_max_l)]
        return flags + q_good, safe, latched, code_out

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        q = self._q.Eval(context)
        if self._status.Eval(context)[1] == STATUS_OK and np.all(np.isfinite(q)):
            output.SetFromVector(q)
        else:
            output.SetFromVector(context.get_discrete_state(self._memory).get_value()[_FLAGS:])

    def _calc_tau(self, context: Context, output: BasicVector) -> None:
        flags = context.get_discrete_state(self._memory).get_value()
        tau = self._tau.Eval(context)
        if flags[0] != 0.0 or flags[3] == 0.0 or not np.all(np.isfinite(tau)):
            output.SetFromVector(context.get_discrete_state(self._safe).get_value())
        else:
            output.SetFromVector(np.clip(tau, -self._tau_max, self._tau_max))


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
