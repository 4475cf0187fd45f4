"""The stability map over a grid of dotted scenario paths, one fresh process per grid point.

The grid uses the study syntax (:mod:`drake_coop.studies.expand`: ``control_period``,
``robots.*.gains.k_d``, ``robots.*.gains.K_R``, variants …) and its validation; each grid point
is one :class:`~drake_coop.studies.expand.Case` whose canonical scenario YAML crosses the process
boundary (no pydrake object is pickled). Locally the points run on the study engines' loop
(:func:`~drake_coop.studies.engines.run_in_processes`: a fresh ``spawn`` process per point,
since Python LeafSystems leak across diagrams, each dying with its parent); on Ray, one
``@ray.remote(max_calls=1)`` task per point.
"""

from __future__ import annotations

import math
import time
from typing import Callable

from drake_coop.studies.engines import run_in_processes
from drake_coop.studies.expand import Case, expand
from drake_coop.studies.spec import Study

__all__ = ["COLUMNS", "grid_cases", "point_rows", "run_grid", "status_of"]

#: Columns of ``stability.csv`` after the swept paths.
COLUMNS = ["point", "rho", "status", "residual", "slowest_abs", "slowest_time_constant_s",
           "slowest_hz", "slowest_states", "fastest_abs", "dynamic_states", "epsilon",
           "wall_time_s", "message"]

#: The status of a point whose ρ depends on the finite-difference step (not a result).
STEP_DEPENDENT = "step_dependent"

#: Largest ``|F(x*) − x*|`` accepted as an equilibrium.
EQUILIBRIUM_TOL = 1e-6


def status_of(rho: float, residual: float) -> str:
    """``stable`` (ρ < 1), ``unstable`` (ρ ≥ 1) or ``no_equilibrium`` (Newton did not
    converge: ρ is that of the last iterate).

    Parameters
    ----------
    rho : float
        ρ(Φ).
    residual : float
        Newton's last residual.
    """
    if not math.isfinite(rho):
        return "unstable"
    if residual > EQUILIBRIUM_TOL:
        return "no_equilibrium"
    return "stable" if rho < 1.0 else "unstable"


def grid_cases(base_yaml: str | None, grid: dict[str, list]) -> list[Case]:
    """The grid's points as validated cases (:func:`drake_coop.studies.expand.expand`).

    Parameters
    ----------
    base_yaml : str or None
        The base scenario's YAML text; None for the defaults.
    grid : dict of str to list
        Each swept path's values.

    Raises
    ------
    drake_coop.studies.spec.StudyError
        A bad path or value, naming it (``grid.control_period = -1: …``).
    """
    return expand(Study(name="stability", base_yaml=base_yaml, grid=dict(grid)),
                  max_cases_option=None)


def point_rows(scenario_yaml: str, points: list[str], epsilon: float = 1e-3) -> list[dict]:
    """ρ(Φ) of one scenario at each operating point (never raises: ``status = error``).

    Parameters
    ----------
    scenario_yaml : str
        The case's scenario, YAML text.
    points : list of str
        The operating points (``free``, ``held``).
    epsilon : float
        The central differences' step.

    Returns
    -------
    list of dict
        One row per point.
    """
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.stability.operating import operating_point
    from drake_coop.stability.period_map import analyse

    rows = []
    for point in points:
        start = time.perf_counter()
        try:
            report = analyse(operating_point(load_scenario(data=scenario_yaml), point).map,
                             epsilon=epsilon)
        except Exception as exc:      # recorded, not fatal
            rows.append({"point": point, "rho": math.nan, "status": "error",
                         "wall_time_s": time.perf_counter() - start,
                         "message": f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"})
            continue
        slow, fast = report.slowest, report.fastest
        status, message = status_of(report.rho, report.residual), ""
        if not report.step_agrees:
            status = STEP_DEPENDENT
            message = (f"rho = {report.rho:.6g} with epsilon = {epsilon:g} but "
                       f"{report.rho_check:.6g} with {report.epsilon_check:g}: the "
                       "finite-difference step is outside where the map is resolved")
        rows.append({
            "point": point, "rho": report.rho, "status": status,
            "residual": report.residual,
            "slowest_abs": slow.magnitude if slow else math.nan,
            "slowest_time_constant_s": slow.time_constant if slow else math.nan,
            "slowest_hz": slow.frequency_hz if slow else math.nan,
            "slowest_states": " ".join(slow.dominant) if slow else "",
            "fastest_abs": fast.magnitude if fast else math.nan,
            "dynamic_states": len(report.dynamic), "epsilon": epsilon,
            "wall_time_s": time.perf_counter() - start, "message": message})
    return rows


def run_grid(cases: list[Case], points: list[str], on_result: Callable[[Case, list], None], *,
             workers: int = 2, engine: str = "local", address: str | None = None,
             epsilon: float = 1e-3) -> None:
    """Compute every case's rows in fresh processes (``local``) or Ray tasks (``ray``),
    handing each case's rows to ``on_result`` as they arrive.

    Parameters
    ----------
    cases : list of Case
        The grid's cases.
    points : list of str
        The operating points.
    on_result : Callable[[Case, list], None]
        Receives each case and its rows.
    workers : int
        Processes (``local``).
    engine : str
        ``local`` or ``ray``.
    address : str or None
        The Ray cluster's address; None starts a local one.
    epsilon : float
        The central differences' step.
    """
    if engine == "ray":
        import ray

        started = False
        if not ray.is_initialized():
            if address is None:
                ray.init(num_cpus=max(1, workers), include_dashboard=False,
                         log_to_driver=False, configure_logging=False)
            else:
                ray.init(address=address, log_to_driver=False, configure_logging=False)
            started = True
        try:
            task = ray.remote(max_calls=1, num_cpus=1)(point_rows)
            refs = {task.remote(c.scenario_yaml, points, epsilon): c for c in cases}
            pending = list(refs)
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    on_result(refs[ref], ray.get(ref))
        finally:
            if started:
                ray.shutdown()
        return

    def death(message: str) -> list[dict]:
        return [{"point": p, "rho": math.nan, "status": "error", "message": message}
                for p in points]

    run_in_processes(cases, point_rows, lambda case: (case.scenario_yaml, points, epsilon),
                     on_result, death, workers=workers)
