r"""The one-period map of a sampled closed loop, its equilibrium and its monodromy matrix Φ.

A closed loop whose controllers tick every ``h`` and whose plant steps every ``Δt`` (``h = N Δt``)
is, between two ticks, a map of its whole state

.. math::
    x_{k+1} = F(x_k), \qquad x_k = x(t_k^-),

``x(t_k^-)`` the state at the tick time ``t_k`` *before* that tick's updates (what
``Simulator.AdvanceTo(t_k)`` leaves: Drake handles the events at ``t_k`` at the start of the
next step). ``F`` is evaluated with the Simulator itself, as a fresh simulation from ``x``:
restore the operating point's context (time, abstract state, parameters such as locked joints
and active constraints), write ``x``, ``Initialize()`` — which runs the initialization events,
so that abstract state derived from the state is recomputed from ``x`` (a discrete plant with
sampled output ports keeps its step results there) — and ``AdvanceTo(t_0 + h)``. At an equilibrium ``x* = F(x*)`` the loop is locally
asymptotically stable iff the spectral radius of the monodromy matrix ``Φ = ∂F/∂x (x*)`` is
below one.

Drake's ``Linearize`` cannot do this here (Python LeafSystems do not convert to AutoDiff; on
this diagram drake 1.51 aborts the process), so ``Φ`` comes from central differences,

.. math::
    \Phi_{:,j} \approx \frac{F(x^* + \varepsilon_j e_j) - F(x^* - \varepsilon_j e_j)}{2\varepsilon_j},

error ``O(ε²)`` from truncation plus ``O(η/ε)`` from the map's own noise ``η`` (rounding, the
plant's iterative contact solver). :func:`step_sensitivity` measures it by repeating the
computation at several ``ε``.

Which components take part (:class:`MapReport`):

* *counters* — entries that advance by exactly one per period whatever the state (tick indices
  latched by the sampled systems): functions of time, not of the loop; never perturbed.
* *locked* — positions/velocities of joints the plant holds locked
  (:meth:`~drake_coop.stability.state.LoopState.locked_indices`).
* *overwritten* — entries whose column of ``Φ`` is exactly zero: the next tick overwrites them
  before anything reads them (the torque latched for the previous interval, the older slot of a
  delay buffer). A zero column contributes an eigenvalue 0 and nothing else (expand
  ``det(μI − Φ)`` along it), so dropping them leaves ``ρ(Φ)`` unchanged.
* *dynamic* — the rest: ``Φ`` is reported on these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram

from drake_coop.stability.state import LoopState

__all__ = ["MapReport", "Mode", "PeriodMap", "analyse", "find_equilibrium", "jacobian",
           "modes", "step_sensitivity"]


class PeriodMap:
    """:math:`x_{k+1} = F(x_k)` over one control period ``h``, evaluated with the Simulator.

    Parameters
    ----------
    diagram : Diagram
        The closed loop.
    context : Context
        A root context of ``diagram`` at the operating point, its time a tick ``t_0``; it is
        cloned (time, state, abstract state and parameters restored before every evaluation).
    period : float
        The control period ``h``.
    """

    def __init__(self, diagram: Diagram, context: Context, period: float):
        self.diagram = diagram
        self.period = float(period)
        self.nominal = context.Clone()
        self.t0 = context.get_time()
        self.state = LoopState(diagram, context)
        self.simulator = Simulator(diagram, context.Clone())
        self.evaluations = 0

    @property
    def x0(self) -> np.ndarray:
        """The state of the operating point's context."""
        return self.state.get(self.nominal)

    def set_nominal_state(self, x: np.ndarray) -> None:
        """Make ``x`` the state of the operating point (e.g. the equilibrium found).

        Parameters
        ----------
        x : numpy.ndarray
            The loop's state vector.
        """
        self.state.set(self.nominal, x)

    def __call__(self, x: np.ndarray, periods: int = 1) -> np.ndarray:
        """``F^periods(x)``."""
        context = self.simulator.get_mutable_context()
        context.SetTimeStateAndParametersFrom(self.nominal)
        self.state.set(context, x)
        self.simulator.Initialize()
        self.simulator.AdvanceTo(self.t0 + periods * self.period)
        self.evaluations += 1
        return self.state.get(context)


