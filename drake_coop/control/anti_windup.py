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
Control*, ISA 2006, section 3.5), the first scheme:

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

Why conditional integration is the first scheme: it has no gain of its own, and with the arm
never clipped it *is* (6), to the bit (``c ≡ 0``).

What it does not do: restore the unsaturated run. Held through a saturated lift, ``ΔF̃``
also misses the integration the unsaturated loop does there, and ends the lift short of it;
for the momentum observer integrating the *commanded* torque, whose ``ΔF̃`` does not wind
up there, it is then worse than the paper's (6). The reference-table page's saturation
claim gives the numbers, loop by loop.

**Back-calculation** (tracking anti-windup; Åström & Hägglund, section 3.5), the second
scheme: the integral is driven by the part of the command the actuator did not apply,

.. math::
    \Delta\tilde F(k+1) = \Delta\tilde F(k)
        + h\,\Big(\hat\lambda(k) - \lambda_d(k)
        + K_{aw}\,P(q)\,\big(\operatorname{sat}(\tau(k)) - \tau(k)\big)\Big),
    \qquad P(q) = \frac{1}{k_F}\,\big(J_\varphi^T(q)\big)^+,

while held (0 otherwise). ``P`` is derived from (13): ``ΔF̃`` enters the torque through
``+k_F J_φᵀ ΔF̃``, so a change ``δ`` of ``ΔF̃`` changes ``τ`` by ``k_F J_φᵀ δ``, and the change
that best removes a joint-torque excess ``e`` (least squares) is ``δ = (J_φᵀ)⁺ e / k_F``
(``(J_φᵀ)⁺ = (J_φ J_φᵀ)⁻¹ J_φ``, the undamped form of the map (21) uses to read joint
torques as constraint forces). ``K_aw`` (1/s) is the tracking rate, the inverse of the classic tracking time
constant: with ``(13)``'s ``k_F`` term alone, the excess along ``J_φᵀ`` shrinks by
``1 − h K_aw`` a tick, so ``0 < K_aw ≤ 1/h``. The path of ``ΔF̃`` through ``ξ ΔF̃`` in (4)
(and so ``K_R`` and ``q̈_r`` in (13)) is left out of ``P``: it changes the excess's scale
along the same directions, which ``K_aw`` takes up. With nothing clipped the added term is
not computed and the tick is (6)'s floating-point operations, to the bit.

The natural gain is ``K_aw = k_F``: the term is then ``(J_φᵀ)⁺ (sat(τ) − τ)``, the unapplied
torque read as a constraint force, in newtons like ``λ̂ − λ_d``. For the applied-torque
residual (the momentum observer integrating ``sat(τ)``) that is, up to the observer's
first-order lag, what an observer integrating the *commanded* torque adds to its estimate
(it reads the torque the arm did not receive as external torque): (6) then integrates the
commanded-torque observer's force error while (13) keeps the residual's estimate. For the
observer that already integrates the commanded torque, the same term counts the excess a
second time. The excess on a saturated lift is the lift's load, not the force loop's: at a
tracking rate well above ``k_F`` back-calculation makes ``ΔF̃`` carry it (``1/k_F`` times
the excess's constraint component), gives up the squeeze to relieve the joint, and (6)
sheds that afterwards only at the rate ``k_F``. The reference-table page's saturation claim
gives the numbers, gain by gain.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ANTI_WINDUP_SCHEMES", "back_calculation", "back_calculation_gains", "check_gain",
           "check_limits", "clipped", "force_integral_step"]

#: The values of a robot's ``anti_windup`` field besides null (the paper's (6)).
ANTI_WINDUP_SCHEMES = ("conditional", "back_calculation")


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


