"""The parameters of the paper's blocks: the gains, the interchangeable sources, their checks.

Everything a block of :mod:`drake_coop.control` is configured with is defined here, so that the
library stands on Drake and NumPy alone (the scenario files of the application build these
types; :mod:`drake_coop.scenario.schema` re-exports them). Each check raises ``TypeError`` for a
value of the wrong type and ``ValueError`` for one out of range, always in one line naming the
argument (``gains.K_R``, ``period``, ...).
"""


import math
from dataclasses import dataclass, field
from numbers import Real
from typing import Optional

import numpy as np

from drake_coop.control.registry import names as _source_names

#: The velocity sources a robot's control block can use (:data:`~drake_coop.control.registry.
#: SOURCES`): the paper's observer (15)-(16), the true velocities (a tachometer) or a backward
#: difference of the encoders.
VELOCITY_SOURCES = _source_names("velocity")
#: The force sources (:data:`~drake_coop.control.registry.SOURCES`): the paper's observer
#: (22), an F/T sensor, none, the momentum observer.
FORCE_SOURCES = _source_names("force")

#: The control periods a block accepts (s): below 10 µs no arm's driver samples, above 1 s
#: the law's forward-Euler integrals mean nothing.
PERIOD_RANGE = (1e-5, 1.0)


@dataclass
class Gains:
    """Gains of the controller (13) and observers (15)-(16), (22) of one robot.

    Attributes
    ----------
    Lambda : float
        k of the paper's ``Lambda = k I`` (1/s): the gain of q̃ in q̇_r (4) and of z in (8).
    K_R : list[float]
        Diagonal of ``K_R`` (N·m·s/rad), the velocity-error gain of (13), one per joint.
    k_d : float
        Observer gain of (15)-(16) (1/s).
    k_F : float
        Gain of the force integral ΔF̃ in (13) (dimensionless).
    xi : float
        ``xi`` of (4): ``ξ = xi I`` (m×m), weight of ΔF̃ in the reference velocity.
    xi_matrix : list[list[float]] or None
        ``ξ`` of (4) as a full m×m matrix (symmetric positive definite); replaces ``xi`` when
        given.
    zeta : float
        ``zeta`` of (13), weight of Δλ̃ (dimensionless).
    beta : float
        ``beta`` of (4), position-constraint gain (1/s). Not given by the paper.
    momentum_gain : float
        ``K_O`` of the generalized-momentum observer (``force_source: momentum``,
        :mod:`drake_coop.control.momentum`), 1/s: the estimate follows the external torque
        as a first-order filter of time constant ``1/K_O``; ``0 < h K_O <= 1``.
    """

    Lambda: float = 35.0
    K_R: list[float] = field(default_factory=lambda: [120.0, 120.0, 120.0])
    k_d: float = 40.0
    k_F: float = 0.05
    xi: float = 1e-5
    xi_matrix: Optional[list[list[float]]] = None
    zeta: float = 1e-3
    beta: float = 10.0
    momentum_gain: float = 50.0

    def __post_init__(self) -> None:
        """Types only (a string or a dict for a gain is a ``TypeError`` naming it); the
        ranges depend on the arm and the period: :func:`check_gains`,
        :func:`check_momentum_gain`."""
        for name in ("Lambda", "k_d", "k_F", "xi", "zeta", "beta", "momentum_gain"):
            as_number(getattr(self, name), name)
        as_array(self.K_R, "K_R")
        if self.xi_matrix is not None:
            as_array(self.xi_matrix, "xi_matrix")


def as_number(value, name: str) -> float:
    """``value`` as a float; ``TypeError`` naming ``name`` for a string, a bool or a container.

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.
    """
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise TypeError(f"{name}: a number is required (got {type(value).__name__} {value!r})")
    return float(value)


def as_array(value, name: str) -> np.ndarray:
    """``value`` as a float array; ``TypeError`` naming ``name`` for strings or mappings.

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.

    Returns
    -------
    numpy.ndarray
        The value as floats.
    """
    if isinstance(value, (str, bytes, dict)):
        raise TypeError(f"{name}: a list of numbers is required (got {type(value).__name__} "
                        f"{value!r})")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: a list of numbers is required (got {value!r})") from None
    return arr


def check_positive(value, name: str) -> float:
    """``value`` as a float, finite and > 0 (``TypeError``/``ValueError`` naming ``name``).

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.
    """
    x = as_number(value, name)
    if not math.isfinite(x) or x <= 0.0:
        raise ValueError(f"{name}: must be finite and > 0 (got {x!r})")
    return x