@dataclass
class Mode:
    """One eigenvalue ``μ`` of ``Φ``: ``|μ|``, time constant ``−h/ln|μ|`` (s), frequency
    ``arg μ / (2π h)`` (Hz) and the state entries that dominate its eigenvector.

    Attributes
    ----------
    mu : complex
        ``μ``.
    magnitude : float
        ``|μ|``.
    time_constant : float
        ``−h/ln|μ|``, s.
    frequency_hz : float
        ``arg μ / (2π h)``, Hz.
    dominant : list of str
        The dominant state entries' labels.
    """

    mu: complex
    magnitude: float
    time_constant: float
    frequency_hz: float
    dominant: list[str]


@dataclass
class MapReport:
    """Φ at an operating point and what went into it.

    Attributes
    ----------
    rho : float
        ``ρ(Φ)``, the spectral radius (``inf`` when ``Φ`` is not finite).
    Phi : ndarray
        ``Φ`` on the dynamic entries.
    labels : list of str
        Every state entry's label.
    dynamic : list of int
        The entries ``Φ`` is taken over (neither counters, locked nor overwritten).
    counters : list of int
        Entries that count ticks (left out).
    locked : list of int
        Locked joints' entries (left out).
    overwritten : list of int
        Entries a period overwrites whatever their value (zero columns, left out).
    residual : float
        ``max |F(x) − x|`` over the dynamic entries at the point ``Φ`` is taken at.
    epsilon : float
        The central differences' step.
    evaluations : int
        Evaluations of the map so far.
    eigenvalues : ndarray
        The eigenvalues of ``Φ``.
    slowest, fastest : Mode, optional
        The modes of largest and smallest ``|μ|``.
    rho_check : float
        ``ρ`` again with the check step (NaN when not checked).
    epsilon_check : float
        That step (NaN when not checked).
    """

    rho: float
    Phi: np.ndarray
    labels: list[str]
    dynamic: list[int]
    counters: list[int]
    locked: list[int]
    overwritten: list[int]
    residual: float
    epsilon: float
    evaluations: int
    eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0))
    slowest: Mode | None = None
    fastest: Mode | None = None
    #: ρ(Φ) again with the check step :func:`check_step` (NaN when not checked).
    rho_check: float = math.nan
    epsilon_check: float = math.nan

    @property
    def step_agrees(self) -> bool:
        """ρ does not depend on the finite-difference step (the two steps agree to
        :data:`STEP_AGREEMENT`; True when no check ran)."""
        return math.isnan(self.epsilon_check) or _agree(self.rho, self.rho_check)

    def dynamic_labels(self) -> list[str]:
        """The labels of the dynamic entries (those Φ is taken on).
        """
        return [self.labels[i] for i in self.dynamic]


#: Steps of the central differences a user may choose. The free loop's ρ(Φ) does not depend on
#: them (1e-3 … 1e-6 agree to 1e-6; at 1e-16 rounding dominates: ρ = 1.11 for a loop whose ρ
#: is 0.896). The held loop's plateau starts higher: SAP, the plant's iterative solver, stops
#: at a relative tolerance of the constraint impulses, so a perturbation below ~1e-4 does not
#: always move its solution (a torque column of Φ is exactly 0 at ε = 1e-5 and 0.0048 at
#: 3e-5 … 3e-4); with a 4 ms delay ρ is 0.9995 at ε ≤ 1e-5, 1.0646 at 1e-4, 1.06359 at
#: 1e-3 … 1e-2 (``docs/stability.md``). Hence the default :data:`DEFAULT_EPSILON`.
EPSILON_RANGE = (1e-6, 1e-3)
#: The default step: on the plateau of both operating points (free: 1e-6 … 1e-3; held:
#: 1e-3 … 1e-2, ρ to ~1e-5).
DEFAULT_EPSILON = 1e-3
#: Largest ``|ρ_ε − ρ_check|`` (relative to ``max(1, ρ)``) accepted as agreement.
STEP_AGREEMENT = 1e-4


