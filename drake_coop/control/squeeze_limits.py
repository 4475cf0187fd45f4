r"""The squeeze an arm can apply within its torque limits, along its path.

An arm holding the object by friction applies at its contact point the force

.. math::
    F_i = f_i + \lambda\,\nu_i

(its load ``f_i``, the minimum-norm split of the object's wrench,
:func:`~drake_coop.control.object.load_distribution`, plus the squeeze ``λ`` along the inward
normal ``ν_i``). Along the reference ``(q_d, q̇_d, q̈_d)`` its joints must then deliver

.. math::
    \tau(\lambda) = \underbrace{H\ddot q_d + C\dot q_d + D\dot q_d + g
        + J_c^\top f_i}_{\tau_0}
        + \lambda\,\underbrace{J_c^\top \nu_i}_{c},\qquad
    J_c^\top F = J_x^\top F + J_\omega^\top (r \times F)

(``J_c`` the translational Jacobian of the contact point, ``r`` its offset from the controlled
point: the pad's radius along ``ν_i``). Each joint's limit ``|τ_j| ≤ τ_max,j`` bounds ``λ`` to
an interval (:func:`squeeze_interval`); their intersection with ``λ ≥ 0`` is the squeeze the
arm can hold there. A grasp is feasible when the commanded squeeze lies in it at every tick
(:func:`check_squeeze_path`), else it is refused before the run with one line naming the arm,
the time, the joint and the squeezes the limits allow there.

``τ_max`` is the scenario's ``actuators.torque_limits`` or, without them, the URDF's effort
limits as Drake reads them (:func:`effort_limits`).

This module imports only NumPy and Drake.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from drake_coop.control.arm_model import ArmModel

__all__ = ["check_squeeze_path", "effort_limits", "squeeze_interval", "squeeze_torques"]


def effort_limits(plant: MultibodyPlant) -> np.ndarray:
    """Each joint's effort limit (N·m or N), in the plant's velocity order: its actuator's
    ``effort_limit()`` (the URDF's ``<limit effort>``); ``inf`` for a joint without an actuator
    or limit.

    Parameters
    ----------
    plant : MultibodyPlant
        The arm's plant (finalized), as parsed from its URDF.
    """
    limits = np.full(plant.num_velocities(), np.inf)
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        limit = float(actuator.effort_limit())
        if limit > 0.0:
            limits[actuator.joint().velocity_start()] = limit
    return limits


def squeeze_torques(model: ArmModel, q, v, a, load, inward_normal, offset=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(τ_0, c)`` of the module's docstring at one tick: the torque without the squeeze and
    the torque per newton of squeeze.

    Parameters
    ----------
    model : ArmModel
        The arm (its controlled point is the pad's centre).
    q, v, a : array_like
        ``q_d``, ``q̇_d``, ``q̈_d``.
    load : array_like, shape (3,)
        ``f_i``, the force the arm applies to the object for its motion (N, world).
    inward_normal : array_like, shape (3,)
        ``ν_i`` (normalized here).
    offset : array_like, shape (3,), optional
        ``r``: the contact point from the controlled point (world); default zero.

    Returns
    -------
    tau0 : numpy.ndarray
        ``τ_0`` (n,), N·m.
    c : numpy.ndarray
        ``c`` (n,), N·m per N.
    """
    nu = np.asarray(inward_normal, dtype=float)
    nu = nu / np.linalg.norm(nu)
    f = np.asarray(load, dtype=float)
    r = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
    _, Jw, Jx = model.ee_kinematics(np.asarray(q, dtype=float))
    # v_c = v + ω × r = (J_x − [r]× J_ω) q̇: J_cᵀ F = J_xᵀ F + J_ωᵀ (r × F).
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    Jc = Jx - skew @ Jw
    tau0 = model.inverse_dynamics_terms(q, v, a) + Jc.T @ f
    return tau0, Jc.T @ nu


def squeeze_interval(tau0, c, limits) -> tuple[float, float, int, int]:
    """The squeezes ``λ ≥ 0`` with ``|τ_0 + c λ| ≤ τ_max`` on every joint.

    Parameters
    ----------
    tau0 : array_like
        ``τ_0``: the torque without the squeeze (one entry per joint).
    c : array_like
        The torque per newton of squeeze (one entry per joint).
    limits : array_like
        ``τ_max`` per joint (``inf``: no limit).

    Returns
    -------
    lo, hi : float
        The interval (``lo > hi``: no squeeze is within the limits; ``hi`` may be ``inf``).
    j_lo, j_hi : int
        The joints that set ``lo`` and ``hi`` (-1: none, the bound is 0 or ``inf``).
    """
    tau0 = np.asarray(tau0, dtype=float)
    c = np.asarray(c, dtype=float)
    limits = np.asarray(limits, dtype=float)
    if not tau0.shape == c.shape == limits.shape:
        raise ValueError("tau0, c, limits: one entry per joint each is required")
    lo, hi, j_lo, j_hi = 0.0, math.inf, -1, -1
    for j, (o, cj, L) in enumerate(zip(tau0, c, limits)):
        if not np.isfinite(L):
            continue
        if abs(cj) < 1e-12:
            if abs(o) > L:                       # the squeeze cannot help this joint
                return math.inf, 0.0, j, j
            continue
        a, b = sorted(((-L - o) / cj, (L - o) / cj))
        if a > lo:
            lo, j_lo = a, j
        if b < hi:
            hi, j_hi = b, j
    return lo, hi, j_lo, j_hi


def check_squeeze_path(t, tau0, c, lam, limits, name: str,
                       joint_names: list[str] | None = None) -> None:
    """Raise ``ValueError`` (one line naming ``name``, the time, the joint, the squeeze and
    the squeezes its limits allow) at the first tick where ``λ_k`` is outside
    :func:`squeeze_interval` of ``(τ_0,k, c_k)``.

    Parameters
    ----------
    t : array_like, shape (K,)
        Tick times (s).
    tau0, c : array_like, shape (K, n)
        :func:`squeeze_torques` per tick.
    lam : array_like, shape (K,)
        The commanded squeeze per tick (N; 0 where the object is not held).
    limits : array_like, shape (n,)
        ``τ_max`` per joint.
    name : str
        The arm, as the message names it.
    joint_names : list of str, optional
        Joint names for the message (default ``joint j``, 1-based).
    """
    t = np.asarray(t, dtype=float)
    tau0 = np.asarray(tau0, dtype=float)
    c = np.asarray(c, dtype=float)
    lam = np.asarray(lam, dtype=float)
    limits = np.asarray(limits, dtype=float)
    # Vectorized first pass: |τ_0 + c λ| within the limits at every tick.
    tau = tau0 + c * lam[:, None]
    bad = np.flatnonzero(np.any(np.abs(tau) > limits[None, :] * (1 + 1e-9), axis=1))
    if bad.size == 0:
        return
    k = int(bad[0])
    j = int(np.argmax(np.abs(tau[k]) / limits))
    label = joint_names[j] if joint_names else f"joint {j + 1}"
    lo, hi, _, _ = squeeze_interval(tau0[k], c[k], limits)
    allowed = ("no squeeze is within them there" if lo > hi else
               f"they allow {lo:.4g} to {hi:.4g} N there")
    raise ValueError(
        f"{name}: at t = {t[k]:.3f} s the arm's motion and weight, the object's load and the "
        f"squeeze {lam[k]:.4g} N need {tau[k, j]:.4g} at {label}, beyond its torque limit "
        f"{limits[j]:.4g}; {allowed} (a lighter object, more friction, or stronger arms)")
