"""The held object as part of the controller: its model, the load each arm carries, the
squeeze that holds it, its mass estimated online, and the compliant contact's stiffness.

The paper's controllers know nothing about the object: its weight and inertia reach each arm
as a load that the force observer (22) cannot tell from squeeze. The blocks here add, per arm
and beside the paper's (which stay unchanged):

* :class:`ObjectModel`: mass, centre of mass, inertia and the grasp (contact points, inward
  normals), all in an object frame aligned with the world (the desired path translates the
  object without turning it);
* :func:`grasp_matrix`, :func:`object_wrench`, :func:`load_distribution`: the wrench the
  contacts must apply along the desired motion, ``w = [m (a − g); I α + ω × I ω]`` about the
  centre of mass, split by the grasp matrix ``G`` into its minimum-norm (load) part
  ``f_L = G⁺ w`` and an internal (squeeze) part in the null space of ``G`` (the load
  distribution of Walker, Freeman & Marcus with equal weights; Uchiyama & Dauchez's
  external/internal decomposition);
* :func:`mass_shares`: each contact's share ``m_i`` of the mass in that split (the lever rule
  for two opposing pads), so that arm ``i``'s load is ``f_i = m_i (a_d − g)``;
* :class:`LoadFeedforward` (LeafSystem): ``τ_ff,i = J_x(q)ᵀ m_i (a_d − g)``, added to the
  paper's torque (13);
* :class:`MassEstimator` (LeafSystem): recursive least squares of ``m_i`` from the arm's own
  model, ``q``, the commanded ``τ`` and the observer's signals (no F/T sensor);
* :func:`squeeze_for_grasp`, :func:`max_squeeze`: the least squeeze that keeps every contact in
  its friction cone, times a margin, within the torque limits;
* :class:`ObjectStateEstimator` (LeafSystem, shared by the arms): the total mass and centre
  of mass from every arm's share, and the squeeze chosen online from them, rate limited, into
  every arm's ``λ_d``; :class:`CompressedReference` (LeafSystem): ``q_d`` pressed in by the
  online ``λ_d``'s compression;
* :class:`ContactStiffness`: ``λ = a δᵖ``, the compression ``δ(λ)`` that
  :class:`~drake_coop.control.finger.FingerLaw` takes as the constrained position's reference
  on a compliant contact.

What each arm's blocks know, and communication: the object model (or its prior) and the shared
desired path ``a_d(t)`` — both given before the run, as the paper's desired force (29) is —
and the arm's own model and signals. The arms exchange nothing during the run (the paper's
decentralization is kept): each estimates its own share ``m_i``. The one exception is
opt-in and named: :class:`ObjectStateEstimator`, a single block that reads every arm's share
and gives every arm the squeeze chosen online from the estimated total load (with
:class:`CompressedReference`, each arm's own, pressing its joint reference in by that
squeeze's compression on a compliant contact).

Why (22) then estimates the squeeze net of the load: with the arm's dynamics
``H q̈ + C q̇ + D q̇ + g = τ_13 + τ_ff + J_φᵀ λ + J_xᵀ f_t`` (``f_t`` the object's load on the
pad, ``f_t = −f_i`` when the object follows its path) and ``τ_ff = J_xᵀ f_i``, the load terms
cancel and the arm obeys the paper's model (1) with ``τ = τ_13``. The force observer is left
as it is: its closed form (22) is (21) with ``τ = τ_13``, i.e. (21) with the feedforward moved
to the model side, ``λ̂ = J⁺ᵀ {H q̈̂_r + C q̇_r + D q̇_r + g − (τ − τ_ff)}``. Nothing of
the feedforward is fed into the observer: it sees the arm as the paper's.

This module imports only NumPy and Drake.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.framework import (
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    OutputPort,
    State,
)

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.finger import ReferenceLayout
from drake_coop.control.params import check_period, check_positive

#: Standard gravity (m/s²); gravity is ``g = (0, 0, −GRAVITY)`` in the world frame.
GRAVITY = 9.81


def _vector(value, name: str, size: int = 3) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: {size} finite numbers are required (got {np.shape(value)})")
    return v


@dataclass(frozen=True)
class ObjectModel:
    """The held object: mass, centre of mass, inertia and the grasp.

    Every vector is in the object frame, aligned with the world frame (the desired path
    translates the object), with its origin at a point the user picks (e.g. the grasp
    points' midpoint).

    Parameters
    ----------
    mass : float
        ``m`` (kg), > 0.
    com : array_like, shape (3,)
        Centre of mass (m).
    inertia : array_like, shape (3, 3)
        Rotational inertia about the centre of mass (kg·m²), symmetric positive semidefinite.
    grasp_points : array_like, shape (k, 3)
        The contact points (m), one per arm, k >= 1.
    grasp_normals : array_like, shape (k, 3)
        Each contact's normal pointing into the object (the direction the arm pushes to
        squeeze), unit after normalization.

    Raises
    ------
    ValueError
        Naming the field: a mass <= 0 or not finite, wrong shapes, a zero normal.
    """

    mass: float
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    grasp_points: np.ndarray = field(default_factory=lambda: np.array([[-1.0, 0, 0],
                                                                       [1.0, 0, 0]]))
    grasp_normals: np.ndarray = field(default_factory=lambda: np.array([[1.0, 0, 0],
                                                                        [-1.0, 0, 0]]))

    def __post_init__(self):
        m = self.mass
        if isinstance(m, bool) or not isinstance(m, (int, float, np.floating)) \
                or not np.isfinite(m) or m <= 0:
            raise ValueError(f"mass: a finite number > 0 is required (kg), got {m!r}")
        object.__setattr__(self, "mass", float(m))
        object.__setattr__(self, "com", _vector(self.com, "com"))
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)) \
                or not np.allclose(inertia, inertia.T) \
                or np.min(np.linalg.eigvalsh(inertia)) < -1e-12:
            raise ValueError("inertia: a symmetric positive semidefinite 3x3 matrix is required")
        object.__setattr__(self, "inertia", inertia)
        points = np.asarray(self.grasp_points, dtype=float)
        normals = np.asarray(self.grasp_normals, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 1 \
                or not np.all(np.isfinite(points)):
            raise ValueError("grasp_points: k >= 1 rows of 3 finite numbers are required")
        if normals.shape != points.shape or not np.all(np.isfinite(normals)):
            raise ValueError(f"grasp_normals: {points.shape} finite numbers are required "
                             f"(one normal per grasp point), got {normals.shape}")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(norms < 1e-9):
            raise ValueError("grasp_normals: every normal must be nonzero")
        object.__setattr__(self, "grasp_points", points)
        object.__setattr__(self, "grasp_normals", normals / norms[:, None])

    @property
    def contacts(self) -> int:
        """The number of contacts ``k``."""
        return len(self.grasp_points)


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def contact_jacobian(model: ArmModel, q: np.ndarray, contact_offset: np.ndarray | None
                     ) -> np.ndarray:
    """``J_c = J_x − [r]_× J_ω`` (3×n): the translational Jacobian of the point ``E + r`` moving
    with the end effector, ``r`` = ``contact_offset`` (world frame); ``J_x`` when None. A
    force ``F`` applied at ``E + r`` takes the joint torque ``J_cᵀ F`` (its moment ``r × F``
    about ``E`` included): for a spherical pad of radius ``ρ``, ``r = ρ n`` with ``n`` the
    inward normal, the point where the object touches it."""
    J = model.J_x(q)
    if contact_offset is None:
        return J
    return J - _skew(contact_offset) @ model.J_omega(q)


def grasp_matrix(points: np.ndarray, reference_point=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The grasp matrix ``G`` (6 × 3k) of point contacts: ``w = G [f_1; …; f_k]``.

    .. math::
        G = \\begin{bmatrix} I & \\cdots & I \\\\ [r_1]_\\times & \\cdots & [r_k]_\\times
            \\end{bmatrix}, \\qquad r_i = p_i - p_\\mathrm{ref}

    maps the contact forces ``f_i`` (applied to the object at ``p_i``) to their resultant
    force and moment about ``reference_point``.
    """
    points = np.asarray(points, dtype=float)
    ref = _vector(reference_point, "reference_point")
    blocks = [np.vstack([np.eye(3), _skew(p - ref)]) for p in points]
    return np.hstack(blocks)