def _agree(rho: float, rho_check: float) -> bool:
    """``|ρ − ρ_check| <= STEP_AGREEMENT · max(1, |ρ|)``."""
    return abs(rho - rho_check) <= STEP_AGREEMENT * max(1.0, abs(rho))


def check_step(epsilon: float) -> float:
    """The second step :func:`analyse` computes ρ with: ``3 ε`` from ``ε = 3e-4`` up (the
    default 1e-3 is checked at 3e-3; when they disagree :func:`analyse` also tries ``ε/3`` and
    accepts ε if either neighbour agrees: ε then lies on a plateau — the delayed held loop's
    starts at 1e-3, the encoder-delayed held loop's ends there), else 1e-5, or 1e-4 when ``ε``
    is within a factor √10 of 1e-5.

    Parameters
    ----------
    epsilon : float
        The first step.
    """
    if epsilon >= 3e-4:
        return 3.0 * epsilon
    return 1e-4 if abs(math.log10(epsilon / 1e-5)) < 0.5 else 1e-5


def _counters(F: PeriodMap, x: np.ndarray, fx: np.ndarray) -> list[int]:
    """Entries that advance by exactly 1 per period and are whole numbers: tick counters."""
    return [i for i in range(len(x))
            if float(x[i]).is_integer() and fx[i] - x[i] == 1.0]


def jacobian(F: PeriodMap, x: np.ndarray, columns: list[int], epsilon: float | np.ndarray
             ) -> np.ndarray:
    """Central differences ``(F(x + ε e_j) − F(x − ε e_j)) / 2ε`` for ``j`` in ``columns``
    (full rows, shape ``(len(x), len(columns))``).

    Parameters
    ----------
    F : PeriodMap
        The map.
    x : numpy.ndarray
        The state.
    columns : list of int
        The entries to perturb.
    epsilon : float or numpy.ndarray
        The step, one or per entry.

    Returns
    -------
    numpy.ndarray
        The columns (len(x), len(columns)).
    """
    eps = np.broadcast_to(np.asarray(epsilon, dtype=float), (len(x),))
    J = np.zeros((len(x), len(columns)))
    for c, j in enumerate(columns):
        xp, xm = x.copy(), x.copy()
        xp[j] += eps[j]
        xm[j] -= eps[j]
        J[:, c] = (F(xp) - F(xm)) / (2.0 * eps[j])
    return J


def find_equilibrium(F: PeriodMap, x: np.ndarray, free: list[int], *, epsilon: float = 1e-5,
                     tol: float = 1e-10, max_iter: int = 8
                     ) -> tuple[np.ndarray, float, np.ndarray | None]:
    """Newton's method on ``F(x) − x = 0`` over the ``free`` entries (the others as given).

    The Jacobian ``Φ − I`` comes from :func:`jacobian` (recomputed each iteration: the map may
    be unstable, so settling by simulation is no option). Returns ``(x*, residual, Φ_free)``
    with ``residual = max |F(x*) − x*|`` over the free entries and the last Jacobian's
    free-by-free block (None if no iteration ran).

    Parameters
    ----------
    F : PeriodMap
        The map.
    x : numpy.ndarray
        The start.
    free : list of int
        The entries solved for.
    epsilon : float
        The central differences' step.
    tol : float
        The stopping residual.
    max_iter : int
        The largest number of iterations.

    Returns
    -------
    x_star : numpy.ndarray
        The equilibrium.
    residual : float
        ``max |F(x*) − x*|`` over the free entries.
    Phi_free : numpy.ndarray or None
        The last Jacobian's free block.
    """
    x = np.asarray(x, dtype=float).copy()
    free = list(free)
    Phi = None
    r = (F(x) - x)[free]
    for _ in range(max_iter):
        if np.max(np.abs(r), initial=0.0) <= tol:
            break
        Phi = jacobian(F, x, free, epsilon)[free, :]
        try:
            dx = np.linalg.solve(Phi - np.eye(len(free)), -r)
        except np.linalg.LinAlgError:
            dx = np.linalg.lstsq(Phi - np.eye(len(free)), -r, rcond=None)[0]
        x_new = x.copy()
        x_new[free] += dx
        r_new = (F(x_new) - x_new)[free]
        if not np.all(np.isfinite(r_new)) or np.max(np.abs(r_new)) >= np.max(np.abs(r)):
            break
        x, r = x_new, r_new
    return x, float(np.max(np.abs(r), initial=0.0)), Phi