def check_optional_positive(value, name: str) -> float | None:
    """``None``, or ``value`` checked by :func:`check_positive` (a cutoff frequency that may
    be left out).

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.
    """
    return None if value is None else check_positive(value, name)


def check_count(value, name: str) -> int:
    """``value`` as a positive integer (a number of joints); ``TypeError``/``ValueError``
    naming ``name``.

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: a positive integer is required (got {type(value).__name__} "
                        f"{value!r})")
    if value <= 0:
        raise ValueError(f"{name}: a positive integer is required (got {value!r})")
    return int(value)


def check_choice(value, name: str, allowed: tuple[str, ...]) -> str:
    """``value`` if it is one of ``allowed`` (``ValueError`` naming ``name`` otherwise).

    Parameters
    ----------
    value : object
        The argument's value.
    name : str
        The argument's name, for the message.
    allowed : tuple of str
        The allowed values.
    """
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name}: one of {', '.join(allowed)} (got {value!r})")
    return value


def check_gains(gains: Gains, n: int, m: int) -> None:
    """Refuse gains that do not fit an arm of ``n`` joints and ``m`` constraints.

    ``Λ``, ``k_d`` and the ``n`` entries of ``K_R`` must be finite and positive (the observer
    (15)–(16) and the passivity of (13) need them); ``k_F``, ``ζ``, ``β`` and a scalar ``ξ``
    finite and non-negative; a ``ξ`` matrix ``m × m``, symmetric positive definite;
    ``momentum_gain`` a number (its range depends on ``h``: :func:`check_momentum_gain`, where
    the momentum observer is built).

    Parameters
    ----------
    gains : Gains
        The gains to check.
    n : int
        The arm's joints (``K_R``'s length).
    m : int
        Its constraints (``ξ``'s size).

    Raises
    ------
    TypeError
        ``gains`` is not a :class:`Gains`, or a gain is not a number (a string, a dict).
    ValueError
        One line naming the gain and what is allowed.
    """
    if not isinstance(gains, Gains):
        raise TypeError(f"gains: a drake_coop.control.Gains is required "
                        f"(got {type(gains).__name__})")
    K_R = as_array(gains.K_R, "K_R")
    if K_R.shape != (n,):
        raise ValueError(f"K_R: {n} diagonal entries are required, one per joint "
                         f"(got shape {K_R.shape})")
    if not np.all(np.isfinite(K_R)) or np.any(K_R <= 0.0):
        raise ValueError(f"K_R: every entry must be finite and > 0 (got {K_R.tolist()})")
    for name in ("Lambda", "k_d"):
        value = as_number(getattr(gains, name), name)
        if not np.isfinite(value) or value <= 0.0:
            raise ValueError(f"{name}: must be finite and > 0 (got {value})")
    for name in ("k_F", "zeta", "beta"):
        value = as_number(getattr(gains, name), name)
        if not np.isfinite(value) or value < 0.0:
            raise ValueError(f"{name}: must be finite and >= 0 (got {value})")
    as_number(gains.momentum_gain, "momentum_gain")
    if gains.xi_matrix is None:
        xi = as_number(gains.xi, "xi")
        if not np.isfinite(xi) or xi < 0.0:
            raise ValueError(f"xi: must be finite and >= 0 (got {xi})")
        return
    xi = as_array(gains.xi_matrix, "xi_matrix")
    if xi.shape != (m, m):
        raise ValueError(f"xi_matrix: an {m}x{m} matrix is required, one row per constraint "
                         f"(got shape {xi.shape})")
    if (not np.all(np.isfinite(xi)) or not np.allclose(xi, xi.T, rtol=0.0, atol=1e-12)
            or np.linalg.eigvalsh(xi).min() <= 0.0):
        raise ValueError("xi_matrix: must be symmetric positive definite")


def check_momentum_gain(momentum_gain: float, period: float) -> float:
    """The momentum observer's gain ``K_O`` (1/s) checked: finite, ``0 < h K_O <= 1`` (its
    error shrinks by ``1 − h K_O`` per tick; beyond 1 it alternates and grows past 2).

    Parameters
    ----------
    momentum_gain : float
        ``K_O`` (1/s).
    period : float
        The sampling time ``h`` (s).

    Raises
    ------
    TypeError, ValueError
        Naming ``momentum_gain``.
    """
    K_O = check_positive(momentum_gain, "momentum_gain")
    if K_O * float(period) > 1.0:
        raise ValueError(f"momentum_gain: must be at most 1/h = {1.0 / float(period):g} 1/s "
                         f"(got {K_O:g})")
    return K_O


class CheckedPeriod(float):
    """A sampling time ``h`` (s) that :func:`checked_period` has checked, against the plant's
    step ``time_step`` when it was given: the blocks built with it take it as it is
    (:func:`check_period` checks a period once, however many blocks it reaches). Otherwise a
    ``float`` (its arithmetic gives plain floats)."""

    __slots__ = ("time_step",)

    def covers(self, time_step: float | None) -> bool:
        """Whether this period was checked against ``time_step`` (or none is asked).

        Parameters
        ----------
        time_step : float or None
            The plant's time step (s); None or ≤ 0 for a continuous plant.
        """
        return time_step is None or time_step <= 0.0 or time_step == self.time_step


def checked_period(period: float, time_step: float | None = None) -> CheckedPeriod:
    """``period`` checked by :func:`check_period` and marked so: the value to hand to every
    block of a diagram that ticks at it.

    Parameters
    ----------
    period : float
        The sampling time ``h`` (s).
    time_step : float, optional
        The plant's step (s); given, ``h`` must be a whole multiple of it.

    Returns
    -------
    CheckedPeriod
        ``h``, marked as checked against ``time_step``.
    """
    h = CheckedPeriod(check_period(period, time_step))
    h.time_step = time_step
    return h


def check_period(period: float, time_step: float | None = None) -> float:
    """The sampling time ``h`` (s) checked: a number in :data:`PERIOD_RANGE` and, when the
    plant's step ``time_step`` is given, a whole multiple of it (to 1e-9 relative), so every
    tick falls on a plant step.

    Parameters
    ----------
    period : float
        The sampling time ``h`` (s).
    time_step : float, optional
        The plant's step (s); given, ``h`` must be a whole multiple of it.

    Raises
    ------
    TypeError
        ``period`` is not a number (a string, ``None``).
    ValueError
        Naming ``period`` and what is allowed.
    """
    if isinstance(period, CheckedPeriod) and period.covers(time_step):
        return period
    return _validated_period(period, time_step)


def _validated_period(period: float, time_step: float | None = None) -> float:
    """:func:`check_period`'s checks themselves."""
    h = as_number(period, "period")
    lo, hi = PERIOD_RANGE
    if not math.isfinite(h) or not lo <= h <= hi:
        raise ValueError(f"period: the sampling time h must be between {lo:g} and {hi:g} s "
                         f"(got {h!r})")
    if time_step is not None and time_step > 0.0:
        ratio = h / time_step
        if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise ValueError(f"period: must be a whole multiple of the plant's time step "
                             f"{time_step:g} s (got {h:g} s, {ratio:.6g} steps)")
    return h


