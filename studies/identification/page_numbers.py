"""The identification page's summaries of the shipped per-draw CSVs: medians over the draws
of the worst arm's errors (the data budgets), the F/T sensor's squeeze error against the
identified models' (ratios), and the momentum observer's change under torque saturation.

    python studies/identification/page_numbers.py docs/results/identification_page_numbers.json

Reads ``docs/figures/studies/identification_budgets.csv``, ``identified_sources.csv``,
``identified_sources_published.csv`` and ``momentum_saturation.csv`` (written by
``bench/identified_sources.py`` and ``bench/momentum_saturation.py``); NumPy's median.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "docs" / "figures" / "studies"
ROBOTS = ("robot1", "robot2")


def _rows(name: str) -> list[dict]:
    with (STUDIES / name).open(newline="") as handle:
        return list(csv.DictReader(handle))


def _worst(row: dict, column: str) -> float:
    return max(abs(float(row[f"{r}.{column}"])) for r in ROBOTS)


def budgets() -> dict:
    """Per excitation length (``s<seconds>``) and estimator: medians and maxima over the
    draws of the worst arm's model torque error (N·m), first-moment error (%), Coulomb error
    (N·m), the squeeze error (N) and the identification's CPU seconds; and the MAP estimate's
    median torque error over DIDIM's."""
    rows = _rows("identification_budgets.csv")
    out: dict = {}
    for length in sorted({float(r["excitation_s"]) for r in rows}):
        key = f"s{length:.0f}"
        for est in sorted({r["estimator"] for r in rows}):
            sel = [r for r in rows if float(r["excitation_s"]) == length and r["estimator"] == est]
            if not sel:
                continue
            torque = [_worst(r, "torque_error_rms_identified") for r in sel]
            moment = [_worst(r, "first_moment_error_pct") for r in sel]
            coulomb = [_worst(r, "coulomb_error_max") for r in sel]
            squeeze = [float(r["squeeze_error"]) for r in sel]
            cpu = [float(r["identify_cpu_s"]) for r in sel]
            out.setdefault(key, {})[est] = {
                "draws": len(sel), "torque_error_median": float(np.median(torque)),
                "first_moment_error_pct_median": float(np.median(moment)),
                "coulomb_error_median": float(np.median(coulomb)),
                "coulomb_error_max": max(coulomb),
                "squeeze_error_median": float(np.nanmedian(squeeze)),
                "squeeze_error_max": float(np.nanmax(squeeze)),
                "cpu_s_min": min(cpu), "cpu_s_max": max(cpu)}
        if {"map_sdp", "didim"} <= set(out.get(key, {})):
            out[key]["torque_error_map_over_didim"] = (
                out[key]["map_sdp"]["torque_error_median"]
                / out[key]["didim"]["torque_error_median"])
            out[key]["squeeze_error_map_over_didim"] = (
                out[key]["map_sdp"]["squeeze_error_median"]
                / out[key]["didim"]["squeeze_error_median"])
    return out


def sources(name: str) -> dict:
    """The F/T sensor's median and maximum squeeze error over those of the identified
    models (observer (22) and momentum observer)."""
    rows = _rows(name)
    col = {c: [float(r[c]) for r in rows] for c in rows[0] if c != "draw"}
    return {f"sensor_over_{c.replace('+', '_')}": {
        "median": float(np.median(col["sensor"]) / np.median(col[c])),
        "max": max(col["sensor"]) / max(col[c])} for c in ("observer+id", "momentum+id")}


def saturation() -> dict:
    """Robot 1's circle squeeze error per case, relative to the run without limits."""
    rows = {(r["case"], r["robot"]): r for r in _rows("momentum_saturation.csv")}
    base = float(rows[("no limits", "robot1")]["circle_rms"])
    return {case: float(rows[(case, "robot1")]["circle_rms"]) / base - 1.0
            for case in ("commanded", "applied")}


def identify_ratios() -> dict:
    """Per robot of ``identify_realistic.json``: the validation torque error in % of the
    torque RMS, the nominal model's torque error over the identified one's, the largest
    viscous-friction error in % of the true value and the forearm first moment's error in %
    of its true value."""
    document = json.loads((ROOT / "docs" / "results" / "identify_realistic.json").read_text())
    out = {}
    for name, robot in document["robots"].items():
        v, p = robot["validation"], robot["parameters"]
        out[name] = {
            "validation_error_pct": 100.0 * v["torque_error_rms_identified"] / v["torque_rms"],
            "nominal_over_identified": v["torque_error_rms_nominal"]
            / v["torque_error_rms_identified"],
            "viscous_error_max_pct": max(100.0 * abs(p[k]["error"]) / p[k]["true"]
                                         for k in p if k.endswith(".viscous")),
            "first_moment_error_pct": 100.0 * p["link3.hz"]["error"] / p["link3.hz"]["true"]}
    return out


def main(argv: list[str]) -> int:
    """Write the document to ``argv[0]``."""
    document = {"budgets": budgets(), "sources": sources("identified_sources.csv"),
                "sources_published": sources("identified_sources_published.csv"),
                "saturation_circle_change_robot1": saturation(),
                "identify_realistic": identify_ratios()}
    Path(argv[0]).write_text(json.dumps(document, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
