"""The fast suite's CPU time per test: a pytest plugin that records it, a runner, a comparison.

``python bench/suite_cpu.py run OUT.json [--repo DIR] [--python PY]`` runs the README's fast
test command (``python -m pytest -q -p no:cacheprovider -m "not slow"``, as ``.ci/run`` does) in
``DIR`` (another checkout, e.g. an older commit's, with its own environment's ``PY``) with this
file loaded as a plugin (``-p suite_cpu``), which writes, for each test id, the process CPU time
(:func:`time.process_time`, user + system) of its setup, call and teardown, and the CPU time of the
child processes it waited for (a CLI run in a subprocess, a worker), in seconds. A fixture's cost
falls on the test whose setup builds it (a module- or session-scoped fixture: the first test that
uses it) and its teardown on the test after which it is torn down, so the per-test values add up
to the suite's test CPU. Collection (imports, parametrization) is recorded apart.

``python bench/suite_cpu.py compare BASE.json NEW.json [--patch PART.json] [--out RESULT.json]``
compares two such files by test id: the CPU of the ids both ran, the ids only one ran, the
largest changes; ``--patch`` replaces the test files a partial run ran by that run's
(:func:`merge`).

CPU time, not wall time: the machine may be shared, and CPU time inflates less than wall time
under load (cache and frequency effects still do: run two measurements back to back).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import pytest

_OUT_ENV = "SUITE_CPU_OUT"
_PHASES = ("setup", "call", "teardown")


def _children_cpu() -> float:
    """CPU seconds (user + system) of the waited-for child processes so far."""
    t = os.times()
    return t.children_user + t.children_system


class _Recorder:
    """The plugin's state: per test id, CPU seconds per phase and of children, and outcome."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.tests: dict[str, dict] = {}
        self.start_cpu = time.process_time()
        self.start_children = _children_cpu()
        self.start_wall = time.perf_counter()
        self.load_start = os.getloadavg()
        self.collection_cpu = 0.0

    def _entry(self, nodeid: str) -> dict:
        return self.tests.setdefault(nodeid, {p: 0.0 for p in _PHASES} | {
            "children": 0.0, "outcome": "passed"})

    def phase(self, item, when: str):
        """Wrap one phase of one test: a generator for a hookwrapper."""
        c0, k0 = time.process_time(), _children_cpu()
        outcome = yield
        entry = self._entry(item.nodeid)
        entry[when] += time.process_time() - c0
        entry["children"] += _children_cpu() - k0
        del outcome

    def pytest_collection_finish(self, session) -> None:
        self.collection_cpu = time.process_time() - self.start_cpu

    def pytest_runtest_logreport(self, report) -> None:
        entry = self._entry(report.nodeid)
        if report.failed:
            entry["outcome"] = "failed"
        elif report.skipped and entry["outcome"] == "passed":
            entry["outcome"] = "skipped"

    @pytest.hookimpl(trylast=True)
    def pytest_runtest_logfinish(self, nodeid, location) -> None:
        # One line a test as it ends, so a long run can be read before it finishes.
        with open(self.out.with_suffix(".partial.jsonl"), "a") as f:
            f.write(json.dumps({nodeid: self._entry(nodeid)}) + "\n")

    def pytest_sessionfinish(self, session, exitstatus) -> None:
        for entry in self.tests.values():
            entry["cpu"] = sum(entry[p] for p in _PHASES) + entry["children"]
        doc = {
            "about": "Process CPU seconds per test of the fast suite (pytest -m 'not slow'), "
                     "setup + call + teardown + waited-for child processes, from "
                     "bench/suite_cpu.py.",
            "python": platform.python_version(),
            "machine": platform.machine(),
            "cpu_count": os.cpu_count(),
            "loadavg_start": self.load_start,
            "loadavg_end": os.getloadavg(),
            "wall_s": time.perf_counter() - self.start_wall,
            "collection_cpu_s": self.collection_cpu,
            "session_cpu_s": time.process_time() - self.start_cpu,
            "session_children_cpu_s": _children_cpu() - self.start_children,
            "exitstatus": int(exitstatus),
            "tests": self.tests,
        }
        self.out.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


_RECORDER: _Recorder | None = None


def pytest_configure(config) -> None:
    """Start recording when the runner named an output file (``SUITE_CPU_OUT``)."""
    global _RECORDER
    out = os.environ.get(_OUT_ENV)
    if out and _RECORDER is None:
        _RECORDER = _Recorder(Path(out))
        config.pluginmanager.register(_RECORDER, "suite_cpu_recorder")


def _wrap(when: str):
    @pytest.hookimpl(hookwrapper=True)
    def hook(item):
        if _RECORDER is None:
            yield
            return
        yield from _RECORDER.phase(item, when)
    hook.__name__ = f"pytest_runtest_{when}"
    hook.__doc__ = f"Record the CPU time of each test's {when}."
    return hook


pytest_runtest_setup = _wrap("setup")
pytest_runtest_call = _wrap("call")
pytest_runtest_teardown = _wrap("teardown")


def run(out: Path, repo: Path, python: str, extra: list[str]) -> int:
    """Run the fast suite in ``repo`` with ``python`` and this plugin; the JSON goes to ``out``.

    Parameters
    ----------
    out : Path
        The JSON file written (per-test CPU seconds, see the module's docstring).
    repo : Path
        The checkout whose ``tests/`` run (its own ``pyproject.toml`` options apply).
    python : str
        The interpreter of the environment in which that checkout is installed.
    extra : list[str]
        More pytest arguments (e.g. a test path, to try the plugin on a few tests).

    Returns
    -------
    int
        pytest's exit status.
    """
    out.with_suffix(".partial.jsonl").unlink(missing_ok=True)
    env = dict(os.environ, MPLBACKEND="Agg")
    env[_OUT_ENV] = str(out.resolve())
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(__file__).resolve().parent)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH")
                                                   else []))
    cmd = [python, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "not slow",
           "-p", "suite_cpu", *extra]
    return subprocess.call(cmd, cwd=repo, env=env)


