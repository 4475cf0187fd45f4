"""The one shared object-state block (:class:`ObjectStateEstimator`, a LeafSystem): the arms'
mass shares combined into the object's total mass and centre of mass, and the squeeze chosen
online from them into every arm's ``λ_d``."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import (
    Context,
    DiscreteValues,
    InputPort,
    LeafSystem,
    OutputPort,
)

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object.grasp import grasp_matrix
from drake_coop.control.object.model import GRAVITY, ObjectModel
from drake_coop.control.params import check_period, check_positive


class ObjectStateEstimator(LeafSystem):
    r"""The one *shared* object-state block: the arms' local mass estimates combined into the
    object's total mass and centre of mass, and the squeeze chosen online from that load, fed
    to every arm's reference.

    The decentralized blocks (:class:`MassEstimator` per arm, the squeeze fixed before the
    run from the mass the controllers start from) exchange nothing. This block is the
    alternative that communicates: it reads every arm's share ``m̂_i`` (or the given shares)
    and gives

    .. math::
        \hat m = \sum_i \hat m_i, \qquad
        \hat c = \frac{\sum_i \hat m_i\, p_i}{\hat m}

    (``p_i`` the grasp points; for two opposing pads ``ĉ`` lies on the grasp line and is the
    centre of mass the lever rule of :func:`mass_shares` gives back the shares from: the
    line's only identifiable offset, from the vertical forces alone), and the squeeze

    .. math::
        \lambda^*_k = \texttt{squeeze\_for\_grasp}\big(G^+ w(\hat m, \hat c, a_d(t_k)),
            n, \mu, \mathrm{margin}\big), \qquad
        \lambda^0_k = \texttt{squeeze\_for\_grasp}(\dots, \mathrm{margin}=1)

    (:func:`load_distribution` of the estimated object along the desired acceleration
    ``a_d``: the least squeeze in every friction cone, times the margin, clipped to
    ``lambda_max``). While the object is held (every reference's ``held`` row) the squeeze
    is rate limited, falling slowly (``r_↓``) and rising fast (``r_↑``), and never below
    what holds the estimated load,

    .. math::
        \lambda_k = \max\Big(\lambda^0_k,\
            \min\big(\lambda_{k-1} + r_\uparrow h,\
            \max(\lambda_{k-1} - r_\downarrow h,\ \lambda^*_k)\big)\Big),

    and follows ``λ*`` freely otherwise (before the grasp: ``λ*`` of the shares the arms
    start from, their prior). The slow fall keeps the prior's squeeze while the stand still
    carries part of the object at the grasp (the shares then read less than the mass) and
    lowers it to what the converged estimate needs afterwards. Each arm's reference passes through with its
    ``λ_d`` rows replaced by ``s(t) λ_k w_i`` (``w_i`` its force weights), ``s(t)`` the
    grasp's envelope: ``clip(min(t − t_grasp, t_release − t)/ramp, 0, 1)``, the same linear
    ramps as the decentralized friction squeeze (``object_model.squeeze: friction``), so the
    squeeze never jumps. ``λ_k`` is state updated at ``t_k``: the arms' controllers, which
    latch ``τ(k)`` before the tick's discrete updates, read :math:`\lambda_{k-1}` (one tick of
    delay).

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
        """The port of arm ``i``'s share ``m̂_i`` (1,), kg.

        Parameters
        ----------
        i : int
            The arm's index.
        """
        return self._mass_in[i]

    def get_reference_input_port(self, i: int) -> InputPort:
        """The arm ``i``'s planned reference.

        Parameters
        ----------
        i : int
            The arm's index.
        """
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
        """The arm ``i``'s reference with the shared squeeze.

        Parameters
        ----------
        i : int
            The arm's index.
        """
        return self._ref_out[i]

    # ----------------------------------------------------------------- math
    def estimate(self, context: Context) -> tuple[float, np.ndarray]:
        """``(m̂, ĉ)`` from the shares at the current inputs: kg, and (3,), m, world frame.

        Parameters
        ----------
        context : Context
            This system's context.
        """
        shares = np.array([float(p.Eval(context)[0]) for p in self._mass_in])
        return self.combine(shares)

    def combine(self, shares) -> tuple[float, np.ndarray]:
        """``(m̂, ĉ)`` of given shares: ``Σ m̂_i`` and ``Σ m̂_i p_i / Σ m̂_i`` (the points'
        mean while the sum is not positive).

        Parameters
        ----------
        shares : array_like
            ``m̂_i`` (k,), kg.

        Returns
        -------
        m_hat : float
            ``m̂``, kg.
        c_hat : numpy.ndarray
            ``ĉ`` (3,), m, world frame.
        """
        shares = np.asarray(shares, dtype=float).reshape(-1)
        m = float(shares.sum())
        points = self._object.grasp_points
        if m <= 1e-9:
            return m, points.mean(axis=0)
        return m, shares @ points / m

    def target(self, shares, acceleration) -> tuple[float, float]:
        """``(λ*, λ⁰)``: the squeeze with the margin and the least one that holds the
        estimated load (margin 1), both at least ``lambda_min`` and clipped to
        ``lambda_max``.

        Parameters
        ----------
        shares : array_like
            ``m̂_i`` (k,), kg.
        acceleration : array_like
            The object's planned acceleration (3,), m/s², world frame.
        """
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
        r""":math:`\lambda_k` from :math:`\lambda_{k-1}` (the rate limit and the floor while
        held).

        Parameters
        ----------
        previous : float
            :math:`\lambda_{k-1}`, N.
        shares : array_like
            ``m̂_i`` (k,), kg.
        acceleration : array_like
            The object's planned acceleration (3,), m/s², world frame.
        held : bool
            Whether the object is held.
        """
        lam, hold = self.target(shares, acceleration)
        if not held:
            return lam
        return max(hold, min(previous + self._rise * self._h,
                             max(previous - self._rate * self._h, lam)))

    def envelope(self, t: float) -> float:
        """``s(t)``: the grasp's linear ramps.

        Parameters
        ----------
        t : float
            The time, s.

        Returns
        -------
        float
            ``s(t)`` in [0, 1].
        """
        t0, t1 = self._window
        return min(1.0, max(0.0, min(t - t0, t1 - t) / self._ramp))

    def reference(self, context: Context, i: int) -> np.ndarray:
        """The arm ``i``'s reference with ``λ_d,i = s(t) λ_k w_i``.

        Parameters
        ----------
        context : Context
            This system's context.
        i : int
            The arm's index.
        """
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
