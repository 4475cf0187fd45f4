"""Sampled time: the control period and the plant step on one grid, ticks, the sampled low-pass.

Every block of :mod:`drake_coop.control` is sampled at the control period ``h``; a simulated
plant steps at ``dt``. :func:`aligned_periods` puts both on one exact grid (the only place the
periods are aligned), :func:`tick_of` converts a time to a tick index, :func:`lowpass_alpha`
is the gain of the first-order filter the sources share. A block may tick on a :class:`Clock`
of its own (a controller's computer, with its phase and rate against the plant's time):
:func:`on_clock` gives the period and offset of its periodic events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Clock", "aligned_periods", "on_clock", "tick_of", "lowpass_alpha"]


@dataclass(frozen=True)
class Clock:
    """A controller's own clock against the run's (the plant's) time.

    Its tick ``k`` comes at the run's time ``t_k = φ + k h / (1 + ε)``: phase ``φ`` and a rate
    offset ``ε`` (the clock runs ``ε`` fast). A block given a clock keeps ``h`` in its
    equations (it believes its ticks ``h`` apart) and only declares its periodic events on the
    clock (:func:`on_clock`). The default, ``Clock()``, is the run's own grid.

    Attributes
    ----------
    phase : float
        ``φ``, s (``>= 0``, finite).
    ppm : float
        ``ε`` in parts per million (finite, ``> −1e6``).

    Raises
    ------
    ValueError
        A phase or rate outside those ranges, naming the field.
    """

    phase: float = 0.0
    ppm: float = 0.0

    def __post_init__(self):
        for field in ("phase", "ppm"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"clock.{field}: a number is required, got {value!r}")
        if not (math.isfinite(self.phase) and self.phase >= 0.0):
            raise ValueError(f"clock.phase: a finite time >= 0 s is required, got "
                             f"{self.phase!r}")
        if not (math.isfinite(self.ppm) and self.ppm > -1e6):
            raise ValueError(f"clock.ppm: a finite rate offset > -1e6 ppm is required, got "
                             f"{self.ppm!r}")

    @property
    def scale(self) -> float:
        """``1 / (1 + ε)``: a span of the clock in the run's time, per second."""
        return 1.0 / (1.0 + 1e-6 * self.ppm)

    def true_time(self, local):
        """The run's time at which the clock reads ``local``.

        Parameters
        ----------
        local : float or numpy.ndarray
            Times on the clock, s (its tick ``k`` at ``k h``).

        Returns
        -------
        float or numpy.ndarray
            ``φ + local / (1 + ε)``, s.
        """
        return self.phase + local * self.scale


def on_clock(clock: Clock | None, period: float, offset: float = 0.0) -> tuple[float, float]:
    """The period and offset, in the run's time, of a periodic event declared ``(period,
    offset)`` on ``clock``: ``(h / (1 + ε), φ + o / (1 + ε))``; unchanged for None.

    Parameters
    ----------
    clock : Clock or None
        The block's clock; None: the run's grid.
    period : float
        The event's period on the clock, s.
    offset : float
        Its offset on the clock, s.

    Returns
    -------
    tuple of float
        ``(period, offset)`` for Drake's ``DeclarePeriodic*Event``.

    Raises
    ------
    TypeError
        ``clock`` is neither a :class:`Clock` nor None.
    """
    if clock is None:
        return period, offset
    if not isinstance(clock, Clock):
        raise TypeError(f"clock: a Clock or None is required, got {type(clock).__name__}")
    scale = clock.scale
    return period * scale, clock.phase + offset * scale


def aligned_periods(control_period: float, time_step: float) -> tuple[float, float]:
    """Control period ``h`` and plant step ``dt`` adjusted so that their event times coincide.

    Drake schedules a periodic event at ``k * period`` (floating point). With ``h = 0.009`` and
    ``dt = 0.001``, ``k * 0.009`` and ``(9 k) * 0.001`` differ by one rounding now and then, and
    the simulator takes spurious ~1e-17 s steps between the plant's step and the controller's
    tick (a known Drake behaviour) — with the plant stepping *before* the controller reads
    its state.
    Rounding ``dt`` to ``53 − ceil(log2 N)`` significant bits (a relative change below 1e-14)
    makes ``h = N dt`` exact, and then ``k h`` and ``(N k) dt`` are the same real number rounded
    once: every control tick falls exactly on a plant step.

    Parameters
    ----------
    control_period : float
        The control period ``h`` (s), > 0.
    time_step : float
        The plant's step ``dt`` (s), > 0, with ``h / dt`` a whole number ``N`` (to
        rounding).

    Returns
    -------
    (h, dt) : tuple[float, float]
        With ``h == N * dt`` exactly, ``N = round(control_period / time_step)``.
    """
    N = int(round(control_period / time_step))
    if N == 1:
        return float(control_period), float(control_period)
    bits = 53 - math.ceil(math.log2(N))
    _, exponent = math.frexp(time_step)
    scale = 2.0 ** (bits - exponent)
    dt = round(time_step * scale) / scale
    return N * dt, dt


def tick_of(t: float, h: float) -> int | None:
    """The tick index ``k`` if ``t`` is a sampling instant ``k h`` (to 1e-9 relative), else None.

    Parameters
    ----------
    t : float
        A time (s).
    h : float
        The sampling time (s).
    """
    k = round(t / h)
    return k if abs(t - k * h) <= 1e-9 * max(1.0, t) else None


def lowpass_alpha(cutoff_hz: float | None, h: float) -> float:
    """Gain ``α`` of the sampled first-order low-pass ``y(k) = y(k−1) + α (u(k) − y(k−1))``.

    ``α = 1 − exp(−2π f_c h)``: the exact (step-invariant) discretization of
    ``T ẏ = u − y``, ``T = 1/(2π f_c)``, for an input held over each sample. ``α = 1`` (no
    filter) when ``cutoff_hz`` is None.

    Parameters
    ----------
    cutoff_hz : float or None
        The cutoff ``f_c`` (Hz); None: no filter.
    h : float
        The sampling time (s).

    Returns
    -------
    float
        ``α`` in (0, 1].
    """
    if cutoff_hz is None:
        return 1.0
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * h)
