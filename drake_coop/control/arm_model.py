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

``J̇_φ`` on a serial chain of revolute and prismatic joints: the closed-form derivative of the
geometric Jacobian's columns (:mod:`drake_coop.control.arm_closed_form`, with the paper's arm's
one constraint row); forward-mode AutoDiff (:meth:`ArmModel.J_phi_and_derivative_autodiff`) is
the reference and the fallback for a model that is not such a chain (exact both, up to roundings).

Dynamics: ``H a + C v + D v + g`` is one inverse-dynamics call
(``CalcForceElementsContribution`` — gravity and joint damping — then
``CalcInverseDynamics``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces

from drake_coop.control.arm_closed_form import (
    is_serial_chain, jacobian_dot, paper_arm_row, paper_arm_row_dot, paper_arm_row_setup)
from drake_coop.control.deprecation import moved
from drake_coop.control.params import contact_vector, normalized_normals  # noqa: F401

#: Moved names, found here until :mod:`drake_coop.control.deprecation`'s removal date.
_MOVED = dict.fromkeys(("DESCRIPTION_PACKAGES", "add_description_packages",
                        "description_packages", "make_arm_controller_plant"),
                       "drake_coop.control.arm_plant")


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
            self._row_constants, self._lengths = paper_arm_row_setup(closed_form, self._N[0],
                                                                     self._c, offset)

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
        self.serial_chain = is_serial_chain(plant, self.ee_frame)

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
        In closed form: plain floats (:func:`~drake_coop.control.arm_closed_form.paper_arm_row`).
        Cached for the last ``q``: the force observer and the controller evaluate it at the same
        sample of a tick.

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
        phi, j, self._row_terms = paper_arm_row(self._row_constants, self._lengths,
                                                q.tolist())
        self._row_key, self._row = key, (phi, j)
        return phi, j

    def constraint_row_dot(self, q: np.ndarray, v: np.ndarray) -> list[float]:
        """``J̇_φ`` along ``v``, the row (n numbers), m/(rad·s), of a one-constraint arm in
        closed form (plain floats); with Drake's kinematics the first normal times
        :meth:`J_x_dot` (a serial chain), else AutoDiff.

        Parameters
        ----------
        q, v : numpy.ndarray
            As ``q, direction`` in :meth:`J_x_dot`.
        """
        if not self.closed_form:
            if self.serial_chain:
                return (self._N[0] @ self.J_x_dot(q, v)).tolist()
            return self.J_phi_and_derivative_autodiff(q, v)[1][0].tolist()
        self.constraint_row(q)
        return paper_arm_row_dot(self._row_constants, self._lengths, self._row_terms,
                                 v.tolist())

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
        """``H(q)`` (n, n), kg·m²: the inertia matrix.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        self._set_q(q)
        return self.plant.CalcMassMatrix(self.context)

    def Cv(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v`` (n,), N·m.

        Parameters
        ----------
        q, v : numpy.ndarray
            Joint positions (n,), rad, and velocities (n,), rad/s.
        """
        self._set(q, v)
        return self.plant.CalcBiasTerm(self.context)

    def g(self, q: np.ndarray) -> np.ndarray:
        """The gravity vector ``g(q)`` of (1) (left-hand side), (n,), N·m.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        self._set_q(q)
        return -self.plant.CalcGravityGeneralizedForces(self.context)

    def friction_torque(self, v: np.ndarray) -> np.ndarray:
        """``F_c ⊙ tanh(v / v_c)`` (n,), N·m, the compensated Coulomb friction (zeros without
        it).

        Parameters
        ----------
        v : numpy.ndarray
            Joint velocities (n,), rad/s.
        """
        if self.coulomb is None:
            return np.zeros(self.n)
        return self.coulomb * np.tanh(np.asarray(v, dtype=float) / self.coulomb_velocity)

    def inverse_dynamics_terms(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """``H(q) a + C(q, v) v + D v + g(q)``: the model part of (13) and (21); plus
        :meth:`friction_torque` when the model has Coulomb friction (``coulomb``); (n,), N·m.

        Parameters
        ----------
        q, v, a : numpy.ndarray
            Joint positions (n,), rad, velocities, rad/s, and accelerations, rad/s².
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
        palm frame, (3,), m.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        if self.closed_form:
            return self.kinematics.fk(q)
        return self.ee_kinematics(q)[0]

    def J_x(self, q: np.ndarray) -> np.ndarray:
        """The translational Jacobian ``J_x = ∂x/∂q`` of the controlled point (3, n), m/rad,
        world frame (``J_φ = N J_x``); closed form when the arm has it.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        if self.closed_form:
            return self.kinematics.jacobian(q)
        return self.ee_kinematics(q)[2]

    def J_omega(self, q: np.ndarray) -> np.ndarray:
        """The rotational Jacobian ``J_ω`` of the end-effector frame (3, n), rad/rad, world
        frame: its angular velocity is ``J_ω q̇``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        self._set_q(q)
        return self.plant.CalcJacobianSpatialVelocity(
            self.context, JacobianWrtVariable.kV, self.ee_frame, np.zeros(3),
            self.plant.world_frame(), self.plant.world_frame())[:3]

    def phi(self, q: np.ndarray) -> np.ndarray:
        """The constraint (2), ``φ = N (x − c)`` (m,), m.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        return self._N @ (self.ee_position(q) - self._c)

    def J_phi(self, q: np.ndarray) -> np.ndarray:
        """The constraint Jacobian ``J_φ = ∂φ/∂q = N J_x`` (m, n), m/rad.

        Closed form: cached for the last ``q`` (the force observer and the controller evaluate
        it at the same sample of a tick); the caller must not modify the array.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (n,), rad.
        """
        if self.closed_form:
            key = np.asarray(q, dtype=float).tobytes()
            if key != self._J_phi_key:
                self._J_phi_key, self._J_phi = key, self._N @ self.kinematics.jacobian(q)
            return self._J_phi
        return self._N @ self.ee_kinematics(q)[2]

    def J_x_dot(self, q: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """``J̇_x`` (3, n), m/(rad·s), along ``direction`` from the cached geometric Jacobian,
        in closed form (module docstring: ``J̇_k = ω_k × J_k + a_k × s_k``); a serial chain
        only (:attr:`serial_chain`).

        Parameters
        ----------
        q, direction : numpy.ndarray
            Joint positions (n,), rad, and the joint velocities along which to
            differentiate (n,), rad/s.
        """
        _, Jw, Jx = self.ee_kinematics(q)
        return jacobian_dot(Jw, Jx, direction)

    def J_phi_and_derivative(self, q: np.ndarray, direction: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
        """``J_φ(q)`` (m, n), m/rad, and its exact directional derivative
        ``Σ_k ∂J_φ/∂q_k · direction_k`` (m, n), m/(rad·s).

        Closed form of the paper's arms (:meth:`Arm.jacobian_dot`) when it applies; else, on a
        serial chain, the closed-form derivative of the cached geometric Jacobian
        (:meth:`J_x_dot`); else forward-mode AutoDiff
        (:meth:`J_phi_and_derivative_autodiff`).

        Parameters
        ----------
        q, direction : numpy.ndarray
            As in :meth:`J_x_dot` (``direction``: ``q̇_o`` in (7)).
        """
        if self.closed_form:
            return (self.J_phi(q),
                    self._N @ self.kinematics.jacobian_dot(q, np.asarray(direction, dtype=float)))
        if not self.serial_chain:
            return self.J_phi_and_derivative_autodiff(q, direction)
        return self._N @ self.ee_kinematics(q)[2], self._N @ self.J_x_dot(q, direction)

    def J_phi_and_derivative_autodiff(self, q: np.ndarray, direction: np.ndarray
                                      ) -> tuple[np.ndarray, np.ndarray]:
        """``J_φ(q)`` and its directional derivative, as :meth:`J_phi_and_derivative` returns
        them, by forward-mode AutoDiff of Drake's translational Jacobian, one derivative
        component seeded with ``direction`` (any tree; the reference the closed form is
        checked against).

        Parameters
        ----------
        q, direction : numpy.ndarray
            As in :meth:`J_x_dot`.
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


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