def check_gain(gain, period: float) -> float:
    """The back-calculation gain ``K_aw`` (1/s), or a ``ValueError`` naming ``anti_windup_gain``.

    Parameters
    ----------
    gain : float
        ``K_aw``, 1/s: a number with ``0 < h K_aw ≤ 1`` (module docstring).
    period : float
        The sampling time ``h``, s.

    Returns
    -------
    float
        The gain.

    Raises
    ------
    ValueError
        Not a number, or outside ``(0, 1/h]``.
    """
    bound = 1.0 / period
    if (isinstance(gain, bool) or not isinstance(gain, (int, float, np.floating))
            or not (gain > 0.0 and gain * period <= 1.0 + 1e-12)):    # 1/h itself passes
        raise ValueError(f"anti_windup_gain: a tracking rate in (0, 1/h = {bound:g}] 1/s is "
                         f"required (got {gain!r})")
    return float(gain)


def back_calculation_gains(limits: np.ndarray | None, gain, force_gain, period: float
                           ) -> tuple[float, float] | None:
    """A force source's back-calculation gains ``(k_F, K_aw)``, checked; None without a gain.

    Parameters
    ----------
    limits : numpy.ndarray or None
        The source's anti-windup limits (:func:`check_limits`); required with a gain.
    gain : float or None
        ``K_aw`` (1/s, :func:`check_gain`); None: conditional integration (or none).
    force_gain : float or None
        ``k_F`` of (13), 1/s, > 0; required with a gain.
    period : float
        The sampling time ``h``, s.

    Returns
    -------
    tuple of float or None
        ``(k_F, K_aw)``, the last two arguments of :func:`back_calculation`.

    Raises
    ------
    ValueError
        A gain without limits or without ``k_F``, or a value out of range, naming the
        argument.
    """
    if gain is None:
        return None
    if limits is None:
        raise ValueError("anti_windup_gain: needs anti_windup_limits (the clipping it "
                         "reacts to)")
    if (isinstance(force_gain, bool) or not isinstance(force_gain, (int, float, np.floating))
            or not force_gain > 0 or not np.isfinite(force_gain)):
        raise ValueError(f"force_gain: k_F > 0 is required with anti_windup_gain "
                         f"(got {force_gain!r})")
    return float(force_gain), check_gain(gain, period)


def back_calculation(tau: np.ndarray, limits: np.ndarray, J_phi: np.ndarray, k_F: float,
                     gain: float) -> np.ndarray | None:
    """``K_aw P(q) (sat(τ) − τ)``: the back-calculation term of ``ΔF̃``'s rate (module
    docstring), or None when no joint is clipped.

    Parameters
    ----------
    tau : numpy.ndarray
        The commanded torque ``τ(k)`` (n,), N·m.
    limits : numpy.ndarray
        ``τ_max`` (n,), N·m; ``sat(τ) = clip(τ, −τ_max, τ_max)``.
    J_phi : numpy.ndarray
        The constraint Jacobian ``J_φ(q(k))`` (m, n).
    k_F : float
        The force-integral gain of (13), 1/s.
    gain : float
        ``K_aw``, 1/s (:func:`check_gain`).

    Returns
    -------
    numpy.ndarray or None
        The term (m,), N (added to ``λ̂ − λ_d`` in the integral); None when
        ``|τ_i| ≤ τ_max,i`` at every joint.
    """
    if not clipped(tau, limits):
        return None
    excess = np.clip(tau, -limits, limits) - tau
    return gain / k_F * np.linalg.pinv(J_phi.T) @ excess


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
                        frozen: bool = False, correction: np.ndarray | None = None
                        ) -> np.ndarray:
    """One tick of the force integral (6), with conditional integration when ``frozen`` or
    back-calculation when ``correction`` is given.

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
    correction : numpy.ndarray or None
        The back-calculation term (:func:`back_calculation`), N, added to the error; None
        (nothing clipped, or another scheme): (6).

    Returns
    -------
    numpy.ndarray
        ``ΔF̃(k+1)``: ``ΔF̃(k) + h (λ̂ − λ_d)`` held and not frozen (the paper's (6), the same
        floating-point operations), ``ΔF̃(k)`` held and frozen, ``ΔF̃(k) + h (λ̂ − λ_d +
        correction)`` held with a correction, zeros when not held.
    """
    if not held:
        return np.zeros_like(DF)
    if frozen:
        return np.array(DF, dtype=float, copy=True)
    if correction is not None:
        return DF + h * (error + correction)
    return DF + h * error