def modes(Phi: np.ndarray, labels: list[str], period: float, top: int = 3
          ) -> tuple[np.ndarray, Mode | None, Mode | None]:
    """The eigenvalues of ``Φ`` (by decreasing ``|μ|``), its slowest mode (largest ``|μ|``) and its
    fastest (smallest nonzero ``|μ|``), each with the ``top`` dominant state entries.

    Parameters
    ----------
    Phi : numpy.ndarray
        Φ, square.
    labels : list of str
        Its entries' labels.
    period : float
        ``h``, s.
    top : int
        The dominant entries kept per mode.
    """
    if Phi.size == 0:
        return np.zeros(0), None, None
    mu, V = np.linalg.eig(Phi)
    order = np.argsort(-np.abs(mu))
    mu, V = mu[order], V[:, order]

    def mode(i: int) -> Mode:
        m = complex(mu[i])
        a = abs(m)
        tc = -period / math.log(a) if 0.0 < a < 1.0 else math.inf
        w = np.abs(V[:, i])
        lead = [labels[j] for j in np.argsort(-w)[:top]]
        return Mode(m, a, tc, abs(math.atan2(m.imag, m.real)) / (2 * math.pi * period), lead)

    nonzero = [i for i in range(len(mu)) if abs(mu[i]) > 1e-12]
    return mu, mode(0), mode(nonzero[-1]) if nonzero else None


