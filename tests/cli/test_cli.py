"""The ``drake-coop`` command: outputs of a run, exit codes, errors without tracebacks."""

import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.scenario import dump_scenario
from tests.conftest import draw_only, short_scenario, start_paper_run

FIGURES = ["fig2_tracking_errors", "fig3_force_tracking", "fig4_force_estimate",
           "fig5_aux_force_error", "fig6_observation_errors", "fig_force_errors"]


def _write(tmp_path, scenario, name="scenario.yaml"):
    path = tmp_path / name
    path.write_text(dump_scenario(scenario))
    return path


@pytest.fixture(scope="module")
def short_run_dir(short_run_folder):
    """The session's short run (:func:`tests.conftest.short_run_folder`): exit code, folder."""
    code, _, _, _, out = short_run_folder
    return code, out


def test_run_writes_logs_metrics_figures_diagrams_and_replay(short_run_dir):
    code, out = short_run_dir
    assert code == 0
    for robot in ("robot1", "robot2"):
        data = np.load(out / f"{robot}.npz")
        assert data["t"].size == 889 and data["q"].shape == (889, 3)
        header = (out / f"{robot}.csv").read_text().splitlines()[0]
        assert header.startswith("t,")
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "ok"
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["robot1"]) >= {"free", "lift", "circle", "put_down", "return"}
    for fig in FIGURES:
        assert (out / f"{fig}.png").stat().st_size > 10_000
        assert (out / f"{fig}.svg").read_text().lstrip().startswith(("<?xml", "<svg"))
    assert "robot1_controller" in (out / "robot1_control_diagram.dot").read_text()
    top = (out / "system_diagram.dot").read_text()
    assert "robot1_control" in top and "plant" in top
    if shutil.which("dot"):
        assert (out / "system_diagram.svg").exists()
    html = (out / "replay.html").read_text()
    assert "<html" in html.lower() and len(html) > 10_000
    assert re.search(r"<script[^>]*\bsrc=", html) is None    # viewer inlined: opens offline
    assert not list(out.glob("*.tmp*"))        # nothing half-written left behind


def test_plot_redraws_figures_from_the_logs(short_run_dir, monkeypatch):
    """``drake-coop plot`` redraws a run's figure from its logs: one figure, removed first
    and the only one drawn (``replot`` drawing every figure is checked in
    ``tests/results/test_figures.py``)."""
    import functools

    import drake_coop.results.figures as figures

    _, out = short_run_dir
    fig = "fig3_force_tracking"
    monkeypatch.setattr(figures, "plot_figures",
                        functools.partial(figures.plot_figures, only=[fig]))
    monkeypatch.setattr(figures, "fig_references", lambda *args, **kwargs: [])
    (out / f"{fig}.png").unlink()
    assert main(["plot", str(out), "--quiet"]) == 0
    assert (out / f"{fig}.png").stat().st_size > 10_000


def test_bad_scenario_exits_2_with_one_line_naming_the_field(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("plant: {time_step: 0.002}\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "plant.time_step" in err and "Traceback" not in err


def test_diverging_run_exits_1_and_keeps_what_it_logged(tmp_path, capsys, monkeypatch):
    """The logs, run.json and a figure are still written (only the figure checked is drawn:
    :func:`tests.conftest.draw_only`)."""
    draw_only(monkeypatch, "fig3_force_tracking")
    s = short_scenario("none", 0.003)
    for r in s.robots:
        r.gains.K_R = [3000.0] * 3
    s.guards.max_pad_error = 10.0        # the divergence guards, not the pad's
    out = tmp_path / "o"
    code = main(["run", str(_write(tmp_path, s)), "--out", str(out), "--quiet", "--no-replay"])
    assert code == 1
    assert "diverged" in capsys.readouterr().err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "diverged"
    t = np.load(out / "robot1.npz")["t"]
    assert 0 < t[-1] < 8.0
    assert (out / "fig3_force_tracking.png").exists()


def test_console_script_entry_point_reports_errors_without_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "drake_coop", "run", "missing.yaml",
                           "--out", str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "not found" in proc.stderr and "Traceback" not in proc.stderr


def test_ctrl_c_stops_the_run_and_still_writes_the_logs(tmp_path):
    """The run draws one figure (:func:`tests.conftest.start_paper_run`): every figure is
    drawn and checked on the short run."""
    import signal

    out = tmp_path / "o"
    proc, lines = start_paper_run(out, "fig3_force_tracking")   # interrupted once under way
    proc.send_signal(signal.SIGINT)
    rest = proc.stderr.read()
    proc.wait(timeout=120)
    err = "".join(lines) + rest
    assert proc.returncode == 130, err
    assert "interrupted at t =" in err and "Traceback" not in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "interrupted"
    t = np.load(out / "robot1.npz")["t"]
    assert 0.0 < t[-1] < 90.0
    assert (out / "fig3_force_tracking.png").exists()


def test_the_argument_parser_loads_no_pydrake():
    # A Ctrl-C during start-up must arrive as an interrupt (exit 130); one that lands inside
    # pydrake's own initialization surfaces as an ImportError instead. Building the parser
    # (every subcommand's options) therefore stays free of pydrake.
    import subprocess
    import sys
    code = ("import sys; from drake_coop.cli import build_parser; build_parser(); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'pydrake'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_every_option_and_argument_of_every_command_has_help_text():
    """``drake-coop CMD --help`` explains each of its options and arguments."""
    import argparse

    from drake_coop.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = [f"{name} {action.option_strings or action.dest}"
               for name, parser in sub.choices.items() for action in parser._actions
               if not isinstance(action, argparse._HelpAction) and not action.help]
    assert missing == []
    study = sub.choices["study"].format_help()
    assert "a bound, not a worker count" in " ".join(study.split())


def test_every_documented_command_writes_under_an_ignored_folder():
    """Following the README and the docs leaves no untracked folder in a checkout: every
    ``drake-coop ... --out PATH`` they show writes under a folder .gitignore names."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    ignored = [line.strip() for line in (root / ".gitignore").read_text().splitlines()
               if line.strip().endswith("/") and not line.startswith("#")]
    pages = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    outs = {(p.relative_to(root).as_posix(), m) for p in pages if "_build" not in p.parts
            for m in re.findall(r"drake-coop [a-z]+[^`|\n]*?--out +([^ `|\n]+)",
                                p.read_text(encoding="utf-8"))}
    assert len(outs) > 10
    loose = sorted((page, out) for page, out in outs
                   if not re.fullmatch(r"[A-Z_]+\]?", out) and not out.startswith("/tmp")
                   and not any(out.startswith(folder) for folder in ignored))
    assert loose == []


def test_the_getting_started_command_table_lists_every_command():
    import argparse
    import re
    from pathlib import Path

    from drake_coop.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    page = (Path(__file__).resolve().parents[2] / "docs" / "guide" /
            "getting_started.md").read_text(encoding="utf-8")
    table = page.split("## Commands", 1)[1].split("\n\n", 2)[1]
    listed = set(re.findall(r"^\| `drake-coop ([a-z-]+)", table, flags=re.M))
    assert sorted(set(sub.choices) - listed) == []
