"""Sampled time: the control period and the plant step on one grid, ticks, the sampled low-pass.

Every block of :mod:`drake_coop.control` is sampled at the control period ``h``; a simulated
plant steps at ``dt``. :func:`aligned_periods` puts both on one exact grid (the only place the
periods are aligned), :func:`tick_of` converts a time to a tick index, :func:`lowpass_alpha`
is the gain of the first-order filter the sources share.
"""

from __future__ import annotations

import math

__all__ = ["aligned_periods", "tick_of", "lowpass_alpha"]


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