def object_wrench(model: ObjectModel, acceleration, angular_velocity=(0.0, 0.0, 0.0),
                  angular_acceleration=(0.0, 0.0, 0.0), gravity: float = GRAVITY
                  ) -> np.ndarray:
    """The wrench the contacts must apply to the object, about its centre of mass:
    ``w = [m (a − g); I α + ω × I ω]`` with ``g = (0, 0, −gravity)`` (Newton–Euler)."""
    a = _vector(acceleration, "acceleration")
    w = _vector(angular_velocity, "angular_velocity")
    alpha = _vector(angular_acceleration, "angular_acceleration")
    force = model.mass * (a - np.array([0.0, 0.0, -gravity]))
    moment = model.inertia @ alpha + np.cross(w, model.inertia @ w)
    return np.concatenate([force, moment])


def load_distribution(model: ObjectModel, acceleration, angular_velocity=(0.0, 0.0, 0.0),
                      angular_acceleration=(0.0, 0.0, 0.0), gravity: float = GRAVITY
                      ) -> np.ndarray:
    """Each contact's load ``f_L,i`` (k × 3): the minimum-norm contact forces that apply the
    object's wrench (:func:`object_wrench`), ``f_L = G⁺ w`` with ``G`` the grasp matrix about
    the centre of mass.

    ``f_L`` has no internal part (it is orthogonal to the null space of ``G``); any squeeze
    ``f_I`` with ``G f_I = 0`` (for two opposing pads, equal and opposite forces along the
    grasp line) can be added without changing the object's motion (:func:`internal_part`).
    """
    G = grasp_matrix(model.grasp_points, model.com)
    w = object_wrench(model, acceleration, angular_velocity, angular_acceleration, gravity)
    f = np.linalg.pinv(G) @ w
    return f.reshape(model.contacts, 3)


def internal_part(model: ObjectModel, forces) -> np.ndarray:
    """The internal (squeeze) part of contact forces (k × 3): their projection on the null
    space of ``G``, ``(I − G⁺ G) f`` (what moves no object)."""
    G = grasp_matrix(model.grasp_points, model.com)
    f = np.asarray(forces, dtype=float).reshape(-1)
    return ((np.eye(f.size) - np.linalg.pinv(G) @ G) @ f).reshape(model.contacts, 3)


def mass_shares(model: ObjectModel) -> np.ndarray:
    """Each contact's share ``m_i`` (kg) of the object's weight in the minimum-norm split
    (:func:`load_distribution` of a static hold): ``m_i = f_L,i,z / g``, ``Σ m_i = m``.

    For two opposing pads with the centre of mass on the grasp line, the lever rule:
    ``m_1 = m · |p_2 − c| / |p_2 − p_1|``. Arm ``i``'s load along the desired motion is then
    ``f_i = m_i (a − g)`` (exact for the components across the grasp line; along it, any two
    splits differ by an internal force, which the squeeze control sets).
    """
    f = load_distribution(model, np.zeros(3))
    return f[:, 2] / GRAVITY


def squeeze_for_grasp(loads, normals, mu: float, margin: float = 1.5,
                      lambda_max: float | None = None, lambda_min: float = 0.0
                      ) -> tuple[float, bool]:
    """The least squeeze that holds every contact in its friction cone, times a margin.

    Contact ``i`` carries its load ``f_i`` (the force the arm applies to the object for the
    object's motion, :func:`load_distribution`) plus the squeeze ``λ`` along its inward
    normal ``n_i``. Its normal force is ``λ + n_i·f_i`` and its tangential force
    ``t_i = |f_i − (n_i·f_i) n_i|``; Coulomb's cone asks ``t_i ≤ μ (λ + n_i·f_i)``, so

    .. math::
        \\lambda = \\max\\Big(\\lambda_\\min,\\ \\mathrm{margin}\\cdot
                   \\max_i\\big(t_i/\\mu - n_i\\cdot f_i\\big)\\Big)

    (``margin >= 1`` scales the least squeeze: ``t_i ≤ μ (λ + n_i·f_i)/margin`` when
    ``n_i·f_i = 0``). With ``lambda_max`` (the torque limits', :func:`max_squeeze`) the result
    is clipped to it and ``feasible`` is False when it had to be.

    Returns
    -------
    lam : float
        The squeeze (N).
    feasible : bool
        Whether ``lam`` holds the margin within ``lambda_max``.

    Raises
    ------
    ValueError
        ``mu`` <= 0, ``margin`` < 1, a negative ``lambda_min``, shapes.
    """
    if not (np.isfinite(mu) and mu > 0):
        raise ValueError(f"mu: a friction coefficient > 0 is required, got {mu!r}")
    if not (np.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"margin: a number >= 1 is required, got {margin!r}")
    if not (np.isfinite(lambda_min) and lambda_min >= 0):
        raise ValueError(f"lambda_min: a number >= 0 is required, got {lambda_min!r}")
    f = np.atleast_2d(np.asarray(loads, dtype=float))
    n = np.atleast_2d(np.asarray(normals, dtype=float))
    if f.shape != n.shape or f.shape[1] != 3:
        raise ValueError(f"loads, normals: k x 3 each are required, got {f.shape}, {n.shape}")
    n = n / np.linalg.norm(n, axis=1)[:, None]
    fn = np.sum(f * n, axis=1)
    ft = np.linalg.norm(f - fn[:, None] * n, axis=1)
    lam = max(lambda_min, margin * float(np.max(ft / mu - fn)))
    if lambda_max is not None and lam > lambda_max:
        return float(lambda_max), False
    return float(lam), True


