"""The ground truth off the control loop: C++ holds of the plant's data, evaluated after the run.

In the ``planes`` and ``rigid`` modes, when no controller reads the F/T sensor
(``force_source`` other than ``sensor`` on every robot), nothing in the control loop consumes
the ground-truth wrist force: it is a measurement *of the simulation*. Instead of evaluating
:class:`~drake_coop.plant.wrist_dynamics.WristDynamics` at every tick in Python, the experiment
holds, once per tick and with C++ blocks only (:class:`~pydrake.systems.primitives.Multiplexer`,
:class:`~pydrake.systems.primitives.ZeroOrderHold`), exactly what its equation needs, logs it,
and :class:`GroundTruthLog` evaluates the equation
(:class:`~drake_coop.plant.wrist_dynamics.ArmForces`) for all the ticks at once after the run.

Holds (period ``h``, the plant step ``Δt``; each reads the context half a plant step away from
every plant update, or at a tick itself, so no floating-point rounding of an event time can
move it across a plant update):

* ``ground_truth_hold_tick``, offset 0: ``[x(t_k), u_k, a_k]``, the plant's state, the
  actuation its inputs receive (the arms' actuators' outputs: the plant's ``net_actuation``
  without PD-controlled actuators) and its generalized acceleration, in the discrete phase of
  ``t_k``, i.e. after the controller's unrestricted latch of ``τ(k)``, from the context the
  plant's own update reads: the start, actuation and acceleration of the step
  ``[t_k, t_k + Δt)``. Reading the acceleration port there costs no solve of its own: the
  plant's update at the same instant reuses it (``a = (v(t_k + Δt) − v(t_k))/Δt``, the port's
  own formula, bit for bit);
* with ``h ≥ 2Δt``, ``ground_truth_hold_before_tick``, offset ``h − 3Δt/2``:
  ``[x(t_k − Δt), u]`` of the step ``[t_k − Δt, t_k)``, which ends at ``x(t_k)``: the F/T
  sensor model's reading of tick ``k``
  (:mod:`drake_coop.sensing.force_sensor`). Never at offset ``h − Δt``: Drake computes an
  event's time as ``offset + k h``, which rounds differently from the plant's ``j Δt`` on
  some ticks, and a read one rounding after the plant's update would make the plant solve the
  next step for it. With ``h = Δt`` that step is the previous tick's.

A :class:`~pydrake.systems.primitives.VectorLogSink` (``ground_truth_log``) publishes them at
every tick, *before* the tick's updates: the sample at :math:`t_{k+1}` holds the tick hold of
tick ``k`` (shifted back as every latched signal, see
:func:`~drake_coop.experiment.simulate.collect_logs`), the sample at ``t_k`` the step before
``t_k``. :meth:`GroundTruthLog.evaluate` returns per robot ``F_meas`` and ``lambda_meas`` of
the step taken from every tick and ``lambda_sensor``, the F/T model's reading
(:class:`~drake_coop.sensing.force_sensor.FTModel`, the same function the live
:class:`~drake_coop.sensing.force_sensor.FTSensor` steps). :meth:`GroundTruthLog.force_before_tick`
gives the divergence guards the force of the step before the current tick, from the held data
and the current state (no plant solve). :class:`TickForces` (``wrist_forces_at_tick``) gives
the same equation's ``F`` of the step from the last tick as output ports, computed only when
read (the Meshcat force arrows, 30 times a simulated second).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    Context,
    DiagramBuilder,
    InputPort,
    LeafSystem,
    OutputPort,
    ValueProducer,
)
from pydrake.systems.primitives import (
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    VectorLogSink,
    ZeroOrderHold,
)

from drake_coop.plant.cooperative import CoopPlant
from drake_coop.plant.grasp import PadForces
from drake_coop.plant.wrist_dynamics import ArmForces, _holds_last_step
from drake_coop.sensing.force_sensor import FTModel


@dataclass
class GroundTruthLog:
    """The held plant data of the offline ground truth and its evaluation.

    Attributes
    ----------
    logger : VectorLogSink
        ``ground_truth_log``: ``[x, u, a]`` of the tick hold and, with ``h ≥ 2Δt``, ``[x, u]``
        of the before-tick hold, published at every tick.
    equation : ArmForces
        The wrist-force equation of every arm.
    models : list of FTModel
        Each robot's F/T sensor model.
    tick, before_tick : OutputPort
        The holds' output ports (``before_tick`` None when ``h = Δt``).
    state : OutputPort
        The plant's state port (``x(t_k)`` at a tick, for the guards).
    period : float
        ``h`` (s).
    actuation_order : ndarray
        ``(n_u, w)``: the plant's actuation ``u`` from the held actuation sources (``w``
        values, each arm's actuation input in turn).
    """

    logger: VectorLogSink
    equation: ArmForces
    models: list[FTModel]
    tick: OutputPort
    before_tick: OutputPort | None
    state: OutputPort
    period: float
    actuation_order: np.ndarray

    def _now(self, context: Context, port: OutputPort) -> np.ndarray:
        return port.Eval(port.get_system().GetMyContextFromRoot(context))

    def evaluate(self, context: Context, n: int, complete: bool) -> list[dict[str, np.ndarray]]:
        """Per robot ``F_meas`` ``(n, 3)``, ``lambda_meas`` and ``lambda_sensor`` ``(n, m)`` of
        the ticks ``0 … n − 1``.

        ``F_meas`` of tick ``k`` is the force of the step ``[t_k, t_k + Δt)``: the tick hold of
        ``k``, published at :math:`t_{k+1}`. With ``complete`` (the last published tick's updates
        ran, :func:`~drake_coop.experiment.simulate.finish_last_tick`) the last tick's come from
        the hold's current value when it has sampled that tick (the context's time is past
        ``t_K``), else that row is NaN. ``lambda_sensor`` of tick ``k ≥ 1`` is the model's
        reading of ``λ`` of the step ``[t_k − Δt, t_k)``; tick 0's is the model's initial
        reading.

        Parameters
        ----------
        context : Context
            The root context after the run.
        n : int
            The number of ticks.
        complete : bool
            Whether the last published tick's updates ran.

        Returns
        -------
        list of dict
            Per robot: ``F_meas`` (n, 3), ``lambda_meas`` and ``lambda_sensor`` (n, m), N.
        """
        eq = self.equation
        nx, nq = eq.nx, eq.nq
        nu = self.actuation_order.shape[1]            # held actuation values
        width = nx + nu + (nx - nq)                   # the tick hold: [x, u, a]
        P = self.actuation_order.T
        log = self.logger.FindLog(context)
        times, data = log.sample_times(), log.data()
        published = times.size
        tick = data[:width, 1:published].T
        if complete and published > 0:
            valid = context.get_time() > times[published - 1]
            last_tick = self._now(context, self.tick) if valid else np.full(width, np.nan)
            tick = np.vstack([tick, last_tick])
        tick = tick[:n]
        n = tick.shape[0]
        forces = _steps(eq, tick[:, :nx], tick[:, nx + nu:], _rows_times(tick[:, nx:nx + nu], P))
        lam = [F @ N.T for F, N in zip(forces, eq.normals)]
        if self.before_tick is not None:
            before = data[width:, 1:n].T                  # published at t_k: the step before t_k
            a_before = (tick[1:n, nq:nx] - before[:, nq:nx]) / eq.dt
            prior = _steps(eq, before[:, :nx], a_before, _rows_times(before[:, nx:], P))
            prior = [np.vstack([np.zeros((min(n, 1), len(N))), F[:max(n - 1, 0)] @ N.T])
                     for F, N in zip(prior, eq.normals)]
        else:                                              # h = Δt: the previous tick's step
            prior = [np.vstack([np.zeros((min(n, 1), squeeze.shape[1])),
                                squeeze[:max(n - 1, 0)]]) for squeeze in lam]
        return [{"F_meas": F, "lambda_meas": squeeze, "lambda_sensor": model.readings(p)}
                for F, squeeze, p, model in zip(forces, lam, prior, self.models)]

    def force_before_tick(self, context: Context) -> list[np.ndarray]:
        """Every arm's ``F`` of the plant step ``[t_k − Δt, t_k)`` at a tick ``t_k ≥ t_1``
        before its updates: the step held at ``t_k − 3Δt/2`` (the previous tick's hold when
        ``h = Δt``) and the current state ``x(t_k)``, without a plant solve.

        Parameters
        ----------
        context : Context
            The root context at a tick.

        Returns
        -------
        list of numpy.ndarray
            Per arm ``F`` (3,), N, palm frame.
        """
        eq = self.equation
        held = self._now(context, self.before_tick if self.before_tick is not None
                         else self.tick)
        x = held[:eq.nx]
        u = held[eq.nx:eq.nx + self.actuation_order.shape[1]]
        v_now = self._now(context, self.state)[eq.nq:]
        return eq(x, (v_now - x[eq.nq:]) / eq.dt, self.actuation_order @ u)


class TickForces(LeafSystem):
    """Every arm's wrist force ``F`` of the plant step from the last tick, from the tick hold.

    .. pydrake_system::

        name: TickForces
        input_ports:
        - tick_hold
        output_ports:
        - <robot>_F_step

    Reads ``[x(t_k), u_k, a_k]`` of ``ground_truth_hold_tick`` and evaluates
    :class:`~drake_coop.plant.wrist_dynamics.ArmForces` for every arm, once per tick and only
    when an output is read (no event of its own): what the live ground truth's ``<robot>_F_step``
    latches, for readers during the run (the Meshcat force arrows). The logs do not use it.
    Before the hold's first sample (its initial value, all zeros: at ``Simulator.Initialize``)
    every force is zero.

    Parameters
    ----------
    equation : ArmForces
        The wrist-force equation of every arm.
    names : list of str
        The robots' names, in the order of ``equation``'s arms.
    actuation_order : ndarray
        ``(n_u, w)``: the plant's actuation from the held actuation values.

    Input ports
    -----------
    tick_hold : (n_x + w + n_v)-vector
        ``[x, held actuation, a]``.

    Output ports
    ------------
    <robot>_F_step : 3-vector, one per arm
        ``F`` of the step from the last tick (N, palm frame).
    """

    def __init__(self, equation: ArmForces, names: list[str], actuation_order: np.ndarray):
        super().__init__()
        self._eq = equation
        self._order = np.asarray(actuation_order, dtype=float)
        nx, nv, w = equation.nx, equation.nx - equation.nq, self._order.shape[1]
        self._hold = self.DeclareVectorInputPort("tick_hold", nx + w + nv)
        self._forces = self.DeclareCacheEntry(
            "wrist force of every arm",
            ValueProducer(allocate=AbstractValue.Make([np.zeros(3)]).Clone,
                          calc=self._calc_forces),
            {self._hold.ticket()})
        for i, name in enumerate(names):
            self.DeclareVectorOutputPort(
                f"{name}_F_step", 3,
                lambda context, output, i=i: output.SetFromVector(
                    self._forces.Eval(context)[i]),
                prerequisites_of_calc={self._forces.ticket()})

    def get_tick_hold_input_port(self) -> InputPort:
        """``[x, held actuation, a]`` of the tick hold."""
        return self._hold

    def _calc_forces(self, context: Context, value: AbstractValue) -> None:
        held = self._hold.Eval(context)
        eq, w = self._eq, self._order.shape[1]
        if not held.any():           # the hold's initial value: no tick sampled yet
            value.set_value([np.zeros(3) for _ in eq.normals])
            return
        value.set_value(eq(held[:eq.nx], held[eq.nx + w:], self._order @ held[eq.nx:eq.nx + w]))


def _rows_times(rows: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``rows @ matrix`` without BLAS: on a 2-core machine a multithreaded BLAS product of
    ``(K, w)`` rows spins a second thread for about as long as the work (CPU time ~1.5×
    wall in ``collect_logs``); NumPy's own loop costs the same wall time on one core."""
    return np.einsum("kj,ji->ki", rows, matrix)


