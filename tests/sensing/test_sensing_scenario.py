"""The sensing fields of a scenario: defaults are the ideal world, round trips, and
one clear error per bad input (a ScenarioError naming the field; exit 2 through the CLI)."""

from pathlib import Path

import pytest

from drake_coop.cli import main
from drake_coop.scenario import (
    ScenarioError,
    default_scenario,
    dump_scenario,
    load_scenario,
)

ROOT = Path(__file__).resolve().parents[2]


def _with_robot1(fields: str) -> str:
    """``scenarios/paper.yaml`` (no sensing field) with ``fields`` added to robot 1."""
    text = (ROOT / "scenarios" / "paper.yaml").read_text()
    assert "- name: robot1\n" in text
    return text.replace("- name: robot1\n", f"- name: robot1\n  {fields}\n", 1)


def test_defaults_are_the_ideal_sensors_and_the_papers_observers():
    r = default_scenario().robots[0]
    assert (r.velocity_source, r.force_source, r.difference_cutoff_hz) == (
        "observer", "observer", None)
    assert (r.encoders.counts_per_rev, r.encoders.noise_std, r.encoders.delay_samples) == (
        None, 0.0, 0)
    assert (r.force_sensor.noise_std, r.force_sensor.bias, r.force_sensor.cutoff_hz) == (
        0.0, 0.0, None)
    assert r.actuators.torque_limits is None
    m = r.model_error
    assert (m.mass_scale, m.inertia_scale, m.damping_scale, m.payload_mass) == (1, 1, 1, 0)
    assert m.coulomb_friction == []          # no joint friction


def test_realistic_yaml_loads_and_round_trips():
    s = load_scenario(ROOT / "scenarios" / "realistic.yaml")
    assert s.robots[0].encoders.counts_per_rev == 200000
    assert s.robots[1].actuators.torque_limits == [18.0] * 3
    assert load_scenario(data=dump_scenario(s)) == s


def test_sensing_fields_load_from_their_dotted_paths():
    text = _with_robot1(
        "velocity_source: difference\n  difference_cutoff_hz: 20.0\n  force_source: none\n"
        "  encoders: {counts_per_rev: 4096, noise_std: 1.0e-5, delay_samples: 2, seed: 3}\n"
        "  force_sensor: {noise_std: 0.1, bias: -0.5, cutoff_hz: 30.0, seed: 4}\n"
        "  actuators: {torque_limits: [10.0, 20.0, 30.0]}\n"
        "  model_error: {mass_scale: 1.1, inertia_scale: 0.9, damping_scale: 2.0, "
        "payload_mass: 0.5, coulomb_friction: [1.0, 0.5, 0.0]}")
    r = load_scenario(data=text).robots[0]
    assert (r.velocity_source, r.difference_cutoff_hz, r.force_source) == (
        "difference", 20.0, "none")
    assert (r.encoders.counts_per_rev, r.encoders.delay_samples, r.encoders.seed) == (4096, 2, 3)
    assert r.force_sensor.cutoff_hz == 30.0 and r.actuators.torque_limits == [10.0, 20.0, 30.0]
    assert r.model_error.coulomb_friction == [1.0, 0.5, 0.0]


@pytest.mark.parametrize("fields, field", [
    ("velocity_source: tachometer", "robots[0].velocity_source"),
    ("force_source: strain_gauge", "robots[0].force_source"),
    ("encoders: {noise_std: -1.0e-4}", "robots[0].encoders.noise_std"),
    ("encoders: {counts_per_rev: 0}", "robots[0].encoders.counts_per_rev"),
    ("encoders: {counts_per_rev: 1000.5}", "robots[0].encoders.counts_per_rev"),
    ("encoders: {delay_samples: 1.5}", "robots[0].encoders.delay_samples"),
    ("encoders: {delay_samples: -1}", "robots[0].encoders.delay_samples"),
    ("encoders: {seed: -3}", "robots[0].encoders.seed"),
    ("force_sensor: {noise_std: -0.1}", "robots[0].force_sensor.noise_std"),
    ("force_sensor: {cutoff_hz: 55.6}", "robots[0].force_sensor.cutoff_hz"),   # 1/(2h) = 55.56
    ("force_sensor: {cutoff_hz: 0.0}", "robots[0].force_sensor.cutoff_hz"),
    ("velocity_source: difference\n  difference_cutoff_hz: 80.0",
     "robots[0].difference_cutoff_hz"),
    ("difference_cutoff_hz: 10.0", "robots[0].difference_cutoff_hz"),   # needs difference
    ("actuators: {torque_limits: [10.0, 0.0, 10.0]}", "robots[0].actuators.torque_limits[1]"),
    ("actuators: {torque_limits: [10.0, 10.0]}", "robots[0].actuators.torque_limits"),
    ("model_error: {mass_scale: 0.0}", "robots[0].model_error.mass_scale"),
    ("model_error: {inertia_scale: -1.0}", "robots[0].model_error.inertia_scale"),
    ("model_error: {damping_scale: 0.0}", "robots[0].model_error.damping_scale"),
    ("model_error: {payload_mass: -0.1}", "robots[0].model_error.payload_mass"),
    ("model_error: {coulomb_friction: [0.0, -1.0, 0.0]}",
     "robots[0].model_error.coulomb_friction[1]"),
    ("encoders: {resolution: 10}", "robots[0].encoders.resolution"),
])
def test_bad_sensing_input_names_the_field(fields, field):
    with pytest.raises(ScenarioError) as info:
        load_scenario(data=_with_robot1(fields))
    message = str(info.value)
    assert field in message and "\n" not in message


def test_cutoff_at_nyquist_is_reported_with_the_allowed_range():
    with pytest.raises(ScenarioError, match=r"in \(0, 55.5556\) Hz"):
        load_scenario(data=_with_robot1("force_sensor: {cutoff_hz: 60.0}"))


def test_cli_exits_2_with_one_line_for_a_bad_sensing_field(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(_with_robot1("encoders: {counts_per_rev: 0}"))
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "robots[0].encoders.counts_per_rev" in err
    assert "Traceback" not in err and not (tmp_path / "o").exists()
