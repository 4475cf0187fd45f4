"""The short summary ``drake-coop run`` prints at its end, and its physical sanity checks.

:func:`summary_lines` is a table of the circle phase's errors per robot (RMS / max, in the
units a reader reads: µm, N, µrad), taken from :func:`~drake_coop.results.metrics.compute_metrics`:

* ``|x − x_d|``: the worst Cartesian axis of the tracking error (Fig. 2);
* ``λ − λ_d``: measured minus desired squeeze (Fig. 3);
* ``λ − λ̂``: measured minus estimated squeeze (Fig. 4);
* ``z``: the worst joint's observation error ``q − q̂`` (Fig. 6);

and in ``contact`` mode one more line, the held box (:mod:`~drake_coop.results.object_metrics`,
object-level: robot 1's entry): its position error, its turn about the grasp line and its tilt
(degrees), the worst pad's slip with its creep ``floor``, and the slips and drops counted.

:func:`sanity_warnings` looks at the measured squeeze itself. While the object is held and the
desired force of a constraint row is at least :data:`MIN_DESIRED_SHARE` of its peak, the
measured force must have the desired force's sign; where it does not, the end effector pulled
on the object instead of squeezing it (in ``contact`` mode: the object slipped out or was
dropped). The metrics alone cannot say so: a pull of −2 N against a desired 16 N is only an
18 N force error.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_DESIRED_SHARE", "mass_line", "sanity_warnings", "summary_lines",
           "summary_phase"]

#: Share of a row's peak desired force above which its measured force is checked.
MIN_DESIRED_SHARE = 0.1

# (column title, errors whose worst is shown, scales (factor, unit) from small to large)
_COLUMNS = (
    ("|x - x_d| worst axis", ("x_tilde", "y_tilde", "z_tilde"), ((1e6, "µm"), (1e3, "mm"))),
    ("lambda - lambda_d", ("force_error",), ((1.0, "N"),)),
    ("lambda - lambda_hat", ("estimate_error",), ((1.0, "N"),)),
    ("z worst joint", None, ((1e6, "µrad"), (1e3, "mrad"), (1.0, "rad"))),
)


def summary_phase(metrics: dict) -> str:
    """``circle`` when every robot has it (a run that reached the circle), else ``all``.

    Parameters
    ----------
    metrics : dict
        ``metrics[robot][phase]``.
    """
    return "circle" if metrics and all("circle" in m for m in metrics.values()) else "all"


def _worst(entry: dict, names) -> tuple[float, float] | None:
    found = [entry[n] for n in names if n in entry]
    if not found:
        return None
    return max(e["rms"] for e in found), max(e["max"] for e in found)


def _format(rms: float, peak: float, scales) -> str:
    for factor, unit in scales:
        if peak * factor < 1000 or (factor, unit) == scales[-1]:
            return f"{rms * factor:.3g} / {peak * factor:.3g} {unit}"
    raise AssertionError("unreachable")


def summary_lines(metrics: dict, meta: dict, logs: dict | None = None) -> list[str]:
    """The summary table: a title line, a header and one line per robot; with an object
    model's logs, the object's mass line (:func:`mass_line`).

    Parameters
    ----------
    metrics : dict
        :func:`~drake_coop.results.metrics.compute_metrics` of the run.
    meta : dict
        The run's metadata (``phases``: the circle's time span for the title).
    logs : dict or None
        ``logs[robot][array]`` (``t``, ``mass_share``); None: no mass line.

    Returns
    -------
    list of str
        Lines without newline characters.
    """
    phase = summary_phase(metrics)
    spans = {str(name): (a, b) for name, a, b in meta.get("phases", [])}
    if phase == "circle" and "circle" in spans:
        a, b = spans["circle"]
        title = f"circle phase ({a:g}-{b:g} s), RMS / max"
    else:
        title = "whole run (it did not reach the circle phase), RMS / max"
    rows = [["robot"] + [c[0] for c in _COLUMNS]]
    for robot, phases in metrics.items():
        entry = phases.get(phase, {})
        cells = [robot]
        for _, names, scales in _COLUMNS:
            names = names or sorted(k for k in entry if k[:1] == "z" and k[1:].isdigit())
            worst = _worst(entry, names)
            cells.append("-" if worst is None else _format(*worst, scales))
        rows.append(cells)
    widths = [max(len(r[j]) for r in rows) for j in range(len(rows[0]))]
    table = ["  " + "  ".join(c.ljust(w) if j == 0 else c.rjust(w)
                              for j, (c, w) in enumerate(zip(r, widths))) for r in rows]
    return [title] + table + _object_line(metrics, phase) + mass_line(logs or {}, meta)


def mass_line(logs: dict, meta: dict) -> list[str]:
    """The object's mass as the arms estimate it (``object_model`` known or estimated: the
    sum of their ``mass_share`` logs), at the end of the carrying (the circle's end, or the
    run's last held sample) against the true mass, and its lowest value while held.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]``: ``t``, ``mass_share``.
    meta : dict
        ``phases`` and ``object_mass`` (kg).

    Returns
    -------
    list of str
        One line, e.g. ``  object mass: estimate 0.497 kg at t = 65.0 s (true 0.5 kg,
        -0.6 %); lowest while held -0.057 kg at t = 15.2 s (a negative share is fed forward
        as 0)``; none without ``mass_share`` logs or a held sample.
    """
    if not logs or not all("mass_share" in log for log in logs.values()) \
            or "object_mass" not in meta:
        return []
    first = next(iter(logs.values()))
    t = np.asarray(first["t"], dtype=float)
    K = min(len(np.asarray(log["mass_share"])) for log in logs.values())
    t = t[:K]
    total = np.sum([np.asarray(log["mass_share"], dtype=float)[:K] for log in logs.values()],
                   axis=0)
    spans = {str(name): (a, b) for name, a, b in meta.get("phases", [])}
    if "lift" not in spans:
        return []
    t0 = spans["lift"][0]
    t1 = spans["circle"][1] if "circle" in spans else spans.get("put_down", (0, t0))[0]
    held = (t >= t0) & (t < t1) & np.isfinite(total)
    if not held.any():
        return []
    k_end = int(np.flatnonzero(held)[-1])
    k_low = int(np.flatnonzero(held)[np.argmin(total[held])])
    m = float(meta["object_mass"])
    text = (f"  object mass: estimate {total[k_end]:.3g} kg at t = {t[k_end]:.1f} s (true "
            f"{m:g} kg, {100 * (total[k_end] - m) / m:+.1f} %); lowest while held "
            f"{total[k_low]:.3g} kg at t = {t[k_low]:.1f} s")
    if total[k_low] < 0:
        text += " (a negative share is fed forward as 0)"
    return [text]


def _object_line(metrics: dict, phase: str) -> list[str]:
    """The held box's line (``contact`` mode), or none."""
    entries = [m.get(phase, {}) for m in metrics.values()]
    first = entries[0] if entries else {}
    if "object_position_error" not in first:
        return []
    e = first["object_position_error"]
    parts = ["box " + _format(e["rms"], e["max"], ((1e3, "mm"),))]
    for name, label in (("object_turn", "turn"), ("object_tilt", "tilt")):
        if name in first:
            e = first[name]
            parts.append(f"{label} {np.degrees(e['rms']):.3g} / {np.degrees(e['max']):.3g}°")
    slips = [e["slip"] for e in entries if "slip" in e]
    if slips:
        worst = max(slips, key=lambda e: e["max"])
        text = f"slip {worst['max'] * 1e3:.3g} mm max"
        if "floor" in worst:
            text += f" (creep floor {worst['floor'] * 1e3:.2g} mm)"
        parts.append(text)
    slip_count = sum(e.get("slips", {}).get("count", 0) for e in entries)
    drops = first.get("drops", {}).get("count", 0)
    parts.append(f"{slip_count} slips, {drops} drops")
    return ["  object: " + ", ".join(parts)]


def sanity_warnings(logs: dict[str, dict[str, np.ndarray]]) -> list[str]:
    """One line per robot and constraint row whose measured force took the wrong sign.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]``; ``t``, ``lambda_meas`` and ``lambda_d`` are read.

    Returns
    -------
    list of str
        Empty when every check passes; otherwise e.g. ``robot2: the measured squeeze turned
        into a pull (-3.1 N against a desired 24.0 N at t = 41.2 s): was the object dropped?``
    """
    out = []
    for robot, log in logs.items():
        t = np.asarray(log["t"], dtype=float)
        lam = np.asarray(log["lambda_meas"], dtype=float).reshape(len(t), -1)
        lam_d = np.asarray(log["lambda_d"], dtype=float).reshape(len(t), -1)
        for j in range(lam_d.shape[1]):
            desired = lam_d[:, j]
            finite = np.isfinite(desired) & np.isfinite(lam[:, j])
            peak = float(np.max(np.abs(desired[finite]), initial=0.0))
            if peak == 0.0:
                continue
            checked = finite & (np.abs(desired) >= MIN_DESIRED_SHARE * peak)
            wrong = checked & (lam[:, j] * np.sign(desired) < 0)
            if not wrong.any():
                continue
            k = int(np.argmax(np.where(wrong, -lam[:, j] * np.sign(desired), -np.inf)))
            row = f" (row {j + 1})" if lam_d.shape[1] > 1 else ""
            word = "squeeze" if desired[k] > 0 else "pull"
            opposite = "pull" if desired[k] > 0 else "push"
            out.append(f"{robot}{row}: the measured {word} turned into a {opposite} "
                       f"({lam[k, j]:.1f} N against a desired {desired[k]:.1f} N at "
                       f"t = {t[k]:.2f} s, {int(wrong.sum())} samples): was the object "
                       "dropped?")
    return out
