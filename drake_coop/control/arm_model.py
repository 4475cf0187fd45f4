"""The controller's own model of one arm: H, C(q,v)v, D, g, φ and J_φ of (1)–(2).

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
* ``φ(q) = N (x(q) − c)`` and ``J_φ = ∂φ/∂q = N J_x`` (m×n), ``J̇_φ`` along a direction by
  AutoDiff (``N`` the outward normals, ``c`` the contact point: :class:`~drake_coop.plant.arms.Arm`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.plant.arms import Arm


class ArmModel:
    """Rigid-body model of one arm for the controller and the observers.

    Parameters
    ----------
    arm : Arm
        The robot (base pose, frames, constraint normals and contact point).
    urdf : Path, optional
        The model to use; defaults to ``arm.controller_urdf_path``.
    """

    def __init__(self, arm: Arm, urdf: Path | None = None):
        self.arm = arm
        self.urdf = Path(urdf) if urdf is not None else arm.controller_urdf_path
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(self.urdf))
        X_WB = RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base)
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(arm.base_frame), X_WB)
        plant.Finalize()
        self.plant = plant
        self.n = plant.num_positions()
        self.m = arm.m
        self.context = plant.CreateDefaultContext()
        self.ee_frame = plant.GetFrameByName(arm.ee_frame)
        self.D = np.diag([plant.get_joint(j).default_damping()
                          for j in plant.GetJointIndices() if plant.get_joint(j).num_velocities()])
        self.plant_ad = plant.ToAutoDiffXd()
        self.context_ad = self.plant_ad.CreateDefaultContext()
        self.ee_frame_ad = self.plant_ad.GetFrameByName(arm.ee_frame)
        self._world_ad = self.plant_ad.world_frame()
        self._zero_ad = np.zeros(3)
        self._N = arm.N          # φ = N (x − c): J_φ = N J_x
        self._c = arm.c
        self._zero_v = np.zeros(self.n)
        self._q_key = self._v_key = b""   # what the context holds (see _set_q)

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
        """Inertia matrix ``H(q)`` (n×n)."""
        self._set_q(q)
        return self.plant.CalcMassMatrix(self.context)

    def Cv(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v`` (n,)."""
        self._set(q, v)
        return self.plant.CalcBiasTerm(self.context)

    def g(self, q: np.ndarray) -> np.ndarray:
        """Gravity vector ``g(q)`` of (1) (left-hand side), n-vector."""
        self._set_q(q)
        return -self.plant.CalcGravityGeneralizedForces(self.context)

    def inverse_dynamics_terms(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """``H(q) a + C(q, v) v + D v + g(q)``: the model part of (13) and (21)."""
        self._set(q, v)
        H = self.plant.CalcMassMatrix(self.context)
        Cv = self.plant.CalcBiasTerm(self.context)
        g = -self.plant.CalcGravityGeneralizedForces(self.context)
        return H @ a + Cv + self.D @ v + g

    # ----------------------------------------------------------------------- kinematics
    def ee_position(self, q: np.ndarray) -> np.ndarray:
        """End-effector point (pad centre) in the palm frame."""
        self._set_q(q)
        return self.ee_frame.CalcPoseInWorld(self.context).translation()

    def phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint (2), ``φ = N (x − c)`` (m), an m-vector."""
        return self._N @ (self.ee_position(q) - self._c)

    def J_phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint Jacobian ``J_φ = ∂φ/∂q = N J_x`` (m×n)."""
        self._set_q(q)
        Jv = self.plant.CalcJacobianTranslationalVelocity(
            self.context, JacobianWrtVariable.kV, self.ee_frame, np.zeros(3),
            self.plant.world_frame(), self.plant.world_frame())
        return self._N @ Jv

    def J_phi_and_derivative(self, q: np.ndarray, direction: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
        """``J_φ(q)`` and its exact directional derivative ``Σ_k ∂J_φ/∂q_k · direction_k``.

        Forward-mode AutoDiff with one derivative component seeded with ``direction``.
        """
        q_ad = InitializeAutoDiff(np.asarray(q, float), np.asarray(direction, float).reshape(-1, 1))
        self.plant_ad.SetPositions(self.context_ad, q_ad.reshape(-1))
        Jv = self.plant_ad.CalcJacobianTranslationalVelocity(
            self.context_ad, JacobianWrtVariable.kV, self.ee_frame_ad, self._zero_ad,
            self._world_ad, self._world_ad)
        # Vectorised extraction (C++), the same doubles as reading each entry in Python.
        value = ExtractValue(Jv).reshape(3, self.n)
        deriv = ExtractGradient(Jv.reshape(-1, 1))   # an entry without derivatives gives 0
        deriv = (deriv.reshape(3, self.n) if deriv.size == 3 * self.n
                 else np.zeros((3, self.n)))
        return self._N @ value, self._N @ deriv
