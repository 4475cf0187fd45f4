"""Every velocity source × force source under realistic sensing: the table of docs/guide/sensing.md.

``python bench/sources_table.py [--scenario scenarios/realistic.yaml] [--workers 2]
[--t-end 90] [--out sources.json]`` runs the nine combinations (both robots switched together;
two runs at a time, each in its own process, :func:`drake_coop.studies.sweep.sweep`) and prints the
circle-phase errors (25–65 s) as a Markdown table: RMS / max over the phase of λ − λ_d,
λ̂ − λ (the controller's force value against the true squeeze), the worst Cartesian axis of
x − x_d and the worst joint of q̇ − q̇̂, for robot 1 / robot 2. A run that diverged is reported
with its message: that is a result.
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path

from drake_coop.scenario import FORCE_SOURCES, VELOCITY_SOURCES, load_scenario
from drake_coop.studies.sweep import sweep

ROOT = Path(__file__).resolve().parents[1]


def combinations(path: Path) -> list[tuple[str, str, object]]:
    """``(velocity_source, force_source, scenario)`` for the nine combinations."""
    base = load_scenario(path)
    runs = []
    for v in VELOCITY_SOURCES:
        for f in FORCE_SOURCES:
            s = copy.deepcopy(base)
            for robot in s.robots:
                robot.velocity_source, robot.force_source = v, f
            runs.append((v, f, s))
    return runs


def _pair(metrics: dict, name: str, scale: float, digits: int) -> str:
    """``rms / max`` of robot 1 and robot 2, scaled."""
    cells = []
    for robot in ("robot1", "robot2"):
        e = metrics[robot]["circle"][name]
        cells.append(f"{scale * e['rms']:.{digits}f} / {scale * e['max']:.{digits}f}")
    return " ; ".join(cells)


def _tracking(metrics: dict) -> str:
    cells = []
    for robot in ("robot1", "robot2"):
        c = metrics[robot]["circle"]
        worst = max(("x_tilde", "y_tilde", "z_tilde"), key=lambda k: c[k]["rms"])
        cells.append(f"{1e3 * c[worst]['rms']:.3f} / {1e3 * c[worst]['max']:.3f}")
    return " ; ".join(cells)


def table(rows: list[tuple[str, str, dict]]) -> str:
    """The Markdown table of the circle-phase errors."""
    lines = ["| velocity source | force source | λ − λ_d (N) | λ̂ − λ (N) | "
             "worst axis of x − x_d (mm) | q̇ − q̇̂, worst joint (rad/s) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for v, f, result in rows:
        m = result["metrics"]
        if result["meta"]["status"] != "ok" or any("circle" not in m[r] for r in m):
            lines.append(f"| {v} | {f} | {result['meta']['message']} | | | |")
            continue
        lines.append(f"| {v} | {f} | {_pair(m, 'force_error', 1.0, 3)} | "
                     f"{_pair(m, 'estimate_error', 1.0, 3)} | "
                     f"{_tracking(m)} | {_pair(m, 'velocity_error', 1.0, 4)} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "realistic.yaml"))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--t-end", type=float, default=None)
    parser.add_argument("--out", default=None, help="also write the results as JSON")
    args = parser.parse_args()
    runs = combinations(Path(args.scenario))
    results = sweep([s for _, _, s in runs], t_end=args.t_end, workers=args.workers)
    rows = [(v, f, r) for (v, f, _), r in zip(runs, results)]
    print(table(rows))
    if args.out:
        Path(args.out).write_text(json.dumps(
            [{"velocity_source": v, "force_source": f, "meta": r["meta"],
              "metrics": r["metrics"]} for v, f, r in rows], indent=1))


if __name__ == "__main__":
    main()
