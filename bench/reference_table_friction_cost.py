"""What a friction-held case of the reference table costs, before and after a change of the
worker, with its numbers checked against the table's stored ones.

``python bench/reference_table_friction_cost.py --tables DIR --baseline TREE --out JSON``
takes finished cases of the friction-held tables in ``DIR`` (``DIR/paper/cases``,
``DIR/ur10/cases``: the folders ``drake-coop reference-table`` wrote for the bases
``paper_contact`` and ``ur10_pair``), a few draws of each of ``--cells``, and runs them as
the table's worker does (one process per base, version and round, the cases one after
another, :func:`~drake_coop.studies.reference_engine.run_batch`), with the package in
``TREE`` (the code before, e.g. ``git archive`` of an older commit) and with this
checkout's: the two processes of a round run at the same time, so that both see the same
load (on a loaded machine the CPU seconds of a case drift with the load). Each case's
process CPU seconds are the table's own (``cpu_time_s``: ``time.process_time`` around the
case, the per-process import left out). Every rerun's metrics are compared with the stored
case: ``same`` is exact equality, ``max_rel`` the largest relative difference of the table's
numbers (:func:`~drake_coop.studies.reference_table.per_draw`).

The planned minutes scale the results file's plan (``docs/results/
reference_table_friction.json``: ``planned_cpu_s`` per base, its cases' mean CPU as the table
measured it) by the after/before ratio of the paired cases, on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The bases and their tables' folders under ``--tables``.
BASES = {"paper_contact": "paper", "ur10_pair": "ur10"}
#: The cells whose draws are rerun: (row, column).
CELLS = (("observer", "model_30"), ("momentum", "coulomb"))


def pick(folder: Path, cells, draws: int) -> list[Path]:
    """The stored cases of ``cells`` with draws ``0 .. draws-1`` in ``folder/cases``, in cell
    then draw order.

    Parameters
    ----------
    folder : Path
        A table's folder.
    cells : sequence of (str, str)
        ``(row, column)`` pairs.
    draws : int
        Draws per cell.

    Returns
    -------
    list of Path
        The case files found (a draw not finished is left out).
    """
    found = {}
    for path in sorted((folder / "cases").glob("*.json")):
        values = json.loads(path.read_text())["values"]
        key = (values["row"], values["column"])
        if key in cells and values["draw"] < draws and values.get("variant") is None:
            found[(list(cells).index(key), values["draw"])] = path
    return [found[k] for k in sorted(found)]


def worker(files: list[str]) -> list[dict]:
    """Run the stored cases ``files`` in this process, one after another (the table's
    worker), each compared with its stored numbers.

    Parameters
    ----------
    files : list of str
        Case files of a table's store.

    Returns
    -------
    list of dict
        Per case: ``hash``, ``cpu_time_s``, ``same`` (the metrics equal to the stored ones),
        ``max_rel`` (the largest relative difference of the table's numbers).
    """
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import per_draw

    out = []
    for name in files:
        stored = json.loads(Path(name).read_text())
        (_, record), = run_batch([(stored["hash"], stored["scenario_yaml"],
                                   stored["values"]["variant"])], stored["t_end"])
        a, b = per_draw(record), per_draw(stored)
        rel = max((abs(a[k] - b[k]) / max(abs(b[k]), 1e-300) for k in b), default=0.0)
        out.append({"hash": stored["hash"], "cpu_time_s": record["cpu_time_s"],
                    "stored_cpu_time_s": stored["cpu_time_s"],
                    "same": record["metrics"] == stored["metrics"], "max_rel": rel})
    return out


#: What would cut the plant's cost, each with its change to a case: the pads' tetrahedral
#: mesh twice as coarse (``mesh_resolution_hint`` 5 mm -> 10 mm), the plant step 3 ms ->
#: 4.5 ms (two steps a 9 ms control tick instead of three).
ALTERNATIVES = ("pad_mesh_10mm", "plant_step_4p5ms")


def _coarser_pads(hint: float):
    """Wrap the contact object's pad material so that it also sets the pads' mesh
    resolution hint to ``hint`` (m); returns the original to put back."""
    import drake_coop.plant.grasp as grasp
    from pydrake.geometry import ProximityProperties, RoleAssign

    original = grasp._set_pad_material

    def coarser(scene_graph, plant, pads, mu, modulus):
        original(scene_graph, plant, pads, mu, modulus)
        inspector = scene_graph.model_inspector()
        for pad in pads:
            props = ProximityProperties(inspector.GetProximityProperties(pad))
            props.UpdateProperty("hydroelastic", "resolution_hint", float(hint))
            scene_graph.AssignRole(plant.get_source_id(), pad, props, RoleAssign.kReplace)
    grasp._set_pad_material = coarser
    return original


def alternatives(files: list[str]) -> list[dict]:
    """Each stored case of ``files`` rerun as stored, then under each of
    :data:`ALTERNATIVES`, in this process: the table's numbers and CPU seconds of each.

    Parameters
    ----------
    files : list of str
        Case files of a table's store.

    Returns
    -------
    list of dict
        Per case: ``hash``, ``stored`` (the stored numbers), ``runs`` (per version:
        ``numbers``, ``status`` and ``cpu_time_s``).
    """
    import drake_coop.plant.grasp as grasp
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import per_draw

    out = []
    for name in files:
        stored = json.loads(Path(name).read_text())
        runs = {}
        for version in ("as_stored", *ALTERNATIVES):
            text, original = stored["scenario_yaml"], None
            if version == "plant_step_4p5ms":
                scenario = load_scenario(data=text)
                scenario.plant.time_step = 0.0045
                text = dump_scenario(scenario)
            elif version == "pad_mesh_10mm":
                original = _coarser_pads(0.010)
            try:
                (_, record), = run_batch([(stored["hash"], text, stored["values"]["variant"])],
                                         stored["t_end"])
            finally:
                if original is not None:
                    grasp._set_pad_material = original
            runs[version] = {"status": record["status"], "cpu_time_s": record["cpu_time_s"],
                             "numbers": per_draw(record) if record["status"] == "ok" else None}
            print(version, json.dumps(runs[version]), file=sys.stderr, flush=True)
        out.append({"hash": stored["hash"], "values": stored["values"],
                    "stored": per_draw(stored), "runs": runs})
    return out


def _timed(acc: dict, label: str, f):
    """``f`` wrapped to add its process CPU seconds to ``acc[label]`` (nested calls of
    other wrapped functions subtracted: each label's own seconds)."""
    stack = acc.setdefault("_stack", [])

    def timed(*args, **kwargs):
        start = time.process_time()
        stack.append(0.0)
        try:
            return f(*args, **kwargs)
        finally:
            spent = time.process_time() - start
            inner = stack.pop()
            acc[label] = acc.get(label, 0.0) + spent - inner
            if stack:
                stack[-1] += spent
    return timed


def profile(files: list[str]) -> list[dict]:
    """Where a stored case's CPU goes, in this process: the simulator's steps
    (``AdvanceTo``), and inside them the Python systems' updates and outputs (each method
    ``_calc*``/``_update*``/``_latch`` of the package's ``LeafSystem`` classes, its own
    seconds), the rest of the steps being Drake's (the plant's contact geometry and solver,
    the framework, the loggers); outside them the run's stages.

    Parameters
    ----------
    files : list of str
        Case files of a table's store.

    Returns
    -------
    list of dict
        Per case: ``cpu_time_s``, ``advance_s``, ``python_systems_s`` (and ``systems``, per
        method), ``drake_steps_s`` and ``stages`` (per stage outside the steps).
    """
    import importlib
    import inspect
    import pkgutil

    import drake_coop
    import drake_coop.experiment.simulate as simulate
    import drake_coop.results.metrics as metrics
    import drake_coop.scenario.loading as loading
    from drake_coop.experiment import squeeze_check
    from pydrake.systems.framework import LeafSystem

    from drake_coop.studies.reference_engine import run_batch

    acc: dict = {}
    systems = set()
    for info in pkgutil.walk_packages(drake_coop.__path__, "drake_coop."):
        if info.name.endswith("__main__"):     # the command line: runs on import
            continue
        try:
            module = importlib.import_module(info.name)
        except Exception:            # an optional extra (e.g. Ray, LCM tools) not installed
            continue
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if (issubclass(cls, LeafSystem) and cls.__module__ == module.__name__
                    and cls not in systems):
                systems.add(cls)
                for name, f in list(vars(cls).items()):
                    if inspect.isfunction(f) and name.startswith(("_calc", "_update", "_latch")):
                        setattr(cls, name, _timed(acc, f"system:{cls.__name__}.{name}", f))
    for module, names in ((simulate, ("build_experiment", "initialize", "_check_guards",
                                      "plant_sample", "finish_last_tick", "collect_logs",
                                      "first_failure_in_logs")),
                          (squeeze_check, ("check_squeeze_limits",)),
                          (loading, ("load_scenario",)), (metrics, ("compute_metrics",))):
        for name in names:
            setattr(module, name, _timed(acc, f"stage:{name}", getattr(module, name)))

    class Timed(simulate.Simulator):
        def AdvanceTo(self, t):
            return _timed(acc, "advance", super().AdvanceTo)(t)
    simulate.Simulator = Timed
    out = []
    for name in files:
        stored = json.loads(Path(name).read_text())
        for key in [k for k in acc if k != "_stack"]:     # the wrappers share the stack
            del acc[key]
        (_, record), = run_batch([(stored["hash"], stored["scenario_yaml"],
                                   stored["values"]["variant"])], stored["t_end"])
        own = {k: v for k, v in acc.items() if not k.startswith("_")}
        python = {k.split(":", 1)[1]: v for k, v in own.items() if k.startswith("system:")}
        advance = own.get("advance", 0.0) + sum(python.values())   # the steps, inclusive
        stages = {k.split(":", 1)[1]: v for k, v in own.items() if k.startswith("stage:")}
        stages["other"] = record["cpu_time_s"] - advance - sum(stages.values())
        out.append({"hash": stored["hash"], "values": stored["values"],
                    "cpu_time_s": record["cpu_time_s"], "advance_s": advance,
                    "python_systems_s": sum(python.values()),
                    "drake_steps_s": own.get("advance", 0.0),
                    "systems": dict(sorted(python.items(), key=lambda kv: -kv[1])),
                    "stages": stages})
        print(json.dumps(out[-1]["stages"]), out[-1]["python_systems_s"], file=sys.stderr)
    return out


def run_versions(trees: dict[str, Path], files: list[Path]) -> dict[str, dict]:
    """One process per version, all at once (each sees the same load while it runs), each
    with its tree's package running ``files`` (:func:`worker`).

    Parameters
    ----------
    trees : dict of str to Path
        The folder holding the ``drake_coop`` package of each version, by name.
    files : list of Path
        The cases.

    Returns
    -------
    dict of str to dict
        Per version: ``cases`` (:func:`worker`'s), ``package`` (the imported package's
        folder), ``load_before``/``load_after`` (the 1-minute load average around the pair).
    """
    load = os.getloadavg()[0]
    procs = {name: subprocess.Popen(
        [sys.executable, str(Path(__file__).resolve()), "--worker", *map(str, files)],
        env={**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"},
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for name, tree in trees.items()}
    out = {}
    for name, proc in procs.items():
        stdout, stderr = proc.communicate()
        if proc.returncode != 0:
            raise RuntimeError(f"{name}: the worker failed: {stderr.strip()[-300:]}")
        out[name] = json.loads(stdout.strip().splitlines()[-1])
    after = os.getloadavg()[0]
    return {name: {**r, "load_before": load, "load_after": after} for name, r in out.items()}


def measure(tables: Path, baseline: Path, cells, draws: int, rounds: int) -> dict:
    """Alternated runs of the stored cases of every base, before (``baseline``) and after
    (this checkout).

    Parameters
    ----------
    tables : Path
        The folder holding the tables (``paper/``, ``ur10/``).
    baseline : Path
        The tree of the code before.
    cells : sequence of (str, str)
        The cells rerun.
    draws : int
        Draws per cell.
    rounds : int
        Rounds of a before/after pair per base (the pair's processes run at once).

    Returns
    -------
    dict
        Per base its cases and runs, the mean CPU per case before and after, their ratio,
        whether every rerun gave the stored numbers, and the planned minutes.
    """
    plan = json.loads((ROOT / "docs" / "results" / "reference_table_friction.json")
                      .read_text())["bases"]
    out: dict = {"cells": [list(c) for c in cells], "draws": draws, "rounds": rounds,
                 "bases": {}}
    for name, sub in BASES.items():
        files = pick(tables / sub, cells, draws)
        runs = []
        for r in range(rounds):
            for label, run in run_versions({"before": baseline, "after": ROOT},
                                           files).items():
                runs.append({"version": label, "round": r, **run})
                print(name, label, r, [round(c["cpu_time_s"], 3) for c in run["cases"]],
                      flush=True)
        cpu = {v: [c["cpu_time_s"] for run in runs if run["version"] == v
                   for c in run["cases"]] for v in ("before", "after")}
        mean = {v: sum(x) / len(x) for v, x in cpu.items()}
        base = {"cases": [f.stem for f in files], "runs": runs,
                "cpu_per_case_s": mean, "ratio": mean["after"] / mean["before"],
                "all_same": all(c["same"] for run in runs for c in run["cases"]),
                "max_rel": max(c["max_rel"] for run in runs for c in run["cases"])}
        stored = plan.get(name, {})
        if "planned_cpu_s" in stored:
            base["planned_cases"] = stored["planned_cases"]
            base["planned_cpu_s_before"] = stored["planned_cpu_s"]
            base["planned_cpu_s_after"] = stored["planned_cpu_s"] * base["ratio"]
        out["bases"][name] = base
    planned = [b for b in out["bases"].values() if "planned_cpu_s_after" in b]
    out["planned_wall_min_2_cores"] = {
        v: sum(b[f"planned_cpu_s_{v}"] for b in planned) / 2.0 / 60.0
        for v in ("before", "after")}
    return out


def _merge(path: Path, result: dict) -> None:
    """Write ``result``'s keys into the JSON file ``path``, keeping its other keys (the
    measurement and the alternatives are written by separate commands)."""
    data = json.loads(path.read_text()) if path.is_file() else {}
    data.update(result)
    path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")


def main(argv: list[str] | None = None) -> int:
    """The command line (see the module's docstring).

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code.
    """
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    p.add_argument("--profile", nargs="+", metavar="CASE",
                   help="where these stored cases' CPU goes (see profile()); with --out")
    p.add_argument("--alternatives", nargs="+", metavar="CASE",
                   help="rerun these stored cases under each of ALTERNATIVES; with --out")
    p.add_argument("--tables", type=Path, help="the folder holding paper/ and ur10/")
    p.add_argument("--baseline", type=Path, help="the tree of the code before")
    p.add_argument("--draws", type=int, default=2)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    if args.worker:
        import drake_coop

        print(json.dumps({"package": str(Path(drake_coop.__file__).parent),
                          "cases": worker(args.worker)}))
        return 0
    if args.profile:
        if args.out is None:
            p.error("--profile needs --out")
        _merge(args.out, {"profile": profile(args.profile)})
        return 0
    if args.alternatives:
        if args.out is None:
            p.error("--alternatives needs --out")
        _merge(args.out, {"alternatives": alternatives(args.alternatives)})
        return 0
    if args.tables is None or args.baseline is None or args.out is None:
        p.error("--tables, --baseline and --out are needed")
    start = time.process_time()
    result = measure(args.tables, args.baseline, CELLS, args.draws, args.rounds)
    result["driver_cpu_s"] = time.process_time() - start
    _merge(args.out, result)
    print(json.dumps({k: v for k, v in result.items() if k != "bases"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
