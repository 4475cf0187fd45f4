"""The end of ``drake-coop run``: the results summary, the sanity warning, and ``--force``."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from drake_coop.cli import build_parser, main
from drake_coop.results import compute_metrics, save_logs
from drake_coop.results.run_folder import OutputFolderError, RunFolder
from drake_coop.results.summary import sanity_warnings, summary_lines
from drake_coop.scenario import dump_scenario
from tests.conftest import draw_only, short_scenario
from tests.results.test_io import SINE_AMPLITUDE, Y_OFFSET, Z_OBS, synthetic_run

# ---------------------------------------------------------------- the summary table


def _row(lines: list[str], robot: str) -> list[str]:
    line = next(x for x in lines if x.strip().startswith(robot))
    return [c.strip() for c in line.strip()[len(robot):].split("  ") if c.strip()]


def test_summary_gives_the_circle_phase_errors_in_reader_units():
    logs, meta = synthetic_run()
    lines = summary_lines(compute_metrics(logs, meta), meta)
    assert lines[0] == "circle phase (25-65 s), RMS / max"
    # Closed forms of the synthetic errors in the circle: ỹ is a constant −1.5 mm (RMS 1.5),
    # z̃ a sine of amplitude 2 mm (RMS 2/√2 = 1.41, max 2): the worst axis is ỹ's RMS and z̃'s
    # max; λ − λ_d = 0.3 N and λ − λ̂ = 0.25 N constant; z of joint 3 is 3 µrad constant.
    worst_rms = max(abs(Y_OFFSET), SINE_AMPLITUDE / np.sqrt(2)) * 1e3
    assert _row(lines, "robot1") == [f"{worst_rms:.3g} / {SINE_AMPLITUDE * 1e3:.3g} mm",
                                     "0.3 / 0.3 N", "0.25 / 0.25 N",
                                     f"{max(Z_OBS) * 1e6:.3g} / {max(Z_OBS) * 1e6:.3g} µrad"]


def test_summary_switches_to_micrometres_below_a_millimetre():
    metrics = {"robot1": {"circle": {
        "x_tilde": {"rms": 7.1e-6, "max": 9.4e-6}, "y_tilde": {"rms": 1e-6, "max": 2e-6},
        "z_tilde": {"rms": 1.5e-5, "max": 2.0e-5}, "force_error": {"rms": 0.047, "max": 0.088},
        "estimate_error": {"rms": 0.02, "max": 0.032}, "z1": {"rms": 3.9e-7, "max": 9.3e-7}}}}
    lines = summary_lines(metrics, {"phases": [["circle", 25.0, 65.0]]})
    assert _row(lines, "robot1") == ["15 / 20 µm", "0.047 / 0.088 N", "0.02 / 0.032 N",
                                     "0.39 / 0.93 µrad"]


def test_a_run_stopped_before_the_circle_is_summarized_over_the_whole_run():
    logs, meta = synthetic_run(t_end=10.0)
    lines = summary_lines(compute_metrics(logs, meta), meta)
    assert lines[0].startswith("whole run (it did not reach the circle phase)")
    assert _row(lines, "robot2")[1] == "0.1 / 0.1 N"        # the free phase's offset


# ---------------------------------------------------------------- the sanity check


def test_a_squeeze_that_turns_into_a_pull_is_reported_with_its_time():
    logs, _ = synthetic_run()
    log = logs["robot2"]
    dropped = (log["t"] >= 40.0) & (log["t"] < 41.0)
    log["lambda_meas"][dropped] = -3.0
    log["lambda_meas"][np.argmax(dropped)] = -5.0          # the worst sample, at t = 40 s
    (line,) = sanity_warnings(logs)
    assert line.startswith("robot2: the measured squeeze turned into a pull (-5.0 N against "
                           "a desired")
    assert "at t = 40.00 s" in line and f"{int(dropped.sum())} samples" in line


def test_a_pull_only_where_the_desired_force_is_small_is_not_reported():
    logs, _ = synthetic_run()
    for log in logs.values():                     # grasp and release: λ_d ramps through 0
        log["lambda_d"][:] = np.where(log["t"] < 1.0, 1.0, 30.0)
        log["lambda_meas"][:] = np.where(log["t"] < 1.0, -0.5, 29.0)
    assert sanity_warnings(logs) == []


def test_each_constraint_row_is_checked_on_its_own():
    logs, _ = synthetic_run(t_end=1.0)
    for log in logs.values():
        n = log["t"].size
        log["lambda_d"] = np.column_stack([np.full(n, 10.0), np.full(n, 10.0)])
        log["lambda_meas"] = np.column_stack([np.full(n, 9.0), np.full(n, 9.0)])
    logs["robot1"]["lambda_meas"][5, 1] = -1.0
    (line,) = sanity_warnings(logs)
    assert line.startswith("robot1 (row 2): the measured squeeze turned into a pull (-1.0 N")


# ---------------------------------------------------------------- the command


@pytest.fixture(scope="module")
def short_run(short_run_folder):
    """The session's short run (:func:`tests.conftest.short_run_folder`, the same command in
    this process): its exit code and output streams, scenario and folder."""
    code, stdout, stderr, path, out = short_run_folder
    return subprocess.CompletedProcess([], code, stdout, stderr), path, out


def test_run_prints_the_summary_even_when_quiet(short_run):
    proc, _, out = short_run
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    meta = json.loads((out / "run.json").read_text())
    assert proc.stdout.splitlines() == ["drake-coop: " + summary_lines(metrics, meta)[0]] + \
        summary_lines(metrics, meta)[1:]
    assert "warning" not in proc.stderr          # the squeeze stayed a squeeze


def test_run_over_a_previous_run_needs_force_and_keeps_it(short_run, capsys, monkeypatch):
    import drake_coop.experiment.simulate

    _, path, out = short_run
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr(drake_coop.experiment.simulate, "simulate",
                        lambda *a, **k: pytest.fail("simulated before checking --out"))
    assert main(["run", str(path), "--out", str(out), "--quiet", "--t-end", "0.05"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a previous run (completed 8 s); add --force" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_force_replaces_a_previous_run(tmp_path, capsys, monkeypatch):
    """(Of the figures only one is drawn, :func:`tests.conftest.draw_only`: this checks the
    folder's replacement, not the figures.)"""
    draw_only(monkeypatch, "fig2_tracking_errors")
    out = tmp_path / "o"
    logs, meta = synthetic_run(t_end=0.09)
    save_logs(out, logs, meta)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(short_scenario("planes", 0.003)))
    args = ["run", str(path), "--out", str(out), "--quiet", "--no-replay", "--t-end", "0.05"]
    assert main(args) == 2
    assert main(args + ["--force"]) == 0
    assert json.loads((out / "run.json").read_text())["message"] == "completed 0.05 s"


