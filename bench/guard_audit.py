"""The committed run results against the failure guards: no result says ``ok`` past a guard.

The failure guards (:mod:`drake_coop.experiment.failure`) came after some shipped results
were made: a study's ``results.csv`` can record ``ok`` for a case that a run today ends
``failed`` (the model-mismatch study's 28 N squeeze error, beyond ``max_squeeze_error``).
This script reads each committed result's logged maxima and applies the guards' own test
(:func:`~drake_coop.experiment.failure.summary_failure`, the bounds of
:class:`~drake_coop.scenario.schema.Guards`; no shipped study or run changes them)::

    python -m bench.guard_audit            # list what a guard would now stop
    python -m bench.guard_audit --write    # rewrite those rows' status and message
    python -m bench.guard_audit --figures  # redraw every committed study figure

Files read:

* every study's ``docs/figures/studies/*_results.csv`` (its row's ``robotN.<error>.max``
  columns are the study's phase, ``circle`` for every shipped study): a row ``ok`` past a
  guard becomes ``failed`` with the message ``failed in the circle phase: <what> (from the
  logged maximum; not re-run)``; its metrics stay as the run logged them (a run made today
  stops at the trip, so its numbers after it would not exist);
* every shipped study case file (``docs/figures/studies/*_cases/*.json``, each phase of its
  ``metrics``): the same rewrite of its ``status`` and ``message``;
* every benchmark row in ``docs/results/*.json`` that says ``ok`` or ``completed`` and keeps
  its circle's maxima per robot (``object_tilt_max``, ``object_position_error_max``: the rows
  of :func:`bench.lab_arms_object.measure`): listed, to be run again (none is today);
* every shipped run's ``docs/figures/run_results/*/metrics.json`` (each phase): there is no
  status to rewrite; a run past a guard is listed, and its page must say so
  (:data:`FAILED_RUNS` names those whose pages do).

The committed study figures (``docs/figures/studies/<name>_*.png`` beside
``<name>_results.csv``) are drawn from those files: ``--write`` redraws the figures of each
study whose rows it rewrote, ``--figures`` every study's (:func:`redraw`, with
:func:`drake_coop.studies.plots.plot_results` from the results and ``studies/<name>.yaml``),
so a row rewritten ``failed`` is drawn ✕. A figure whose source (its PNG text field) is not
its ``results.csv`` as committed is listed.

Only what the maxima prove is seen: a guard tripped in a phase the file does not summarise,
or a pad's error whose norm (not its worst axis) passes the bound, is not.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import shutil
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The committed studies' results.
STUDY_RESULTS = "docs/figures/studies/*_results.csv"
#: The committed studies' case files (a study's ``--out`` folder shipped with its cases).
STUDY_CASES = "docs/figures/studies/*_cases/*.json"
#: The folder of the committed studies' results and figures, and each study's file.
STUDY_FIGURES = "docs/figures/studies"
STUDY_FILE = "studies/{name}.yaml"
#: The committed single runs' metrics.
RUN_METRICS = "docs/figures/run_results/*/metrics.json"
#: The committed benchmark results (rows of :func:`bench.lab_arms_object.measure`).
BENCH_RESULTS = "docs/results/*.json"
#: Shipped runs that a guard now stops, each with its page (which says so); the test
#: ``tests/test_committed_results_guards.py`` holds the list to the files.
FAILED_RUNS = {"heavy_none": "docs/claims/object_carry.md"}
#: The message of a rewritten row: the phase and the failure's text.
MESSAGE = "failed in the {phase} phase: {who} {text} (from the logged maximum; not re-run)"
_ERRORS = ("position_error", "force_error", "object_tilt", "object_position_error")


def _row_maxima(row: dict) -> dict:
    """Per robot (``robot1``, ...), the row's ``<error>.max`` of :data:`_ERRORS`."""
    out: dict = {}
    for key, value in row.items():
        parts = key.split(".")
        if len(parts) == 3 and parts[0].startswith("robot") and parts[2] == "max" \
                and parts[1] in _ERRORS and value not in ("", None):
            out.setdefault(parts[0], {})[parts[1]] = float(value)
    return out


