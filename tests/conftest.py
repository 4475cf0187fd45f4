"""Shared fixtures: short versions of the paper's scenario (same gains, compressed phases)."""

import pytest

from drake_coop.scenario import Task, default_scenario


def short_scenario(mode: str = "planes", time_step: float = 0.001, **task):
    """The paper's scenario with its phases compressed to 8 s (free 1 s, lift 1 s, circle 4 s,
    put-down 1 s, return 1 s). Gains, h = 9 ms and the geometry are the paper's."""
    s = default_scenario()
    s.plant.object_mode = mode
    s.plant.time_step = time_step
    params = dict(t_pregrasp=0.6, t_grasp=1.0, t_circle_start=2.0, t_circle_end=6.0,
                  t_release=7.0, t_end=8.0)
    params.update(task)
    s.task = Task(**params)
    return s


def compress_phases(scenario):
    """``scenario``'s task phases compressed as :func:`short_scenario`'s (free 1 s, lift 1 s,
    circle 4 s, put-down 1 s, return 1 s: the grasp at 1 s), in place; returns it."""
    for key, value in dict(t_pregrasp=0.6, t_grasp=1.0, t_circle_start=2.0, t_circle_end=6.0,
                           t_release=7.0, t_end=8.0).items():
        setattr(scenario.task, key, value)
    return scenario


def draw_only(monkeypatch, figure: str) -> None:
    """``drake-coop run`` in this process draws only ``figure`` of the paper's figures (its
    file name without suffix): for a test that checks that one figure is written, where
    every figure is drawn and checked on the short run (``tests/cli/test_cli.py``); drawing
    them is most of a short run's cost."""
    import functools

    import drake_coop.results

    monkeypatch.setattr(drake_coop.results, "plot_figures",
                        functools.partial(drake_coop.results.plot_figures, only=[figure]))


@pytest.fixture(scope="session")
def short_run_folder(tmp_path_factory):
    """``drake-coop run SCENARIO --out OUT --quiet`` of :func:`short_scenario` (``planes``,
    3 ms plant step), run once for the session (the command's outputs and its summary are
    checked by ``tests/cli/test_cli.py`` and ``tests/results/test_summary.py``; one 8 s run
    with every output serves both): ``(exit code, stdout, stderr, SCENARIO, OUT)``. A test may
    redraw its figures, but leaves the folder as it found it."""
    import contextlib
    import io

    from drake_coop.cli import main
    from drake_coop.scenario import dump_scenario

    tmp = tmp_path_factory.mktemp("short_run")
    path = tmp / "scenario.yaml"
    path.write_text(dump_scenario(short_scenario("planes", 0.003)))
    out = tmp / "out"
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["run", str(path), "--out", str(out), "--quiet"])
    return code, stdout.getvalue(), stderr.getvalue(), path, out


@pytest.fixture
def make_short_scenario():
    return short_scenario


def advance_to_tick(scenario, k: int, live_ground_truth: bool | None = None):
    """The experiment's simulator stopped exactly at control tick ``k`` (its events not yet
    processed), with the grasp switched on at its tick as :func:`simulate` does.
    ``live_ground_truth=True`` keeps the live ground truth (``RobotSystems.force_sensor``);
    built without logs, the offline one is absent.

    Returns ``(experiment, simulator, context)``.
    """
    from pydrake.systems.analysis import Simulator

    from drake_coop.experiment.diagram import build_experiment

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.ticks import grasp_ticks
    from drake_coop.experiment.simulate import initialize
    from drake_coop.scenario import aligned_periods

    exp = build_experiment(plan_run(scenario), log=False, live_ground_truth=live_ground_truth)
    sim = Simulator(exp.diagram)
    ctx = sim.get_mutable_context()
    initialize(exp, ctx)
    sim.Initialize()
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    k_grasp, _ = grasp_ticks(scenario.task, h)
    sim.AdvanceTo(k_grasp * h)
    exp.coop.set_held(exp.coop.plant.GetMyMutableContextFromRoot(ctx), True)
    sim.AdvanceTo(k * h)
    return exp, sim, ctx


def start_paper_run(out, figure: str | None = None) -> tuple:
    """The paper's run (``drake-coop run --out OUT --no-replay --force``: it may replace a
    previous run) in a subprocess, returned once its simulation is under way (its first
    progress line): ``(process, stderr lines)``. With ``figure`` (a paper figure's file name
    without suffix), the run draws only that figure, as :func:`draw_only` (the reference
    figure not at all): ``python -m drake_coop`` run through :mod:`runpy` after that patch,
    for a test that checks no other figure (drawing them is most of an interrupted run's
    cost)."""
    import subprocess
    import sys

    if figure is None:
        cmd = [sys.executable, "-m", "drake_coop"]
    else:
        cmd = [sys.executable, "-c",
               "import functools, runpy; import drake_coop.results as r; "
               f"r.plot_figures = functools.partial(r.plot_figures, only=[{figure!r}]); "
               "r.fig_references = lambda *args, **kwargs: []; "
               "runpy.run_module('drake_coop', run_name='__main__')"]
    proc = subprocess.Popen([*cmd, "run", "--out", str(out), "--no-replay", "--force"],
                            stderr=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if "realtime" in line:
            break
    return proc, lines
