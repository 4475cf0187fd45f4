"""The arms' clock skew: one arm's controller side ticking on its own clock.

In a cell, each arm's controller runs on its own computer, whose quartz clock has a phase
and a rate of its own. The model: the plant (and every ground-truth log) keeps the run's
time ``t``; the other arms tick at ``k h``; one arm (by default robot 2) has a clock
:class:`ArmClock` — its tick ``k`` happens at the true time ``t_k = φ + k h / (1 + ε)``
(phase ``φ`` in ``[0, h)``, rate offset ``ε``: the clock runs ``ε`` fast). Every periodic
event of that arm's controller side — the velocity and force sources, the controller, the
F/T sensor model — is declared on its clock; between its ticks the arm's torque is held (the
controller's latch), and the plant, stepping at ``Δt``, applies it from its next step: the
zero-order hold between the two machines.

What the model leaves out: the arm's reference trajectory is read at the true time of its
tick (a shared start signal, no drift of the trajectory's time base: at ``ε`` = 100 ppm over
an 8 s cell the two differ by 0.8 ms); its sampled encoders and its computation-delay block
are not moved to its clock (refused: the table's clock column has ideal encoders and no
delay).

The draws (:func:`draw_clock`): ``φ ~ U(0, h)``, the phase of two machines started by hand;
``ε ~ U(−100, 100)`` ppm: the upper end of the tolerance grades of the quartz crystals a
computer's clock runs on (tens of ppm for frequency, temperature and ageing together).
Over the cell's 8 s that rate moves the phase by at most 0.8 ms (a tenth of a 9 ms tick): the
phase dominates.

How it is built: :func:`clock_built` wraps, while the arm's systems are constructed, the
periodic-event declarations of Drake's ``LeafSystem`` and the F/T sensor's C++
``ZeroOrderHold`` so that a declaration ``(period h, offset o)`` — on the arm's own clock —
becomes ``(h / (1 + ε), φ + o / (1 + ε))`` of the run's time. The blocks themselves are the
library's, unchanged.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from drake_coop.scenario.schema import Scenario

__all__ = ["PPM_BOUND", "ArmClock", "clock_built", "clock_variant", "draw_clock", "split_clock"]

#: The rate offsets' bound (ppm): ``ε ~ U(−PPM_BOUND, PPM_BOUND) × 1e-6``.
PPM_BOUND = 100.0
_PREFIX = "clock:"


@dataclass(frozen=True)
class ArmClock:
    """One arm's clock against the run's time.

    Attributes
    ----------
    offset : float
        ``φ``: the true time of its tick 0, s (``0 <= φ``).
    ppm : float
        ``ε`` in parts per million: its clock runs ``ε`` fast (its ticks come
        ``h / (1 + ε)`` apart).
    robot : int
        The arm's index in the scenario.
    """

    offset: float
    ppm: float
    robot: int = 1

    def true_time(self, local: float | np.ndarray) -> float | np.ndarray:
        """The run's time at which the arm's clock reads ``local``.

        Parameters
        ----------
        local : float or numpy.ndarray
            Times on the arm's clock, s (its tick ``k`` at ``k h``).

        Returns
        -------
        float or numpy.ndarray
            ``φ + local / (1 + ε)``, s.
        """
        return self.offset + np.asarray(local) / (1.0 + 1e-6 * self.ppm)


def draw_clock(rng: np.random.Generator, h: float, robot: int = 1) -> ArmClock:
    """One draw of the clock column: ``φ ~ U(0, h)``, ``ε ~ U(−100, 100)`` ppm.

    Parameters
    ----------
    rng : numpy.random.Generator
        The column's generator for this draw.
    h : float
        The control period, s.
    robot : int
        The arm with the skewed clock.

    Returns
    -------
    ArmClock
        The draw.
    """
    offset, ppm = rng.uniform(0.0, h), rng.uniform(-PPM_BOUND, PPM_BOUND)
    return ArmClock(float(offset), float(ppm), robot)


def clock_variant(clock: ArmClock, variant: str | None) -> str:
    """A case's variant carrying ``clock`` (and the row's own ``variant``, if any).

    Parameters
    ----------
    clock : ArmClock
        The arm's clock.
    variant : str or None
        The row's variant (:mod:`~drake_coop.studies.reference_variants`).

    Returns
    -------
    str
        ``clock:<robot>:<φ>:<ε>`` (``repr`` of the floats: exact), then ``|<variant>``.
    """
    text = f"{_PREFIX}{clock.robot}:{clock.offset!r}:{clock.ppm!r}"
    return text if variant is None else f"{text}|{variant}"


def split_clock(variant: str | None) -> tuple[ArmClock | None, str | None]:
    """The clock and the row's variant of a case's variant (:func:`clock_variant`).

    Parameters
    ----------
    variant : str or None
        A case's variant.

    Returns
    -------
    clock : ArmClock or None
        None when the variant carries no clock.
    variant : str or None
        The row's own variant.
    """
    if variant is None or not variant.startswith(_PREFIX):
        return None, variant
    head, _, rest = variant.partition("|")
    robot, offset, ppm = head[len(_PREFIX):].split(":")
    return ArmClock(float(offset), float(ppm), int(robot)), rest or None


def _on_clock(clock: ArmClock, active: list):
    """``(period, offset) → (period', offset')`` on the clock while ``active[0]``."""
    scale = 1.0 / (1.0 + 1e-6 * clock.ppm)

    def warp(period: float, offset: float) -> tuple[float, float]:
        if not active[0]:
            return period, offset
        return period * scale, clock.offset + offset * scale
    return warp


@contextlib.contextmanager
def clock_built(scenario: Scenario, clock: ArmClock | None) -> Iterator[None]:
    """While inside, experiments of ``scenario`` are built with arm ``clock.robot``'s
    controller side on ``clock`` (the module's docstring); None changes nothing.

    Parameters
    ----------
    scenario : Scenario
        The case's scenario.
    clock : ArmClock or None
        The arm's clock.

    Yields
    ------
    None
        The wrapping holds until the block exits.

    Raises
    ------
    ValueError
        The arm does not exist, its offset is negative, or it has sampled encoders or a
        computation delay (not moved to its clock).
    """
    if clock is None:
        yield
        return
    if not 0 <= clock.robot < len(scenario.robots):
        raise ValueError(f"clock.robot: an index of the scenario's {len(scenario.robots)} "
                         f"robots, got {clock.robot}")
    if not clock.offset >= 0.0:
        raise ValueError(f"clock.offset: must be >= 0 s, got {clock.offset!r}")
    robot = scenario.robots[clock.robot]
    e, t = robot.encoders, robot.timing
    if e.noise_std or e.delay_samples or getattr(e, "counts_per_rev", None) or \
            t.computation_delay > 0.0 or t.jitter != "none":
        raise ValueError(f"clock: robot {robot.name} must have ideal encoders and no "
                         "computation delay (neither is moved to its clock)")
    from pydrake.systems.framework import LeafSystem

    import drake_coop.experiment.diagram as diagram
    import drake_coop.sensing.force_sensor as force_sensor

    active = [False]
    warp = _on_clock(clock, active)
    names = ("DeclarePeriodicDiscreteUpdateEvent", "DeclarePeriodicUnrestrictedUpdateEvent",
             "DeclarePeriodicPublishEvent")
    saved_leaf = {n: LeafSystem.__dict__[n] for n in names}
    saved = (diagram.AddCooperativeController, diagram.add_ft_sensor, force_sensor.ZeroOrderHold)

    def declare(original):
        def on_clock(self, period, offset, *args, **kwargs):
            return original(self, *warp(period, offset), *args, **kwargs)
        return on_clock

    def during(function, is_arm):
        def wrapped(*args, **kwargs):
            active[0] = is_arm(args, kwargs)
            try:
                return function(*args, **kwargs)
            finally:
                active[0] = False
        return wrapped

    hold = force_sensor.ZeroOrderHold

    def zero_order_hold(period, size, offset=0.0):
        on_clock_period, on_clock_offset = warp(period, offset)
        return hold(on_clock_period, size, on_clock_offset)

    try:
        for n in names:
            setattr(LeafSystem, n, declare(saved_leaf[n]))
        diagram.AddCooperativeController = during(
            saved[0], lambda a, k: k.get("name") == robot.name)
        diagram.add_ft_sensor = during(saved[1], lambda a, k: a[1] == robot.name)
        force_sensor.ZeroOrderHold = zero_order_hold
        yield
    finally:
        for n in names:
            setattr(LeafSystem, n, saved_leaf[n])
        diagram.AddCooperativeController, diagram.add_ft_sensor, force_sensor.ZeroOrderHold \
            = saved
