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
``Δt/2``, removes it — mode by mode. :func:`continuous_spectrum` extrapolates each eigenvalue
(``2 μ(Δt/2) − μ(Δt)``, each paired with the nearest one at ``Δt``) and is the accurate form
where both maps' eigenvalues are at hand. :func:`continuous_rho` extrapolates the largest
modulus only, ``ρ_c ≈ 2 ρ(Δt/2) − ρ(Δt)``, all a grid's rows keep; it is the same while the
same mode is the largest at both steps, and **reads low where the largest mode changes
between the two plant steps**. On the one joint with the delay compensation (``p`` = 3 ms,
``Δt`` = 1 ms, whole-millisecond delays 0–8 ms): the per-mode extrapolation is within 5e-4 of
the exact continuous ρ except at 4 ms with the exact model (+0.004, a near-crossing of two
modes, both forms); the largest-modulus one is also 0.006 low at 7 ms (exact model) and 0.002
low at 4 ms (model 30 % heavy), where the dominant mode changes
(``tests/stability/test_continuous.py``). :func:`continuous_rows` applies the largest-modulus
form to the rows of a ``drake-coop stability`` grid over ``plant.time_step`` and marks the
pairs whose dominant states differ (``mode_changed``), where the value is a lower estimate.
Delays must be whole multiples of ``Δt``: a delay the coarse plant rounds up to its next step
is not first order in ``Δt`` (the one joint at 0.5 ms: 0.02 off).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["TIME_STEP_PATH", "continuous_rho", "continuous_rows", "continuous_spectrum"]

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
    """
    return 2.0 * float(rho_half) - float(rho_dt)


def continuous_spectrum(eig_dt, eig_half) -> np.ndarray:
    """The continuous arm's eigenvalues, each extrapolated on its own: ``2 μ(Δt/2) − μ(Δt)``
    with ``μ(Δt)`` the eigenvalue at ``Δt`` nearest to ``μ(Δt/2)``.

    Unlike :func:`continuous_rho`, right where the largest mode at ``Δt`` is not the largest
    at ``Δt/2``; ``max(abs(...))`` of the result is the continuous arm's ρ.

    Parameters
    ----------
    eig_dt, eig_half : array_like of complex
        The map's eigenvalues at the plant steps ``Δt`` and ``Δt/2`` (same count).

    Returns
    -------
    numpy.ndarray
        One extrapolated eigenvalue per eigenvalue at ``Δt/2``, in their order.

    Raises
    ------
    ValueError
        The two spectra differ in size.
    """
    coarse = np.asarray(eig_dt, dtype=complex).ravel()
    fine = np.asarray(eig_half, dtype=complex).ravel()
    if coarse.size != fine.size or coarse.size == 0:
        raise ValueError(f"eig_dt, eig_half: two spectra of one size, got {coarse.size} and "
                         f"{fine.size}")
    return np.array([2.0 * mu - coarse[np.argmin(np.abs(coarse - mu))] for mu in fine])


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
        One row per pair; ``mode_changed`` is True where the two rows' ``slowest_states``
        (the dominant mode's states) differ — ``rho_continuous`` is then a lower estimate
        (see the module's note) — and None where the rows do not carry them.

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
                        "status_dt": coarse["status"], "status_half": fine["status"],
                        "mode_changed": _mode_changed(coarse, fine)})
    return out


def _mode_changed(coarse: dict, fine: dict) -> bool | None:
    a, b = coarse.get("slowest_states"), fine.get("slowest_states")
    if not a or not b:
        return None
    return set(str(a).split()) != set(str(b).split())