def audit_csv(path: Path, phase: str = "circle") -> tuple[list[str], list[dict], list]:
    """A study's results: its header, rows and ``(index, Failure)`` of each ``ok`` row past
    a guard.

    Parameters
    ----------
    path : Path
        A ``results.csv``.
    phase : str
        The study's phase (its columns' phase).

    Returns
    -------
    header : list of str
        The columns.
    rows : list of dict
        The rows.
    failures : list of tuple
        ``(row index, Failure)`` for each row that says ``ok`` past a guard.
    """
    from drake_coop.experiment.failure import summary_failure
    from drake_coop.scenario.schema import Guards

    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        header, rows = list(reader.fieldnames or []), list(reader)
    failures = []
    if "status" not in header:
        return header, rows, failures
    for k, row in enumerate(rows):
        if row["status"] != "ok":
            continue
        failure = summary_failure(_row_maxima(row), Guards(), phase)
        if failure is not None:
            failures.append((k, failure))
    return header, rows, failures


def audit_metrics(metrics: dict) -> list:
    """A run's metrics (``metrics.json``, a case file's ``metrics``): ``(phase, Failure)`` of
    each phase whose maxima pass a guard.

    Parameters
    ----------
    metrics : dict
        ``metrics[robot][phase][error] = {"max": ...}``
        (:func:`~drake_coop.results.metrics.compute_metrics`).

    Returns
    -------
    list of tuple
        ``(phase, Failure)``, at most one per phase.
    """
    from drake_coop.experiment.failure import summary_failure
    from drake_coop.scenario.schema import Guards

    phases = {p for robot in metrics.values() for p in robot if p != "all"}
    out = []
    for phase in sorted(phases):
        maxima = {}
        for robot, per_phase in metrics.items():
            entry = per_phase.get(phase, {})
            m = {e: entry[e]["max"] for e in _ERRORS[1:] if e in entry}
            axes = [entry[a]["max"] for a in ("x_tilde", "y_tilde", "z_tilde") if a in entry]
            if axes:
                m["position_error"] = max(axes)
            maxima[robot] = m
        failure = summary_failure(maxima, Guards(), phase)
        if failure is not None:
            out.append((phase, failure))
    return out


def audit_bench(data) -> list:
    """A benchmark results file: ``(path in the file, Failure)`` of each row that says ``ok``
    or ``completed`` while its circle's maxima pass a guard.

    Parameters
    ----------
    data : dict or list
        The file's JSON.

    Returns
    -------
    list of tuple
        ``(dotted path of the row, Failure)``.
    """
    from drake_coop.experiment.failure import summary_failure
    from drake_coop.scenario.schema import Guards

    out = []

    def walk(node, path):
        if isinstance(node, dict):
            robots = node.get("robots")
            if node.get("status") in ("ok", "completed") and isinstance(robots, dict):
                maxima = {name: {e: r[f"{e}_max"] for e in _ERRORS[2:] if f"{e}_max" in r}
                          for name, r in robots.items() if isinstance(r, dict)}
                failure = summary_failure(maxima, Guards(), "circle")
                if failure is not None:
                    out.append((".".join(path), failure))
            for key, value in node.items():
                walk(value, [*path, str(key)])
        elif isinstance(node, list):
            for k, value in enumerate(node):
                walk(value, [*path, str(k)])

    walk(data, [])
    return out


def rewrite(path: Path, header: list[str], rows: list[dict], failures: list,
            phase: str = "circle") -> None:
    """Write ``path`` again with each failing row's status ``failed`` and its message.

    Parameters
    ----------
    path : Path
        The ``results.csv``.
    header : list of str
        Its columns.
    rows : list of dict
        Its rows.
    failures : list of tuple
        ``(row index, Failure)`` of :func:`audit_csv`.
    phase : str
        The phase named in the message.
    """
    for k, failure in failures:
        rows[k]["status"] = "failed"
        rows[k]["message"] = MESSAGE.format(phase=phase, who=failure.who, text=failure.text)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=header, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    path.write_text(buffer.getvalue())


def study_figures() -> dict[str, list[Path]]:
    """Each committed study's figures: name → the PNGs in :data:`STUDY_FIGURES` named
    ``<name>_*.png`` (the longest such name owns a figure: ``object_carry_lab_vs_base.png``
    is ``object_carry_lab``'s, not ``object_carry``'s).

    Returns
    -------
    dict of str to list of Path
        Every study with a ``<name>_results.csv``, its figures sorted (maybe none).
    """
    names = sorted(p.name[:-len("_results.csv")] for p in ROOT.glob(STUDY_RESULTS))
    out: dict[str, list[Path]] = {name: [] for name in names}
    for png in sorted((ROOT / STUDY_FIGURES).glob("*.png")):
        owner = max((n for n in names if png.name.startswith(n + "_")), key=len, default=None)
        if owner is not None:
            out[owner].append(png)
    return out