def normalized_normals(normals) -> np.ndarray:
    """``normals`` as unit rows ``(m, 3)``, ``m = 1..3``, checked to be independent.

    Parameters
    ----------
    normals : array_like, shape (m, 3) or (3,)
        The constraint normals.

    Returns
    -------
    numpy.ndarray
        The unit normals (m, 3).

    Raises
    ------
    ValueError
        Naming ``normals``: wrong shape, a zero or non-finite row, or dependent rows.
    """
    N = np.atleast_2d(as_array(normals, "normals"))
    if N.ndim != 2 or N.shape[1] != 3 or not 1 <= N.shape[0] <= 3:
        raise ValueError(f"normals: 1 to 3 rows of 3 numbers are required (got shape "
                         f"{np.shape(normals)})")
    if not np.all(np.isfinite(N)):
        raise ValueError("normals: every entry must be finite")
    norms = np.linalg.norm(N, axis=1, keepdims=True)
    if np.any(norms < 1e-9):
        raise ValueError("normals: a row is zero (each row is a direction)")
    N = N / norms
    if np.linalg.matrix_rank(N, tol=1e-6) < N.shape[0]:
        raise ValueError(f"normals: the {N.shape[0]} rows must be linearly independent "
                         "(rank-deficient constraints)")
    return N


def contact_vector(contact_point) -> np.ndarray:
    """``contact_point`` as a finite 3-vector (``ValueError`` naming it otherwise).

    Parameters
    ----------
    contact_point : array_like, shape (3,)
        The contact point ``c`` (m).
    """
    c = as_array(contact_point, "contact_point")
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"contact_point: 3 finite numbers are required (got "
                         f"{np.shape(contact_point)})")
    return c
