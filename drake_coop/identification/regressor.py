r"""The inverse-dynamics regressor of one arm, built numerically from Drake's inverse dynamics.

The joint torques of a rigid arm are linear in its dynamic parameters:

.. math::
    \tau = H(q)\ddot q + C(q,\dot q)\dot q + D\dot q + g(q) + f_c\,\mathrm{sign}(\dot q)
          = Y(q, \dot q, \ddot q)\,\theta .

Per moving body ``b`` (a link with every body welded to it: force sensor, pad, payload form
one composite) ten inertial parameters, in the body frame ``B`` about its origin ``Bo``:

``θ_b = [m, h_x, h_y, h_z, I_xx, I_yy, I_zz, I_xy, I_xz, I_yz]`` with ``h = m p_BoBcm`` the
first moment and ``I`` the rotational inertia about ``Bo``; the spatial inertia is linear in
``θ_b``, and so are Drake's inverse dynamics and gravity forces. Per joint ``j`` three more:
the reflected rotor inertia ``I_a = N² J_m`` (adds ``I_a q̈_j``), the viscous friction ``D_j``
(``D_j q̇_j``) and the Coulomb friction ``f_c`` (``f_c sign(q̇_j)``).

The columns of ``Y`` for a body's parameters are differences of Drake's inverse dynamics
(``CalcInverseDynamics − CalcGravityGeneralizedForces``) of a single-arm plant in which only
that body carries inertia: ``Y e_k = τ(θ_0 + e_k) − τ(θ_0)``, exact because ``τ`` is linear in
``θ`` (``θ_0`` a unit point mass at the origin; the shifted ``θ_0 + e_k`` need not be physical,
Drake's validity check is skipped for it). The rotor and friction columns are closed forms.
Not every combination of ``θ`` changes the torques (e.g. the waist link's mass); the
identifiable combinations are the row space of ``Y`` (:func:`identifiable_basis`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import MultibodyForces, SpatialInertia, UnitInertia

#: Names of a body's ten inertial parameters, in the order of ``θ_b``.
BODY_PARAMETERS = ("m", "hx", "hy", "hz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")
#: Names of a joint's three parameters.
JOINT_PARAMETERS = ("rotor_inertia", "viscous", "coulomb")


def spatial_inertia_from_theta(theta: np.ndarray) -> SpatialInertia:
    """The spatial inertia ``M_BBo_B`` of ten parameters ``[m, h, I_Bo]`` (no validity check).

    A zero mass gives the zero spatial inertia (the first moment and inertia must then be
    zero too for the result to mean anything; the regressor never uses it otherwise).

    Parameters
    ----------
    theta : numpy.ndarray
        ``[m, h, I_Bo]`` (10,): kg, kg·m, kg·m².
    """
    m = float(theta[0])
    Ixx, Iyy, Izz, Ixy, Ixz, Iyz = (float(x) for x in theta[4:10])
    if m == 0.0:
        return SpatialInertia(0.0, np.zeros(3), UnitInertia(0.0, 0.0, 0.0),
                              skip_validity_check=True)
    return SpatialInertia(m, np.asarray(theta[1:4], float) / m,
                          UnitInertia(Ixx / m, Iyy / m, Izz / m, Ixy / m, Ixz / m, Iyz / m),
                          skip_validity_check=True)


def theta_from_spatial_inertia(M: SpatialInertia) -> np.ndarray:
    """The ten parameters ``[m, h, I_Bo]`` of a spatial inertia about a body's origin.

    Parameters
    ----------
    M : SpatialInertia
        About the body's origin.

    Returns
    -------
    numpy.ndarray
        ``[m, h, I_Bo]`` (10,): kg, kg·m, kg·m².
    """
    m = M.get_mass()
    h = m * M.get_com()
    I = M.CalcRotationalInertia().CopyToFullMatrix3()
    return np.array([m, *h, I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])


def pseudo_inertia(theta: np.ndarray) -> np.ndarray:
    """The 4×4 pseudo-inertia ``J = [[½ tr(I) 1 − I, h], [hᵀ, m]]`` of ten parameters.

    ``J ⪰ 0`` exactly when the parameters are those of some nonnegative mass distribution
    (Wensing, Kim, Slotine, IEEE RA-L 2018): the physical-consistency condition.

    Parameters
    ----------
    theta : array_like
        ``[m, h, I_Bo]`` (10,), numbers or symbolic expressions.
    """
    m, hx, hy, hz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz = theta
    # Σ = ½ tr(I) 1 − I written out (also for symbolic entries: no products with 0 or 1).
    Sxx, Syy, Szz = 0.5 * (Iyy + Izz - Ixx), 0.5 * (Ixx + Izz - Iyy), 0.5 * (Ixx + Iyy - Izz)
    return np.array([[Sxx, -Ixy, -Ixz, hx],
                     [-Ixy, Syy, -Iyz, hy],
                     [-Ixz, -Iyz, Szz, hz],
                     [hx, hy, hz, m]])


@dataclass
class ArmStructure:
    """The kinematic structure of one arm for identification.

    Attributes
    ----------
    plant : MultibodyPlant
        A finalized single-arm plant (base welded at the robot's pose; inertias irrelevant).
    links : list[str]
        The moving composite bodies, one per joint (the child body of each joint).
    members : dict[str, list[str]]
        The bodies welded into each composite (its own name first).
    joints : list[str]
        The actuated joints, in the order of ``q``.
    gear_ratios : ndarray
        Gear ratio ``N`` per joint (1 without a transmission).
    """

    plant: MultibodyPlant
    links: list[str]
    members: dict[str, list[str]]
    joints: list[str]
    gear_ratios: np.ndarray

    @property
    def n(self) -> int:
        """The number of joints."""
        return len(self.joints)

    @property
    def num_parameters(self) -> int:
        """The number of parameters ``p``: ten per composite link, three per joint."""
        return 10 * len(self.links) + 3 * self.n

    def parameter_names(self) -> list[str]:
        """``link.m``, ``link.hx``, … then ``joint.rotor_inertia``, ``joint.viscous``, …

        Returns
        -------
        list of str
            The names, in θ's order.
        """
        names = [f"{link}.{p}" for link in self.links for p in BODY_PARAMETERS]
        names += [f"{j}.{p}" for p in JOINT_PARAMETERS for j in self.joints]
        return names

    def joint_slice(self, kind: str) -> slice:
        """Where a joint parameter (``rotor_inertia``, ``viscous``, ``coulomb``) sits in θ.

        Parameters
        ----------
        kind : str
            ``rotor_inertia``, ``viscous`` or ``coulomb``.

        Returns
        -------
        slice
            Its entries in θ.
        """
        k = JOINT_PARAMETERS.index(kind)
        start = 10 * len(self.links) + k * self.n
        return slice(start, start + self.n)


def load_structure(urdf: str | Path, base_frame: str, X_WB: RigidTransform | None = None,
                   payload_mass: float = 0.0, sensor_joint: str = "flange_sensor_weld"
                   ) -> ArmStructure:
    """Parse ``urdf`` into a single-arm plant and find its composite bodies.

    Parameters
    ----------
    urdf : path
        The arm's URDF.
    base_frame : str
        The frame welded to the world at ``X_WB`` (identity by default).
    payload_mass : float
        A payload (:func:`drake_coop.plant.model_error.add_payload`) welded to the flange; it
        joins the last link's composite.
    X_WB : RigidTransform or None
        The base frame's pose in the world; None for the identity.
    sensor_joint : str
        The force sensor's weld joint (the payload's place).

    Returns
    -------
    ArmStructure
        The arm's plant and composite bodies.
    """
    from drake_coop.plant.model_error import add_payload

    plant = MultibodyPlant(0.0)
    (instance,) = Parser(plant).AddModels(str(urdf))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame),
                     X_WB if X_WB is not None else RigidTransform())
    add_payload(plant, instance, payload_mass, sensor_joint)
    plant.Finalize()
    joints = [plant.get_joint(j) for j in plant.GetJointIndices(instance)
              if plant.get_joint(j).num_velocities() == 1]
    parent_joint = {}
    for j in plant.GetJointIndices(instance):
        joint = plant.get_joint(j)
        parent_joint[joint.child_body().name()] = joint
    links = [j.child_body().name() for j in joints]
    members = {}
    for b in plant.GetBodyIndices(instance):
        body = plant.get_body(b)
        name = body.name()
        root = name
        while root not in links and root in parent_joint:
            root = parent_joint[root].parent_body().name()
        if root in links:
            members.setdefault(root, []).append(name)
    for link in links:
        members[link].sort(key=lambda s: s != link)
    ratios = np.ones(len(joints))
    for a in plant.GetJointActuatorIndices(instance):
        actuator = plant.get_joint_actuator(a)
        k = [j.name() for j in joints].index(actuator.joint().name())
        ratios[k] = actuator.default_gear_ratio()
    return ArmStructure(plant=plant, links=links, members=members,
                        joints=[j.name() for j in joints], gear_ratios=ratios)


def true_parameters(structure: ArmStructure, plant: MultibodyPlant | None = None
                    ) -> np.ndarray:
    """The parameters ``θ`` of a plant's default inertias, rotors and damping.

    Each composite's ten parameters are Drake's ``CalcSpatialInertia`` of its member bodies
    about the link's origin. Coulomb friction is not a URDF property: zero here.

    Parameters
    ----------
    structure : ArmStructure
        The arm's parameter layout (its plant).
    plant : MultibodyPlant, optional
        Another finalized plant of the same arm (same body and joint names, e.g. the
        controller's :class:`~drake_coop.control.arm_model.ArmModel` plant); default the
        structure's own. Bodies it lacks (a payload) are skipped.
    """
    plant = structure.plant if plant is None else plant
    context = plant.CreateDefaultContext()
    theta = []
    for link in structure.links:
        body = plant.GetBodyByName(link)
        indices = [plant.GetBodyByName(b).index() for b in structure.members[link]
                   if plant.HasBodyNamed(b)]
        theta.append(theta_from_spatial_inertia(
            plant.CalcSpatialInertia(context, body.body_frame(), indices)))
    rotor = np.zeros(structure.n)
    for a in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(a)
        k = structure.joints.index(actuator.joint().name())
        rotor[k] = actuator.default_rotor_inertia() * actuator.default_gear_ratio() ** 2
    damping = np.array([plant.GetJointByName(j).default_damping() for j in structure.joints])
    return np.concatenate([*theta, rotor, damping, np.zeros(structure.n)])


class Regressor:
    """``Y(q, q̇, q̈)`` of one arm (module docstring), stacked over samples.

    Parameters
    ----------
    structure : ArmStructure
        The arm's parameter layout (its plant).
    coulomb_velocity : float
        ``sign(q̇)`` is smoothed as ``tanh(q̇ / v)`` with this ``v`` (rad/s) so that samples
        near rest do not flip the friction column on noise; a modelling choice of the
        identification (the simulated truth's own scale is not assumed known).
    """

    def __init__(self, structure: ArmStructure, coulomb_velocity: float = 0.02):
        self.structure = structure
        self.coulomb_velocity = float(coulomb_velocity)
        plant = structure.plant
        self._plant = plant
        self._context = plant.CreateDefaultContext()
        self._forces = MultibodyForces(plant)
        self._zero = spatial_inertia_from_theta(np.zeros(10))
        for a in plant.GetJointActuatorIndices():
            plant.get_joint_actuator(a).SetRotorInertia(self._context, 0.0)
        self._bodies = [plant.get_body(b) for b in plant.GetBodyIndices(
            plant.GetBodyByName(structure.links[0]).model_instance())]

    def _torques(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        plant, context = self._plant, self._context
        out = np.empty_like(q)
        for k in range(q.shape[0]):
            plant.SetPositions(context, q[k])
            plant.SetVelocities(context, v[k])
            out[k] = (plant.CalcInverseDynamics(context, a[k], self._forces)
                      - plant.CalcGravityGeneralizedForces(context))
        return out

    def matrix(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """The stacked regressor, shape ``(N n, p)``: rows sample-major (``k n + j``).

        Parameters
        ----------
        q, v, a : ndarray, shape (N, n)
            Positions, velocities and accelerations of the samples.

        Returns
        -------
        numpy.ndarray
            ``Y`` (N n, p).
        """
        q, v, a = (np.atleast_2d(np.asarray(x, float)) for x in (q, v, a))
        N, n = q.shape
        s = self.structure
        Y = np.zeros((N, n, s.num_parameters))
        for body in self._bodies:
            body.SetSpatialInertiaInBodyFrame(self._context, self._zero)
        theta0 = np.array([1.0, 0, 0, 0, 1.0, 1.0, 1.0, 0, 0, 0])
        for i, link in enumerate(s.links):
            body = self._plant.GetBodyByName(link)
            body.SetSpatialInertiaInBodyFrame(self._context, spatial_inertia_from_theta(theta0))
            base = self._torques(q, v, a)
            for k in range(10):
                e = theta0.copy()
                e[k] += 1.0
                body.SetSpatialInertiaInBodyFrame(self._context, spatial_inertia_from_theta(e))
                Y[:, :, 10 * i + k] = self._torques(q, v, a) - base
            body.SetSpatialInertiaInBodyFrame(self._context, self._zero)
        cols = np.arange(n)
        Y[:, cols, s.joint_slice("rotor_inertia").start + cols] = a
        Y[:, cols, s.joint_slice("viscous").start + cols] = v
        Y[:, cols, s.joint_slice("coulomb").start + cols] = np.tanh(v / self.coulomb_velocity)
        return Y.reshape(N * n, s.num_parameters)


#: A column of ``Y`` whose norm is below this fraction of the largest column's is round-off
#: (a parameter the torques do not see, computed as the difference of two equal torques:
#: 5.5e-15 N·m against columns of 11–10⁴ on the CRS arms): it is set to zero, not scaled up
#: to a unit column that the SVD would count as a direction.
COLUMN_RTOL = 1e-10
#: Singular values of the column-scaled ``Y`` below this fraction of the largest are zero.
RANK_RTOL = 1e-8


def column_scale(Y: np.ndarray, column_rtol: float = COLUMN_RTOL) -> np.ndarray:
    """The column norms of ``Y`` used to scale it, with round-off columns marked ``inf``.

    ``Y / column_scale(Y)`` has unit columns, and zero columns where ``Y``'s column is zero or
    below ``column_rtol`` times the largest column norm (see :data:`COLUMN_RTOL`); dividing a
    parameter vector by the scale gives 0 for those parameters.

    Parameters
    ----------
    Y : numpy.ndarray
        The regressor (N n, p).
    column_rtol : float
        The relative norm below which a column is round-off.
    """
    scale = np.linalg.norm(Y, axis=0)
    largest = float(scale.max()) if scale.size else 0.0
    scale = scale.copy()
    scale[scale <= column_rtol * largest] = np.inf
    return scale


def base_rank(singular_values: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """The numerical rank: singular values above ``rtol`` times the largest (relative).

    Parameters
    ----------
    singular_values : numpy.ndarray
        Decreasing singular values.
    rtol : float
        The relative tolerance.
    """
    sv = np.asarray(singular_values, dtype=float)
    if sv.size == 0 or sv[0] <= 0.0:
        return 0
    return int(np.sum(sv > rtol * sv[0]))


def identifiable_basis(Y: np.ndarray, rtol: float = RANK_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal bases of the identifiable parameter directions of ``Y``.

    Columns are scaled to unit norm first (so that units do not decide the rank); round-off
    columns are zeroed (:func:`column_scale`), and the rank is relative (:func:`base_rank`).

    Parameters
    ----------
    Y : numpy.ndarray
        The regressor (N n, p).
    rtol : float
        The relative rank tolerance.

    Returns
    -------
    (scale, V_id)
        ``scale`` the column norms (p,), 1 for zero and zeroed columns, ``V_id`` (p×r) the
        right singular vectors of the scaled ``Y`` with singular values above ``rtol`` times
        the largest: the directions of ``θ / scale`` that the torques determine (zero rows
        at the zeroed columns).
    """
    scale = column_scale(Y)
    _, sv, Vt = np.linalg.svd(Y / scale, full_matrices=False)
    r = base_rank(sv, rtol)
    return np.where(np.isinf(scale), 1.0, scale), Vt[:r].T


def condition_number(Y: np.ndarray, rtol: float = RANK_RTOL) -> tuple[float, int]:
    """The condition number of the column-scaled ``Y`` on its identifiable subspace, and its rank.

    ``σ_1 / σ_r`` with ``r`` the number of singular values above ``rtol σ_1`` (round-off
    columns zeroed first: :func:`column_scale`): the sensitivity of the identifiable
    combinations to torque errors (the criterion the excitation is chosen by).

    Parameters
    ----------
    Y : numpy.ndarray
        The regressor (N n, p).
    rtol : float
        The relative rank tolerance.
    """
    sv = np.linalg.svd(Y / column_scale(Y), compute_uv=False)
    r = base_rank(sv, rtol)
    if r == 0:
        return float("inf"), 0
    return float(sv[0] / sv[r - 1]), r