def _steps(eq: ArmForces, x: np.ndarray, a: np.ndarray, u: np.ndarray
           ) -> list[np.ndarray]:
    """:meth:`ArmForces.steps` on the rows whose data are finite (a diverged run's last rows
    may not be), NaN on the others."""
    K = x.shape[0]
    ok = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(a), axis=1) \
        & np.all(np.isfinite(u), axis=1)
    out = [np.full((K, 3), np.nan) for _ in eq.normals]
    if ok.any():
        try:
            values = eq.steps(x[ok], a[ok], u[ok])
        except np.linalg.LinAlgError:           # a singular Jacobian: row by row
            rows = [eq(xi, ai, ui) for xi, ai, ui in zip(x[ok], a[ok], u[ok])]
            values = [np.array([r[arm] for r in rows]) for arm in range(len(eq.normals))]
        for o, v in zip(out, values):
            o[ok] = v
    return out


def add_ground_truth(builder: DiagramBuilder, coop: CoopPlant, period: float,
                     models: list[FTModel], actuation: list[OutputPort] | None = None,
                     tick_forces: bool = True) -> GroundTruthLog:
    """The holds and the logger of the offline ground truth (see the module's docstring),
    wired to the plant: C++ systems only, no Python call during the run.

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder (the plant is in it).
    coop : CoopPlant
        The plant, in ``planes`` or ``rigid`` mode.
    period : float
        The control period ``h``, a multiple of the plant's step.
    models : list of FTModel
        Each robot's F/T sensor model (for ``lambda_sensor``).
    actuation : list of OutputPort, optional
        The ports feeding each arm's actuation input (in the order of ``coop.arms``): what
        the holds sample as ``u``. Default: the plant's ``net_actuation`` port, the same
        values (no PD-controlled actuators), but its evaluation between two plant updates
        costs more than the sources' (measured ~4 % of the plant's cost per tick).
    tick_forces : bool
        Also add :class:`TickForces` (``wrist_forces_at_tick``) for readers during the run;
        without it the diagram has one system less, whose per-step cost every run would pay.

    Returns
    -------
    GroundTruthLog
        The log, read after the run.
    """
    if coop.mode not in ("planes", "rigid"):
        raise ValueError(f"the offline ground truth needs planes or rigid mode, not "
                         f"{coop.mode!r}")
    plant = coop.plant
    dt = plant.time_step()
    nx, nu = plant.num_multibody_states(), plant.num_actuators()
    if actuation is None:
        sources = [plant.get_net_actuation_output_port()]
        order = np.eye(nu)
    else:
        sources = list(actuation)
        order = np.zeros((nu, sum(p.size() for p in sources)))   # sources → plant's u
        start = 0
        for h, port in zip(coop.arms, sources):
            for j in range(port.size()):
                column = np.zeros(nu)
                plant.SetActuationInArray(h.instance, np.eye(port.size())[j], column)
                order[:, start + j] = column
            start += port.size()
    width = nx + order.shape[1]
    nv = plant.num_velocities()
    signals = builder.AddNamedSystem("ground_truth_signals",
                                     Multiplexer([nx] + [p.size() for p in sources]))
    builder.Connect(plant.get_state_output_port(), signals.get_input_port(0))
    for j, port in enumerate(sources):
        builder.Connect(port, signals.get_input_port(j + 1))
    with_a = builder.AddNamedSystem("ground_truth_signals_and_acceleration",
                                    Multiplexer([width, nv]))
    builder.Connect(signals.get_output_port(0), with_a.get_input_port(0))
    builder.Connect(plant.get_generalized_acceleration_output_port(), with_a.get_input_port(1))
    tick = builder.AddNamedSystem("ground_truth_hold_tick",
                                  ZeroOrderHold(period, width + nv, 0.0))
    builder.Connect(with_a.get_output_port(0), tick.get_input_port())
    held = [tick]
    before = None
    if _holds_last_step(period, dt):
        before = builder.AddNamedSystem("ground_truth_hold_before_tick",
                                        ZeroOrderHold(period, width, period - 1.5 * dt))
        builder.Connect(signals.get_output_port(0), before.get_input_port())
        held.append(before)
    mux = builder.AddNamedSystem("ground_truth_log_signals",
                                 Multiplexer([s.get_output_port().size() for s in held]))
    for j, s in enumerate(held):
        builder.Connect(s.get_output_port(), mux.get_input_port(j))
    logger = LogVectorOutput(mux.get_output_port(0), builder, publish_period=period)
    logger.set_name("ground_truth_log")
    equation = ArmForces(plant, coop.arms, dt)
    if tick_forces:
        forces = builder.AddNamedSystem("wrist_forces_at_tick", TickForces(
            equation, [h.arm.name for h in coop.arms], order))
        builder.Connect(tick.get_output_port(), forces.get_input_port())
    return GroundTruthLog(logger=logger, equation=equation,
                          models=list(models), tick=tick.get_output_port(),
                          before_tick=None if before is None else before.get_output_port(),
                          state=plant.get_state_output_port(), period=float(period),
                          actuation_order=order)


