"""Computation delay and sampling jitter (:mod:`drake_coop.sensing.latency`): the
switch on the plant's step grid against the definition, seeded reproducible jitter, the
fields' validation, and the paper's diagram unchanged at the defaults."""

import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from drake_coop.cli import main
from drake_coop.experiment.diagram import build_experiment
from drake_coop.experiment.plan import plan_run
from drake_coop.scenario import ScenarioError, default_scenario, load_scenario
from drake_coop.scenario.schema import Timing
from drake_coop.control.timing import aligned_periods
from drake_coop.sensing.latency import ActuationDelay, lateness, switch_step

ROOT = Path(__file__).resolve().parents[2]
H, DT = aligned_periods(0.009, 0.001)


def _applied(timing: Timing, ticks: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """What a plant reading at every step sees behind the block, driven by ``τ(k) = k``."""
    b = DiagramBuilder()
    t = np.arange(ticks + 2) * H
    src = b.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
        t, np.arange(ticks + 2, dtype=float)[None, :])))
    block = b.AddSystem(ActuationDelay(1, H, DT, timing, 0))
    b.Connect(src.get_output_port(), block.get_tau_cmd_input_port())
    log = LogVectorOutput(block.get_tau_output_port(), b, publish_period=DT)
    diagram = b.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(ticks * H)
    data = log.FindLog(sim.get_context())
    return data.sample_times(), data.data()[0]


def _expected(times: np.ndarray, switches: dict[int, int]) -> np.ndarray:
    """Definition: at ``t = k h + r Δt`` the block gives ``k`` if ``r >= s_k`` else ``k − 1``
    (tick 0's torque at once)."""
    out = []
    for t in times:
        k = int(math.floor(t / H + 1e-9))
        r = int(round((t - k * H) / DT))
        out.append(float(k) if (k == 0 or r >= switches[k]) else float(k - 1))
    return np.array(out)


@pytest.mark.parametrize("delay, steps", [(0.002, 2), (0.0025, 3), (0.009, 9), (0.0001, 1)])
def test_computation_delay_switches_at_the_first_plant_step_at_or_after_it(delay, steps):
    assert switch_step(delay, DT, 9) == steps
    times, applied = _applied(Timing(computation_delay=delay))
    np.testing.assert_array_equal(applied, _expected(times, {k: steps for k in range(50)}))


def test_uniform_jitter_switches_each_tick_at_its_own_seeded_lateness():
    timing = Timing(computation_delay=0.001, jitter="uniform", jitter_scale=0.006, seed=3)
    switches = {k: switch_step(0.001 + lateness(timing, 0, k, H), DT, 9) for k in range(50)}
    assert len(set(switches.values())) > 3          # the lateness really varies
    times, applied = _applied(timing)
    np.testing.assert_array_equal(applied, _expected(times, switches))


def test_jitter_is_reproducible_and_depends_on_seed_and_robot():
    t = Timing(jitter="exponential", jitter_scale=0.002, seed=7)
    a = [lateness(t, 0, k, H) for k in range(200)]
    assert a == [lateness(t, 0, k, H) for k in range(200)]
    assert a != [lateness(t, 1, k, H) for k in range(200)]
    assert a != [lateness(Timing(jitter="exponential", jitter_scale=0.002, seed=8), 0, k, H)
                 for k in range(200)]
    assert 0.0015 < np.mean(a) < 0.0025 and max(a) <= H  # mean 2 ms, cut at h


def test_defaults_add_no_block_to_the_papers_diagram():
    exp = build_experiment(plan_run(default_scenario()), log=False)
    names = {s.get_name() for s in exp.diagram.GetSystems()}
    assert not any(n.endswith("_latency") for n in names)
    assert all(rs.latency is None for rs in exp.robots)


def test_a_delay_inserts_the_block_between_controller_and_actuators():
    s = default_scenario()
    s.robots[1].timing.computation_delay = 0.002
    exp = build_experiment(plan_run(s), log=False)
    assert exp.robots[0].latency is None and exp.robots[1].latency is not None
    assert exp.robots[1].latency.get_name() == "robot2_latency"


def _with_robot1(fields: str) -> str:
    text = (ROOT / "scenarios" / "paper.yaml").read_text()
    return text.replace("- name: robot1\n", f"- name: robot1\n  {fields}\n", 1)


@pytest.mark.parametrize("fields, message", [
    ("timing: {computation_delay: 0.01}", "robots[0].timing.computation_delay must be <="),
    ("timing: {computation_delay: -0.001}", "robots[0].timing.computation_delay must be a finite"),
    ("timing: {jitter: gaussian, jitter_scale: 0.001}", "robots[0].timing.jitter must be one of"),
    ("timing: {jitter: uniform}", "robots[0].timing.jitter_scale must be > 0"),
    ("timing: {jitter_scale: 0.001}", "robots[0].timing.jitter_scale applies"),
    ("timing: {computation_delay: 0.005, jitter: uniform, jitter_scale: 0.005}",
     "computation_delay + jitter_scale must be <="),
])
def test_bad_timing_input_names_the_field(fields, message):
    with pytest.raises(ScenarioError, match=message.replace("[", r"\[").replace("]", r"\]")
                       .replace("+", r"\+")):
        load_scenario(data=_with_robot1(fields))


def test_cli_exits_2_with_one_line_for_a_bad_timing_field(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(_with_robot1("timing: {computation_delay: 0.05}"))
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "timing.computation_delay" in err[0]


def test_a_jittered_run_is_reproducible_and_its_seed_matters():
    from drake_coop.experiment.simulate import simulate

    def q(seed: int) -> np.ndarray:
        s = default_scenario()
        for robot in s.robots:
            robot.timing.jitter = "uniform"
            robot.timing.jitter_scale = 0.006
            robot.timing.seed = seed
        return simulate(s, t_end=0.3).logs["robot1"]["q"]

    a = q(1)
    np.testing.assert_array_equal(a, q(1))
    assert not np.array_equal(a, q(2))