def analyse(F: PeriodMap, x_guess: np.ndarray | None = None, *,
            epsilon: float = DEFAULT_EPSILON,
            newton: bool = True, tol: float = 1e-10, check: bool = True) -> MapReport:
    """The equilibrium, Φ on the dynamic entries, ρ(Φ) and the slowest and fastest modes.

    Order: counters (one evaluation), locked joints, then a first Jacobian at ``x_guess``
    names the overwritten entries (zero columns), Newton's method solves ``F(x) = x`` on the
    dynamic entries only (an overwritten entry, e.g. a sensor's latched reading of the stiff
    constraint force, would otherwise put its own sensitivity into the residual), and Φ is
    computed again at the equilibrium.

    Parameters
    ----------
    F : PeriodMap
        The map at the operating point.
    x_guess : ndarray, optional
        Start of the equilibrium search (default: the operating point's state).
    epsilon : float
        Step of the central differences (absolute, every entry: radians, rad/s, metres, N·s
        and N·m, all of order 0.1–1 at the operating points). Default
        :data:`DEFAULT_EPSILON` (1e-3): on the plateau of both points (free: 1e-3 … 1e-6
        agree to 1e-6; held: 1e-3 … 1e-2 agree to ~1e-5, while below 1e-4 the plant's
        iterative solver does not resolve a small perturbation of the held loop, see
        :data:`EPSILON_RANGE` and :func:`step_sensitivity`).
    newton : bool
        Solve ``F(x) = x`` first (else Φ is taken at ``x_guess``).
    tol : float
        Newton's stopping residual, ``max |F(x) − x|`` over the dynamic entries
        (:func:`find_equilibrium`).
    check : bool
        Compute ρ again with a second step (:func:`check_step`; from ``ε = 3e-4`` up, a third
        one, ``ε/3``, when the second disagrees) and report the agreeing one, or the second
        (``rho_check``; :attr:`MapReport.step_agrees`): a ρ that depends on the step is not
        the map's.
    """
    x = F.x0 if x_guess is None else np.asarray(x_guess, dtype=float).copy()
    fx = F(x)
    counters = _counters(F, x, fx)
    locked = F.state.locked_indices(F.nominal)
    candidates = [i for i in range(len(x)) if i not in set(counters) | set(locked)]
    J = jacobian(F, x, candidates, epsilon)
    overwritten = [j for c, j in enumerate(candidates) if not np.any(J[:, c])]
    dynamic = [j for j in candidates if j not in set(overwritten)]
    if newton:
        x, residual, _ = find_equilibrium(F, x, dynamic, epsilon=epsilon, tol=tol)
        F.set_nominal_state(x)
        J = jacobian(F, x, candidates, epsilon)
    else:
        residual = float(np.max(np.abs((fx - x)[dynamic]), initial=0.0))
    cols = [candidates.index(j) for j in dynamic]
    Phi = J[np.ix_(dynamic, cols)]
    labels = F.state.labels
    if not np.all(np.isfinite(Phi)):
        return MapReport(rho=math.inf, Phi=Phi, labels=labels, dynamic=dynamic,
                         counters=counters, locked=locked, overwritten=overwritten,
                         residual=residual, epsilon=epsilon, evaluations=F.evaluations)
    mu, slow, fast = modes(Phi, [labels[j] for j in dynamic], F.period)
    rho = float(np.max(np.abs(mu))) if len(mu) else 0.0
    rho_check = epsilon_check = math.nan

    def rho_at(step: float) -> float:
        J_check = jacobian(F, x, dynamic, step)[dynamic, :]
        return (float(np.max(np.abs(np.linalg.eigvals(J_check))))
                if np.all(np.isfinite(J_check)) else math.inf)

    if check and dynamic:
        epsilon_check = check_step(epsilon)
        rho_check = rho_at(epsilon_check)
        if epsilon >= 3e-4 and not _agree(rho, rho_check):
            # ε is on a plateau if either neighbour agrees: the delayed held loop's plateau
            # starts at 1e-3, the encoder-delayed held loop's ends there.
            below = rho_at(epsilon / 3.0)
            if _agree(rho, below):
                rho_check, epsilon_check = below, epsilon / 3.0
    return MapReport(rho=rho, Phi=Phi, labels=labels, dynamic=dynamic, counters=counters,
                     locked=locked, overwritten=overwritten, residual=residual,
                     epsilon=epsilon, evaluations=F.evaluations, eigenvalues=mu,
                     slowest=slow, fastest=fast, rho_check=rho_check,
                     epsilon_check=epsilon_check)


def step_sensitivity(F: PeriodMap, x: np.ndarray, dynamic: list[int],
                     epsilons=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8)) -> list[tuple[float, float, float]]:
    """``(ε, ρ(Φ_ε), max|Φ_ε − Φ_ref|)`` for each ``ε``, ``Φ_ref`` the first ``ε``'s.

    Parameters
    ----------
    F : PeriodMap
        The map.
    x : numpy.ndarray
        The state.
    dynamic : list of int
        The dynamic entries.
    epsilons : sequence of float
        The steps.

    Returns
    -------
    list of tuple
        ``(ε, ρ, max|Φ_ε − Φ_ref|)`` per step.
    """
    out = []
    ref = None
    for eps in epsilons:
        J = jacobian(F, x, dynamic, eps)[dynamic, :]
        if ref is None:
            ref = J
        rho = float(np.max(np.abs(np.linalg.eigvals(J)))) if J.size else 0.0
        out.append((float(eps), rho, float(np.max(np.abs(J - ref)))))
    return out