def stale_figures() -> list[Path]:
    """The committed study figures not drawn from their ``results.csv`` as it is (their PNG
    text field :data:`~drake_coop.studies.plots.SOURCE_KEY` missing or naming other bytes).

    Returns
    -------
    list of Path
        The stale figures.
    """
    from PIL import Image

    from drake_coop.studies.plots import SOURCE_KEY, source_text

    stale = []
    for name, figures in study_figures().items():
        source = source_text(ROOT / STUDY_FIGURES / f"{name}_results.csv")
        for png in figures:
            with Image.open(png) as image:
                if image.text.get(SOURCE_KEY) != source:
                    stale.append(png)
    return stale


def redraw(name: str, figures: list[Path]) -> list[Path]:
    """Draw study ``name``'s committed ``figures`` again from its committed results and
    study file (each figure the study draws is drawn; only those named are replaced).

    Parameters
    ----------
    name : str
        The study (``<name>_results.csv``, ``studies/<name>.yaml``).
    figures : list of Path
        The figures to replace.

    Returns
    -------
    list of Path
        ``figures``, rewritten.

    Raises
    ------
    ValueError
        If the results do not fit the study file, or a figure is not one the study draws.
    """
    from drake_coop.studies.plots import plot_results

    with tempfile.TemporaryDirectory() as tmp:
        drawn = {p.name: p for p in plot_results(ROOT / STUDY_FILE.format(name=name),
                                                 ROOT / STUDY_FIGURES / f"{name}_results.csv",
                                                 tmp)}
        for png in figures:
            if png.name not in drawn:
                raise ValueError(f"{png}: study {name} draws no such figure "
                                 f"(it draws {', '.join(sorted(drawn))})")
            shutil.copyfile(drawn[png.name], png)
    return figures


def main(argv=None) -> int:
    """List (or with ``--write`` rewrite) the committed results past a guard.

    Parameters
    ----------
    argv : list of str or None
        The command line (None: ``sys.argv``).

    Returns
    -------
    int
        0 when nothing says ``ok`` past a guard (after ``--write``), else 1.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true",
                        help="rewrite the failing rows' status and message in place, and "
                             "redraw those studies' figures")
    parser.add_argument("--figures", action="store_true",
                        help="redraw every committed study's figures from its results")
    args = parser.parse_args(argv)
    left = 0
    rewritten = set()
    for path in sorted(ROOT.glob(STUDY_RESULTS)):
        header, rows, failures = audit_csv(path)
        for k, failure in failures:
            print(f"{path.relative_to(ROOT)} row {rows[k]['index']}: ok, but "
                  f"{failure.who} {failure.text}")
        if failures and args.write:
            rewrite(path, header, rows, failures)
            rewritten.add(path.name[:-len("_results.csv")])
        elif failures:
            left += len(failures)
    for name, figures in study_figures().items():
        if figures and (args.figures or name in rewritten):
            for png in redraw(name, figures):
                print(f"redrew {png.relative_to(ROOT)}")
    for png in stale_figures():
        print(f"{png.relative_to(ROOT)}: not drawn from its results.csv as committed "
              "(redraw with --figures)")
        left += 1
    for path in sorted(ROOT.glob(STUDY_CASES)):
        record = json.loads(path.read_text())
        found = audit_metrics(record.get("metrics") or {}) if record.get("status") == "ok" else []
        for phase, failure in found[:1]:
            print(f"{path.relative_to(ROOT)}: ok, but {failure.who} {failure.text} ({phase})")
            if args.write:
                record["status"] = "failed"
                record["message"] = MESSAGE.format(phase=phase, who=failure.who,
                                                   text=failure.text)
                path.write_text(json.dumps(record, indent=1, allow_nan=False) + "\n")
            else:
                left += 1
    for path in sorted(ROOT.glob(BENCH_RESULTS)):
        for where, failure in audit_bench(json.loads(path.read_text())):
            print(f"{path.relative_to(ROOT)} {where}: ok, but {failure.who} {failure.text}")
            left += 1
    for path in sorted(ROOT.glob(RUN_METRICS)):
        for phase, failure in audit_metrics(json.loads(path.read_text())):
            name = path.parent.name
            print(f"{path.relative_to(ROOT)} ({phase}): {failure.who} {failure.text}"
                  + (f" (said on {FAILED_RUNS[name]})" if name in FAILED_RUNS else ""))
            left += name not in FAILED_RUNS
    return 1 if left else 0


if __name__ == "__main__":
    raise SystemExit(main())
