r"""Anti-windup of the force integral (6) while an actuator is clipped (opt-in).

The paper's integral (6), sampled at ``h`` as every force source with a state does it,

.. math::
    \Delta\tilde F(k+1) = \Delta\tilde F(k) + h\,\big(\hat\lambda(k) - \lambda_d(k)\big)
    \quad\text{while the object is held, 0 otherwise,}

feeds the controller (13) through ``k_F ΔF̃`` (and (4) through ``ξ ΔF̃``). While a joint's
torque is clipped at its limit, the torque (13) asks for is not the torque applied: the force
error of that time is not the loop's to correct, yet (6) integrates it. On the reference
table's saturated lift ``ΔF̃`` winds up to many times its unsaturated value, and after the
saturation the loop unwinds it only at the rate of its remaining force error, which holds
the squeeze off ``λ_d`` for seconds (``bench/reference_table_saturation.py``).

**Conditional integration** (also called clamping; Åström & Hägglund, *Advanced PID
Control*, ISA 2006, section 3.5), the scheme chosen here:

.. math::
    \Delta\tilde F(k+1) = \Delta\tilde F(k)
        + h\,\big(1 - c(k)\big)\big(\hat\lambda(k) - \lambda_d(k)\big), \qquad
    c(k) = \begin{cases} 1 & |\tau_i(k)| > \tau_{\max,i} \text{ for some joint } i,\\
                          0 & \text{otherwise,}\end{cases}

while held (0 otherwise, as (6)): ``ΔF̃`` holds the value it had when the arm last applied
the law's torque. ``τ(k)`` is the *commanded* torque of tick ``k`` (the controller's output,
which every force source with this option reads) and ``τ_max`` the arm's torque limits (the
limits of the actuators' saturation; a value equal to the limit passes unclipped, as Drake's
``Saturation`` passes it). Both are what a real arm's controller has: it computes ``τ`` and is
given the limits.

Why this scheme: it has no gain of its own, and with the arm never clipped it *is* (6), to
the bit (``c ≡ 0``). Back-calculation (``ΔF̃`` driven back by the torque excess ``τ −
sat(τ)``) would need that excess mapped into the constraint's force space through
``J_φ⁺ᵀ`` and a tracking time constant: a second gain, and a scheme that differs from (6)
whenever the mapping does.

What it does not do: restore the unsaturated run. Held through a saturated lift, ``ΔF̃``
also misses the integration the unsaturated loop does there, and ends the lift short of it;
for the momentum observer integrating the *commanded* torque, whose ``ΔF̃`` does not wind
up there, it is then worse than the paper's (6). The reference-table page's saturation
claim gives the numbers, loop by loop.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ANTI_WINDUP_SCHEMES", "check_limits", "clipped", "force_integral_step"]

#: The values of a robot's ``anti_windup`` field besides null (the paper's (6)).
ANTI_WINDUP_SCHEMES = ("conditional",)


def check_limits(limits, n: int) -> np.ndarray:
    """The arm's torque limits as an array, or a ``ValueError`` naming ``anti_windup_limits``.

    Parameters
    ----------
    limits : array_like
        The torque limits ``τ_max`` (n,), N·m, each > 0 (``inf``: that joint never clips).
    n : int
        The number of joints.

    Returns
    -------
    numpy.ndarray
        The limits (n,), float.

    Raises
    ------
    ValueError
        Not ``n`` numbers, or one not > 0 (NaN included).
    """
    try:
        array = np.asarray(limits, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"anti_windup_limits: {n} torque limits > 0 are required "
                         f"(got {limits!r})") from None
    if array.shape != (n,) or not np.all(array > 0):
        raise ValueError(f"anti_windup_limits: {n} torque limits > 0 are required "
                         f"(got {limits!r})")
    return array


def clipped(tau: np.ndarray, limits: np.ndarray | None) -> bool:
    """``c(k)``: whether any joint's commanded torque exceeds its limit (module docstring).

    Parameters
    ----------
    tau : numpy.ndarray
        The commanded torque ``τ(k)`` (n,), N·m.
    limits : numpy.ndarray or None
        ``τ_max`` (n,), N·m; None: no anti-windup (never clipped).

    Returns
    -------
    bool
        True when ``|τ_i| > τ_max,i`` for some joint ``i``.
    """
    return limits is not None and bool(np.any(np.abs(tau) > limits))


def force_integral_step(DF: np.ndarray, error: np.ndarray, held: bool, h: float,
                        frozen: bool = False) -> np.ndarray:
    """One tick of the force integral (6), with conditional integration when ``frozen``.

    Parameters
    ----------
    DF : numpy.ndarray
        ``ΔF̃(k)`` (m,), N·s.
    error : numpy.ndarray
        ``λ̂(k) − λ_d(k)`` (m,), N.
    held : bool
        Whether the object is held at tick ``k`` (else ``ΔF̃`` is reset to 0).
    h : float
        The sampling time (s).
    frozen : bool
        ``c(k)``: an actuator is clipped (:func:`clipped`); ``ΔF̃`` is then held.

    Returns
    -------
    numpy.ndarray
        ``ΔF̃(k+1)``: ``ΔF̃(k) + h (λ̂ − λ_d)`` held and not frozen (the paper's (6), the same
        floating-point operations), ``ΔF̃(k)`` held and frozen, zeros when not held.
    """
    if not held:
        return np.zeros_like(DF)
    if frozen:
        return np.array(DF, dtype=float, copy=True)
    return DF + h * error
