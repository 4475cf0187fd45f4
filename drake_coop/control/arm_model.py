r"""The controller's own model of one arm: H, C(q,v)v, D, g, φ and J_φ of (1)–(2).

The controller (13) and the observers (15)–(16), (22) are model based. Their model is a
single-arm :class:`~pydrake.multibody.plant.MultibodyPlant` parsed from the controller's URDF
(the simulated arm's URDF by default, a perturbed one in robustness studies), with its base
frame welded at the robot's pose in the palm frame, so that gravity, ``φ`` and ``J_φ`` are
expressed exactly as in the paper's Section IV. It never reads the simulated plant's context.

Quantities (robot ``i``, ``n`` joints, ``m`` constraints):

* ``H(q)`` inertia matrix, including the reflected rotor inertia ``N² J_m`` of the gears;
* ``C(q, v) v`` Coriolis and centrifugal forces (Drake's bias term, evaluated at ``v``);
* ``D`` diagonal viscous friction (the joints' damping);
* ``g(q)`` gravity torques on the left-hand side of (1) (``g = −τ_g`` in Drake's sign);
* ``φ(q) = N (x(q) − c)`` and ``J_φ = ∂φ/∂q = N J_x`` (m×n), ``J̇_φ`` along a direction
  (``N`` the outward normals, ``c`` the contact point).

The controlled point ``x(q)`` is the origin of ``ee_frame`` or, with ``point_offset`` ``o``,
the point fixed in that frame's body at ``o`` from its origin (expressed in ``ee_frame``):
``x = p_WE + R_WE o``, Drake's ``p_BoBp_B`` of its Jacobian functions. On a pad held by
friction this is the pad's *material* contact point: at a contact that does not slip it
moves with the object even when the pad rolls (to first order in the rolling angle), which
the pad's centre does not (it moves ``r Δα`` against the object when the pad turns by
``Δα``).

Kinematics: a closed form when one is given (the paper's arms: the application passes
:class:`~drake_coop.kinematics.crs.CrsKinematics` when the controller's URDF has the simulated
arm's geometry); otherwise Drake's. Drake's kinematics of a tick are **one evaluation**
(:meth:`ArmModel.ee_kinematics`: the pad's position and its geometric Jacobian ``[J_ω; J_x]``
from one ``CalcJacobianSpatialVelocity``), kept while ``q`` is unchanged and shared by ``φ``,
``J_φ`` and ``J̇_φ``, so the force observer and the controller of a tick evaluate it once.

``J̇_φ`` along a direction ``d`` on a serial chain of revolute and prismatic joints is the
closed-form derivative of the geometric Jacobian's columns (no AutoDiff): with ``a_k`` the
angular column of joint ``k`` (its world axis, 0 for a prismatic joint), ``J_k`` its
translational column, :math:`\omega_k = \sum_{j<k} a_j d_j` the angular velocity of the body
that carries joint ``k`` and :math:`s_k = \sum_{j \ge k} J_j d_j` the pad's velocity relative
to that body,

.. math:: \dot J_k = \omega_k \times J_k + a_k \times s_k

(``J_k = a_k × (x − p_k)``: ``ȧ_k = ω_k × a_k``, ``d/dt (x − p_k) = ω_k × (x − p_k) + s_k``,
and the Jacobi identity). Exact, to the roundings of a few cross products; checked against
forward-mode AutoDiff (:meth:`ArmModel.J_phi_and_derivative_autodiff`, kept as the reference
and as the fallback for a model that is not such a chain) and finite differences.
Both paths are exact; they differ by roundings.
Dynamics: ``H a + C v + D v + g`` is one inverse-dynamics call
(``CalcForceElementsContribution`` — gravity and joint damping — then
``CalcInverseDynamics``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import MultibodyForces
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.control.params import as_array


class ArmModel:
    """Rigid-body model of one arm for the controller and the observers.

    Parameters
    ----------
    plant : MultibodyPlant
        A finalized plant holding the arm alone, its base welded where it is in the world
        of the simulated plant (:func:`make_arm_controller_plant`, or
        :func:`~drake_coop.control.block.MakeArmControllerPlant` from a model instance of the
        simulated plant); continuous or discrete, only its kinematics and dynamics functions
        are used.
    ee_frame : str
        Name of the end-effector frame whose origin is the contact point ``x(q)`` of (2).
    normals : array_like, shape (m, 3) or (3,)
        The object's outward normals at the contact (rows, normalized here); ``m = 1..3``,
        linearly independent.
    contact_point : array_like, shape (3,)
        ``c`` of ``φ(q) = N (x(q) − c)``, in the world frame.
    coulomb : array_like, shape (n,), optional
        Coulomb friction torques ``F_c`` of the joints (N·m, ``≥ 0``; e.g. the identified
        ones of ``drake-coop identify``), compensated in the model:
        :meth:`inverse_dynamics_terms` then adds ``F_c ⊙ tanh(v / v_c)`` (the identification's
        own smoothing of ``sign v``). None (the paper's model, the default): no such term.
    coulomb_velocity : float
        ``v_c`` (rad/s) of that smoothing, > 0 (default 0.02, the identification's).
    closed_form : object, optional
        Closed-form kinematics of a three-joint arm of the paper's kind (``fk(q)``,
        ``jacobian(q)``, ``jacobian_dot(q, v)``, ``geometry`` with ``h1, L2, L3``, ``R_base``,
        ``p_base``, ``with_offset(o)``: :class:`~drake_coop.kinematics.crs.CrsKinematics`),
        used for ``φ``, ``J_φ`` and ``J̇_φ`` instead of Drake's; it must describe the same arm
        as ``plant`` (its ``point_offset`` is set to this model's).
    point_offset : array_like, shape (3,), optional
        The controlled point's offset from ``ee_frame``'s origin, fixed in its body and
        expressed in ``ee_frame`` (m): ``x(q) = p_WE + R_WE o`` (module docstring). Default:
        the origin itself (the paper's E).

    Raises
    ------
    ValueError
        Naming ``plant``, ``ee_frame``, ``normals``, ``contact_point`` or ``point_offset``.
    """

    def __init__(self, plant: MultibodyPlant, ee_frame: str, normals, contact_point,
                 closed_form=None, coulomb=None, coulomb_velocity: float = 0.02,
                 point_offset=None):
        if not isinstance(plant, MultibodyPlant) or not plant.is_finalized():
            raise ValueError("plant: a finalized single-arm MultibodyPlant is required "
                             "(see make_arm_controller_plant)")
        if plant.num_positions() != plant.num_velocities() or plant.num_positions() == 0:
            raise ValueError(f"plant: the arm must have as many positions as velocities and "
                             f"at least one (it has {plant.num_positions()} and "
                             f"{plant.num_velocities()}; weld its base)")
        if not isinstance(ee_frame, str) or not plant.HasFrameNamed(ee_frame):
            raise ValueError(f"ee_frame: the controller's plant has no frame named "
                             f"{ee_frame!r}")
        offset = np.zeros(3)
        if point_offset is not None:
            offset = np.asarray(point_offset, dtype=float)
            if offset.shape != (3,) or not np.all(np.isfinite(offset)):
                raise ValueError(f"point_offset: 3 finite numbers are required (m, in "
                                 f"ee_frame), got {np.shape(point_offset)}")
        #: The controlled point's offset from ``ee_frame``'s origin (its frame, m).
        self.point_offset = offset
        self._offset = offset.copy()
        self._setup(plant, ee_frame, normalized_normals(normals), contact_vector(contact_point))
        self.coulomb = None
        if coulomb is not None:
            F_c = np.asarray(coulomb, dtype=float)
            if F_c.shape != (self.n,) or not np.all(np.isfinite(F_c)) or np.any(F_c < 0):
                raise ValueError(f"coulomb: {self.n} finite torques >= 0 are required (got "
                                 f"{np.shape(coulomb)})")
            if not (isinstance(coulomb_velocity, (int, float)) and coulomb_velocity > 0
                    and math.isfinite(coulomb_velocity)):
                raise ValueError(f"coulomb_velocity: a finite number > 0 is required (got "
                                 f"{coulomb_velocity!r})")
            self.coulomb = F_c
        self.coulomb_velocity = float(coulomb_velocity)
        if closed_form is not None and not np.array_equal(
                getattr(closed_form, "offset", np.zeros(3)), offset):
            closed_form = closed_form.with_offset(offset)
        self.kinematics = closed_form
        self.closed_form = closed_form is not None
        self._row_key = b""
        self._J_phi_key = b""
        if self.closed_form:
            geometry = closed_form.geometry
            # (h1, L2, A = L3 + o_z, o_x, o_y): the centre's formulas with the forearm to P.
            self._lengths = (geometry.h1, geometry.L2, geometry.L3 + float(offset[2]),
                             float(offset[0]), float(offset[1]))
            n = self._N[0]
            nl = closed_form.R_base.T @ n            # the first normal in the base frame
            self._row_constants = (float(nl[0]), float(nl[1]), float(nl[2]),
                                   float(n @ (closed_form.p_base - self._c)))

    @classmethod
    def from_plant(cls, plant: MultibodyPlant, ee_frame: str, normals, contact_point
                   ) -> "ArmModel":
        """The model of an arm given as its own single-arm plant, with Drake's kinematics
        (the constructor without ``closed_form``).

        Parameters
        ----------
        plant : MultibodyPlant
            The arm's own finalized single-arm plant.
        ee_frame : str
            The name of the end-effector (pad) frame.
        normals : array_like
            The constraint normals (m, 3) or (3,).
        contact_point : array_like
            The contact point ``c`` (3,), m, world frame.

        Returns
        -------
        ArmModel
            The model.
        """
        return cls(plant, ee_frame, normals, contact_point)

    def _setup(self, plant: MultibodyPlant, ee_frame: str, N: np.ndarray, c: np.ndarray
               ) -> None:
        self.plant = plant
        self.n = plant.num_positions()
        self.m = N.shape[0]
        self.context = plant.CreateDefaultContext()
        self.ee_frame = plant.GetFrameByName(ee_frame)
        self.D = np.diag([plant.get_joint(j).default_damping()
                          for j in plant.GetJointIndices() if plant.get_joint(j).num_velocities()])
        self.plant_ad = plant.ToAutoDiffXd()
        self.context_ad = self.plant_ad.CreateDefaultContext()
        self.ee_frame_ad = self.plant_ad.GetFrameByName(ee_frame)
        self._world_ad = self.plant_ad.world_frame()
        self._zero_ad = np.zeros(3)
        self._N = N          # φ = N (x − c): J_φ = N J_x
        self._c = c
        self._zero_v = np.zeros(self.n)
        self._q_key = self._v_key = b""   # what the context holds (see _set_q)
        self._forces = MultibodyForces(plant)
        self._kin_key = b""
        self._kin = None
        self.serial_chain = _serial_chain(plant, self.ee_frame)

    @property
    def N(self) -> np.ndarray:
        """The constraint normals (rows, unit), ``m × 3``."""
        return self._N

    @property
    def c(self) -> np.ndarray:
        """The contact point ``c`` of (2) in the world frame."""
        return self._c

    # ------------------------------------------------ one constraint, plain floats
    def constraint_row(self, q: np.ndarray) -> tuple[float, list[float]]:
        """``φ(q)`` and ``J_φ(q)`` (as a list) of the first constraint row.

        With Drake's kinematics: from the tick's one evaluation (:meth:`ee_kinematics`).
        In closed form: plain floats (a 3-vector per NumPy call costs more than the
        arithmetic), the same
        formulas as :class:`~drake_coop.kinematics.crs.CrsKinematics` with the normal ``n``
        rotated into the base frame: ``φ = (R_bᵀ n)·x_local(q) + n·(p_b − c)``,
        ``J_φ = (R_bᵀ n)ᵀ J_local(q)``. Cached for the last ``q``: the force observer and the
        controller evaluate it at the same sample of a tick.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        phi : float
            ``φ(q)``, m.
        J_phi : list of float
            The row ``J_φ(q)`` (n numbers), m/rad.
        """
        key = q.tobytes()
        if key == self._row_key:
            return self._row
        if not self.closed_form:                 # Drake's kinematics: the tick's one evaluation
            x, _, Jx = self.ee_kinematics(q)
            n0 = self._N[0]
            self._row_key, self._row = key, (float(n0 @ (x - self._c)), (n0 @ Jx).tolist())
            return self._row
        nx, ny, nz, off = self._row_constants
        h1, L2, L3, ox, oy = self._lengths
        q1, q2, q3 = q.tolist()
        s1, c1 = math.sin(q1), math.cos(q1)
        s2, c2 = math.sin(q2), math.cos(q2)
        s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
        if ox or oy:                      # a point off the forearm's axis (point_offset)
            b, e = L3 * c23 - ox * s23, L3 * s23 + ox * c23
            r, a = L2 * s2 + e, L2 * c2 + b
            phi = (nx * (r * c1 - oy * s1) + ny * (r * s1 + oy * c1)
                   + nz * (h1 + L2 * c2 + b) + off)
            j = [-nx * (r * s1 + oy * c1) + ny * (r * c1 - oy * s1),
                 nx * a * c1 + ny * a * s1 - nz * r, nx * b * c1 + ny * b * s1 - nz * e]
        else:
            b, e = L3 * c23, L3 * s23
            r, a = L2 * s2 + e, L2 * c2 + b
            phi = nx * r * c1 + ny * r * s1 + nz * (h1 + L2 * c2 + b) + off
            j = [-nx * r * s1 + ny * r * c1, nx * a * c1 + ny * a * s1 - nz * r,
                 nx * b * c1 + ny * b * s1 - nz * e]
        self._row_key, self._row = key, (phi, j)
        self._row_terms = (s1, c1, s2, r, a, b, e)
        return phi, j

    def constraint_row_dot(self, q: np.ndarray, v: np.ndarray) -> list[float]:
        """``J̇_φ`` along ``v`` of a one-constraint arm in closed form (plain floats); with
        Drake's kinematics the first normal times :meth:`J_x_dot` (a serial chain), else
        AutoDiff.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            The direction (joint velocities) (n,), rad/s.

        Returns
        -------
        list of float
            The row ``J̇_φ`` (n numbers), m/(rad·s).
        """
        if not self.closed_form:
            if self.serial_chain:
                return (self._N[0] @ self.J_x_dot(q, v)).tolist()
            return self.J_phi_and_derivative_autodiff(q, v)[1][0].tolist()
        self.constraint_row(q)
        s1, c1, s2, r, a, b, e = self._row_terms
        nx, ny, nz, _ = self._row_constants
        L2 = self._lengths[1]
        oy = self._lengths[4]
        v1, v2, v3 = v.tolist()
        w = v2 + v3
        rd = a * v2 + b * v3
        ad = -L2 * s2 * v2 - e * w
        bd = -e * w
        ed = b * w
        if oy:
            return [nx * (-rd * s1 - r * c1 * v1 + oy * s1 * v1)
                    + ny * (rd * c1 - r * s1 * v1 - oy * c1 * v1),
                    nx * (ad * c1 - a * s1 * v1) + ny * (ad * s1 + a * c1 * v1) - nz * rd,
                    nx * (bd * c1 - b * s1 * v1) + ny * (bd * s1 + b * c1 * v1) - nz * ed]
        return [nx * (-rd * s1 - r * c1 * v1) + ny * (rd * c1 - r * s1 * v1),
                nx * (ad * c1 - a * s1 * v1) + ny * (ad * s1 + a * c1 * v1) - nz * rd,
                nx * (bd * c1 - b * s1 * v1) + ny * (bd * s1 + b * c1 * v1) - nz * ed]

    # -------------------------------------------------------------------------- helpers
    def _set_q(self, q: np.ndarray) -> None:
        """Positions into the model's context, only when they changed.

        At a tick the force observer and the controller evaluate the model at the same
        ``q``; keeping the context untouched keeps Drake's kinematics cache (the same doubles
        as recomputing them).
        """
        q = np.asarray(q, dtype=float)
        key = q.tobytes()
        if key != self._q_key:
            self.plant.SetPositions(self.context, q)
            self._q_key = key

    def _set(self, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """Positions and velocities (default zero) into the model's context."""
        self._set_q(q)
        v = self._zero_v if v is None else np.asarray(v, dtype=float)
        key = v.tobytes()
        if key != self._v_key:
            self.plant.SetVelocities(self.context, v)
            self._v_key = key

    # ------------------------------------------------------------------------- dynamics
    def H(self, q: np.ndarray) -> np.ndarray:
        """Inertia matrix ``H(q)`` (n×n).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``H(q)`` (n, n), kg·m².
        """
        self._set_q(q)
        return self.plant.CalcMassMatrix(self.context)

    def Cv(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v`` (n,).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            Joint velocities (n,), rad/s.

        Returns
        -------
        numpy.ndarray
            ``C(q, v) v`` (n,), N·m.
        """
        self._set(q, v)
        return self.plant.CalcBiasTerm(self.context)

    def g(self, q: np.ndarray) -> np.ndarray:
        """Gravity vector ``g(q)`` of (1) (left-hand side), n-vector.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``g(q)`` (n,), N·m.
        """
        self._set_q(q)
        return -self.plant.CalcGravityGeneralizedForces(self.context)

    def friction_torque(self, v: np.ndarray) -> np.ndarray:
        """``F_c ⊙ tanh(v / v_c)``, the compensated Coulomb friction (zeros without it).

        Parameters
        ----------
        v : numpy.ndarray
            Joint velocities (n,), rad/s.

        Returns
        -------
        numpy.ndarray
            The friction torque (n,), N·m.
        """
        if self.coulomb is None:
            return np.zeros(self.n)
        return self.coulomb * np.tanh(np.asarray(v, dtype=float) / self.coulomb_velocity)

    def inverse_dynamics_terms(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """``H(q) a + C(q, v) v + D v + g(q)``: the model part of (13) and (21); plus
        :meth:`friction_torque` when the model has Coulomb friction (``coulomb``).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        v : numpy.ndarray
            Joint velocities (n,), rad/s.
        a : numpy.ndarray
            Joint accelerations (n,), rad/s².

        Returns
        -------
        numpy.ndarray
            The torque (n,), N·m.
        """
        self._set(q, v)
        # Drake's inverse dynamics is M a + C v − τ_app; the force elements give
        # τ_app = τ_g − D v (gravity, and the joints' damping).
        self.plant.CalcForceElementsContribution(self.context, self._forces)
        tau = self.plant.CalcInverseDynamics(self.context, np.asarray(a, dtype=float),
                                             self._forces)
        if self.coulomb is not None:
            tau = tau + self.friction_torque(v)
        return tau

    # ----------------------------------------------------------------------- kinematics
    def ee_kinematics(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The controlled point's position ``x`` (3,), the angular ``J_ω`` (3×n) and the
        point's translational ``J_x`` (3×n) Jacobians, world frame, from one Drake evaluation
        (``p_BoBp_B`` = ``point_offset``); kept for the last ``q`` (the blocks of a tick share
        it). Read-only arrays: the caller must not modify them.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        x : numpy.ndarray
            The controlled point (3,), m.
        J_omega : numpy.ndarray
            ``J_ω`` (3, n), rad/rad.
        J_x : numpy.ndarray
            ``J_x`` (3, n), m/rad.
        """
        q = np.asarray(q, dtype=float)
        key = q.tobytes()
        if key != self._kin_key:
            self._set_q(q)
            J = self.plant.CalcJacobianSpatialVelocity(
                self.context, JacobianWrtVariable.kV, self.ee_frame, self._offset,
                self.plant.world_frame(), self.plant.world_frame())
            x = self.ee_frame.CalcPoseInWorld(self.context).multiply(self._offset)
            Jw, Jx = J[:3], J[3:]
            for a in (x, Jw, Jx):
                a.flags.writeable = False
            self._kin_key, self._kin = key, (x, Jw, Jx)
        return self._kin

    def ee_position(self, q: np.ndarray) -> np.ndarray:
        """The controlled point (the pad's centre E, or the ``point_offset`` point) in the
        palm frame.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            The point (3,), m.
        """
        if self.closed_form:
            return self.kinematics.fk(q)
        return self.ee_kinematics(q)[0]

    def J_x(self, q: np.ndarray) -> np.ndarray:
        """Translational Jacobian ``J_x = ∂x/∂q`` of the controlled point (3×n), world frame
        (``J_φ = N J_x``); closed form when the arm has it.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``J_x`` (3, n), m/rad.
        """
        if self.closed_form:
            return self.kinematics.jacobian(q)
        return self.ee_kinematics(q)[2]

    def J_omega(self, q: np.ndarray) -> np.ndarray:
        """Rotational Jacobian ``J_ω`` of the end-effector frame (3×n), world frame: its
        angular velocity is ``J_ω q̇``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``J_ω`` (3, n), rad/rad.
        """
        self._set_q(q)
        return self.plant.CalcJacobianSpatialVelocity(
            self.context, JacobianWrtVariable.kV, self.ee_frame, np.zeros(3),
            self.plant.world_frame(), self.plant.world_frame())[:3]

    def phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint (2), ``φ = N (x − c)`` (m), an m-vector.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``φ(q)`` (m,), m.
        """
        return self._N @ (self.ee_position(q) - self._c)

    def J_phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint Jacobian ``J_φ = ∂φ/∂q = N J_x`` (m×n).

        Closed form: cached for the last ``q`` (the force observer and the controller evaluate
        it at the same sample of a tick); the caller must not modify the array.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.

        Returns
        -------
        numpy.ndarray
            ``J_φ`` (m, n), m/rad.
        """
        if self.closed_form:
            key = np.asarray(q, dtype=float).tobytes()
            if key != self._J_phi_key:
                self._J_phi_key, self._J_phi = key, self._N @ self.kinematics.jacobian(q)
            return self._J_phi
        return self._N @ self.ee_kinematics(q)[2]

    def J_x_dot(self, q: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """``J̇_x`` along ``direction`` (3×n) from the cached geometric Jacobian, in closed
        form (module docstring: ``J̇_k = ω_k × J_k + a_k × s_k``); a serial chain only
        (:attr:`serial_chain`).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        direction : numpy.ndarray
            The joint velocities along which to differentiate (n,), rad/s.

        Returns
        -------
        numpy.ndarray
            ``J̇_x`` (3, n), m/(rad·s).
        """
        _, Jw, Jx = self.ee_kinematics(q)
        d = np.asarray(direction, dtype=float)
        wd = Jw * d                                     # a_j d_j
        vd = Jx * d                                     # J_j d_j
        w = np.cumsum(wd, axis=1) - wd                  # ω_k = Σ_{j<k} a_j d_j
        sk = np.cumsum(vd[:, ::-1], axis=1)[:, ::-1]    # s_k = Σ_{j≥k} J_j d_j
        return _cross_columns(w, Jx) + _cross_columns(Jw, sk)

    def J_phi_and_derivative(self, q: np.ndarray, direction: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
        """``J_φ(q)`` and its exact directional derivative ``Σ_k ∂J_φ/∂q_k · direction_k``.

        Closed form of the paper's arms (:meth:`Arm.jacobian_dot`) when it applies; else, on a
        serial chain, the closed-form derivative of the cached geometric Jacobian
        (:meth:`J_x_dot`); else forward-mode AutoDiff
        (:meth:`J_phi_and_derivative_autodiff`).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        direction : numpy.ndarray
            The joint velocities along which to differentiate (n,), rad/s (``q̇_o`` in (7)).

        Returns
        -------
        J_phi : numpy.ndarray
            ``J_φ`` (m, n), m/rad.
        J_phi_dot : numpy.ndarray
            Its directional derivative (m, n), m/(rad·s).
        """
        if self.closed_form:
            return (self.J_phi(q),
                    self._N @ self.kinematics.jacobian_dot(q, np.asarray(direction, dtype=float)))
        if not self.serial_chain:
            return self.J_phi_and_derivative_autodiff(q, direction)
        return self._N @ self.ee_kinematics(q)[2], self._N @ self.J_x_dot(q, direction)

    def J_phi_and_derivative_autodiff(self, q: np.ndarray, direction: np.ndarray
                                      ) -> tuple[np.ndarray, np.ndarray]:
        """``J_φ(q)`` and its directional derivative by forward-mode AutoDiff of Drake's
        translational Jacobian, one derivative component seeded with ``direction`` (any
        tree; the reference the closed form is checked against).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        direction : numpy.ndarray
            The joint velocities along which to differentiate (n,), rad/s.

        Returns
        -------
        J_phi : numpy.ndarray
            ``J_φ`` (m, n), m/rad.
        J_phi_dot : numpy.ndarray
            Its directional derivative (m, n), m/(rad·s).
        """
        q_ad = InitializeAutoDiff(np.asarray(q, float), np.asarray(direction, float).reshape(-1, 1))
        self.plant_ad.SetPositions(self.context_ad, q_ad.reshape(-1))
        Jv = self.plant_ad.CalcJacobianTranslationalVelocity(
            self.context_ad, JacobianWrtVariable.kV, self.ee_frame_ad, self._offset,
            self._world_ad, self._world_ad)
        # Vectorised extraction (C++), the same doubles as reading each entry in Python.
        value = ExtractValue(Jv).reshape(3, self.n)
        deriv = ExtractGradient(Jv.reshape(-1, 1))   # an entry without derivatives gives 0
        deriv = (deriv.reshape(3, self.n) if deriv.size == 3 * self.n
                 else np.zeros((3, self.n)))
        return self._N @ value, self._N @ deriv


#: Description packages found in the Python environment: the package name the URDFs use,
#: and the data folder under ``site-packages`` (``example-robot-data``'s wheel holds no Python
#: module; its ``package.xml`` names it ``example_robot_descriptions``, its URDFs say
#: ``package://example-robot-data/...``).
DESCRIPTION_PACKAGES = {"example-robot-data": "cmeel.prefix/share/example-robot-data"}


def description_packages() -> dict[str, Path]:
    """The installed description packages by the name their URDFs use (folders holding a
    ``package.xml`` under an entry of ``sys.path``); empty when none is installed.

    Returns
    -------
    dict of str to Path
        Package name → its folder.
    """
    import sys

    found = {}
    for name, sub in DESCRIPTION_PACKAGES.items():
        for entry in sys.path:
            folder = Path(entry or ".") / sub
            if (folder / "package.xml").is_file():
                found[name] = folder.resolve()
                break
    return found


def add_description_packages(package_map) -> None:
    """Add :func:`description_packages` to a :class:`~pydrake.multibody.parsing.PackageMap`
    (those it does not know yet), so a parser reads ``package://example-robot-data/...``.

    Parameters
    ----------
    package_map : PackageMap
        The parser's package map.
    """
    for name, folder in description_packages().items():
        if not package_map.Contains(name):
            package_map.Add(name, str(folder))


def make_arm_controller_plant(model_file: str | Path, base_frame: str,
                              X_WB: RigidTransform | None = None) -> MultibodyPlant:
    """The controller's own single-arm plant, as Drake's ``InverseDynamicsController`` wants.

    Parameters
    ----------
    model_file : str or Path
        The arm's URDF or SDFormat file (``package://`` URLs resolved by Drake's parser, which
        also knows the installed description packages, :func:`add_description_packages`).
    base_frame : str
        The frame welded to the world.
    X_WB : RigidTransform, optional
        The base frame's pose in the world of the simulated plant (identity by default).

    Returns
    -------
    MultibodyPlant
        Finalized, continuous (time step 0), the base welded at ``X_WB``.
    """
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    add_description_packages(parser.package_map())
    text = str(model_file)
    if "://" in text:
        parser.AddModelsFromUrl(text)
    else:
        parser.AddModels(text)
    if not plant.HasFrameNamed(base_frame):
        raise ValueError(f"base_frame: {model_file} has no frame named {base_frame!r}")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame),
                     RigidTransform() if X_WB is None else X_WB)
    plant.Finalize()
    return plant


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

    Returns
    -------
    numpy.ndarray
        ``c`` (3,), m.
    """
    c = as_array(contact_point, "contact_point")
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"contact_point: 3 finite numbers are required (got "
                         f"{np.shape(contact_point)})")
    return c


def _cross_columns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Column-wise cross products of two 3×n arrays (``np.cross`` without its overhead)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _serial_chain(plant: MultibodyPlant, frame) -> bool:
    """Whether the joints moving ``frame`` form a chain of revolute and prismatic joints of
    one velocity each, numbered from the base outwards (what :meth:`ArmModel.J_x_dot`
    assumes); joints off the chain have zero Jacobian columns and do not matter."""
    parent_joint = {}
    for j in plant.GetJointIndices():
        joint = plant.get_joint(j)
        parent_joint[joint.child_body().index()] = joint
    body = frame.body()
    starts = []
    while body.index() in parent_joint:
        joint = parent_joint[body.index()]
        if joint.num_velocities() == 1:
            if joint.type_name() not in ("revolute", "prismatic"):
                return False
            starts.append(joint.velocity_start())
        elif joint.num_velocities() != 0:
            return False
        body = joint.parent_body()
    starts.reverse()
    return all(a < b for a, b in zip(starts, starts[1:]))