@dataclass
class PadForceLog:
    """The ``contact`` mode's ground truth off the control loop: the pads' contact forces of
    every plant step, held and logged by C++ blocks, sorted into ticks after the run.

    :class:`~drake_coop.plant.grasp.PadForces` (``pad_forces``) computes ``[F_1, …, F_l]``
    from the plant's contact results when read; a C++ ``ZeroOrderHold``
    (``pad_forces_hold``, period ``Δt``, offset 0) reads it in the discrete phase of every
    plant update, from the context of the plant's own update (after the controllers' latch
    at a tick: the step taken, its solve shared), so between :math:`t_j` and :math:`t_{j+1}` it
    holds the force of the step ``[t_j, t_j + Δt)``; a ``VectorLogSink`` (``pad_forces_log``)
    publishes it at every plant step, before that step's updates: the sample at ``t_j`` is
    the step ``[t_j − Δt, t_j)``. One Python call per plant step (the output's calculation,
    which reads the contact results only at the two steps next to a tick, NaN at the others),
    no Python event, nothing read between two plant updates.

    After the run (:meth:`evaluate`), tick ``k`` (``t_k = k N Δt``, ``N = h/Δt``) takes
    ``F_meas`` from the sample at ``t_k + Δt`` (the step taken from the tick) and the F/T
    sensor model's reading from ``λ`` of the sample at ``t_k`` (the step before the tick,
    :meth:`~drake_coop.sensing.force_sensor.FTModel.readings`), the same rules as the live
    path. A controller that reads its F/T sensor during the run reads ``λ`` of the hold at
    ``t_k − Δt/2`` (:meth:`add_lambda_last_step`).

    Attributes
    ----------
    logger : VectorLogSink or None
        ``pad_forces_log`` (None without logging).
    hold : OutputPort
        ``pad_forces_hold``'s output: ``[F_1, …, F_l]`` of the last plant step.
    normals : list of ndarray
        Each robot's outward normals ``N_i`` (rows): ``λ_i = N_i F_i``.
    models : list of FTModel
        Each robot's F/T sensor model.
    period, time_step : float
        ``h`` and ``Δt`` (s).
    """

    logger: VectorLogSink | None
    hold: OutputPort
    normals: list[np.ndarray]
    models: list[FTModel]
    period: float
    time_step: float

    def _held(self, context: Context) -> np.ndarray:
        return self.hold.Eval(self.hold.get_system().GetMyContextFromRoot(context))

    def force_before_tick(self, context: Context) -> list[np.ndarray]:
        """Every pad's ``F`` of the plant step ``[t_k − Δt, t_k)`` at a tick ``t_k`` before its
        updates (the hold's value: no plant solve).

        Parameters
        ----------
        context : Context
            The root context at a tick.

        Returns
        -------
        list of numpy.ndarray
            Per pad ``F`` (3,), N, world frame.
        """
        F = self._held(context)
        return [F[3 * i:3 * i + 3].copy() for i in range(len(self.normals))]

    def add_lambda_last_step(self, builder: DiagramBuilder, index: int, name: str
                             ) -> OutputPort:
        """``N_i F_i`` of robot ``index``'s pad from the hold (a C++ ``MatrixGain``,
        ``<name>_lambda_last_step``): read at ``t_k − Δt/2`` it is ``λ`` of the step
        ``[t_k − Δt, t_k)``, the live F/T sensor model's input.

        Parameters
        ----------
        builder : DiagramBuilder
            The experiment's builder.
        index : int
            The robot's index.
        name : str
            The robot's name (the system's prefix).

        Returns
        -------
        OutputPort
            The gain's output (m,), N.
        """
        N = np.atleast_2d(self.normals[index])
        D = np.zeros((N.shape[0], 3 * len(self.normals)))
        D[:, 3 * index:3 * index + 3] = N
        gain = builder.AddNamedSystem(f"{name}_lambda_last_step", MatrixGain(D))
        builder.Connect(self.hold, gain.get_input_port())
        return gain.get_output_port()

    def evaluate(self, context: Context, n: int, complete: bool) -> list[dict[str, np.ndarray]]:
        """Per robot ``F_meas`` ``(n, 3)``, ``lambda_meas`` and ``lambda_sensor`` ``(n, m)`` of
        the ticks ``0 … n − 1``.

        ``F_meas`` of tick ``k`` is the step ``[t_k, t_k + Δt)``, published at ``t_k + Δt``;
        with ``complete`` the last tick's comes from the hold's current value when it has
        sampled that tick (the context's time is past ``t_k``), else that row is NaN (so is
        any row whose sample is missing). ``lambda_sensor`` of tick ``k ≥ 1`` is the model's
        reading of ``λ`` of the step ``[t_k − Δt, t_k)``, published at ``t_k``.

        Parameters
        ----------
        context : Context
            The root context after the run.
        n : int
            The number of ticks.
        complete : bool
            Whether the last published tick's updates ran.

        Returns
        -------
        list of dict
            Per robot: ``F_meas`` (n, 3), ``lambda_meas`` and ``lambda_sensor`` (n, m), N.
        """
        width = 3 * len(self.normals)
        steps = int(round(self.period / self.time_step))
        log = self.logger.FindLog(context)
        times, data = log.sample_times(), log.data()
        j = np.rint(times / self.time_step).astype(int)          # the plant step's index
        ticks = np.arange(n) * steps
        size = max(int(j.max()) + 1 if j.size else 0, int(ticks[-1]) + 2 if n else 0)
        by_step = np.full((size, width), np.nan)
        by_step[j] = data.T
        if complete and n > 0:
            last = int(ticks[-1]) + 1          # the step from the last tick: not published
            if np.isnan(by_step[last]).all() and context.get_time() > ticks[-1] * self.time_step:
                by_step[last] = self._held(context)
        after = by_step[ticks + 1]
        before = np.zeros((n, width))
        before[1:] = by_step[ticks[1:]]
        out = []
        for i, (N, model) in enumerate(zip(self.normals, self.models)):
            N = np.atleast_2d(N)
            F = after[:, 3 * i:3 * i + 3]
            prior = before[:, 3 * i:3 * i + 3] @ N.T
            out.append({"F_meas": F, "lambda_meas": F @ N.T,
                        "lambda_sensor": model.readings(prior)})
        return out


