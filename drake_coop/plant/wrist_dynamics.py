r"""Every arm's ground-truth wrist force from the arm's own equations of motion, one plant step
at a time: the ``planes`` and ``rigid`` modes, where the object's pull on the end-effector
point is the only external force on an arm.

:class:`ArmForces` is the equation (SAP's momentum balance of the step, the joints' damping
taken implicitly, solved for the force ``F`` through the end-effector point's Jacobian);
:class:`WristDynamics` is the system that serves it live, once for all arms, and latches it at
every tick. The offline ground truth (:mod:`drake_coop.plant.ground_truth`) evaluates
:class:`ArmForces` after the run instead when no controller reads the F/T sensor. How the
force is wired to each arm's sensor and when it is read: :mod:`drake_coop.plant.wrist`.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces
from pydrake.systems.framework import Context, LeafSystem, ValueProducer

from drake_coop.plant.cooperative import ArmHandles


class ArmForces:
    r"""The equation of :class:`WristDynamics` without a system: every arm's wrist force ``F``
    of one plant step, from the step's start state, acceleration and actuation.

    .. math::
        J_x(q_j)^T F = M(q_j)\,a + C(q_j, v_j) v_j - \tau_g(q_j) + D (v_j + \Delta t\, a)
                       - B u

    (SAP's momentum balance with the joints' damping taken implicitly; ``J_x`` the
    translational Jacobian of the end-effector point, columns of the arm's joints). The
    right-hand side is one inverse-dynamics call on a private context of the plant; ``F``
    solves the arm's rows (``n = 3``: square; ``n > 3``: least squares, exact for a full-rank
    ``J_x``). The live :class:`WristDynamics` calls it once per step it serves; the offline
    ground truth (:class:`~drake_coop.plant.ground_truth.GroundTruthLog`) calls
    :meth:`steps` once for all the steps of a run, from held plant data.

    Parameters
    ----------
    plant : MultibodyPlant
        The finalized plant (a private context is made from it).
    arms : list of ArmHandles
        The arms, in order.
    time_step : float
        The plant's step ``Δt`` (s).
    """

    def __init__(self, plant: MultibodyPlant, arms: list[ArmHandles], time_step: float):
        self._plant = plant
        self._context = plant.CreateDefaultContext()
        self._forces = MultibodyForces(plant)
        self.dt = float(time_step)
        nv = plant.num_velocities()
        #: Sizes of the plant's state ``[q, v]`` and of its actuation ``u``.
        self.nq, self.nx, self.nu = (plant.num_positions(), plant.num_multibody_states(),
                                     plant.num_actuators())
        self._B = plant.MakeActuationMatrix()
        damping = np.zeros(nv)
        for j in plant.GetJointIndices():
            joint = plant.get_joint(j)
            if joint.num_velocities() > 0:
                damping[joint.velocity_start():joint.velocity_start() + joint.num_velocities()] \
                    = joint.default_damping_vector()
        self._damping_dt = damping * self.dt
        self._arms = []
        for h in arms:
            columns = plant.GetVelocitiesFromArray(h.instance,
                                                   np.arange(nv, dtype=float)).astype(int)
            self._arms.append((h.ee_body.body_frame(), columns))
        #: Each arm's outward normals ``N_i`` (rows): ``λ_i = N_i F_i``.
        self.normals = [np.asarray(h.arm.N, dtype=float) for h in arms]

    def _rows(self, x: np.ndarray, a: np.ndarray, u: np.ndarray
              ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Every arm's ``(J_x, b)`` of ``J_xᵀ F = b`` for one step."""
        plant, pc = self._plant, self._context
        plant.SetPositionsAndVelocities(pc, x)
        plant.CalcForceElementsContribution(pc, self._forces)
        generalized = (plant.CalcInverseDynamics(pc, a, self._forces) + self._damping_dt * a
                       - self._B @ u)
        world = plant.world_frame()
        return [(plant.CalcJacobianTranslationalVelocity(
                    pc, JacobianWrtVariable.kV, frame, np.zeros(3), world, world)[:, columns],
                 generalized[columns]) for frame, columns in self._arms]

    def __call__(self, x: np.ndarray, a: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
        """``F`` of every arm for the step from the plant state ``x`` with acceleration ``a``
        under the actuation ``u``."""
        out = []
        for J, b in self._rows(x, a, u):
            if J.shape[1] == 3:
                out.append(_solve_transposed3(J.tolist(), b.tolist()))
            else:
                out.append(np.linalg.lstsq(J.T, b, rcond=None)[0])
        return out

    def steps(self, x: np.ndarray, a: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
        r"""``F`` of every arm for ``K`` plant steps at once: step ``i`` starts at ``x[i]``
        (plant state ``[q, v]``) with the acceleration ``a[i]`` (the plant's
        generalized-acceleration port, :math:`(v_{j+1} - v_j)/\Delta t`) under ``u[i]``.

        Returns one ``(K, 3)`` array per arm; the square solves are batched (NumPy's LU), the
        plant's calls are one inverse dynamics and one Jacobian per arm and step.

        Parameters
        ----------
        x : numpy.ndarray
            Plant states ``[q, v]`` (K, n_x).
        a : numpy.ndarray
            Generalized accelerations (K, n_v).
        u : numpy.ndarray
            Actuation (K, n_u), N·m.

        Returns
        -------
        list of numpy.ndarray
            Per arm ``F`` (K, 3), N, palm frame.
        """
        x = np.asarray(x, dtype=float).reshape(-1, self.nx)
        a = np.asarray(a, dtype=float).reshape(-1, self.nx - self.nq)
        u = np.asarray(u, dtype=float).reshape(-1, self.nu)
        K = x.shape[0]
        plant, pc, forces = self._plant, self._context, self._forces
        world = plant.world_frame()
        origin = np.zeros(3)
        inverse = np.empty_like(a)
        jacobians = [np.empty((K, 3, a.shape[1])) for _ in self._arms]
        for i in range(K):           # the plant's calls only; the rest is vectorized below
            plant.SetPositionsAndVelocities(pc, x[i])
            plant.CalcForceElementsContribution(pc, forces)
            inverse[i] = plant.CalcInverseDynamics(pc, a[i], forces)
            for J, (frame, _) in zip(jacobians, self._arms):
                J[i] = plant.CalcJacobianTranslationalVelocity(
                    pc, JacobianWrtVariable.kV, frame, origin, world, world)
        generalized = inverse + self._damping_dt * a - np.einsum("kj,ij->ki", u, self._B)
        out = []
        for J, (_, columns) in zip(jacobians, self._arms):
            Jt = np.transpose(J[:, :, columns], (0, 2, 1))                   # (K, n, 3)
            rhs = generalized[:, columns]                                     # (K, n)
            if K == 0:
                out.append(np.zeros((0, 3)))
            elif Jt.shape[1] == 3:
                out.append(np.linalg.solve(Jt, rhs[:, :, None])[:, :, 0])
            else:
                out.append(np.einsum("kij,kj->ki", np.linalg.pinv(Jt), rhs))
        return out


class WristDynamics(LeafSystem):
    r"""Every arm's ground-truth wrist force from the arm's own equations of motion, for the
    modes where the object's pull on the end-effector point is the only external force on an
    arm (``planes``, ``rigid``: a ball constraint at the end-effector body's origin).

    For the plant step from ``(q_j, v_j)`` to :math:`v_{j+1} = v_j + \Delta t\, a` under the
    actuation ``u``, SAP's momentum balance with the joints' damping taken implicitly is

    .. math::
        J_x(q_j)^T F = M(q_j)\,a + C(q_j, v_j) v_j - \tau_g(q_j) + D (v_j + \Delta t\, a)
                       - B u,

    ``J_x`` the translational Jacobian of the end-effector point (columns of the arm's
    joints), ``B`` the actuation matrix. The right-hand side is one inverse-dynamics call on a
    private context of the plant (force elements: gravity and ``D v_j``) plus ``D Δt a − B u``.
    ``F`` solves the arm's rows (``n = 3``: square; ``n > 3``: least squares, exact for a
    full-rank ``J_x``). No reaction forces and no per-body lists cross into Python. The
    equation is :class:`ArmForces`, which the offline ground truth
    (:mod:`drake_coop.plant.ground_truth`) evaluates after the run instead of this system when
    no controller reads the F/T sensor.

    Two steps are served, each from quantities the plant computes anyway:

    * ``<robot>_wrist``, the step that starts at the context's state (the step the plant takes
      at that time): ``a`` is the plant's generalized-acceleration port, which reuses the
      solve of the plant's own update when read at the same time (the latch at a tick);
    * with a control ``period`` of at least two plant steps, ``<robot>_lambda_last_step``,
      ``N_i F`` of the step that *ended* at the context's state: ``(q_j, v_j, u)`` held by a
      C++ hold at ``t_k − 3Δt/2`` (input ``held``, see
      :func:`~drake_coop.plant.wrist.add_force_sensors`) and
      :math:`a = (v_{j+1} - v_j)/\Delta t` from the live state (the acceleration port's own
      formula, bit for bit). Read in ``(t_k − Δt, t_k]`` it is the step ``[t_k − Δt, t_k)``:
      the F/T sensor model's reading of tick ``k``. The plant's solve is not repeated: reading
      the acceleration port between two plant updates would solve that step a second time
      (a change of time invalidates the solve; measured in ``docs/benchmark.md``).

    Parameters
    ----------
    plant : MultibodyPlant
        The finalized plant.
    arms : list of ArmHandles
        The arms.
    time_step : float
        The plant's step ``Δt``, s.
    period : float or None
        The control period ``h``, s; None for no latched outputs.

    Input ports
    -----------
    state, generalized_acceleration, net_actuation
        The plant's ports of the same names (``net_actuation`` per actuator).
    held : (n_x + n_u)-vector, with a ``period``
        ``[state, net_actuation]`` held at ``t_k − 3Δt/2``.

    Output ports
    ------------
    <robot>_wrist : 3-vector, one per arm
        ``F``, the force of the object on the end effector (palm frame), of the step from the
        context's state.
    <robot>_F_step, <robot>_lambda_step : 3- and m-vectors, one per arm, with a ``period``
        ``F`` and ``N_i F`` of the step taken from the last tick, latched at that tick by one
        discrete update for all arms (state only: see :mod:`drake_coop.plant.wrist`).
    <robot>_lambda_last_step : m-vector, one per arm, with a ``period`` of at least two plant
        steps
        ``N_i F`` of the step that ended at the context's state.
    """

    def __init__(self, plant: MultibodyPlant, arms: list[ArmHandles], time_step: float,
                 period: float | None = None):
        super().__init__()
        self._equation = ArmForces(plant, arms, time_step)
        self._dt = float(time_step)
        nv = plant.num_velocities()
        self._nq = plant.num_positions()
        self._nx = plant.num_multibody_states()
        self._normals = self._equation.normals
        self._state = self.DeclareVectorInputPort("state", self._nx)
        self._acceleration = self.DeclareVectorInputPort("generalized_acceleration", nv)
        self._actuation = self.DeclareVectorInputPort("net_actuation", plant.num_actuators())
        self._signals = self.DeclareCacheEntry(
            "wrist forces of every arm",
            ValueProducer(allocate=AbstractValue.Make([np.zeros(0)]).Clone,
                          calc=self._calc_signals),
            {self._state.ticket(), self._acceleration.ticket(), self._actuation.ticket()})
        for i, h in enumerate(arms):
            self.DeclareVectorOutputPort(
                f"{h.arm.name}_wrist", 3,
                lambda context, output, i=i: output.SetFromVector(
                    self._signals.Eval(context)[i]),
                prerequisites_of_calc={self._signals.ticket()})
        self._latched = []
        if period is not None:
            for h in arms:
                F = self.DeclareDiscreteState(3)
                lam = self.DeclareDiscreteState(h.arm.m)
                self._latched.append((F, lam))
                self.DeclareStateOutputPort(f"{h.arm.name}_F_step", F)
                self.DeclareStateOutputPort(f"{h.arm.name}_lambda_step", lam)
            self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_step)
        self._held = None
        if period is not None and _holds_last_step(period, time_step):
            self._held = self.DeclareVectorInputPort("held", self._nx + plant.num_actuators())
            self._last = self.DeclareCacheEntry(
                "squeeze of the last step of every arm",
                ValueProducer(allocate=AbstractValue.Make([np.zeros(0)]).Clone,
                              calc=self._calc_last_step),
                {self._state.ticket(), self._held.ticket()})
            for i, h in enumerate(arms):
                self.DeclareVectorOutputPort(
                    f"{h.arm.name}_lambda_last_step", h.arm.m,
                    lambda context, output, i=i: output.SetFromVector(
                        self._last.Eval(context)[i]),
                    prerequisites_of_calc={self._last.ticket()})

    def _arm_forces(self, x: np.ndarray, a: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
        """``F`` of every arm for the step from ``x`` with acceleration ``a`` under ``u``
        (:class:`ArmForces`)."""
        return self._equation(x, a, u)

    def _calc_signals(self, context: Context, value: AbstractValue) -> None:
        value.set_value(self._arm_forces(self._state.Eval(context),
                                         self._acceleration.Eval(context),
                                         self._actuation.Eval(context)))

    def _update_step(self, context: Context, discrete_state) -> None:
        """Latch every arm's ``F`` and ``N_i F`` of the step the plant takes from this tick
        (same context as the plant's update: its solve is shared)."""
        forces = self._arm_forces(self._state.Eval(context), self._acceleration.Eval(context),
                                  self._actuation.Eval(context))     # no cache: one call less
        for (F_index, lam_index), N, F in zip(self._latched, self._normals, forces):
            discrete_state.set_value(F_index, F)
            discrete_state.set_value(lam_index, N @ F)

    def _calc_last_step(self, context: Context, value: AbstractValue) -> None:
        held = self._held.Eval(context)
        x, u = held[:self._nx], held[self._nx:]
        a = (self._state.Eval(context)[self._nq:] - x[self._nq:]) / self._dt
        value.set_value([N @ F for N, F in zip(self._normals, self._arm_forces(x, a, u))])


def _solve_transposed3(J: list[list[float]], b: list[float]) -> np.ndarray:
    """``F`` with ``Jᵀ F = b`` for a 3×3 ``J`` (rows), by the adjugate on plain floats.

    With ``c_i`` the columns of ``J`` (the rows of ``Jᵀ``),
    ``F = (b_0 (c_1 × c_2) + b_1 (c_2 × c_0) + b_2 (c_0 × c_1)) / (c_0 · (c_1 × c_2))``.
    ``np.linalg.solve`` costs ~5 µs on a 3×3 (call overhead); this costs ~1 µs.
    """
    (a0, a1, a2), (b0, b1, b2), (e0, e1, e2) = J        # rows x, y, z; columns c_0, c_1, c_2
    # c_0 = (a0, b0, e0), c_1 = (a1, b1, e1), c_2 = (a2, b2, e2)
    x12 = (b1 * e2 - e1 * b2, e1 * a2 - a1 * e2, a1 * b2 - b1 * a2)      # c_1 × c_2
    x20 = (b2 * e0 - e2 * b0, e2 * a0 - a2 * e0, a2 * b0 - b2 * a0)      # c_2 × c_0
    x01 = (b0 * e1 - e0 * b1, e0 * a1 - a0 * e1, a0 * b1 - b0 * a1)      # c_0 × c_1
    det = a0 * x12[0] + b0 * x12[1] + e0 * x12[2]
    g0, g1, g2 = b
    return np.array([(g0 * x12[i] + g1 * x20[i] + g2 * x01[i]) / det for i in range(3)])


def _holds_last_step(period: float, time_step: float) -> bool:
    """Whether a plant update lies between two ticks (``h ≥ 2Δt``): then the step before a
    tick is read from a state held at ``t_k − 3Δt/2`` (:class:`WristDynamics`)."""
    return int(round(period / time_step)) >= 2
