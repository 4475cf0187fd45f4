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
full run's. ``--paper-control --out JSON`` runs one short case of ``contact.yaml`` as shipped
(the paper's control, no object model). ``--rerun DIR --out JSON`` runs finished cases of a
table again and compares their numbers; ``--compare A B --out JSON`` compares two folders'
finished cases of one base (the same table run elsewhere, e.g. on a cluster). ``--results DIR --out JSON`` writes the results file
from the tables and logs in ``DIR``; ``--page JSON`` prints its tables with ``{result}``
roles for ``docs/reference_table.md``.
"""

from __future__ import annotations

import argparse
import json
import math
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
FULL_ROWS = {"observer": 1, "momentum": 1, "none": 1}


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


def paper_control() -> dict:
    """One short case (exact model, observer (22)) of ``scenarios/contact.yaml`` as shipped
    (``object_model: none``, the paper's control): why the bases estimate the box."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import T_SHORT, compress, per_draw

    scenario = compress(load_scenario(ROOT / "scenarios" / "contact.yaml"))
    (_, record), = run_batch([("paper_control", dump_scenario(scenario), None)], T_SHORT)
    return {**per_draw(record), "status": record["status"], "cpu_time_s": record["cpu_time_s"],
            "object_model": scenario.object_model.mode}


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
    found = {(c, d): folder / "identified" / c / str(d) / "models.json"
             for c in cols if c.startswith("id_") for d in range(draws)}
    cols = [c for c in cols if all(f.is_file() for (k, _), f in found.items() if k == c)]
    models = {key: json.loads(f.read_text()) for key, f in found.items() if key[0] in cols}
    cases = expand_table(load_scenario(base), rows, cols, draws, peaks=peaks, models=models)
    records = ResultStore(folder).load()
    table = write_table(folder, cases, records, rows, cols)
    table["draws"] = draws
    distinct: dict = {}
    for c in cases:                    # a shared case counted in the first row that has it
        distinct.setdefault(c.hash, c)
    table["distinct_cases"] = len(distinct)
    table["distinct_finished"] = sum(h in records for h in distinct)
    cpu: dict = {}
    for h, c in distinct.items():
        if h in records and records[h].get("cpu_time_s") is not None:
            cpu.setdefault(c.params["row"], []).append(records[h]["cpu_time_s"])
    table["cpu_per_case_s"] = {row: sum(v) / len(v) for row, v in cpu.items()}
    refused: dict = {}                 # cases the scenario's checks refused before running
    for c in cases:
        r = records.get(c.hash)
        if r is not None and r["status"] == "error":
            entry = refused.setdefault(c.params["column"], {"cases": 0, "message": r["message"]})
            entry["cases"] += 1
    table["refused"] = refused
    table["cpu_distinct_s"] = sum(sum(v) for v in cpu.values())
    return table


#: The bases of the results file: name -> (the table's folder under ``--results``, its base).
BASES = {"paper_contact": "paper", "ur10_pair": "ur10"}


def saturating_joints(peaks: dict) -> dict[str, list[int]]:
    """Per robot, the joints whose saturation-column limit can fall below the lift's peak
    torque (``SATURATION_FRACTION × U(0.95, 1.05) × lift`` above the floor ``1.02 × other``
    for some draw): none means the column cannot saturate on that base."""
    from drake_coop.studies.reference_table import SATURATION_FRACTION

    out = {}
    for robot, p in peaks.items():
        out[robot] = [j for j, (lift, other) in enumerate(zip(p["lift"], p["other"]))
                      if SATURATION_FRACTION * 1.05 * lift > 1.02 * other]
    return out


def planned_cases(base: Path, draws: int) -> int:
    """The distinct cases of the whole friction-held table on ``base`` (every row under
    :data:`~drake_coop.studies.reference_table.FRICTION_COLUMNS`, ``draws`` a cell): the
    identified column has the ±30 % column's structure (every row's draw its own, the
    applied-torque residual the momentum observer's), so it is counted as that column."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import ROWS, expand_table

    from drake_coop.scenario.model_check import check_models

    scenario = load_scenario(base)
    peaks = {r.name: {"lift": [1.0] * n, "other": [0.5] * n}
             for r, n in zip(scenario.robots, check_models(scenario))}
    rows = [r.name for r in ROWS]
    count = 0
    for cols in (["exact"], ["model_30"], ["model_30"], ["coulomb"], ["saturation"]):
        count += len({c.hash for c in expand_table(scenario, rows, cols, draws, peaks=peaks)})
    return count


def results(folder: Path, draws: int, rows: list[str], cols: list[str]) -> dict:
    """The results file's content from ``folder`` (as the commands on the page leave it:
    ``bases/``, one table folder per base, ``logs/`` of ``/usr/bin/time -v``,
    ``full_paper.json``, ``rerun.json``, ``identification_cpu.json``): per base the table of
    ``rows`` × ``cols`` (the cells whose every draw finished), its planned CPU (the finished
    distinct cases' own CPU, the unfinished ones at their mean, and the identifications' CPU
    as ``identification_cpu.json`` gives it per base: a run's process CPU less its cases'),
    the stages' process CPU and wall, the overlap check and the rerun."""
    from bench.reference_table import time_log
    from drake_coop.studies.reference_table import SEGMENT, T_SHORT

    found = folder / "identification_cpu.json"
    identification_cpu = json.loads(found.read_text()) if found.is_file() else {}

    out: dict = {"draws": draws, "segment": {**SEGMENT, "t_end_case": T_SHORT}, "bases": {}}
    for name, sub in BASES.items():
        if not (folder / sub / "cases").is_dir():
            continue
        table = snapshot(folder / sub, folder / "bases" / f"{name}.yaml", rows, cols, draws)
        for cells in table["cells"].values():      # a cell not yet at its draws: pending
            for col in [c for c, s in cells.items() if s["n"] < draws]:
                del cells[col]
        out["bases"][name] = table
        table["scenario_yaml"] = (folder / "bases" / f"{name}.yaml").read_text()
        cpu = [v for v in table["cpu_per_case_s"].values()]
        from drake_coop.studies.reference_table import FRICTION_COLUMNS

        every = set(FRICTION_COLUMNS) <= set(table["columns"])
        # every column expanded (the identified one's models found): its distinct cases, else
        # the count from the columns' structure
        table["planned_cases"] = (table["distinct_cases"] if every else
                                  planned_cases(folder / "bases" / f"{name}.yaml", draws))
        ident = identification_cpu.get(name)
        if ident is not None:
            table["identification_cpu_s"] = ident
        if cpu:
            table["cpu_per_case_mean_s"] = sum(cpu) / len(cpu)
            left = table["planned_cases"] - table["distinct_finished"]
            # the finished cases' own CPU, the rest at the mean, and the identifications
            table["planned_cpu_s"] = (table["cpu_distinct_s"] + left * table["cpu_per_case_mean_s"]
                                      + (ident or 0.0))
        calibration = folder / sub / "calibration.json"
        if calibration.is_file():
            table["peaks"] = json.loads(calibration.read_text())["peaks"]
            table["saturating_joints"] = saturating_joints(table["peaks"])
    planned = [b["planned_cpu_s"] for b in out["bases"].values() if "planned_cpu_s" in b]
    out["planned_wall_min_2_cores"] = sum(planned) / 2.0 / 60.0
    # the free cores (a cluster's) that bring the part within the hour it was sized for
    out["planned_cpu_s"] = sum(planned)
    out["cores_for_60_min"] = math.ceil(sum(planned) / 3600.0)
    out["planned_wall_min_at_cores_for_60"] = (sum(planned) / out["cores_for_60_min"] / 60.0
                                               if planned else 0.0)
    logs = sorted((folder / "logs").glob("*.log"))
    out["runs"] = [time_log(p) for p in logs]
    out["cpu_s"] = sum(r.get("cpu_s", 0.0) for r in out["runs"])
    full = folder / "full_paper.json"
    if full.is_file() and "paper_contact" in out["bases"]:
        out["full"] = json.loads(full.read_text())
        out["overlap"] = overlap(out["bases"]["paper_contact"], out["full"])
    control = folder / "paper_control.json"
    if control.is_file():
        out["paper_control"] = json.loads(control.read_text())
    rerun = folder / "rerun.json"
    if rerun.is_file():
        out["rerun"] = json.loads(rerun.read_text())
    cluster = folder / "cluster.json"
    if cluster.is_file():
        out["cluster"] = json.loads(cluster.read_text())
    return out


def page_tables(data: dict, base: str, source: str = "reference_table_friction") -> str:
    """The tables of one base as Markdown whose numbers are ``{result}`` roles on ``source``:
    the squeeze error and the estimate's error (median [95 %], p90), then slips, drops and the
    worst slide per cell; ``pending`` where a cell has not all its draws."""
    from drake_coop.studies.reference_table import ROWS, columns

    table = data["bases"][base]
    labels = {r.name: r.label for r in ROWS}
    col_labels = {c.name: c.label for c in columns({}, {})}
    rows = [r for r in table["rows"] if r in table["cells"]]
    cols = [c for c in table["columns"] if c not in table.get("refused", {})
            and any(c in table["cells"][r] for r in rows)]
    head = "| force source | " + " | ".join(col_labels[c] for c in cols) + " |\n" \
        + "|" + " --- |" * (len(cols) + 1) + "\n"

    def role(path: str, fmt: str = ".3f") -> str:
        return f"{{result}}`{source}:bases.{base}.cells.{path} as {fmt}`"

    def grid(cell_text) -> str:
        lines = []
        for row in rows:
            cells = [cell_text(row, col) if col in table["cells"][row] else "pending"
                     for col in cols]
            lines.append(f"| {labels[row]} | " + " | ".join(cells) + " |")
        return head + "\n".join(lines) + "\n"

    def error(key: str):
        def text(row: str, col: str) -> str:
            c = f"{row}.{col}.{key}"
            cell = table["cells"][row][col]
            if cell["diverged"] >= cell["n"]:          # no draw finished: no median
                return f"— ({role(f'{row}.{col}.diverged', '.0f')} of {cell['n']} diverged)"
            out = (f"{role(c + '.median.0')} [{role(c + '.median.1')}, {role(c + '.median.2')}]"
                   f" / {role(c + '.p90.0')}")
            if table["cells"][row][col]["diverged"]:
                out += f" ({role(f'{row}.{col}.diverged', '.0f')} diverged)"
            return out
        return text

    def held(row: str, col: str) -> str:
        c = f"{row}.{col}"
        return (f"{role(c + '.slips', '.0f')} ({role(c + '.slipped', '.0f')} draws) / "
                f"{role(c + '.dropped', '.0f')} / {role(c + '.slide.median.0', '.3f [mm]')} mm "
                f"[{role(c + '.slide.p90.0', '.3f [mm]')}]")

    return ("**Squeeze error λ − λ_d** (circle RMS, worst robot, N): median [95 %] / p90\n\n"
            + grid(error("squeeze"))
            + "\n**Estimate error λ̂ − λ** (circle RMS, worst robot, N): median [95 %] / p90\n\n"
            + grid(error("estimate"))
            + "\n**Slips (draws with one) / draws with a drop / the worst pad's slide since the "
              "grasp, median [p90]**\n\n" + grid(held))


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
    parser.add_argument("--compare", nargs=2, default=None, metavar="DIR",
                        help="compare two table folders of one base case by case (--out JSON)")
    parser.add_argument("--paper-control", action="store_true",
                        help="one short case of contact.yaml as shipped (object_model none)")
    parser.add_argument("--page", default=None, metavar="JSON",
                        help="print the results file's tables with {result} roles")
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
    if args.paper_control:
        Path(args.out).write_text(json.dumps(paper_control(), indent=1) + "\n")
    if args.page:
        data = json.loads(Path(args.page).read_text())
        for base in data["bases"]:
            print(f"<!-- {base} -->\n" + page_tables(data, base))
    if args.rerun:
        from bench.reference_table import rerun

        Path(args.out).write_text(json.dumps(rerun(Path(args.rerun), args.count), indent=1)
                                  + "\n")
    if args.compare:
        from bench.reference_table import compare_stores

        result = compare_stores(*map(Path, args.compare))
        result["folders"] = args.compare
        Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
        print({k: v for k, v in result.items() if k != "differ"})
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
