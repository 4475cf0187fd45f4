"""The reference table's friction-held part: the box held by friction at two hydroelastic pads.

``python -m bench.reference_table_friction --bases DIR`` writes the two bases the part runs on:

* ``paper_contact.yaml`` — the paper's arms on ``scenarios/contact.yaml`` (the box held by
  friction, 0.5 kg, μ 1, a 3 ms plant step, the stand lowered during the circle) with
  ``object_model: {mode: estimated}``, as the object guide measures it: with the paper's own
  control (``mode: none``) the unmodelled weight alone gives about 3 N of squeeze error, which
  would bury every force source's difference;
* ``ur10_pair.yaml`` — the lab pair: two UR10s carrying the same box (``estimated``), placed and
  tuned as ``bench/every_arm.py`` placed and tuned them (its row ``ur10`` in
  ``docs/results/every_arm.json``: the placement, the derived gains that passed every check of
  ``drake-coop gains``); of the lab pairs that carry the box it is the cheapest to simulate.

Each base then runs with ``drake-coop reference-table --base FILE`` (a base in ``contact``
mode takes :data:`~drake_coop.studies.reference_table.FRICTION_COLUMNS` by default).
``--full BASE --out JSON`` runs the overlap check: the exact-model cases of a few rows on the
whole task (to the circle's end), to compare the short segment's order of the sources with the
full run's. ``--results DIR ... --out JSON`` writes the results file from finished tables.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The lab pair: its row of ``docs/results/every_arm.json``.
LAB_PAIR = "ur10"


def paper_contact_text() -> str:
    """The paper's arms on ``contact.yaml`` with an estimated object model, as YAML text."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    scenario = load_scenario(ROOT / "scenarios" / "contact.yaml")
    scenario.object_model.mode = "estimated"
    return dump_scenario(load_scenario(data=dump_scenario(scenario)))


def lab_pair_text(folder: Path, key: str = LAB_PAIR) -> str:
    """The lab pair ``key`` of ``docs/results/every_arm.json`` with its stored gains, as YAML
    text (loaded as ``drake-coop gains`` loads it, then given ``contact.yaml``'s plant as
    ``bench/every_arm.py`` does)."""
    from bench.lab_arms_object import contact_scenario
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.stability.gains_cli import load_for_gains

    case = json.loads((ROOT / "docs" / "results" / "every_arm.json").read_text())["cases"][key]
    if case.get("status") != "ok":
        raise ValueError(f"every_arm.json: the {key} row did not carry the box")
    path = folder / f".{key}.pair.yaml"
    path.write_text(case["scenario_yaml"])
    try:
        scenario = load_for_gains(str(path))
        for robot in scenario.robots:
            g = case["gains"]["robots"][robot.name]
            robot.gains.K_R, robot.gains.Lambda, robot.gains.xi = g["K_R"], g["Lambda"], g["xi"]
            robot.gains.xi_matrix = None
        path.write_text(dump_scenario(scenario))
        return dump_scenario(contact_scenario(str(path)))
    finally:
        path.unlink(missing_ok=True)


def write_bases(folder: Path) -> dict[str, Path]:
    """Write both bases into ``folder``; their paths by name."""
    folder.mkdir(parents=True, exist_ok=True)
    out = {"paper_contact": folder / "paper_contact.yaml",
           "ur10_pair": folder / "ur10_pair.yaml"}
    out["paper_contact"].write_text(paper_contact_text())
    out["ur10_pair"].write_text(lab_pair_text(folder))
    return out


#: The overlap check's rows (each source the shipped contact studies report) and their draws.
FULL_ROWS = {"observer": 1, "momentum": 1, "sensor_0p3": 3, "none": 1}