def compare(base: dict, new: dict, top: int = 25) -> dict:
    """Compare two per-test CPU files by test id.

    Parameters
    ----------
    base, new : dict
        Two files written by :func:`run` (``tests``: test id → phases' CPU seconds).
    top : int
        How many of the largest savings and of the largest costs to list.

    Returns
    -------
    dict
        ``common``: the number of ids both ran and their CPU seconds in each (``base_cpu_s``,
        ``new_on_common_cpu_s``) and the ratio; ``new_total_cpu_s`` / ``base_total_cpu_s``:
        every test of each; ``only_base`` / ``only_new``: the ids one of them lacks;
        ``largest_savings`` / ``largest_costs``: per id, base and new CPU seconds.
    """
    b, n = base["tests"], new["tests"]
    common = sorted(set(b) & set(n))
    base_common = sum(b[i]["cpu"] for i in common)
    new_common = sum(n[i]["cpu"] for i in common)
    deltas = sorted(((n[i]["cpu"] - b[i]["cpu"], i) for i in common))
    row = lambda d, i: {"id": i, "base_cpu_s": round(b[i]["cpu"], 3),  # noqa: E731
                        "new_cpu_s": round(n[i]["cpu"], 3), "change_s": round(d, 3)}
    return {
        "common_tests": len(common),
        "base_cpu_s": round(base_common, 2),
        "new_on_common_cpu_s": round(new_common, 2),
        "common_ratio": round(new_common / base_common, 4),
        "base_total_cpu_s": round(sum(t["cpu"] for t in b.values()), 2),
        "new_total_cpu_s": round(sum(t["cpu"] for t in n.values()), 2),
        "base_tests": len(b),
        "new_tests": len(n),
        "only_base": sorted(set(b) - set(n)),
        "only_new": sorted(set(n) - set(b)),
        "largest_savings": [row(d, i) for d, i in deltas[:top] if d < 0],
        "largest_costs": [row(d, i) for d, i in reversed(deltas[-top:]) if d > 0],
    }


def merge(full: dict, patch: dict) -> dict:
    """A whole-suite file with the test files ``patch`` ran replaced by its run of them.

    For a measurement after changing a few test files on a busy machine: the tests of the
    files not changed keep their CPU from ``full`` (their code is the same), the changed
    files' tests are taken whole from ``patch`` (tests added, removed or renamed there
    included).

    Parameters
    ----------
    full, patch : dict
        Files written by :func:`run`: the whole fast suite, and a run of some of its files.

    Returns
    -------
    dict
        ``full`` with ``tests`` merged, and ``merged_files``: the files taken from ``patch``.
    """
    files = {test_id.split("::")[0] for test_id in patch["tests"]}
    tests = {i: t for i, t in full["tests"].items() if i.split("::")[0] not in files}
    tests.update(patch["tests"])
    return {**{k: v for k, v in full.items() if k != "tests"}, "tests": tests,
            "merged_files": sorted(files)}


def _main(argv: list[str] | None = None) -> int:
    """Command line: ``run`` or ``compare`` (see the module's docstring)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run the fast suite and record each test's CPU")
    r.add_argument("out", type=Path)
    r.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1])
    r.add_argument("--python", default=sys.executable)
    r.add_argument("pytest_args", nargs="*", help="more pytest arguments (after --)")
    c = sub.add_parser("compare", help="compare two files by test id")
    c.add_argument("base", type=Path)
    c.add_argument("new", type=Path)
    c.add_argument("--top", type=int, default=25)
    c.add_argument("--out", type=Path, help="also write the comparison as JSON")
    c.add_argument("--about", default="", help="the JSON's 'about' text (with --out)")
    c.add_argument("--patch", type=Path, action="append", default=[],
                   help="a run of some test files whose tests replace those files' in NEW")
    a, rest = p.parse_known_args(argv)
    if a.cmd == "run":
        extra = [arg for arg in a.pytest_args + rest if arg != "--"]
        return run(a.out, a.repo, a.python, extra)
    if rest:
        p.error(f"unrecognized arguments: {' '.join(rest)}")
    base, new = (json.loads(f.read_text()) for f in (a.base, a.new))
    for patch in a.patch:
        new = merge(new, json.loads(patch.read_text()))
    result = compare(base, new, a.top)
    for key in ("common_tests", "base_cpu_s", "new_on_common_cpu_s", "common_ratio",
                "base_total_cpu_s", "new_total_cpu_s", "base_tests", "new_tests"):
        print(f"{key}: {result[key]}")
    print(f"only in base: {len(result['only_base'])}; only in new: {len(result['only_new'])}")
    for title in ("largest_savings", "largest_costs"):
        print(title)
        for row in result[title]:
            print(f"  {row['base_cpu_s']:8.2f} -> {row['new_cpu_s']:8.2f}  {row['id']}")
    if a.out:
        # The ids only the new run has (tests added since the base) are counted, not listed.
        doc = {"about": a.about, **result, "only_new": len(result["only_new"]),
               "base_meta": {k: v for k, v in base.items() if k != "tests"},
               "new_meta": {k: v for k, v in new.items() if k != "tests"}}
        a.out.write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(_main())
