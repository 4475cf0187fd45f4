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

How it is built: :func:`arm_clocks` gives the run's plan one
:class:`~drake_coop.control.timing.Clock` per robot (the arm's, the others None;
:meth:`~drake_coop.experiment.plan.RunPlan.with_clocks`), and every block of that arm's
controller side declares its periodic events on it: a declaration ``(period h, offset o)`` on
the arm's clock is ``(h / (1 + ε), φ + o / (1 + ε))`` of the run's time
(:func:`~drake_coop.control.timing.on_clock`); each block keeps ``h`` in its equations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.scenario.schema import Scenario

__all__ = ["PPM_BOUND", "ArmClock", "arm_clocks", "clock_variant", "draw_clock", "split_clock"]

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


def arm_clocks(scenario: Scenario, clock: ArmClock | None) -> tuple | None:
    """The plan's clocks (:meth:`~drake_coop.experiment.plan.RunPlan.with_clocks`) of a case
    with ``clock``: the arm's :class:`~drake_coop.control.timing.Clock`, None for the others.

    Parameters
    ----------
    scenario : Scenario
        The case's scenario.
    clock : ArmClock or None
        The arm's clock; None: no clock at all.

    Returns
    -------
    tuple of (Clock or None), or None
        One entry per robot; None when ``clock`` is None.

    Raises
    ------
    ValueError
        The arm does not exist, or its phase is negative.
    """
    from drake_coop.control.timing import Clock

    if clock is None:
        return None
    if not 0 <= clock.robot < len(scenario.robots):
        raise ValueError(f"clock.robot: an index of the scenario's {len(scenario.robots)} "
                         f"robots, got {clock.robot}")
    arm = Clock(phase=clock.offset, ppm=clock.ppm)
    return tuple(arm if i == clock.robot else None for i in range(len(scenario.robots)))
