r"""The exciting trajectory: a windowed finite Fourier series, inside the arm's limits.

Each joint follows

.. math::
    q_j(t) = q_{0,j} + w(t) \sum_{l=1}^{L} \big(a_{jl} \sin(l\omega_f t)
             + b_{jl} \cos(l\omega_f t)\big), \qquad \omega_f = 2\pi / T,

a periodic series (period ``T``) multiplied by a window ``w`` that rises from 0 to 1 over
``T_r`` at the start and falls back at the end with a quintic (zero velocity and acceleration
at both ends): the arm starts and stops at rest in ``q_0``. Derivatives are exact (product
rule). :func:`design_excitation` draws random coefficients (decaying as ``1/l``), scales each
candidate until the nominal model's torque and the joint limits are respected with margins,
and keeps the candidate whose regressor has the smallest condition number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_coop.scenario.task_path import quintic


@dataclass
class FourierExcitation:
    """A windowed finite Fourier series per joint (module docstring).

    Attributes
    ----------
    q0 : ndarray, shape (n,)
        Centre posture (rad): where the arm starts and ends, at rest.
    a, b : ndarray, shape (n, L)
        Sine and cosine coefficients (rad).
    period : float
        ``T`` (s), the period of the series.
    duration : float
        Length of the trajectory (s).
    ramp : float
        ``T_r`` (s), the window's rise and fall time.
    """

    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    period: float
    duration: float
    ramp: float

    def _window(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        up = quintic(np.clip(t / self.ramp, 0.0, 1.0))
        down = quintic(np.clip((self.duration - t) / self.ramp, 0.0, 1.0))
        w = up[0] * down[0]
        dw = (up[1] * down[0] - up[0] * down[1]) / self.ramp
        ddw = (up[2] * down[0] - 2.0 * up[1] * down[1] + up[0] * down[2]) / self.ramp ** 2
        return w, dw, ddw

    def _series(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        L = self.a.shape[1]
        wl = 2.0 * np.pi / self.period * np.arange(1, L + 1)          # (L,)
        arg = np.outer(np.asarray(t, float), wl)                       # (N, L)
        s, c = np.sin(arg), np.cos(arg)
        f = s @ self.a.T + c @ self.b.T
        df = (c * wl) @ self.a.T - (s * wl) @ self.b.T
        ddf = -(s * wl ** 2) @ self.a.T - (c * wl ** 2) @ self.b.T
        return f, df, ddf

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q, q̇, q̈`` at the times ``t`` (shape (N,)), each of shape (N, n).

        Parameters
        ----------
        t : array_like
            The times (N,), s.

        Returns
        -------
        q, qdot, qddot : numpy.ndarray
            (N, n): rad, rad/s, rad/s².
        """
        t = np.atleast_1d(np.asarray(t, float))
        w, dw, ddw = (x[:, None] for x in self._window(t))
        f, df, ddf = self._series(t)
        return (self.q0 + w * f, dw * f + w * df, ddw * f + 2.0 * dw * df + w * ddf)

    def scaled(self, factor: float) -> "FourierExcitation":
        """The same trajectory with its excursion from ``q_0`` multiplied by ``factor``.

        Parameters
        ----------
        factor : float
            The excursion's factor.
        """
        return FourierExcitation(self.q0, self.a * factor, self.b * factor, self.period,
                                 self.duration, self.ramp)


class ExcitationError(ValueError):
    """No excitation inside the arm's limits (one-line message)."""


