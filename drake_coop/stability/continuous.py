"""ρ of the continuous arm from maps on the discrete plant: the half-step bias and its removal.

The one-period map runs on the simulated plant, a discrete ``MultibodyPlant`` stepping every
``Δt``. A torque switched on at a plant step acts over that whole step in the implicit step's
velocity update, so on a real (continuous) arm the same loop behaves as if each torque arrived
about half a plant step *later*: the discrete map is biased toward stability by about
``Δt/2`` of delay. On the one-joint closed form (:mod:`~drake_coop.stability.one_joint`, exact
integration of the continuous joint across the delayed switch) ρ at ``Δt = 1 ms`` is 0.911 at
zero delay against the continuous arm's 0.937, and ρ at delay ``d`` lies within 0.003 of the
continuous arm's at ``d − Δt/2``.

The bias is first order in ``Δt``, so Richardson extrapolation of two maps, at ``Δt`` and
``Δt/2``, removes it: ``ρ_c ≈ 2 ρ(Δt/2) − ρ(Δt)`` (one-joint, ``Δt`` = 1 ms: within 2e-4
of the exact continuous ρ from 0 to 6 ms of delay without compensation, within 1e-3 with it
except where the largest eigenvalue changes mode between the two steps, 0.004 at 4 ms;
``tests/stability/test_delay_map.py``). :func:`continuous_rows` applies it to the rows of a
``drake-coop stability`` grid over ``plant.time_step``.
"""

from __future__ import annotations

import math

__all__ = ["TIME_STEP_PATH", "continuous_rho", "continuous_rows"]

#: The grid path of the plant step.
TIME_STEP_PATH = "plant.time_step"


def continuous_rho(rho_dt: float, rho_half: float) -> float:
    """``2 ρ(Δt/2) − ρ(Δt)``: ρ with the plant step's first-order bias removed.

    Parameters
    ----------
    rho_dt : float
        ρ at the plant step ``Δt``.
    rho_half : float
        ρ at ``Δt/2``.

    Returns
    -------
    float
        The extrapolated ρ.
    """
    return 2.0 * float(rho_half) - float(rho_dt)


def continuous_rows(rows: list[dict], swept: list[str]) -> list[dict]:
    """Pair each row at plant step ``Δt`` with the row at ``Δt/2`` of the same other swept
    values and operating point; return one row per pair with ``rho_dt``, ``rho_half``,
    ``rho_continuous``, ``time_step``, both statuses, and the other swept values.

    Parameters
    ----------
    rows : list of dict
        The grid's rows (``stability.csv``'s).
    swept : list of str
        The grid's swept paths (``plant.time_step`` among them).

    Returns
    -------
    list of dict
        One row per pair.

    Raises
    ------
    ValueError
        ``plant.time_step`` not among ``swept``.
    """
    if TIME_STEP_PATH not in swept:
        raise ValueError(f"swept: {TIME_STEP_PATH} must be one of the grid's paths, got "
                         f"{', '.join(swept) or 'none'}")
    others = [k for k in swept if k != TIME_STEP_PATH]

    def key(r: dict) -> tuple:
        return tuple(str(r[k]) for k in others) + (r["point"],)

    by_key: dict[tuple, dict[float, dict]] = {}
    for r in rows:
        by_key.setdefault(key(r), {})[float(r[TIME_STEP_PATH])] = r
    out = []
    for k, steps in by_key.items():
        for dt, coarse in sorted(steps.items(), reverse=True):
            fine = next((v for s, v in steps.items() if math.isclose(s, dt / 2, rel_tol=1e-9)),
                        None)
            if fine is None:
                continue
            rho_c = continuous_rho(float(coarse["rho"]), float(fine["rho"]))
            out.append({**{o: coarse[o] for o in others}, "point": coarse["point"],
                        "time_step": dt, "rho_dt": float(coarse["rho"]),
                        "rho_half": float(fine["rho"]), "rho_continuous": rho_c,
                        "status_dt": coarse["status"], "status_half": fine["status"]})
    return out
