"""The simulated driver of one arm in torque mode: what reaches the arm from the newest
command, and the status it publishes, by the arm's declared conventions
(:class:`~drake_coop.robot.driver_spec.DriverSpec`: time base, gravity, expiry, damping).

:class:`TorqueDriver` runs, at every driver cycle ``t`` (the newest command ``c`` as received,
the arm's state ``q, v`` at ``t``, ``now`` the driver's clock in its time base, µs)::

    status published first (:data:`STATUS_LEAD` ahead of t, stamped t): utime = now, q, v,
        τ_J = the torque on the arm (gravity included), τ_ext = the external-torque
        estimate (emulation), τ_J_d = τ_d
    c newer than the one held: held
    held and |now − c.utime| > expiry: dropped (not taken again)
    none held:   τ_d = −k_d v                       (gravity compensation and damping)
    held:        τ_d = c.τ − g(q)  if gravity == driver_subtracts, else c.τ
    on the arm:  τ = τ_d + g(q)    if gravity in (robot_adds, driver_subtracts) or none held,
                 τ = τ_d           otherwise (gravity: none)

with ``g(q)`` the arm's own gravity torque (its ``gravity`` input: the robot's model, the
arm's exact model in :func:`~drake_coop.robot.drivers.add_driver_side`, Drake's C++
``InverseDynamics`` in gravity-compensation mode; so a ``driver_subtracts`` command reaches
the arm as sent). The driver holds each arm until that
arm's own first command (another arm's command releases nothing).

The plain simulated driver clips ``τ_d`` to the driver's torque limits and takes a
malformed command (not torque mode, a wrong joint count, a non-finite torque) as none.
:data:`EMULATE` (``drake-coop sim-driver --emulate drake-franka-driver``) follows
drake-franka-driver's torque mode as its published source does, point by point: 7 joints
only; a held command not in torque mode, carrying positions or velocities, not 7 torques, or
a non-finite torque stops the driver (its loop throws: :attr:`TorqueDriver.fault` names the
field; the arm is then held by gravity compensation and damping, and no status follows);
no clipping; ``τ_d`` passed through libfranka's control loop as the driver calls it
(``limit_rate`` on, cutoff ``--low_pass_freq`` = 30 Hz): first-order low-pass against the
last ``τ_d`` sent, ``y = a x + (1 − a) y₋``, ``a = T / (T + 1/(2π f_c))``, then the rate
limit ``|Δτ_d| ≤ 1000 N·m/s · T`` (``T`` = 1 ms, libfranka's cycle); the status's
``joint_torque_external`` an estimate of the external torque from the arm's model with
Franka's sign (``tau_ext_hat_filtered``, the negative of the environment's torque on the arm,
as Drake's ``lcmt_panda_status`` says): ``τ₋ − (H(q)(v − v₋)/c + C(q, v)v + D v + g(q))``, with
``q, v`` the state the status publishes, ``v₋`` the one the cycle before's status published
(both latched :data:`EXTERNAL_LEAD` ahead of their cycles), ``τ₋`` the torque on the arm over
that cycle and ``c`` the cycle. With an exact model and no contact it reads only the
discretization's error: the change of the model's terms over the plant's step
(``ID(q₋, v₋, a) − ID(q, v, a)``, ``a = (v − v₋)/c``; about 0.02 N·m on a Panda moving at
0.6 rad/s).
"""

from __future__ import annotations

import math
import struct
import time

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State

from drake import lcmt_panda_status
from drake_coop.robot.driver_spec import SharedPandaCommand, default_damping