@pytest.mark.parametrize("status, needs_force", [("ok", True), ("diverged", True),
                                                 ("stopped", True), ("interrupted", False)])
def test_only_a_completed_diverged_or_watchdog_stopped_run_is_kept_without_force(tmp_path, status, needs_force):
    out = tmp_path / "o"
    logs, meta = synthetic_run(t_end=0.09)
    save_logs(out, logs, dict(meta, status=status))
    if needs_force:
        with pytest.raises(OutputFolderError, match="add --force"):
            RunFolder(out).prepare(ticks=1)
    RunFolder(out).prepare(ticks=1, replace=needs_force)


def test_help_does_not_limit_the_package_to_two_arms():
    text = build_parser().format_help()
    assert "two-arm" not in text and "cooperating robot arms" in text


def test_scenarios_lists_whole_descriptions_without_issue_numbers(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) >= 8
    for line in lines:
        assert "issue" not in line.lower() and line.rstrip().endswith("."), line


def test_run_warns_on_stderr_when_a_squeeze_turned_into_a_pull(capsys):
    from types import SimpleNamespace

    from drake_coop.cli.run import _print_summary

    logs, meta = synthetic_run()
    logs["robot1"]["lambda_meas"][(logs["robot1"]["t"] > 30.0)] = -2.0   # dropped at 30 s
    _print_summary(SimpleNamespace(logs=logs, meta=meta), compute_metrics(logs, meta))
    out, err = capsys.readouterr()
    assert out.startswith("drake-coop: circle phase (25-65 s), RMS / max\n")
    (line,) = err.splitlines()
    assert line.startswith("drake-coop: warning: robot1: the measured squeeze turned into a "
                           "pull (-2.0 N against a desired")


def test_the_mass_line_gives_the_summed_estimate_at_the_carrying_end_and_its_lowest():
    """Two arms' shares summed: at the circle's end and at its lowest while held, with the
    true mass and a note when the sum went negative; no line without mass shares."""
    from drake_coop.results.summary import mass_line

    t = np.arange(0.0, 10.0, 0.5)
    share = np.where(t < 2.0, 0.3, 0.26)
    share[t == 2.5] = -0.03                        # the dip after the grasp
    logs = {"r1": {"t": t, "mass_share": share}, "r2": {"t": t, "mass_share": share}}
    meta = {"object_mass": 0.5, "phases": [["free", 0, 2], ["lift", 2, 4], ["circle", 4, 8],
                                           ["put_down", 8, 9], ["return", 9, 10]]}
    (line,) = mass_line(logs, meta)
    assert line == ("  object mass: estimate 0.52 kg at t = 7.5 s (true 0.5 kg, +4.0 %); "
                    "lowest while held -0.06 kg at t = 2.5 s (a negative share is fed forward "
                    "as 0)")
    assert mass_line({"r1": {"t": t}}, meta) == []
