"""A compliant contact's force–compression law ``λ = a δᵖ`` (:class:`ContactStiffness`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ContactStiffness:
    r"""A compliant contact's force–compression law ``λ = a δᵖ`` along its normal.

    The remedy of the ``−β Δp`` lag on a compliant contact: the controller's reference for the
    constrained position becomes ``p_d = −δ(λ_d)`` (:class:`~drake_coop.control.finger.FingerLaw`'s
    ``contact_stiffness``), so the pad is held where the contact carries ``λ_d``; without it,
    ``−β φ`` pulls the pad back out of its own compression and the squeeze lags.

    Parameters
    ----------
    a : float
        Stiffness coefficient (N/mᵖ), > 0.
    exponent : float
        ``p`` (1 for a linear spring ``k = a`` N/m; about 2 for a hydroelastic sphere against
        a flat face, whose contact patch grows with the compression), in [1, 3].
    integral_time : float
        ``T_i`` (s), > 0: the time in which the force integral of (4) removes this model's
        own error (:meth:`integral_gain`); default 0.5 s.
    radius : float, optional
        A hydroelastic sphere of this radius ``r`` (m) pressed on a rigid face (``exponent``
        2): Drake's linear pressure field ``p = E (1 − ρ/r)`` (``ρ`` the distance from the
        sphere's centre) integrated over the contact disc gives, exactly,

        .. math:: \lambda = a\,\Big(\delta^2 - \frac{2\,\delta^3}{3 r}\Big),
                  \qquad a = \pi E

        (``δ ≤ r``): the ``δ³/r`` term makes the pad softer than ``a δ²`` by
        ``2δ/(3r)`` (7 % at 1.6 mm on a 15 mm pad). Default: ``λ = a δᵖ``.
    """

    a: float
    exponent: float = 1.0
    integral_time: float = 0.5
    radius: float | None = None

    def __post_init__(self):
        if self.radius is not None and not (np.isfinite(self.radius) and self.radius > 0
                                            and self.exponent == 2.0):
            raise ValueError(f"radius: a sphere's radius > 0 (m) with exponent 2 is required, "
                             f"got {self.radius!r} with exponent {self.exponent!r}")
        if not (np.isfinite(self.a) and self.a > 0):
            raise ValueError(f"a: a stiffness > 0 is required, got {self.a!r}")
        if not (np.isfinite(self.exponent) and 1.0 <= self.exponent <= 3.0):
            raise ValueError(f"exponent: a number in [1, 3] is required, got {self.exponent!r}")
        if not (np.isfinite(self.integral_time) and self.integral_time > 0):
            raise ValueError(f"integral_time: a time > 0 is required (s), got "
                             f"{self.integral_time!r}")

    def compliance(self, lam: float) -> float:
        """``c = dδ/dλ = δ/(p λ)`` (m/N) at ``max(λ, 1 N)`` (a Hertz-like contact is
        infinitely compliant at zero force).

        Parameters
        ----------
        lam : float
            The force ``λ``, N.
        """
        lam = max(float(lam), 1.0)
        if self.radius is not None:         # 1 / (dλ/dδ)
            d = float(self.compression(lam))
            return 1.0 / (self.a * (2.0 * d - 2.0 * d * d / self.radius))
        return float(self.compression(lam)) / (self.exponent * lam)

    def integral_gain(self, lam: float) -> float:
        """``c(λ)/T_i`` (m/(N·s)): times ``β``, the force integral's gain ``ξ_c`` that
        :class:`~drake_coop.control.finger.FingerLaw` adds to ``ξ`` on this contact, so that
        ``β Δp = ξ_c ΔF̃`` moves the pad by the compression a force error asks for within
        ``T_i``.

        Parameters
        ----------
        lam : float
            The force ``λ``, N.
        """
        return self.compliance(lam) / self.integral_time

    def compression(self, lam) -> np.ndarray:
        r""":math:`\delta(\lambda) = (\max(\lambda, 0)/a)^{1/p}` (m), elementwise; with
        ``radius`` the root of the sphere's law ``λ/a = δ² − 2δ³/(3r)`` in ``[0, r]``; a force
        at or beyond the whole hemisphere's ``a r²/3`` gives exactly ``r``.

        The sphere's root by Newton's method, in the variable where it is a simple root:
        for ``δ ≤ r/2`` (``λ/a ≤ r²/6``) on ``δ`` from ``√(λ/a)``; for ``δ > r/2`` on
        ``u = 1 − δ/r``, whose law ``3u² − 2u³ = s``, ``s = 1 − 3λ/(a r²)``, has its double
        root (``δ = r``) at ``s = 0`` only: from ``u = √(s/3)`` Newton converges
        quadratically (relative error ``ε → ε²/2``) however close ``λ`` is to ``a r²/3``, and
        ``δ = r (1 − u)``. Each iterate stops once its step is within 1e-15 of it. The
        arithmetic is additions, products, quotients and square roots only (IEEE 754 rounds
        each correctly on every CPU), in the same order for one force (Python floats, the
        controller's every tick) as for an array, so both give the same bits.

        Parameters
        ----------
        lam : float or array_like
            The force ``λ``, N.
        """
        lam = np.maximum(np.asarray(lam, dtype=float), 0.0)
        if self.radius is None:
            return (lam / self.a) ** (1.0 / self.exponent)
        r = self.radius
        if lam.size == 1:       # one contact (the controller's, every tick): on floats
            return np.full(lam.shape, self._sphere_root(float(lam.reshape(-1)[0])))
        t = lam / self.a
        s = 1.0 - 3.0 * t / (r * r)
        d = np.where(s <= 0.0, r, 0.0)

        def newton(x, step_of):
            active = np.ones(x.shape, dtype=bool)
            for _ in range(60):
                index = np.flatnonzero(active)
                if index.size == 0:
                    break
                step = step_of(x[index], index)
                x[index] = x[index] - step
                active[index[np.abs(step) <= 1e-15 * x[index]]] = False
            return x

        near = np.flatnonzero((s > 0.0) & (s < 0.5))
        sn = s[near]
        u = newton(np.sqrt(sn / 3.0), lambda u, i: (3.0 * u * u - 2.0 * u * u * u - sn[i])
                   / (6.0 * u * (1.0 - u)))
        d[near] = r * (1.0 - u)
        far = np.flatnonzero((s >= 0.5) & (t > 0.0))
        tf = t[far]
        d[far] = newton(np.sqrt(tf), lambda x, i: (x * x - 2.0 * x * x * x / (3.0 * r) - tf[i])
                        / (2.0 * x - 2.0 * x * x / r))
        return d.reshape(lam.shape)

    def _sphere_root(self, lam: float) -> float:
        """:meth:`compression` of one force ``λ ≥ 0`` with ``radius``, on Python floats:
        the same operations in the same order as the array path (so the same bits), at a
        fraction of the cost."""
        r = self.radius
        t = lam / self.a
        s = 1.0 - 3.0 * t / (r * r)
        if s <= 0.0:
            return r
        if t == 0.0:
            return 0.0
        if s < 0.5:
            u = math.sqrt(s / 3.0)
            for _ in range(60):
                step = (3.0 * u * u - 2.0 * u * u * u - s) / (6.0 * u * (1.0 - u))
                u = u - step
                if abs(step) <= 1e-15 * u:
                    break
            return r * (1.0 - u)
        d = math.sqrt(t)
        for _ in range(60):
            step = (d * d - 2.0 * d * d * d / (3.0 * r) - t) / (2.0 * d - 2.0 * d * d / r)
            d = d - step
            if abs(step) <= 1e-15 * d:
                break
        return d

    def force(self, delta) -> np.ndarray:
        """``λ(δ) = a max(δ, 0)ᵖ`` (N), elementwise; with ``radius``,
        ``a (δ² − 2δ³/(3r))`` for ``δ`` in ``[0, r]``.

        Parameters
        ----------
        delta : float or array_like
            The compression ``δ``, m.
        """
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        if self.radius is None:
            return self.a * d ** self.exponent
        d = np.minimum(d, self.radius)
        return self.a * (d * d - 2.0 * d ** 3 / (3.0 * self.radius))