#: The mode name of drake-franka-driver's emulation (``sim-driver --emulate``).
EMULATE = "drake-franka-driver"
#: The joints drake-franka-driver serves (``kNdof``).
FRANKA_JOINTS = 7
#: libfranka's control cycle (``kDeltaT``, s) and torque-rate limit (``kMaxTorqueRate``,
#: N·m/s), and drake-franka-driver's default low-pass cutoff (``--low_pass_freq``, Hz).
FRANKA_CYCLE = 1e-3
FRANKA_TORQUE_RATE = 1000.0
FRANKA_LOW_PASS_HZ = 30.0
#: libfranka's "no filter" cutoff (``kMaxCutoffFrequency``, Hz).
FRANKA_NO_FILTER_HZ = 1000.0
#: Simulated seconds by which a cycle's status is published ahead of the cycle's time ``t``
#: (stamped ``t``): one µs, the stamp's resolution. The status is the state at ``t`` before
#: that instant's updates whatever the rounding of the plant's step times (``j Δt`` may fall
#: an ulp before or after the cycle's ``c·1 ms``), and a controller's tick at ``t`` latches it
#: before its own update whatever the rounding of ``k h``: its message arrives a µs earlier.
STATUS_LEAD = 1e-6
#: Simulated seconds ahead of a cycle's time ``t`` at which the emulation latches the cycle's
#: external-torque estimate (:data:`STATUS_LEAD` + 1 µs): from the state the status then
#: publishes, the velocity latched a cycle before and the torque on the arm over that cycle.
#: The status and the ``tau_external`` port hold that latched value until the next latch, so
#: whoever reads them at any instant (a controller's tick at ``t``, which may fall an ulp after
#: the driver's cycle and before the plant's step) reads one consistent estimate: computed on
#: the fly at such an instant, the estimate paired the driver's fresh velocity with a state
#: the plant had not stepped yet, took the acceleration as 0 and read the torque that
#: accelerates the arm (up to 4.4 N·m on a Panda's shoulder in free motion).
EXTERNAL_LEAD = 2e-6
#: The faults of an emulated driver's loop (its ``DRAKE_THROW_UNLESS`` and libfranka's
#: ``checkFinite``), by code.
FAULTS = {1: "control_mode_expected is not torque", 2: "num_joint_position is not 0",
          3: "num_joint_velocity is not 0", 4: "num_joint_torque is not 7",
          5: "joint_torque is not finite"}


#: The columns of :attr:`TorqueDriver.journal`'s rows, one row per command taken on the cycle
#: it was taken (n values each but the first two): the driver's clock ``now`` and the
#: command's ``utime`` (µs), the command's torque as received, ``τ_d`` after the driver's
#: chain (emulation: low-pass, rate limit), the robot's ``g(q)``, the torque on the arm,
#: ``q``.
JOURNAL = ("now", "utime", "tau_wire", "tau_d", "gravity", "tau_applied", "q")


class DriverClock:
    """A driver's clock in its time base (µs), as a function of the run's time ``t`` (s).

    ``run``: ``round(t·1e6)``; ``epoch``: ``origin + round(t·1e6)`` (a simulated clock: the
    loopback run, a lockstep run, a test), or the wall clock itself (``wall=True``: the paced
    ``sim-driver``, whose run time follows the wall clock).

    Parameters
    ----------
    time_base : str
        ``epoch`` or ``run``.
    origin : int or None
        The epoch's µs at ``t = 0``; None: the wall clock's whole second now.
    wall : bool
        Read the wall clock (``epoch`` only).
    """

    def __init__(self, time_base: str = "epoch", origin: int | None = None, wall: bool = False):
        if time_base not in ("epoch", "run"):
            raise ValueError(f"time_base: 'epoch' or 'run' (got {time_base!r})")
        self.time_base = time_base
        self.wall = bool(wall) and time_base == "epoch"
        self.origin = 0 if time_base == "run" else (
            int(time.time()) * 1_000_000 if origin is None else int(origin))

    def utime(self, t: float) -> int:
        """The clock at run time ``t``.

        Parameters
        ----------
        t : float
            The run's time, s.

        Returns
        -------
        int
            µs in the time base.
        """
        if self.wall:
            return int(time.time() * 1e6)
        return self.origin + int(round(t * 1e6))


def _no_message(msg) -> bool:
    return msg.utime == 0 and msg.num_joint_torque == 0 and msg.control_mode_expected == 0