@dataclass
class ExcitationLimits:
    """What the excitation must respect.

    Attributes
    ----------
    q_min, q_max : ndarray
        Joint limits (rad); the trajectory keeps ``margin`` inside them.
    torque_limits : ndarray
        ``|τ_j|`` bound (N·m; ``inf`` for none); the nominal model's torque along the
        trajectory must stay below ``torque_fraction`` of it (room for the tracking feedback,
        the unknown friction and payload).
    velocity_limits : ndarray
        ``|q̇_j|`` bound (rad/s).
    margin : float
        How far inside the joint limits the trajectory stays, rad.
    torque_fraction : float
        The fraction of ``torque_limits`` the nominal torque may use.
    """

    q_min: np.ndarray
    q_max: np.ndarray
    torque_limits: np.ndarray
    velocity_limits: np.ndarray
    margin: float = 0.1
    torque_fraction: float = 0.6

    def violation(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> float:
        """The largest ratio of use to allowance (``<= 1`` inside every limit).

        Parameters
        ----------
        q : numpy.ndarray
            Positions (N, n), rad.
        v : numpy.ndarray
            Velocities (N, n), rad/s.
        tau : numpy.ndarray
            The nominal torques (N, n), N·m.
        """
        centre = 0.5 * (self.q_max + self.q_min)
        half = 0.5 * (self.q_max - self.q_min) - self.margin
        ratios = [np.max(np.abs(q - centre) / half),
                  np.max(np.abs(v) / self.velocity_limits),
                  np.max(np.abs(tau) / (self.torque_fraction * self.torque_limits))]
        return float(max(ratios))


def default_period(duration: float) -> float:
    """The series' period for an excitation of ``duration`` s: the whole trajectory up to
    10 s, 10 s beyond (repeated periods average the noise).

    Parameters
    ----------
    duration : float
        The excitation's length, s.
    """
    return float(min(duration, 10.0))


def design_excitation(duration: float, q0: np.ndarray, limits: ExcitationLimits,
                      nominal_torque, regressor_of, *, harmonics: int = 5,
                      candidates: int = 12, seed: int = 0, amplitude: float = 0.6,
                      samples: int = 150) -> tuple[FourierExcitation, float]:
    """Choose a well-conditioned excitation inside the limits.

    Parameters
    ----------
    duration : float
        Length (s).
    q0 : ndarray
        Centre posture (must itself be inside the limits, with the nominal gravity torque).
    limits : ExcitationLimits
        The joint, velocity and torque limits to respect.
    nominal_torque : callable
        ``(q, v, a) -> τ`` (arrays (N, n)) of the nominal model (the one the user has).
    regressor_of : callable
        ``(q, v, a) -> Y`` (:meth:`drake_coop.identification.regressor.Regressor.matrix`).
    harmonics : int
        ``L``.
    candidates : int
        Random candidates tried; the one with the lowest condition number wins.
    amplitude : float
        Initial excursion of each joint (rad) before scaling to the limits.
    samples : int
        Time samples used to score a candidate.
    seed : int
        Seeds the random candidates.

    Returns
    -------
    (FourierExcitation, float)
        The chosen trajectory and its regressor's condition number.

    Raises
    ------
    ExcitationError
        When even the centre posture or a small excursion violates the limits.
    """
    from drake_coop.identification.regressor import condition_number

    n = q0.size
    ramp = min(1.0, 0.2 * duration)
    period = default_period(duration)
    t = np.linspace(0.0, duration, samples)
    zero = np.zeros((1, n))
    rest = limits.violation(q0[None, :], zero, nominal_torque(q0[None, :], zero, zero))
    if rest > 1.0:
        raise ExcitationError(
            f"the centre posture {np.round(q0, 3).tolist()} is outside the joint or torque "
            f"limits (use {rest:.2f} of the allowance)")
    rng = np.random.default_rng(seed)
    best, best_cond = None, np.inf
    for _ in range(candidates):
        scale = amplitude / np.arange(1, harmonics + 1)
        cand = FourierExcitation(q0, rng.uniform(-1, 1, (n, harmonics)) * scale,
                                 rng.uniform(-1, 1, (n, harmonics)) * scale,
                                 period, duration, ramp)
        for _ in range(40):
            q, v, a = cand.evaluate(t)
            use = limits.violation(q, v, nominal_torque(q, v, a))
            if use <= 1.0:
                break
            cand = cand.scaled(0.85 * min(1.0, 1.0 / use) ** 0.5)
        else:
            continue
        if np.max(np.abs(cand.a)) + np.max(np.abs(cand.b)) < 0.02:
            continue           # squeezed to nothing: it would excite nothing
        cond, _ = condition_number(regressor_of(q, v, a))
        if cond < best_cond:
            best, best_cond = cand, cond
    if best is None:
        raise ExcitationError(
            f"no excitation of {duration:g} s stays inside the joint, velocity and torque "
            f"limits (the torque limits leave too little beyond gravity)")
    return best, best_cond
