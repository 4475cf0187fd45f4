"""Gains for an arm: derived from its controller model at the task's postures with the
sampled-loop rules, then checked with the one-period map (``drake-coop gains``).

The rules (``h`` the control period; numbers from :doc:`/stability` and the gains page):

``K_R`` (per joint)
    The sampled velocity loop of joint ``j`` alone is stable while ``h K_R,j / J_j < 2``
    (single-joint estimate; the full map is less strict: the paper's ``K_R = 150`` is stable).
    ``J_j = min_q 1/(H(q)⁻¹)_jj`` is the smallest inertia joint ``j`` sees, the other joints
    free, over the task's postures ``q`` (home, the free path and the held path every
    :data:`POSTURE_STEP` s). ``K_R,j = κ J_j / h`` with ``κ = KAPPA`` (half the bound; the
    paper's gains have ``h K_R / J_j`` = 0.69–1.71).
``Λ``, ``k_d``
    The paper's shape ``k_d / Λ = 40/35``, ``Λ ≤ 35`` 1/s and ``Λ ≤ κ / (3 h)`` (the position
    loop three times slower than the velocity loop ``K_R / J = κ / h``), and the observer's
    forward-Euler limit with margin: ``h p_f ≤ σ = SIGMA`` (half of ``2/p_f > h``), ``p_f`` the
    fast pole of (15)–(16) (:func:`~drake_coop.stability.one_joint.observer_period_limit`).
``ξ``
    The force integral's gain through the motion, ``g = ξ J⁺ᵀ K_R J⁺`` (1/s at the grasp
    posture; for ``m > 1`` the mean eigenvalue of the ``m × m`` matrix), set to
    :data:`FORCE_LOOP_GAIN` (the paper's arms: 0.026 and 0.013), so ``ξ`` follows the arm's
    ``K_R`` and geometry.
``k_F``, ``ζ``, ``β``
    The paper's 0.05, 0.001 (dimensionless) and our 10 1/s.
``momentum_gain``
    ``K_O = min(50, 0.5/h)``: ``h K_O ≤ 1/2``, half the momentum observer's Euler limit.

The check: ρ of the one-period map (:func:`~drake_coop.stability.period_map.analyse`) at the
``free`` and ``held`` operating points is below 1 at the derived gains **and** with every
``K_R`` multiplied by :data:`GAIN_MARGIN` (a stated gain margin). When it fails, ``κ`` is
scaled by :data:`BACKOFF` and the derivation repeated (at most :data:`MAX_ATTEMPTS` times).
At gains that pass, the task is checked (:mod:`drake_coop.stability.task_check`: the map at
postures along the lift and the circle, the torque limits along the path, and in ``contact``
mode the grasp's own dynamics, :mod:`drake_coop.stability.grasp_dynamics`); a failing
map backs ``κ`` off, a failing torque or grasp check refuses with its one line.
A scenario in ``contact`` mode is checked on its ``planes`` copy (the map does not take a
floating box), and a scenario with an object model on a copy without it
(:func:`~drake_coop.stability.task_check.map_copy`).
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from drake_coop.control.params import Gains
from drake_coop.scenario.schema import Scenario
from drake_coop.stability.task_check import map_copy

__all__ = ["DerivedGains", "GainsReport", "check_gains_map", "derive_and_check", "derive_gains",
           "map_failure_reason",
           "derive_robot_gains", "gains_for_scenario", "task_postures"]

#: Target ``h K_R,j / J_j`` (half the single-joint bound 2).
KAPPA = 1.0
#: Target ``h p_f`` of the velocity observer (half its forward-Euler bound 2).
SIGMA = 1.0
#: The paper's ``Λ`` and ``k_d`` (robot 1), the shape and cap of the derived ones (1/s).
LAMBDA_PAPER, K_D_PAPER = 35.0, 40.0
#: The force integral's loop gain ``ξ J⁺ᵀ K_R J⁺`` (1/s).
FORCE_LOOP_GAIN = 0.02
#: Seconds between two postures of the task at which ``H`` is evaluated.
POSTURE_STEP = 0.5
#: ``K_R`` factor at which ρ must still be below 1 (the stated margin).
GAIN_MARGIN = 1.25
#: Factor on ``κ`` after a failed check, and the number of attempts.
BACKOFF = 0.7
MAX_ATTEMPTS = 4


@dataclass
class DerivedGains:
    """One robot's derived gains and what they were derived from.

    Attributes
    ----------
    name : str
        The robot's name.
    gains : Gains
        The derived gains.
    inertia : list of float
        ``J_j``, each joint's least effective inertia over the postures, kg·m² (kg for a
        prismatic joint).
    kappa : float
        ``κ`` of ``K_R,j = κ J_j / h`` (dimensionless) the gains were derived with.
    observer_h_pf : float
        ``h p_f`` of the observer's fast pole (stable below 2).
    postures : int
        The number of postures the inertia was taken over.
    """

    name: str
    gains: Gains
    inertia: list[float]          # J_j, kg·m² (or kg for a prismatic joint)
    kappa: float
    observer_h_pf: float
    postures: int


@dataclass
class GainsReport:
    """The derived gains of every robot and the map's check.

    Attributes
    ----------
    robots : list of DerivedGains
        One per robot.
    rho : dict of str to float
        ρ of the map per check (``free``, ``held``, ``free_margin``, …).
    attempts : int
        The attempts made (``κ`` backed off after each failure).
    stable : bool
        Whether every check gave ρ < 1.
    checked_on : str
        The object mode the map was computed in.
    messages : list of str
        What each attempt found.
    task : TaskReport or None
        The task's checks at the last gains that passed the map
        (:func:`~drake_coop.stability.task_check.check_task`); None when none did.
    refusal : str
        Why no gains are given ('' when ``stable``): the failing check's one line.
    """

    robots: list[DerivedGains]
    rho: dict[str, float] = field(default_factory=dict)     # "free", "held", "free_margin", …
    attempts: int = 1
    stable: bool = False
    checked_on: str = "planes"
    messages: list[str] = field(default_factory=list)
    task: object = None
    refusal: str = ""


def task_postures(robot, step: float = POSTURE_STEP) -> tuple[np.ndarray, np.ndarray]:
    """The joint reference ``q_d`` of one robot every ``step`` seconds of its run (home, free
    path, held path), and the first held posture (the grasp).

    Parameters
    ----------
    robot : RobotPlan
        The robot's plan (:attr:`~drake_coop.experiment.plan.RobotPlan.samples`, its
        references to the run's end: the whole task with a plan of the whole task).
    step : float
        The sampling of the task, s.

    Returns
    -------
    postures : numpy.ndarray
        ``q_d`` (K, n), rad.
    grasp : numpy.ndarray
        The grasp posture (n,), rad.
    """
    _, samples = robot.samples
    q = robot.layout.column(samples, "q_d")
    held = robot.layout.column(samples, "held")[:, 0] > 0.5
    stride = max(1, int(round(step / robot.run.h)))
    grasp = q[int(np.argmax(held))] if held.any() else q[0]
    return q[::stride].copy(), grasp.copy()


def _observer_gains(h: float, kappa: float) -> tuple[float, float, float]:
    """``Λ``, ``k_d`` and ``h p_f`` by the rules of the module docstring."""
    from drake_coop.stability.one_joint import observer_period_limit

    Lambda = min(LAMBDA_PAPER, kappa / (3.0 * h))
    k_d = K_D_PAPER / LAMBDA_PAPER * Lambda
    h_pf = 2.0 * h / observer_period_limit(Lambda, k_d)
    if h_pf > SIGMA:
        Lambda, k_d = Lambda * SIGMA / h_pf, k_d * SIGMA / h_pf
        h_pf = 2.0 * h / observer_period_limit(Lambda, k_d)
    return Lambda, k_d, h_pf


def derive_robot_gains(model, postures: np.ndarray, grasp: np.ndarray, h: float,
                       kappa: float = KAPPA, name: str = "robot") -> DerivedGains:
    """One robot's gains from its controller model (an
    :class:`~drake_coop.control.arm_model.ArmModel`) at ``postures`` (rows of ``q``), the
    grasp posture and the control period ``h`` (module docstring).

    Parameters
    ----------
    model : ArmModel
        The controller's model of the arm.
    postures : numpy.ndarray
        The task's postures (K, n), rad.
    grasp : numpy.ndarray
        The grasp posture (n,), rad.
    h : float
        The control period, s.
    kappa : float
        ``κ``, the fraction of the sampling limit.
    name : str
        The robot's name.
    """
    inv_diag = np.array([np.diag(np.linalg.inv(model.H(q))) for q in postures])
    inertia = 1.0 / inv_diag.max(axis=0)           # min over postures of 1/(H⁻¹)_jj
    K_R = kappa * inertia / h
    Lambda, k_d, h_pf = _observer_gains(h, kappa)
    J = model.J_phi(grasp)
    J_pinv = np.linalg.pinv(J)
    G = J_pinv.T @ np.diag(K_R) @ J_pinv
    g = float(np.mean(np.linalg.eigvalsh(0.5 * (G + G.T))))
    xi = FORCE_LOOP_GAIN / g
    gains = Gains(Lambda=float(Lambda), K_R=[float(k) for k in K_R], k_d=float(k_d),
                  k_F=0.05, xi=float(xi), zeta=1e-3, beta=10.0,
                  momentum_gain=float(min(50.0, 0.5 / h)))
    return DerivedGains(name, gains, inertia.tolist(), kappa, h_pf, len(postures))


def gains_for_scenario(scenario: Scenario, derived: list[DerivedGains], K_R_factor: float = 1.0
                       ) -> Scenario:
    """A copy of ``scenario`` with each robot's gains replaced by the derived ones (``K_R``
    times ``K_R_factor``); a ``xi_matrix`` is dropped (the derived ``ξ`` is scalar).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    derived : list of DerivedGains
        One per robot.
    K_R_factor : float
        The factor on ``K_R`` (the margin check uses :data:`GAIN_MARGIN`).
    """
    s = copy.deepcopy(scenario)
    for robot, d in zip(s.robots, derived):
        g = copy.deepcopy(d.gains)
        g.K_R = [k * K_R_factor for k in g.K_R]
        robot.gains = g
    return s


def derive_gains(scenario: Scenario, kappa: float = KAPPA,
                 progress: Callable[[str], None] = lambda m: None) -> list[DerivedGains]:
    """Every robot's gains (:func:`derive_robot_gains`) at its task's postures.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    kappa : float
        ``κ``.
    progress : Callable[[str], None]
        Receives one line per step.
    """
    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.arms import arm_model

    plan = plan_run(scenario)
    out = []
    for i, robot in enumerate(scenario.robots):
        postures, grasp = task_postures(plan.robots[i])
        d = derive_robot_gains(arm_model(plan.arms[i]), postures, grasp, plan.h, kappa,
                               robot.name)
        progress(f"{robot.name}: n={len(d.gains.K_R)}, {d.postures} postures, "
                 f"J_j min {min(d.inertia):.3g}, K_R {np.round(d.gains.K_R, 1).tolist()}, "
                 f"Lambda {d.gains.Lambda:.3g}, k_d {d.gains.k_d:.3g}, xi {d.gains.xi:.3g}")
        out.append(d)
    return out


def check_gains_map(scenario: Scenario, epsilon: float = 1e-5,
                    progress: Callable[[str], None] = lambda m: None,
                    why: dict | None = None) -> dict[str, float]:
    """ρ of the one-period map of ``scenario`` at the free and held operating points.

    Parameters
    ----------
    scenario : Scenario
        The scenario with the gains to check.
    epsilon : float
        The central differences' step.
    progress : Callable[[str], None]
        Receives one line per step.
    why : dict or None
        When given, receives per operating point whose ρ is not below 1 one phrase saying
        why (:func:`map_failure_reason`).

    Returns
    -------
    dict of str to float
        ρ per operating point (``inf`` where the map's equilibrium was not found).
    """
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse

    rho = {}
    for point in ("free", "held"):
        start = time.perf_counter()
        report = analyse(operating_point(scenario, point).map, epsilon=epsilon)
        rho[point] = float(report.rho) if report.residual <= 1e-6 else math.inf
        if why is not None and rho[point] >= 1.0:
            why[point] = map_failure_reason(report)
        progress(f"  {point}: rho = {rho[point]:.6g} ({time.perf_counter() - start:.1f} s)")
    return rho


def map_failure_reason(report) -> str:
    """Why a map's ρ is not below 1, in one phrase: its equilibrium not found (Newton's
    residual), or its slowest mode (its eigenvalue and the state entries it lives in).

    Parameters
    ----------
    report : MapReport
        :func:`~drake_coop.stability.period_map.analyse`'s report.

    Returns
    -------
    str
        E.g. ``slowest mode mu = 2.36 (real: diverges without oscillating) in
        so101_2::wrist_roll_w, ...``.
    """
    if report.residual > 1e-6:
        return (f"no steady state of the loop found there (the one-period map's fixed point: "
                f"residual {report.residual:.3g} > 1e-06), so no rho")
    mode = report.slowest
    if mode is None:
        return f"rho {report.rho:.4g}"
    kind = ("real: diverges without oscillating" if abs(complex(mode.mu).imag) < 1e-12
            else f"oscillating at {mode.frequency_hz:.3g} Hz")
    where = ", ".join(label.split(":", 1)[-1] for label in mode.dominant)
    return f"slowest mode |mu| = {mode.magnitude:.3g} ({kind}) in {where}"


def derive_and_check(scenario: Scenario, kappa: float = KAPPA, epsilon: float = 1e-5,
                     progress: Callable[[str], None] = lambda m: None) -> GainsReport:
    """Derive, check at the gains and at ``GAIN_MARGIN × K_R``, then the task
    (:func:`~drake_coop.stability.task_check.check_task`: the map along the task's postures,
    the torque limits along the path, the grasp's own dynamics in ``contact`` mode); back off
    ``κ`` when a map fails; refuse at once when the torque or the grasp fails (a lower ``κ``
    does not mend them), ``report.refusal`` saying why and what to change.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    kappa : float
        The first ``κ``.
    epsilon : float
        The central differences' step.
    progress : Callable[[str], None]
        Receives one line per step.

    Returns
    -------
    GainsReport
        The gains and the checks.
    """
    target, mode = map_copy(scenario)
    report = GainsReport(robots=[], checked_on=mode)
    for attempt in range(1, MAX_ATTEMPTS + 1):
        progress(f"attempt {attempt}: kappa = h K_R / J = {kappa:.3g}")
        derived = derive_gains(target, kappa, progress)
        progress("stability map at the derived gains")
        why: dict = {}
        rho = check_gains_map(gains_for_scenario(target, derived), epsilon, progress, why)
        if max(rho.values()) < 1.0:
            progress(f"stability map with K_R x {GAIN_MARGIN}")
            margin = check_gains_map(gains_for_scenario(target, derived, GAIN_MARGIN),
                                     epsilon, progress)
            rho.update({f"{k}_margin": v for k, v in margin.items()})
        report.robots, report.rho, report.attempts = derived, rho, attempt
        if max(rho.values()) < 1.0 and len(rho) == 4:
            if _task_verdict(scenario, derived, report, epsilon, progress):
                return report
            if report.task.refusal and not _map_failed(report.task):
                return report            # torque or grasp: a lower κ does not mend them
            found = report.task.refusal
        else:
            found = "rho " + ", ".join(f"{k} {v:.4g}" + (f" ({why[k]})" if k in why else "")
                                       for k, v in rho.items())
        report.messages.append(f"kappa {kappa:.3g}: {found}")
        kappa *= BACKOFF
    report.refusal = report.refusal or (
        f"no derived gains passed the stability check after {MAX_ATTEMPTS} attempts, "
        f"lowering kappa each time (first: {report.messages[0] if report.messages else 'none'}"
        f"; last: {report.messages[-1] if report.messages else 'none'}): the loop stays "
        "unstable at every kappa tried; look at the named joints' "
        "inertia and damping in the URDF (Drake ignores rotor inertia), the control period "
        "or the posture")
    return report


def _map_failed(task) -> bool:
    """Whether the task's map check (the one a lower ``κ`` may mend) is what failed."""
    return any(c.name == "map" and not c.passes for c in task.checks)


def _task_verdict(scenario: Scenario, derived: list[DerivedGains], report: GainsReport,
                  epsilon: float, progress: Callable[[str], None]) -> bool:
    """The task's checks (:func:`~drake_coop.stability.task_check.check_task`) on
    ``scenario`` with the derived gains: sets ``report.task``, ``stable`` and ``refusal``."""
    from drake_coop.stability.task_check import check_task

    report.task = check_task(gains_for_scenario(scenario, derived), epsilon, progress=progress)
    report.stable = report.task.passes
    report.refusal = report.task.refusal
    return report.stable