def command_fault(msg, n: int) -> int:
    """drake-franka-driver's checks of a held torque command (0: passes; else a key of
    :data:`FAULTS`).

    Parameters
    ----------
    msg : lcmt_panda_command
        The command.
    n : int
        The arm's joints.

    Returns
    -------
    int
        The fault code.
    """
    if msg.control_mode_expected != lcmt_panda_status.CONTROL_MODE_TORQUE:
        return 1
    if msg.num_joint_position != 0:
        return 2
    if msg.num_joint_velocity != 0:
        return 3
    if msg.num_joint_torque != n or len(msg.joint_torque) != n:
        return 4
    if not all(math.isfinite(v) for v in msg.joint_torque):
        return 5
    return 0


class TorqueDriver(LeafSystem):
    """One arm's driver in torque mode (see the module).

    .. pydrake_system::

        name: TorqueDriver
        input_ports:
        - command
        - state
        - gravity
        output_ports:
        - tau_applied
        - tau_commanded
        - tau_external

    ``command``: the newest ``lcmt_panda_command`` received (a subscriber's output);
    ``state``: the arm's ``[q, v]`` (2n); ``gravity``: the robot's ``g(q)`` at that state (n,
    N·m). ``tau_applied``: the torque on the arm from this
    cycle (gravity included), ``tau_commanded``: the held command's torque as received (0
    while none is held); ``tau_external``: the newest status's external-torque estimate,
    latched :data:`EXTERNAL_LEAD` ahead of each cycle (zeros but in the emulation with a
    ``model``, and before its second latch).

    Parameters
    ----------
    spec : DriverSpec
        The arm's driver (conventions, expiry, damping, limits, channel).
    clock : DriverClock
        The driver's clock.
    lcm : DrakeLcmInterface or None
        Where the status is published (on ``spec.status_channel``); None: no status.
    model : ArmModel or None
        The arm's model for the external-torque estimate (``H``, ``Cv``); None: zeros.
    emulate : str or None
        :data:`EMULATE`, or None for the plain simulated driver.
    low_pass_hz : float
        The emulation's torque cutoff (Hz; :data:`FRANKA_NO_FILTER_HZ` or more: none).

    Raises
    ------
    ValueError
        ``emulate`` of an arm without 7 joints, or an unknown ``emulate``.
    """

    def __init__(self, spec, clock: DriverClock, lcm=None, model=None,
                 emulate: str | None = None, low_pass_hz: float = FRANKA_LOW_PASS_HZ):
        super().__init__()
        if emulate not in (None, EMULATE):
            raise ValueError(f"emulate: {EMULATE!r} or None (got {emulate!r})")
        n = spec.n
        if emulate and n != FRANKA_JOINTS:
            raise ValueError(f"robots: {spec.robot} has {n} joints; {EMULATE} serves "
                             f"{FRANKA_JOINTS} only")
        self._spec, self._n, self._clock = spec, n, clock
        self._lcm, self._model, self._emulate = lcm, model, emulate
        self._kd = default_damping(n, spec.damping)
        self._limits = (None if emulate or spec.torque_limits is None
                        else np.asarray(spec.torque_limits, dtype=float))
        self._expire_us = int(spec.command_timeout * 1e6)
        self._period = spec.period * (1.0 + spec.clock_drift)
        self._alpha = (None if low_pass_hz >= FRANKA_NO_FILTER_HZ else
                       FRANKA_CYCLE / (FRANKA_CYCLE + 1.0 / (2 * math.pi * low_pass_hz)))
        #: The bytes of the first status this driver published (None before).
        self.first_status: bytes | None = None
        #: None, or a list that receives a row per command taken (:data:`JOURNAL`) and, while
        #: it is a list, :attr:`expiries` one per command dropped for its age.
        self.journal: list | None = None
        #: ``[now, utime]`` (µs) of each command dropped for its age, while :attr:`journal` is
        #: kept.
        self.expiries: list = []
        self._msg = self.DeclareAbstractInputPort(
            "command", AbstractValue.Make(SharedPandaCommand()))
        self._state = self.DeclareVectorInputPort("state", 2 * n)
        self._gravity = self.DeclareVectorInputPort("gravity", n)
        self._applied = self.DeclareDiscreteState(n)
        self._commanded = self.DeclareDiscreteState(n)
        # memory: τ_d sent (libfranka's tau_J_d), v of the last latch (EXTERNAL_LEAD),
        # [newest utime seen, held (0/1), fault code, commands expired, cycles the rate limit
        # bound]
        self._memo = self.DeclareDiscreteState(np.concatenate(
            [np.zeros(2 * n), [-math.inf, 0.0, 0.0, 0.0, 0.0]]))
        # the external-torque estimate latched for the status (EXTERNAL_LEAD)
        self._external = self.DeclareDiscreteState(n)
        self._format = struct.Struct(f">8sqi{8 * n}ddbqb")
        self._fingerprint = lcmt_panda_status._get_packed_fingerprint()
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._period, spec.clock_phase, self._update)
        if emulate and model is not None:
            # each cycle's estimate latched EXTERNAL_LEAD ahead of the cycle; v latched at
            # initialization too (the estimate zeros), so the first estimate has a v₋
            self.DeclareInitializationUnrestrictedUpdateEvent(self._latch_first)
            lead = spec.clock_phase - EXTERNAL_LEAD
            self.DeclarePeriodicUnrestrictedUpdateEvent(
                self._period, lead + self._period if lead < 0.0 else lead, self._latch)
        if lcm is not None:
            # each cycle's status STATUS_LEAD ahead of the cycle, stamped with the cycle's time
            # (a first cycle closer than that to t = 0: at initialization, before any update)
            lead = spec.clock_phase - STATUS_LEAD
            if lead < 0.0:
                self.DeclareInitializationPublishEvent(
                    lambda context: self._publish(context, spec.clock_phase))
                lead += self._period
            self.DeclarePeriodicPublishEvent(
                self._period, lead,
                lambda context: self._publish(context, context.get_time() + STATUS_LEAD))
            self.DeclareForcedPublishEvent(self._publish)
        self.DeclareStateOutputPort("tau_applied", self._applied)
        self.DeclareStateOutputPort("tau_commanded", self._commanded)
        self.DeclareStateOutputPort("tau_external", self._external)

    def fault(self, context: Context) -> str:
        """The emulated driver's stop (``"<channel>: <field> ..."``), or ``''``.

        Parameters
        ----------
        context : Context
            This system's context.

        Returns
        -------
        str
            The one-line reason, or ``''``.
        """
        code = int(context.get_discrete_state(self._memo).get_value()[2 * self._n + 2])
        return "" if code == 0 else f"{self._spec.command_channel}: {FAULTS[code]}"

    def _update(self, context: Context, state: State) -> None:
        n = self._n
        x = self._state.Eval(context)
        v = np.asarray(x[n:])
        msg = self._msg.Eval(context)
        memo = context.get_discrete_state(self._memo).get_value()
        last, (seen, held, fault, expired, bound) = memo[:n], memo[2 * n:]
        now = self._clock.utime(context.get_time())
        taken = fault == 0 and not _no_message(msg) and msg.utime != seen
        if taken:
            seen, held = float(msg.utime), 1.0          # a new command: held
        if held and abs(now - int(seen)) > self._expire_us:
            held, expired = 0.0, expired + 1.0          # expired: dropped for good
            if self.journal is not None:
                self.expiries.append([float(now), seen])
        tau_cmd = np.zeros(n)
        g = np.asarray(self._gravity.Eval(context), dtype=float)
        if held and fault == 0:
            code = command_fault(msg, n)
            if code and self._emulate:
                fault, held = float(code), 0.0          # the driver's loop throws: it stops
            elif code:
                held = 0.0                              # the plain driver: taken as none
            else:
                tau_cmd = np.asarray(msg.joint_torque, dtype=float)
        if held:
            tau_d = tau_cmd - g if self._spec.gravity == "driver_subtracts" else tau_cmd.copy()
        else:
            tau_d = -self._kd * v
        if self._emulate:
            if self._alpha is not None:
                tau_d = self._alpha * tau_d + (1.0 - self._alpha) * last
            step = FRANKA_TORQUE_RATE * FRANKA_CYCLE
            limited = last + np.clip(tau_d - last, -step, step)
            bound += float(np.any(np.abs(tau_d - last) > step))
            tau_d = limited
        elif self._limits is not None:
            tau_d = np.clip(tau_d, -self._limits, self._limits)
        adds = not held or self._spec.gravity != "none"
        tau = tau_d + g if adds else tau_d
        state.get_mutable_discrete_state(self._memo).SetFromVector(
            np.concatenate([tau_d, memo[n:2 * n], [seen, held, fault, expired, bound]]))
        if taken and held and self.journal is not None:
            self.journal.append(np.concatenate(
                [[now, seen], tau_cmd, tau_d, g, tau, x[:n]]))
        state.get_mutable_discrete_state(self._applied).SetFromVector(tau)
        state.get_mutable_discrete_state(self._commanded).SetFromVector(tau_cmd)

    def external_torque(self, q, v, v_prev, tau) -> np.ndarray:
        """The external-torque estimate with Franka's sign (``tau_ext_hat_filtered``):
        ``τ − (H(q)(v − v₋)/c + C(q, v)v + D v + g(q))`` (the model's inverse dynamics in one
        evaluation, :meth:`~drake_coop.control.arm_model.ArmModel.inverse_dynamics_terms`).

        Parameters
        ----------
        q, v : numpy.ndarray
            The arm's state now (n,).
        v_prev : numpy.ndarray
            Its velocity one cycle before (n,).
        tau : numpy.ndarray
            The torque on the arm over that cycle (n,), gravity included.

        Returns
        -------
        numpy.ndarray
            The estimate (n,), N·m.
        """
        return np.asarray(tau, dtype=float) - self._model.inverse_dynamics_terms(
            q, v, (v - v_prev) / self._period)

    def counts(self, context: Context) -> dict[str, int]:
        """What the driver did to the commands so far.

        Parameters
        ----------
        context : Context
            This system's context.

        Returns
        -------
        dict
            ``expired``: commands dropped for their age (each once); ``rate_limited``: cycles
            on which the emulation's rate limit changed ``τ_d`` (0 for the plain driver).
        """
        memo = context.get_discrete_state(self._memo).get_value()
        n = self._n
        return {"expired": int(memo[2 * n + 3]), "rate_limited": int(memo[2 * n + 4])}

    def _latch(self, context: Context, state: State) -> None:
        """The cycle's external-torque estimate, from the state now, the velocity of the last
        latch and the torque on the arm; the velocity kept for the next."""
        n = self._n
        memo = context.get_discrete_state(self._memo).get_value()
        x = np.asarray(self._state.Eval(context))
        ext = self.external_torque(x[:n], x[n:], memo[n:2 * n],
                                   context.get_discrete_state(self._applied).get_value())
        state.get_mutable_discrete_state(self._external).SetFromVector(ext)
        self._keep_velocity(context, state, x[n:])

    def _latch_first(self, context: Context, state: State) -> None:
        """At initialization: the velocity kept, no estimate (zeros)."""
        self._keep_velocity(context, state, np.asarray(self._state.Eval(context))[self._n:])

    def _keep_velocity(self, context: Context, state: State, v: np.ndarray) -> None:
        memo = np.array(context.get_discrete_state(self._memo).get_value())
        memo[self._n:2 * self._n] = v
        state.get_mutable_discrete_state(self._memo).SetFromVector(memo)

    def _publish(self, context: Context, t: float | None = None) -> None:
        memo = context.get_discrete_state(self._memo).get_value()
        if memo[2 * self._n + 2] != 0:
            return                                      # the driver has stopped
        n = self._n
        x = np.asarray(self._state.Eval(context))
        q, v = x[:n], x[n:]
        tau = context.get_discrete_state(self._applied).get_value()
        ext = context.get_discrete_state(self._external).get_value()
        t = context.get_time() if t is None else t
        zeros = (0.0,) * n
        data = self._format.pack(
            self._fingerprint, self._clock.utime(t), n, *q, *q, *v, *zeros, *zeros, *tau,
            *memo[:n], *ext, 1.0, lcmt_panda_status.kMove, int(round(t * 1e3)) * 1000,
            lcmt_panda_status.CONTROL_MODE_TORQUE)
        if self.first_status is None:
            self.first_status = data
        self._lcm.Publish(self._spec.status_channel, data)