def max_squeeze(J_phi, tau_limits, tau_other) -> float:
    """The largest squeeze ``λ`` whose torque ``−J_φᵀ λ`` (13) stays, with the other torques
    ``tau_other`` (gravity, load), within ``|τ_j| ≤ tau_limits_j`` at one posture
    (one constraint): ``min_j`` over the joints of the room left in the pushing direction."""
    j = np.asarray(J_phi, dtype=float).reshape(-1)
    lim = np.asarray(tau_limits, dtype=float).reshape(-1)
    other = np.asarray(tau_other, dtype=float).reshape(-1)
    if not (j.shape == lim.shape == other.shape):
        raise ValueError("J_phi, tau_limits, tau_other: one entry per joint each is required")
    best = np.inf
    for jj, L, o in zip(j, lim, other):
        if abs(jj) < 1e-12:
            continue
        # τ_j = o − jj λ within [−L, L], λ >= 0.
        bound = (o + L) / jj if jj > 0 else (o - L) / jj
        best = min(best, bound)
    return float(max(best, 0.0))


@dataclass(frozen=True)
class ContactStiffness:
    """A compliant contact's force–compression law ``λ = a δᵖ`` along its normal.

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

        .. math:: \\lambda = a\\,\\Big(\\delta^2 - \\frac{2\\,\\delta^3}{3 r}\\Big),
                  \\qquad a = \\pi E

        (``δ ≤ r``): the ``δ³/r`` term makes the pad softer than ``a δ²`` by
        ``2δ/(3r)`` (7 % at 1.6 mm on a 15 mm pad). Default: ``λ = a δᵖ``.

    The remedy of the ``−β Δp`` lag on a compliant contact: the controller's reference for the
    constrained position becomes ``p_d = −δ(λ_d)`` (:class:`~drake_coop.control.finger.FingerLaw`'s
    ``contact_stiffness``), so the pad is held where the contact carries ``λ_d``; without it,
    ``−β φ`` pulls the pad back out of its own compression and the squeeze lags.
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
        infinitely compliant at zero force)."""
        lam = max(float(lam), 1.0)
        if self.radius is not None:         # 1 / (dλ/dδ)
            d = float(self.compression(lam))
            return 1.0 / (self.a * (2.0 * d - 2.0 * d * d / self.radius))
        return float(self.compression(lam)) / (self.exponent * lam)

    def integral_gain(self, lam: float) -> float:
        """``c(λ)/T_i`` (m/(N·s)): times ``β``, the force integral's gain ``ξ_c`` that
        :class:`~drake_coop.control.finger.FingerLaw` adds to ``ξ`` on this contact, so that
        ``β Δp = ξ_c ΔF̃`` moves the pad by the compression a force error asks for within
        ``T_i``."""
        return self.compliance(lam) / self.integral_time

    def compression(self, lam) -> np.ndarray:
        """``δ(λ) = (max(λ, 0)/a)^{1/p}`` (m), elementwise; with ``radius`` the root of
        the sphere's law ``λ/a = δ² − 2δ³/(3r)`` in ``[0, r]``; a force at or beyond the
        whole hemisphere's ``a r²/3`` gives exactly ``r``.

        The sphere's root by Newton's method, in the variable where it is a simple root:
        for ``δ ≤ r/2`` (``λ/a ≤ r²/6``) on ``δ`` from ``√(λ/a)``; for ``δ > r/2`` on
        ``u = 1 − δ/r``, whose law ``3u² − 2u³ = s``, ``s = 1 − 3λ/(a r²)``, has its double
        root (``δ = r``) at ``s = 0`` only: from ``u = √(s/3)`` Newton converges
        quadratically (relative error ``ε → ε²/2``) however close ``λ`` is to ``a r²/3``, and
        ``δ = r (1 − u)``. Each iterate stops once its step is within 1e-15 of it. The
        arithmetic is additions, products, quotients and square roots only (IEEE 754 rounds
        each correctly on every CPU), in the same order for one force (Python floats, the
        controller's every tick) as for an array, so both give the same bits."""
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
        ``a (δ² − 2δ³/(3r))`` for ``δ`` in ``[0, r]``."""
        d = np.maximum(np.asarray(delta, dtype=float), 0.0)
        if self.radius is None:
            return self.a * d ** self.exponent
        d = np.minimum(d, self.radius)
        return self.a * (d * d - 2.0 * d ** 3 / (3.0 * self.radius))


class LoadFeedforward(LeafSystem):
    """One arm's share of the object's load, fed forward as joint torques.

    .. math::
        \\tau_{ff} = J_x(q)^T f_i, \\qquad f_i = m_i\\,(a_d - g) \\quad\\text{while held,}
        \\qquad \\tau_{ff} = 0 \\text{ otherwise}

    with ``m_i`` the arm's share of the object's mass (:func:`mass_shares`, or
    :class:`MassEstimator`'s estimate), ``a_d`` the object's desired acceleration along the
    shared path and ``g = (0, 0, −g)``. Add ``tau_ff`` to the controller's ``τ`` (13) before
    the actuators; the force observer (22) is left as it is (see the module docstring).

    .. pydrake_system::

        name: LoadFeedforward
        input_ports:
        - q
        - reference
        - acceleration_d
        - mass_share
        - f_couple (optional)
        output_ports:
        - tau_ff
        - f_load

    Latched by a periodic unrestricted update at ``t_k`` (as the controller's ``τ(k)``), so
    the plant's step at ``t_k`` applies it; both outputs are state output ports.

    Parameters
    ----------
    model : ArmModel
        The arm's model (``J_x``).
    period : float
        ``h`` (s).
    gravity : float
        ``g`` (m/s²).
    contact_offset : array_like, shape (3,), optional
        ``r`` from the end-effector point E to where the load acts (world frame; for a
        spherical pad the radius along the inward normal): ``τ_ff = J_cᵀ f_i``
        (:func:`contact_jacobian`). Default: the load acts at E (``J_x``).
    friction : float, optional
        ``μ`` of a grasp held by friction: a pad can pass the object no more tangential force
        than its friction cone at the commanded squeeze holds, so the part of ``f_i`` across
        the constraint normals ``N`` is limited to ``μ ‖λ_d‖``,

        .. math::
            f_t = (I - N^+ N) f_i, \\qquad f_i \\leftarrow f_i - f_t
            + \\min\\!\\big(1, \\mu\\,\\|\\lambda_d\\| / \\|f_t\\|\\big)\\, f_t .

        While the squeeze ramps up at the grasp the feedforward follows it (the rest of the
        weight stays on whatever supports the object) instead of sliding the pad up the
        object's face. Default: no limit (a rigid grasp).
    couple : bool
        Declare the input ``f_couple``: a force added to ``f_i`` (before the friction limit),
        the arm's part of the squeeze's couple when the two pads' normal forces act along
        offset lines (:func:`~drake_coop.control.couple.squeeze_couple`). Default
        False: no such port.

    Input ports
    -----------
    q : n-vector
        Measured joint positions.
    reference : (3n + m + 1)-vector
        The arm's reference (its ``held`` row; ``λ_d`` with ``friction``).
    acceleration_d : 3-vector
        The object's desired acceleration ``a_d`` (world frame, m/s²).
    mass_share : 1-vector
        ``m_i`` (kg).
    f_couple : 3-vector, with ``couple``
        ``f_c,i`` (N), added to ``f_i``.

    Output ports
    ------------
    tau_ff : n-vector
        ``J_xᵀ f_i`` (N·m).
    f_load : 3-vector
        ``f_i`` (N), the force the arm applies to the object for its motion.
    """

    def __init__(self, model: ArmModel, period: float, gravity: float = GRAVITY,
                 contact_offset=None, friction: float | None = None, couple: bool = False):
        super().__init__()
        check_period(period)
        self._model = model
        self._r = None if contact_offset is None else _vector(contact_offset, "contact_offset")
        self._mu = None if friction is None else check_positive(friction, "friction")
        N = np.asarray(model.N, dtype=float)
        #: Projector onto the directions across the constraint normals (``I − N⁺N``).
        self._across = np.eye(3) - np.linalg.pinv(N) @ N
        n = model.n
        self._layout = ReferenceLayout(n, model.m)
        self._lambda_d = self._layout.slices()["lambda_d"]
        self._g = np.array([0.0, 0.0, -float(gravity)])
        self._q = self.DeclareVectorInputPort("q", n)
        self._reference = self.DeclareVectorInputPort("reference", self._layout.size)
        self._a_d = self.DeclareVectorInputPort("acceleration_d", 3)
        self._mass = self.DeclareVectorInputPort("mass_share", 1)
        self._couple = self.DeclareVectorInputPort("f_couple", 3) if couple else None
        self._tau_state = self.DeclareDiscreteState(np.zeros(n))
        self._f_state = self.DeclareDiscreteState(np.zeros(3))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self._tau_out = self.DeclareStateOutputPort("tau_ff", self._tau_state)
        self._f_out = self.DeclareStateOutputPort("f_load", self._f_state)

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_reference_input_port(self) -> InputPort:
        """The arm's reference (its ``held`` row)."""
        return self._reference

    def get_acceleration_d_input_port(self) -> InputPort:
        """The object's desired acceleration ``a_d``."""
        return self._a_d

    def get_mass_share_input_port(self) -> InputPort:
        """The arm's share ``m_i`` of the object's mass."""
        return self._mass

    def get_f_couple_input_port(self) -> InputPort:
        """``f_c,i``, the arm's part of the squeeze's couple (with ``couple`` only)."""
        if self._couple is None:
            raise ValueError("couple: the f_couple port exists only with couple=True")
        return self._couple

    def get_tau_ff_output_port(self) -> OutputPort:
        """``τ_ff = J_xᵀ f_i``."""
        return self._tau_out

    def get_f_load_output_port(self) -> OutputPort:
        """``f_i = m_i (a_d − g)``."""
        return self._f_out

    def load(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """``(τ_ff, f_i)`` at the current inputs (what a tick latches)."""
        reference = self._reference.Eval(context)
        if not self._layout.held(reference):
            return np.zeros(self._model.n), np.zeros(3)
        q = self._q.Eval(context)
        f = float(self._mass.Eval(context)[0]) * (self._a_d.Eval(context) - self._g)
        if self._couple is not None:
            f = f + self._couple.Eval(context)
        if self._mu is not None:
            f = self.friction_limited(f, reference[self._lambda_d])
        return contact_jacobian(self._model, q, self._r).T @ f, f

    def friction_limited(self, f: np.ndarray, lambda_d: np.ndarray) -> np.ndarray:
        """``f`` with its part across the constraint normals limited to ``μ ‖λ_d‖`` (the
        ``friction`` parameter; ``f`` unchanged without it)."""
        f = np.asarray(f, dtype=float)
        if self._mu is None:
            return f
        f_t = self._across @ f
        size = float(np.linalg.norm(f_t))
        limit = self._mu * float(np.linalg.norm(np.clip(lambda_d, 0.0, None)))
        if size <= limit:
            return f
        return f - f_t + (limit / size) * f_t

    def _update(self, context: Context, state: State) -> None:
        tau, f = self.load(context)
        xd = state.get_mutable_discrete_state()
        xd.set_value(self._tau_state, tau)
        xd.set_value(self._f_state, f)


class MassEstimator(LeafSystem):
    """Recursive least squares of one arm's share ``m_i`` of the object's mass, from the
    arm's model, its measured ``q``, the commanded ``τ`` and the velocity observer — no F/T
    sensor.

    The force the object applies to the pad, from the arm's own model with the controller's
    reference acceleration and the observer's velocity (the loop tracks ``q̈̂_r``):

    .. math::
        \\hat F = J_x(q)^{+T}\\big(H(q)\\ddot{\\hat q}_r + C(q,\\dot q_o)\\dot q_o
                  + D\\dot q_o + g(q) - \\tau\\big)

    (``J_x^{+T}`` the least-squares inverse of ``J_xᵀ``; the inverse for a 3-joint arm). The
    arm applies ``−F̂`` to the object, whose vertical part is ``m_i (g + a_d,z)``: a linear
    regression ``y = φ θ`` with ``y = −F̂_z``, ``φ = g + a_d,z``, ``θ = m_i``, solved by RLS
    with forgetting factor ``ρ`` and measurement variance ``R``:

    .. math::
        K = \\frac{P\\varphi}{\\rho R + \\varphi^2 P},\\quad
        \\hat\\theta \\leftarrow \\hat\\theta + K(y - \\varphi\\hat\\theta),\\quad
        P \\leftarrow (P - K\\varphi P)/\\rho

    updated at every tick while the object is held (``held`` row of the reference), frozen
    otherwise. The squeeze (along the grasp line, horizontal here) does not enter ``F̂_z``.

    Persistence of excitation: the regressor must satisfy
    ``Σ_{window} φ² ≥ α > 0`` over every window of the forgetting horizon ``1/(1 − ρ)``
    samples; with ``φ = g + a_d,z`` this holds whenever the desired vertical acceleration stays
    away from free fall (``a_d,z > −g``), i.e. always in a carrying task: gravity itself
    excites the mass. A centre-of-mass offset along the grasp line is identifiable only from
    both arms' shares together (``c = (m_1 p_1 + m_2 p_2)/(m_1 + m_2)`` on that line); each
    arm alone estimates what its own feedforward needs, its share ``m_i``.

    .. pydrake_system::

        name: MassEstimator
        input_ports:
        - q
        - qdot_o
        - qddot_r_hat
        - tau
        - acceleration_d
        - reference
        - f_couple (optional)
        output_ports:
        - mass_share
        - force_estimate

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm (identified or nominal).
    period : float
        The update period (s): the control period ``h`` or a whole multiple of it (the
        estimate is slow; :mod:`drake_coop.experiment.object_blocks` updates it every 5 ticks).
    prior : float
        ``θ̂(0)``, the prior share (kg), >= 0.
    prior_std : float
        Its standard deviation (kg), > 0: ``P(0) = prior_std²``.
    forgetting : float
        ``ρ`` in (0, 1] per update; default 0.995 (a horizon of 200 updates, 1.8 s at 9 ms:
        the stand carries the object during the first moments of the grasp, whose samples are
        then forgotten).
    noise_std : float
        ``√R`` (N), the spread of ``F̂_z``; default 1 N.
    gravity : float
        ``g`` (m/s²).
    contact_offset : array_like, shape (3,), optional
        ``r`` from E to where the object's force acts (world frame): ``F̂`` is then solved
        with ``J_c`` (:func:`contact_jacobian`) instead of ``J_x``. Without it, on a spherical
        pad the moment ``r × F`` of the carried weight about the pad's centre reads as extra
        vertical force (+3.5 % and +4.7 % for the two shipped arms at the circle's start).
    couple : bool
        Declare the input ``f_couple`` (:class:`LoadFeedforward`'s): the arm's part of the
        squeeze's couple, which is no part of the mass, is taken out of the measurement,
        ``y = −F̂_z − f_c,z``. Default False: no such port.

    Input ports
    -----------
    q : n-vector
        Measured joint positions.
    qdot_o : n-vector
        The velocity observer's ``q̇_o`` (8).
    qddot_r_hat : n-vector
        The controller's ``q̈̂_r(k)`` (11).
    tau : n-vector
        The torque commanded at the tick (the controller's plus the feedforward).
    acceleration_d : 3-vector
        The object's desired acceleration.
    reference : (3n + m + 1)-vector
        The arm's reference (its ``held`` row).
    f_couple : 3-vector, with ``couple``
        ``f_c,i`` (N).

    Output ports
    ------------
    mass_share : 1-vector
        ``θ̂ = m̂_i`` (kg), state.
    force_estimate : 3-vector
        The last ``F̂`` (N), state.
    """

    def __init__(self, model: ArmModel, period: float, prior: float, prior_std: float,
                 forgetting: float = 0.995, noise_std: float = 1.0,
                 gravity: float = GRAVITY, contact_offset=None, couple: bool = False):
        super().__init__()
        check_period(period)
        if not (np.isfinite(prior) and prior >= 0):
            raise ValueError(f"prior: a mass >= 0 is required (kg), got {prior!r}")
        if not (np.isfinite(prior_std) and prior_std > 0):
            raise ValueError(f"prior_std: a number > 0 is required (kg), got {prior_std!r}")
        if not (0 < forgetting <= 1):
            raise ValueError(f"forgetting: a number in (0, 1] is required, got {forgetting!r}")
        if not (np.isfinite(noise_std) and noise_std > 0):
            raise ValueError(f"noise_std: a number > 0 is required (N), got {noise_std!r}")
        self._model = model
        self._r = None if contact_offset is None else _vector(contact_offset, "contact_offset")
        n = model.n
        self._layout = ReferenceLayout(n, model.m)
        self._rho = float(forgetting)
        self._R = float(noise_std) ** 2
        self._g = float(gravity)
        self._q = self.DeclareVectorInputPort("q", n)
        self._qdot_o = self.DeclareVectorInputPort("qdot_o", n)
        self._qddot = self.DeclareVectorInputPort("qddot_r_hat", n)
        self._tau = self.DeclareVectorInputPort("tau", n)
        self._a_d = self.DeclareVectorInputPort("acceleration_d", 3)
        self._reference = self.DeclareVectorInputPort("reference", self._layout.size)
        self._couple = self.DeclareVectorInputPort("f_couple", 3) if couple else None
        self._theta = self.DeclareDiscreteState([float(prior)])
        self._P = self.DeclareDiscreteState([float(prior_std) ** 2])
        self._F = self.DeclareDiscreteState(np.zeros(3))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._mass_out = self.DeclareStateOutputPort("mass_share", self._theta)
        self._F_out = self.DeclareStateOutputPort("force_estimate", self._F)

    def get_q_input_port(self) -> InputPort:
        """Measured joint positions ``q``."""
        return self._q

    def get_qdot_o_input_port(self) -> InputPort:
        """The observer's ``q̇_o``."""
        return self._qdot_o

    def get_qddot_r_hat_input_port(self) -> InputPort:
        """The controller's ``q̈̂_r``."""
        return self._qddot

    def get_tau_input_port(self) -> InputPort:
        """The commanded torque."""
        return self._tau

    def get_acceleration_d_input_port(self) -> InputPort:
        """The object's desired acceleration."""
        return self._a_d

    def get_reference_input_port(self) -> InputPort:
        """The arm's reference (its ``held`` row)."""
        return self._reference

    def get_f_couple_input_port(self) -> InputPort:
        """``f_c,i`` (with ``couple`` only)."""
        if self._couple is None:
            raise ValueError("couple: the f_couple port exists only with couple=True")
        return self._couple

    def get_mass_share_output_port(self) -> OutputPort:
        """``m̂_i`` (kg)."""
        return self._mass_out

    def get_force_estimate_output_port(self) -> OutputPort:
        """``F̂`` (N)."""
        return self._F_out

    def pad_force(self, q, qdot_o, qddot_r_hat, tau) -> np.ndarray:
        """``F̂ = J_x^{+T} (H q̈̂_r + C(q, q̇_o) q̇_o + D q̇_o + g − τ)``: the object's force
        on the pad, from the arm's model (N) (``J_c`` with a ``contact_offset``)."""
        rhs = self._model.inverse_dynamics_terms(q, qdot_o, qddot_r_hat) - tau
        J = contact_jacobian(self._model, q, self._r)
        if J.shape[1] == 3:
            try:
                return np.linalg.solve(J.T, rhs)
            except np.linalg.LinAlgError:     # a singular posture: the least-squares force
                pass
        return np.linalg.lstsq(J.T, rhs, rcond=None)[0]

    def _update(self, context: Context, xd: DiscreteValues) -> None:
        if not self._layout.held(self._reference.Eval(context)):
            return
        F = self.pad_force(self._q.Eval(context), self._qdot_o.Eval(context),
                           self._qddot.Eval(context), self._tau.Eval(context))
        phi = self._g + float(self._a_d.Eval(context)[2])
        theta = float(context.get_discrete_state(self._theta).value()[0])
        P = float(context.get_discrete_state(self._P).value()[0])
        y = -F[2]
        if self._couple is not None:
            y -= float(self._couple.Eval(context)[2])
        K = P * phi / (self._rho * self._R + phi * phi * P)
        theta += K * (y - phi * theta)
        P = (P - K * phi * P) / self._rho
        xd.set_value(self._theta, [theta])
        xd.set_value(self._P, [P])
        xd.set_value(self._F, F)


class ObjectStateEstimator(LeafSystem):
    """The one *shared* object-state block: the arms' local mass estimates combined into the
    object's total mass and centre of mass, and the squeeze chosen online from that load, fed
    to every arm's reference.

    The decentralized blocks (:class:`MassEstimator` per arm, the squeeze fixed before the
    run from the mass the controllers start from) exchange nothing. This block is the
    alternative that communicates: it reads every arm's share ``m̂_i`` (or the given shares)
    and gives

    .. math::
        \\hat m = \\sum_i \\hat m_i, \\qquad
        \\hat c = \\frac{\\sum_i \\hat m_i\\, p_i}{\\hat m}

    (``p_i`` the grasp points; for two opposing pads ``ĉ`` lies on the grasp line and is the
    centre of mass the lever rule of :func:`mass_shares` gives back the shares from: the
    line's only identifiable offset, from the vertical forces alone), and the squeeze

    .. math::
        \\lambda^*_k = \\texttt{squeeze\\_for\\_grasp}\\big(G^+ w(\\hat m, \\hat c, a_d(t_k)),
            n, \\mu, \\mathrm{margin}\\big), \\qquad
        \\lambda^0_k = \\texttt{squeeze\\_for\\_grasp}(\\dots, \\mathrm{margin}=1)

    (:func:`load_distribution` of the estimated object along the desired acceleration
    ``a_d``: the least squeeze in every friction cone, times the margin, clipped to
    ``lambda_max``). While the object is held (every reference's ``held`` row) the squeeze
    is rate limited, falling slowly (``r_↓``) and rising fast (``r_↑``), and never below
    what holds the estimated load,

    .. math::
        \\lambda_k = \\max\\Big(\\lambda^0_k,\\
            \\min\\big(\\lambda_{k-1} + r_\\uparrow h,\\
            \\max(\\lambda_{k-1} - r_\\downarrow h,\\ \\lambda^*_k)\\big)\\Big),

    and follows ``λ*`` freely otherwise (before the grasp: ``λ*`` of the shares the arms
    start from, their prior). The slow fall keeps the prior's squeeze while the stand still
    carries part of the object at the grasp (the shares then read less than the mass) and
    lowers it to what the converged estimate needs afterwards. Each arm's reference passes through with its
    ``λ_d`` rows replaced by ``s(t) λ_k w_i`` (``w_i`` its force weights), ``s(t)`` the
    grasp's envelope: ``clip(min(t − t_grasp, t_release − t)/ramp, 0, 1)``, the same linear
    ramps as the decentralized friction squeeze (``object_model.squeeze: friction``), so the
    squeeze never jumps. ``λ_k`` is state updated at ``t_k``: the arms' controllers, which
    latch ``τ(k)`` before the tick's discrete updates, read ``λ_{k−1}`` (one tick of delay).

    Each arm's feedforward share from the shared estimate would be the lever rule of
    ``(m̂, ĉ)`` at its grasp point, which is ``m̂_i`` again (``ĉ`` is defined from the
    shares): the shared block adds nothing to the feedforward, only to the squeeze.

    .. pydrake_system::

        name: ObjectStateEstimator
        input_ports:
        - mass_share_0
        - mass_share_1
        - reference_0
        - reference_1
        - acceleration_d
        output_ports:
        - total_mass
        - com
        - squeeze
        - reference_out_0
        - reference_out_1

    (one ``mass_share_i``, ``reference_i`` and ``reference_out_i`` per arm; two shown.)

    Parameters
    ----------
    grasp_points : array_like, shape (k, 3)
        The contact points ``p_i`` (m), one per arm, k >= 2, in a world-aligned object frame.
    grasp_normals : array_like, shape (k, 3)
        Each contact's inward normal.
    layouts : list of ReferenceLayout
        Each arm's reference layout (its ``λ_d`` and ``held`` rows).
    period : float
        ``h`` (s).
    mu : float
        The friction coefficient the controllers assume, > 0.
    margin : float
        The squeeze's safety factor, >= 1.
    grasp_window : tuple of float
        ``(t_grasp, t_release)`` (s) of the envelope ``s(t)``.
    ramp : float
        The envelope's ramp time (s), > 0.
    rate : float
        ``r_↓`` (N/s), the fastest fall of ``λ_k`` while held, > 0.
    rise_rate : float
        ``r_↑`` (N/s), the fastest rise of ``λ_k`` while held (above the floor ``λ⁰``), > 0.
    lambda_min : float
        The least squeeze (N), >= 0.
    lambda_max : float, optional
        The torque limits' squeeze (:func:`max_squeeze`); default none.
    force_weights : list of array_like, optional
        ``w_i`` (one per constraint row of arm ``i``); default ones.
    gravity : float
        ``g`` (m/s²).

    Input ports
    -----------
    mass_share_i : 1-vector
        Arm ``i``'s share ``m̂_i`` (kg) (:class:`MassEstimator`'s, or a constant).
    reference_i : (3n_i + m_i + 1)-vector
        Arm ``i``'s reference as planned.
    acceleration_d : 3-vector
        The object's desired acceleration ``a_d`` (world frame).

    Output ports
    ------------
    total_mass : 1-vector
        ``m̂`` (kg).
    com : 3-vector
        ``ĉ`` (m; the grasp points' mean while ``m̂ <= 0``).
    squeeze : 1-vector
        ``λ_k`` (N, state; before the envelope).
    reference_out_i : (3n_i + m_i + 1)-vector
        ``reference_i`` with ``λ_d,i = s(t) λ_k w_i``.

    Raises
    ------
    ValueError
        Naming the argument: fewer than two arms, shapes, ``mu`` <= 0, ``margin`` < 1, a
        window that is not ``t_grasp < t_release``, ``ramp`` or ``rate`` <= 0.
    """

    def __init__(self, grasp_points, grasp_normals, layouts: list[ReferenceLayout],
                 period: float, mu: float, margin: float = 1.5,
                 grasp_window: tuple[float, float] = (0.0, np.inf), ramp: float = 1.0,
                 rate: float = 1.0, rise_rate: float = 20.0, lambda_min: float = 0.0, lambda_max: float | None = None,
                 force_weights=None, gravity: float = GRAVITY):
        super().__init__()
        check_period(period)
        points = np.asarray(grasp_points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 2:
            raise ValueError("grasp_points: k >= 2 rows of 3 numbers are required (one per arm)")
        # The object model validates the normals; its mass is a placeholder.
        self._object = ObjectModel(1.0, points.mean(axis=0), np.zeros((3, 3)), points,
                                   grasp_normals)
        k = len(points)
        if len(layouts) != k:
            raise ValueError(f"layouts: one ReferenceLayout per grasp point ({k}) is required, "
                             f"got {len(layouts)}")
        self._layouts = [ReferenceLayout.check(lay, f"layouts[{i}]")
                         for i, lay in enumerate(layouts)]
        self._mu = check_positive(mu, "mu")
        if not (np.isfinite(margin) and margin >= 1.0):
            raise ValueError(f"margin: a number >= 1 is required, got {margin!r}")
        self._margin = float(margin)
        t0, t1 = (float(v) for v in grasp_window)
        if not t0 < t1:
            raise ValueError(f"grasp_window: t_grasp < t_release is required, got {grasp_window!r}")
        self._window = (t0, t1)
        self._ramp = check_positive(ramp, "ramp")
        self._rate = check_positive(rate, "rate")
        self._rise = check_positive(rise_rate, "rise_rate")
        if not (np.isfinite(lambda_min) and lambda_min >= 0):
            raise ValueError(f"lambda_min: a number >= 0 is required, got {lambda_min!r}")
        self._lambda_min = float(lambda_min)
        self._lambda_max = None if lambda_max is None else check_positive(lambda_max,
                                                                         "lambda_max")
        if force_weights is None:
            force_weights = [np.ones(lay.m) for lay in self._layouts]
        if len(force_weights) != k:
            raise ValueError(f"force_weights: one list per arm ({k}) is required")
        self._weights = []
        for i, (w, lay) in enumerate(zip(force_weights, self._layouts)):
            w = np.asarray(w, dtype=float).reshape(-1)
            if w.shape != (lay.m,) or not np.all(np.isfinite(w)):
                raise ValueError(f"force_weights[{i}]: {lay.m} finite numbers are required")
            self._weights.append(w)
        self._h = float(period)
        self._g = float(gravity)
        self._pinv_key, self._pinv = None, None
        self._mass_in = [self.DeclareVectorInputPort(f"mass_share_{i}", 1) for i in range(k)]
        self._ref_in = [self.DeclareVectorInputPort(f"reference_{i}", lay.size)
                        for i, lay in enumerate(self._layouts)]
        self._a_d = self.DeclareVectorInputPort("acceleration_d", 3)
        self._lam = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        masses = {self.input_port_ticket(p.get_index()) for p in self._mass_in}
        self._mass_out = self.DeclareVectorOutputPort(
            "total_mass", 1, lambda c, out: out.SetAtIndex(0, self.estimate(c)[0]),
            prerequisites_of_calc=masses)
        self._com_out = self.DeclareVectorOutputPort(
            "com", 3, lambda c, out: out.SetFromVector(self.estimate(c)[1]),
            prerequisites_of_calc=masses)
        self._squeeze_out = self.DeclareStateOutputPort("squeeze", self._lam)
        self._ref_out = []
        for i, lay in enumerate(self._layouts):
            self._ref_out.append(self.DeclareVectorOutputPort(
                f"reference_out_{i}", lay.size,
                lambda c, out, i=i: out.SetFromVector(self.reference(c, i)),
                prerequisites_of_calc={self.input_port_ticket(self._ref_in[i].get_index()),
                                       self.discrete_state_ticket(self._lam),
                                       self.time_ticket()}))
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)

    # ----------------------------------------------------------------- ports
    def get_mass_share_input_port(self, i: int) -> InputPort:
        """Arm ``i``'s share ``m̂_i``."""
        return self._mass_in[i]

    def get_reference_input_port(self, i: int) -> InputPort:
        """Arm ``i``'s planned reference."""
        return self._ref_in[i]

    def get_acceleration_d_input_port(self) -> InputPort:
        """The object's desired acceleration ``a_d``."""
        return self._a_d

    def get_total_mass_output_port(self) -> OutputPort:
        """``m̂ = Σ m̂_i``."""
        return self._mass_out

    def get_com_output_port(self) -> OutputPort:
        """``ĉ = Σ m̂_i p_i / m̂``."""
        return self._com_out

    def get_squeeze_output_port(self) -> OutputPort:
        """``λ_k`` (before the envelope)."""
        return self._squeeze_out

    def get_reference_output_port(self, i: int) -> OutputPort:
        """Arm ``i``'s reference with the shared squeeze."""
        return self._ref_out[i]

    # ----------------------------------------------------------------- math
    def estimate(self, context: Context) -> tuple[float, np.ndarray]:
        """``(m̂, ĉ)`` from the shares at the current inputs."""
        shares = np.array([float(p.Eval(context)[0]) for p in self._mass_in])
        return self.combine(shares)

    def combine(self, shares) -> tuple[float, np.ndarray]:
        """``(m̂, ĉ)`` of given shares: ``Σ m̂_i`` and ``Σ m̂_i p_i / Σ m̂_i`` (the points'
        mean while the sum is not positive)."""
        shares = np.asarray(shares, dtype=float).reshape(-1)
        m = float(shares.sum())
        points = self._object.grasp_points
        if m <= 1e-9:
            return m, points.mean(axis=0)
        return m, shares @ points / m

    def target(self, shares, acceleration) -> tuple[float, float]:
        """``(λ*, λ⁰)``: the squeeze with the margin and the least one that holds the
        estimated load (margin 1), both at least ``lambda_min`` and clipped to
        ``lambda_max``."""
        m, c = self.combine(shares)
        if m <= 1e-9:
            return self._lambda_min, self._lambda_min
        # load_distribution of the point-mass object (m̂, ĉ): G⁺ [m̂ (a − g); 0] about ĉ
        # (G⁺ kept while ĉ stays: the shares change every few ticks).
        key = tuple(c)
        if key != self._pinv_key:
            self._pinv = np.linalg.pinv(grasp_matrix(self._object.grasp_points, c))
            self._pinv_key = key
        force = m * (np.asarray(acceleration, dtype=float) - np.array([0.0, 0.0, -self._g]))
        loads = (self._pinv[:, :3] @ force).reshape(-1, 3)
        # squeeze_for_grasp with the margin 1 (written out: this runs at every tick).
        n = self._object.grasp_normals
        fn = np.sum(loads * n, axis=1)
        ft = np.linalg.norm(loads - fn[:, None] * n, axis=1)
        bare = float(np.max(ft / self._mu - fn))
        cap = np.inf if self._lambda_max is None else self._lambda_max
        lam = min(max(self._lambda_min, self._margin * bare), cap)
        hold = min(max(self._lambda_min, bare), cap)
        return lam, hold

    def step(self, previous: float, shares, acceleration, held: bool) -> float:
        """``λ_k`` from ``λ_{k−1}`` (the rate limit and the floor while held)."""
        lam, hold = self.target(shares, acceleration)
        if not held:
            return lam
        return max(hold, min(previous + self._rise * self._h,
                             max(previous - self._rate * self._h, lam)))

    def envelope(self, t: float) -> float:
        """``s(t)``: the grasp's linear ramps."""
        t0, t1 = self._window
        return min(1.0, max(0.0, min(t - t0, t1 - t) / self._ramp))

    def reference(self, context: Context, i: int) -> np.ndarray:
        """Arm ``i``'s reference with ``λ_d,i = s(t) λ_k w_i``."""
        r = np.array(self._ref_in[i].Eval(context), dtype=float)
        lam = float(context.get_discrete_state(self._lam).value()[0])
        r[self._layouts[i].slices()["lambda_d"]] = (
            self.envelope(context.get_time()) * lam * self._weights[i])
        return r

    def _shares_and_held(self, context: Context):
        shares = np.array([float(p.Eval(context)[0]) for p in self._mass_in])
        held = all(lay.held(p.Eval(context)) for lay, p in zip(self._layouts, self._ref_in))
        return shares, held

    def _initialize(self, context: Context, xd: DiscreteValues) -> None:
        shares, _ = self._shares_and_held(context)
        xd.set_value(self._lam, [self.target(shares, self._a_d.Eval(context))[0]])

    def _update(self, context: Context, xd: DiscreteValues) -> None:
        shares, held = self._shares_and_held(context)
        previous = float(context.get_discrete_state(self._lam).value()[0])
        xd.set_value(self._lam, [self.step(previous, shares, self._a_d.Eval(context), held)])


class CompressedReference(LeafSystem):
    """One arm's joint reference pressed into a compliant contact by the compression its
    current ``λ_d`` asks for, online (for a ``λ_d`` chosen during the run, e.g. by
    :class:`ObjectStateEstimator`).

    On a compliant contact the pad is held where the contact carries ``λ_d``: pressed in by
    ``δ(λ_d)`` (:class:`ContactStiffness`) along the inward normal ``n``, in the joint
    references too (else the tangent part of (4) reads the compression as a position error
    and the pad sags). A planned ``λ_d`` gets it on the planned path (the experiment's
    ``compressed_path``, the exact inverse kinematics of ``x_d + δ n``); an online one gets
    its first order at each tick,

    .. math::
        q_d \\leftarrow q_d + J_x(q_d)^+\\, n\\, \\delta(\\lambda_{d,1})\\ \\text{while held},

    with ``J_x⁺`` the least-squares inverse (the inverse for a 3-joint arm) and ``λ_d,1`` the
    first constraint row. When the reference follows the pad's material contact point ``P``
    across the normal and its centre ``E`` along it (``point_offset``, the experiment's
    ``control_point``), the Jacobian is that followed point's,
    ``J_y = (I − n nᵀ) J_P + n nᵀ J_E``: the pad is pressed in along the normal with ``P``
    kept on its path across it. ``q̇_d`` and ``q̈_d`` are left as they are (the online squeeze
    changes slowly: ``δ̇ = c(λ) λ̇`` is below 1 mm/s on the shipped pads). The paper's
    blocks are unchanged; this block sits between the reference and them.

    .. pydrake_system::

        name: CompressedReference
        input_ports:
        - reference
        output_ports:
        - compressed_reference

    Parameters
    ----------
    model : ArmModel
        The arm's model (``J_x``).
    stiffness : ContactStiffness
        The contact's law ``λ = a δᵖ``.
    inward : array_like, shape (3,)
        The contact's inward normal (world frame; normalized).
    point_offset : array_like, shape (3,), optional
        ``P``'s offset from the end effector's origin, fixed in its body and expressed in
        its frame (:class:`~drake_coop.control.arm_model.ArmModel`'s ``point_offset``);
        default: the reference follows ``E`` itself.

    Input ports
    -----------
    reference : (3n + m + 1)-vector
        The arm's reference, planned without the compression.

    Output ports
    ------------
    compressed_reference : (3n + m + 1)-vector
        The same with ``q_d`` pressed in.
    """

    def __init__(self, model: ArmModel, stiffness: ContactStiffness, inward,
                 point_offset=None):
        super().__init__()
        if not callable(getattr(stiffness, "compression", None)):
            raise TypeError("stiffness: a ContactStiffness is required, got "
                            f"{type(stiffness).__name__}")
        n = _vector(inward, "inward")
        size = float(np.linalg.norm(n))
        if size < 1e-9:
            raise ValueError("inward: a nonzero normal is required")
        self._n = n / size
        self._model = model
        #: The followed point's model (None: the centre's) and the projector across n.
        self._point = None if point_offset is None else ArmModel(
            model.plant, model.ee_frame.name(), model.N, model.c,
            point_offset=_vector(point_offset, "point_offset"))
        self._across = np.eye(3) - np.outer(self._n, self._n)
        self._stiffness = stiffness
        self._layout = ReferenceLayout(model.n, model.m)
        self._in = self.DeclareVectorInputPort("reference", self._layout.size)
        self._out = self.DeclareVectorOutputPort(
            "compressed_reference", self._layout.size,
            lambda c, out: out.SetFromVector(self.compressed(self._in.Eval(c))))

    def get_reference_input_port(self) -> InputPort:
        """The planned reference."""
        return self._in

    def get_compressed_reference_output_port(self) -> OutputPort:
        """The reference with ``q_d`` pressed in."""
        return self._out

    def compressed(self, r) -> np.ndarray:
        """``r`` with ``q_d + J_x(q_d)⁺ n δ(λ_d,1)`` while held (``r`` otherwise)."""
        r = np.array(r, dtype=float)
        lay = self._layout
        if not lay.held(r):
            return r
        s = lay.slices()
        q_d = r[s["q_d"]]
        delta = float(self._stiffness.compression(r[s["lambda_d"]][0]))
        if delta == 0.0:
            return r
        J = self._model.J_x(q_d)
        if self._point is not None:
            J = self._across @ self._point.J_x(q_d) + (np.eye(3) - self._across) @ J
        r[s["q_d"]] = q_d + np.linalg.lstsq(J, self._n * delta, rcond=None)[0]
        return r
