"""The ground truth off the control loop: C++ holds of the plant's data, evaluated after the run.

In the ``planes`` and ``rigid`` modes, when no controller reads the F/T sensor
(``force_source`` other than ``sensor`` on every robot), nothing in the control loop consumes
the ground-truth wrist force: it is a measurement *of the simulation*. Instead of evaluating
:class:`~drake_coop.plant.wrist.WristDynamics` at every tick in Python, the experiment holds,
once per tick and with C++ blocks only (:class:`~pydrake.systems.primitives.Multiplexer`,
:class:`~pydrake.systems.primitives.ZeroOrderHold`), exactly what its equation needs, logs it,
and :class:`GroundTruthLog` evaluates the equation (:class:`~drake_coop.plant.wrist.ArmForces`)
for all the ticks at once after the run.

Holds (period ``h``, the plant step ``Δt``; each reads the context half a plant step away from
every plant update, or at a tick itself, so no floating-point rounding of an event time can
move it across a plant update):

* ``ground_truth_hold_tick``, offset 0: ``[x(t_k), u_k]``, the plant's state and the
  actuation its inputs receive (the arms' actuators' outputs: the plant's ``net_actuation``
  without PD-controlled actuators) in the discrete phase of ``t_k``, i.e. after the
  controller's unrestricted latch of ``τ(k)``, from the context the plant's own update reads:
  the start and the actuation of the step ``[t_k, t_k + Δt)``;
* ``ground_truth_hold_step_end``, offset ``Δt/2``: ``x(t_k + Δt)``, the state that step
  produced (``a = (v(t_k + Δt) − v(t_k))/Δt``, the acceleration port's own formula). Never at
  offset ``Δt``: Drake computes an event's time as ``offset + k h``, which rounds differently
  from the plant's ``j Δt`` on some ticks;
* with ``h ≥ 2Δt``, ``ground_truth_hold_before_tick``, offset ``h − 3Δt/2``:
  ``[x(t_k − Δt), u]`` of the step ``[t_k − Δt, t_k)``, which ends at ``x(t_k)``: the F/T
  sensor model's reading of tick ``k``
  (:mod:`drake_coop.sensing.force_sensor`). With ``h = Δt`` that step is the previous tick's.

A :class:`~pydrake.systems.primitives.VectorLogSink` (``ground_truth_log``) publishes them at
every tick, *before* the tick's updates: the sample at ``t_{k+1}`` holds the two tick holds of
tick ``k`` (shifted back as every latched signal, see
:func:`~drake_coop.experiment.simulate.collect_logs`), the sample at ``t_k`` the step before
``t_k``. :meth:`GroundTruthLog.evaluate` returns per robot ``F_meas`` and ``lambda_meas`` of
the step taken from every tick and ``lambda_sensor``, the F/T model's reading
(:class:`~drake_coop.sensing.force_sensor.FTModel`, the same function the live
:class:`~drake_coop.sensing.force_sensor.FTSensor` steps). :meth:`GroundTruthLog.force_before_tick`
gives the divergence guards the force of the step before the current tick, from the held data
and the current state (no plant solve).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import Context, DiagramBuilder, OutputPort
from pydrake.systems.primitives import (
    LogVectorOutput,
    Multiplexer,
    VectorLogSink,
    ZeroOrderHold,
)

from drake_coop.plant.cooperative import CoopPlant
from drake_coop.plant.wrist import ArmForces, _holds_last_step
from drake_coop.sensing.force_sensor import FTModel


@dataclass
class GroundTruthLog:
    """The held plant data of the offline ground truth and its evaluation.

    Attributes
    ----------
    logger : VectorLogSink
        ``ground_truth_log``: ``[x, u]`` of the tick hold, ``x`` of the step-end hold and, with
        ``h ≥ 2Δt``, ``[x, u]`` of the before-tick hold, published at every tick.
    equation : ArmForces
        The wrist-force equation of every arm.
    models : list of FTModel
        Each robot's F/T sensor model.
    tick, step_end, before_tick : OutputPort
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
    step_end: OutputPort
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
        ``k`` (published at ``t_{k+1}``) and the step-end hold. With ``complete`` (the last
        published tick's updates ran, :func:`~drake_coop.experiment.simulate.finish_last_tick`)
        the last tick's come from the holds' current values when both holds have sampled
        after that tick (the context's time is past ``t_K + Δt/2``), else that row is NaN.
        ``lambda_sensor`` of tick ``k ≥ 1`` is the model's reading of ``λ`` of the step
        ``[t_k − Δt, t_k)``; tick 0's is the model's initial reading.
        """
        eq = self.equation
        nx, nq = eq.nx, eq.nq
        nu = self.actuation_order.shape[1]            # held actuation values
        P = self.actuation_order.T
        log = self.logger.FindLog(context)
        times, data = log.sample_times(), log.data()
        published = times.size
        tick = data[:nx + nu, 1:published].T
        end = data[nx + nu:2 * nx + nu, 1:published].T
        if complete and published > 0:
            dt = eq.dt
            valid = context.get_time() > times[published - 1] + 0.5 * dt
            last_tick = self._now(context, self.tick) if valid else np.full(nx + nu, np.nan)
            last_end = self._now(context, self.step_end) if valid else np.full(nx, np.nan)
            tick = np.vstack([tick, last_tick])
            end = np.vstack([end, last_end])
        tick, end = tick[:n], end[:n]
        n = tick.shape[0]
        forces = _steps(eq, tick[:, :nx], end[:, nq:], tick[:, nx:] @ P)
        lam = [F @ N.T for F, N in zip(forces, eq.normals)]
        if self.before_tick is not None:
            before = data[2 * nx + nu:, 1:n].T            # published at t_k: the step before t_k
            prior = _steps(eq, before[:, :nx], tick[1:n, nq:nx], before[:, nx:] @ P)
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
        ``h = Δt``) and the current state ``x(t_k)``, without a plant solve."""
        eq = self.equation
        held = self._now(context, self.before_tick if self.before_tick is not None
                         else self.tick)
        x = held[:eq.nx]
        v_now = self._now(context, self.state)[eq.nq:]
        return eq(x, (v_now - x[eq.nq:]) / eq.dt, self.actuation_order @ held[eq.nx:])


def _steps(eq: ArmForces, x: np.ndarray, v_next: np.ndarray, u: np.ndarray
           ) -> list[np.ndarray]:
    """:meth:`ArmForces.steps` on the rows whose data are finite (a diverged run's last rows
    may not be), NaN on the others."""
    K = x.shape[0]
    ok = np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(v_next), axis=1) \
        & np.all(np.isfinite(u), axis=1)
    out = [np.full((K, 3), np.nan) for _ in eq.normals]
    if ok.any():
        try:
            values = eq.steps(x[ok], v_next[ok], u[ok])
        except np.linalg.LinAlgError:           # a singular Jacobian: row by row
            rows = [eq(xi, (vi - xi[eq.nq:]) / eq.dt, ui)
                    for xi, vi, ui in zip(x[ok], v_next[ok], u[ok])]
            values = [np.array([r[arm] for r in rows]) for arm in range(len(eq.normals))]
        for o, v in zip(out, values):
            o[ok] = v
    return out


def add_ground_truth(builder: DiagramBuilder, coop: CoopPlant, period: float,
                     models: list[FTModel], actuation: list[OutputPort] | None = None
                     ) -> GroundTruthLog:
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
    signals = builder.AddNamedSystem("ground_truth_signals",
                                     Multiplexer([nx] + [p.size() for p in sources]))
    builder.Connect(plant.get_state_output_port(), signals.get_input_port(0))
    for j, port in enumerate(sources):
        builder.Connect(port, signals.get_input_port(j + 1))
    tick = builder.AddNamedSystem("ground_truth_hold_tick", ZeroOrderHold(period, width, 0.0))
    builder.Connect(signals.get_output_port(0), tick.get_input_port())
    end = builder.AddNamedSystem("ground_truth_hold_step_end",
                                 ZeroOrderHold(period, nx, 0.5 * dt))
    builder.Connect(plant.get_state_output_port(), end.get_input_port())
    held = [tick, end]
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
    return GroundTruthLog(logger=logger, equation=ArmForces(plant, coop.arms, dt),
                          models=list(models), tick=tick.get_output_port(),
                          step_end=end.get_output_port(),
                          before_tick=None if before is None else before.get_output_port(),
                          state=plant.get_state_output_port(), period=float(period),
                          actuation_order=order)