def full_runs(base: Path, rows: dict[str, int] = FULL_ROWS) -> dict:
    """The exact model's cases of ``rows`` (row -> draws) on the whole task of ``base``, to
    the circle's end (not compressed), in this process: per row the draws' numbers
    (:func:`~drake_coop.studies.reference_table.per_draw`) and CPU seconds."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import ROWS, per_draw

    scenario = load_scenario(base)
    t_end = scenario.task.t_circle_end
    sources = {r.name: r for r in ROWS}
    out: dict = {"base": base.name, "t_end": t_end, "rows": {}}
    for row, draws in rows.items():
        for draw in range(draws):
            s = load_scenario(data=dump_scenario(scenario))
            sources[row].apply(s, draw)
            (_, record), = run_batch([(row, dump_scenario(s), None)], t_end)
            entry = {**per_draw(record), "status": record["status"],
                     "cpu_time_s": record["cpu_time_s"]}
            out["rows"].setdefault(row, []).append(entry)
            print(row, draw, json.dumps(entry), flush=True)
    return out


def overlap(short: dict, full: dict) -> list[dict]:
    """The short table's exact-model order of the sources against the whole task's
    (:func:`bench.reference_table.verdicts`: ``agrees``, ``tied`` or ``disagrees``)."""
    import numpy as np

    from bench.reference_table import verdicts
    from drake_coop.studies.reference_table import bootstrap_interval

    a = {row: cells["exact"]["squeeze"]["median"] for row, cells in short["cells"].items()
         if "exact" in cells and row in full["rows"]}
    b = {row: list(bootstrap_interval(np.array([d["squeeze"] for d in draws]), 0.5))
         for row, draws in full["rows"].items()}
    return verdicts(a, b)


def snapshot(folder: Path, base: Path, rows: list[str], cols: list[str], draws: int) -> dict:
    """The table of ``rows`` × ``cols`` at ``draws`` draws from the cases finished in
    ``folder`` on ``base`` (nothing runs; ``folder``'s tables rewritten), with the counts of
    its distinct cases and their CPU per row."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_engine import write_table
    from drake_coop.studies.reference_table import expand_table
    from drake_coop.studies.store import ResultStore

    calibration = folder / "calibration.json"
    peaks = json.loads(calibration.read_text())["peaks"] if calibration.is_file() else None
    cols = [c for c in cols if c != "saturation" or peaks is not None]
    models = {(c, d): json.loads((folder / "identified" / c / str(d) / "models.json")
                                 .read_text())
              for c in cols if c.startswith("id_") for d in range(draws)}
    cases = expand_table(load_scenario(base), rows, cols, draws, peaks=peaks, models=models)
    records = ResultStore(folder).load()
    table = write_table(folder, cases, records, rows, cols)
    table["draws"] = draws
    distinct = {c.hash: c for c in cases}
    table["distinct_cases"] = len(distinct)
    table["distinct_finished"] = sum(h in records for h in distinct)
    cpu: dict = {}
    for h, c in distinct.items():
        if h in records and records[h].get("cpu_time_s") is not None:
            cpu.setdefault(c.params["row"], []).append(records[h]["cpu_time_s"])
    table["cpu_per_case_s"] = {row: sum(v) / len(v) for row, v in cpu.items()}
    table["cpu_distinct_s"] = sum(sum(v) for v in cpu.values())
    return table


#: The bases of the results file: name -> (the table's folder under ``--results``, its base).
BASES = {"paper_contact": "paper", "ur10_pair": "ur10"}


def results(folder: Path, draws: int, rows: list[str], cols: list[str]) -> dict:
    """The results file's content from ``folder`` (as the commands on the page leave it:
    ``bases/``, one table folder per base, ``logs/`` of ``/usr/bin/time -v``,
    ``full_paper.json``, ``rerun.json``): per base the table of ``rows`` × ``cols`` (the cells
    whose every draw finished), the stages' process CPU and wall, the overlap check and the
    rerun."""
    from bench.reference_table import time_log
    from drake_coop.studies.reference_table import SEGMENT, T_SHORT

    out: dict = {"draws": draws, "segment": {**SEGMENT, "t_end_case": T_SHORT}, "bases": {}}
    for name, sub in BASES.items():
        if not (folder / sub / "cases").is_dir():
            continue
        table = snapshot(folder / sub, folder / "bases" / f"{name}.yaml", rows, cols, draws)
        for cells in table["cells"].values():      # a cell not yet at its draws: pending
            for col in [c for c, s in cells.items() if s["n"] < draws]:
                del cells[col]
        out["bases"][name] = table
    logs = sorted((folder / "logs").glob("*.log"))
    out["runs"] = [time_log(p) for p in logs]
    out["cpu_s"] = sum(r.get("cpu_s", 0.0) for r in out["runs"])
    full = folder / "full_paper.json"
    if full.is_file() and "paper_contact" in out["bases"]:
        out["full"] = json.loads(full.read_text())
        out["overlap"] = overlap(out["bases"]["paper_contact"], out["full"])
    rerun = folder / "rerun.json"
    if rerun.is_file():
        out["rerun"] = json.loads(rerun.read_text())
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bases", default=None, metavar="DIR", help="write the two bases")
    parser.add_argument("--full", default=None, metavar="BASE",
                        help="the overlap check's whole-task runs of BASE into --out")
    parser.add_argument("--results", default=None, metavar="DIR",
                        help="write the results file of DIR's tables to --out")
    parser.add_argument("--rerun", default=None, metavar="DIR",
                        help="run --count finished cases of DIR again, compare, into --out")
    parser.add_argument("--count", type=int, default=4)
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--rows", default=None, help="--results: comma-separated rows")
    parser.add_argument("--columns", default=None, help="--results: comma-separated columns")
    parser.add_argument("--out", default=None, metavar="JSON")
    args = parser.parse_args()
    if args.results:
        from drake_coop.studies.reference_table import FRICTION_COLUMNS, ROWS

        rows = args.rows.split(",") if args.rows else [r.name for r in ROWS]
        cols = args.columns.split(",") if args.columns else list(FRICTION_COLUMNS)
        data = results(Path(args.results), args.draws, rows, cols)
        Path(args.out).write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    if args.rerun:
        from bench.reference_table import rerun

        Path(args.out).write_text(json.dumps(rerun(Path(args.rerun), args.count), indent=1)
                                  + "\n")
    if args.bases:
        for name, path in write_bases(Path(args.bases)).items():
            print(name, path)
    if args.full:
        start = time.process_time()
        result = full_runs(Path(args.full))
        result["cpu_s"] = time.process_time() - start
        Path(args.out).write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