def add_pad_force_log(builder: DiagramBuilder, coop: CoopPlant, period: float,
                      models: list[FTModel], log: bool = True) -> PadForceLog:
    """The ``contact`` mode's ground truth of :class:`PadForceLog`, wired to the plant:
    ``pad_forces`` (:class:`~drake_coop.plant.grasp.PadForces`), ``pad_forces_hold`` (C++,
    every plant step) and, with ``log``, ``pad_forces_log`` (publishing at every plant step).

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder (the plant is in it).
    coop : CoopPlant
        The plant, in ``contact`` mode.
    period : float
        The control period ``h``, a multiple of the plant's step.
    models : list of FTModel
        Each robot's F/T sensor model (for ``lambda_sensor``).
    log : bool
        Add the logger (without it only the hold, for the guards and live F/T models).
    """
    if coop.mode != "contact":
        raise ValueError(f"the pads' ground truth needs contact mode, not {coop.mode!r}")
    plant = coop.plant
    dt = plant.time_step()
    pads = builder.AddNamedSystem("pad_forces", PadForces(coop.grasp, period, dt))
    builder.Connect(plant.get_contact_results_output_port(),
                    pads.get_contact_results_input_port())
    forces = pads.get_forces_output_port()
    hold = builder.AddNamedSystem("pad_forces_hold", ZeroOrderHold(dt, forces.size(), 0.0))
    builder.Connect(forces, hold.get_input_port())
    logger = None
    if log:
        logger = LogVectorOutput(hold.get_output_port(), builder, publish_period=dt)
        logger.set_name("pad_forces_log")
    return PadForceLog(logger=logger, hold=hold.get_output_port(),
                       normals=[np.asarray(h.arm.N, dtype=float) for h in coop.arms],
                       models=list(models), period=float(period), time_step=float(dt))
