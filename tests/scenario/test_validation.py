"""Hostile scenario files: each case is refused with one line naming the field.

One test per finding of the review's list: broken model files, unreadable or non-UTF-8
files, degenerate periods and horizons, unhelpful messages, malformed input that used to be
accepted. Messages must be one line of at most 300 characters, and no case may build anything.
"""

import math
import re
import time
import tracemalloc

import pytest

from drake_coop.experiment.ticks import MAX_TICKS, check_run_size
from drake_coop.experiment.plan import plan_run
from drake_coop.scenario import (
    BOUNDS,
    LENGTHS,
    Scenario,
    ScenarioError,
    load_scenario,
)
from drake_coop.scenario.bounds import MAX_MESSAGE, Bound, numeric_fields
from drake_coop.scenario.safe_yaml import MAX_BYTES

ROBOT2 = "{name: robot2, model: crs_a255, base_xyz: [1.16, 0, 0], base_yaw_deg: 180, " \
         "contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}"


def _refused(text: str | None = None, path=None) -> str:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, data=text) if path is not None else load_scenario(data=text)
    message = str(info.value)
    assert "\n" not in message and len(message) <= MAX_MESSAGE, message
    return message


def _with_controller_model(path) -> str:
    return f"robots: [{{controller_model: '{path}'}}, {ROBOT2}]"


# ---------------------------------------------------------------- model files


URDF_NO_BASE = """<robot name="x"><link name="pad"/><link name="l1"/>
<joint name="j" type="revolute"><parent link="l1"/><child link="pad"/>
<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""


@pytest.mark.parametrize("content, problem", [
    (None, "not found"),
    (b"", "is not valid XML"),
    (b"hello, not xml", "is not valid XML"),
    (bytes(range(256)) * 4, "is not valid XML"),
    ("dir", "is not a regular file"),
    (URDF_NO_BASE.encode(), "has no link named 'base_link'"),
    (b"<sdf version='1.7'><model name='m'/></sdf>", "not <robot>"),
    (b'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="r"/>',
     "must not declare a DTD"),
])
def test_broken_controller_model_is_named_before_anything_is_built(tmp_path, content, problem):
    path = tmp_path / "model.urdf"
    if content == "dir":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    message = _refused(_with_controller_model(path))
    assert message.startswith("robots[0].controller_model: ") and str(path) in message
    assert problem in message, message


def test_controller_model_must_be_a_urdf_file():
    assert ".urdf file" in _refused(_with_controller_model("/etc/passwd"))


def test_controller_model_with_the_wrong_number_of_joints(tmp_path):
    from drake_coop.plant.arms import urdf_dir

    text = (urdf_dir() / "crs_a465_3dof.urdf").read_text()
    path = tmp_path / "two_joints.urdf"
    path.write_text(text.replace('name="joint3" type="revolute"', 'name="joint3" type="fixed"'))
    assert ("robots[0].controller_model has 2 joints, the simulated arm 3"
            in _refused(_with_controller_model(path)))


def test_a_perturbed_but_valid_controller_model_is_accepted(tmp_path):
    from drake_coop.plant.arms import urdf_dir

    text = (urdf_dir() / "crs_a465_3dof.urdf").read_text()
    path = tmp_path / "heavier.urdf"
    heavier = re.sub(r'<mass value="([0-9.eE+-]+)"',
                     lambda m: f'<mass value="{1.1 * float(m.group(1))}"', text, count=1)
    assert heavier != text
    path.write_text(heavier)
    s = load_scenario(data=_with_controller_model(path))
    assert s.robots[0].controller_model == str(path)


# ---------------------------------------------------------------- the file itself


def test_non_utf8_file_is_named(tmp_path):
    path = tmp_path / "latin1.yaml"
    text = "plant: {object_mode: 'planes'}  # é\n"
    path.write_bytes(text.encode("latin-1"))
    message = _refused(path=path)
    assert f"is not UTF-8 text (byte {text.index('é')}" in message and str(path) in message


def test_unreadable_file_is_named():
    # /proc/self/mem is a regular file whose read fails (EIO), even for root.
    assert "cannot be read" in _refused(path="/proc/self/mem")


def test_directory_and_oversized_files(tmp_path):
    assert "is not a regular file" in _refused(path=tmp_path)
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (MAX_BYTES + 1))
    assert f"larger than {MAX_BYTES} bytes" in _refused(path=big)


def test_alias_bomb_fails_fast_with_small_memory():
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev, name = chr(96 + i), chr(97 + i)
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    bomb = "\n".join(lines) + "\n"
    assert len(bomb) < 600
    tracemalloc.start()
    message = _refused(bomb)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert "expands (through its aliases) to more than" in message
    assert peak < 20e6          # the expansion would be ~400 million strings


def test_anchors_and_merge_keys_stay_usable():
    s = load_scenario(data="_gains: &g {Lambda: 30.0, k_d: 40.0}\n"
                           f"robots: [{{gains: {{<<: *g, beta: 5.0}}}}, {ROBOT2}]\n")
    assert (s.robots[0].gains.Lambda, s.robots[0].gains.beta) == (30.0, 5.0)


def test_duplicate_keys_are_refused_naming_the_key():
    message = _refused("control_period: 0.009\nplant: {time_step: 0.001}\ncontrol_period: 0.003")
    assert "duplicate key 'control_period' at line 3" in message


def test_empty_file_and_null_sections_are_named():
    assert "the scenario is empty" in _refused("")
    for section in ("plant", "task", "guards"):
        assert _refused(f"{section}: null").startswith(f"{section} must be a mapping of fields")
    assert _refused("robots: null").startswith("robots must be a list, got null")


def test_empty_robot_list_is_refused():
    assert "robots must list 2 to 8 robots (the paper's l >= 2 fingers), got 0" in _refused(
        "robots: []")
    assert "got 1" in _refused("robots: [{}]")


def test_a_400_digit_integer_is_named():
    message = _refused("task: {t_end: " + "9" * 400 + "}")
    assert message == "task.t_end must be a finite number, got an integer of 400 digits"


def test_echoed_values_are_cut_short():
    message = _refused("plant: {object_mode: '" + "x" * 5000 + "'}")
    assert message.startswith("plant.object_mode must be one of") and len(message) < 200
    message = _refused("robots: [{name: " + "[1, " * 50 + "]" * 50 + "}]")
    assert message.startswith("robots[0].name must be a string") and len(message) < 200


# ---------------------------------------------------------------- ranges


@pytest.mark.parametrize("text, field", [
    ("plant: {time_step: 1.0e-300}", "plant.time_step"),
    ("control_period: 1.0e-7\nplant: {time_step: 1.0e-7}", "control_period"),
    ("task: {t_end: 1.0e+300}", "task.t_end"),
    ("plant: {friction: 1.0e+300}", "plant.friction"),
    ("robots: [{base_yaw_deg: 1.0e+300}, " + ROBOT2 + "]", "robots[0].base_yaw_deg"),
    ("robots: [{gains: {Lambda: 1.0e+300}}, " + ROBOT2 + "]", "robots[0].gains.Lambda"),
    ("robots: [" + ROBOT2.replace("}", ", gains: {K_R: [1, 1.0e+300, 1]}}") + ", {}]",
     "robots[0].gains.K_R[1]"),
    ("task: {force_mean: 1.0e+300}", "task.force_mean"),
    ("task: {force_omega: 1e300}", "task.force_omega"),       # YAML 1.1 string, as Drake reads
    ("guards: {max_force: 1.0e+300}", "guards.max_force"),
    ("guards: {check_period: .inf}", "guards.check_period"),
    ("guards: {joint_limit_margin_deg: -1}", "guards.joint_limit_margin_deg"),
])
def test_out_of_range_numbers_are_refused_with_the_bound(text, field):
    message = _refused(text)
    pattern = field.replace("[0]", "[]").replace("[1]", "[]")
    assert message.startswith(f"{field} must be a finite number in {BOUNDS[pattern]}"), message


def test_every_numeric_field_has_a_bound_and_every_list_a_length():
    fields = numeric_fields(Scenario)
    assert set(fields) == set(BOUNDS), set(fields) ^ set(BOUNDS)
    lists = {f[:-2] for f in fields if f.endswith("[]")}
    assert set(LENGTHS) <= lists | {f[:-2] for f in lists if f.endswith("[]")}


@pytest.mark.parametrize("bound, inside, outside", [
    (Bound(0.0, 1.0, lo_open=True), [1e-300, 0.5, 1.0], [0.0, -1.0, 1.0000001]),
    (Bound(-2.0, 2.0), [-2.0, 0.0, 2.0], [-2.0000001, 2.5]),
    (Bound(0.0, 1.0, hi_open=True), [0.0, 0.999], [1.0]),
])
def test_bounds_are_closed_or_open_at_each_end(bound, inside, outside):
    assert all(v in bound for v in inside) and not any(v in bound for v in outside)
    assert str(bound)[0] == ("(" if bound.lo_open else "[")
    assert str(bound)[-1] == (")" if bound.hi_open else "]")


def test_paper_values_are_inside_their_bounds():
    s = load_scenario(data="{}")
    for pattern, bound in BOUNDS.items():
        if pattern.startswith("robots") or pattern.endswith("[]"):
            continue
        section, name = pattern.split(".") if "." in pattern else (None, pattern)
        if section and getattr(s, section) is None:      # an optional section (cell)
            continue
        value = getattr(getattr(s, section), name) if section else getattr(s, name)
        if value is None:        # an optional field left unset: derived (object_model.mass, mu)
            continue
        assert value in bound and math.isfinite(value)


# ---------------------------------------------------------------- size of a run


def test_long_task_is_valid_but_a_full_run_of_it_is_refused():
    s = load_scenario(data="task: {t_end: 10000}")
    with pytest.raises(ScenarioError, match=rf"control ticks, at most {MAX_TICKS}"):
        check_run_size(s)
    check_run_size(s, 0.05)          # a short run of it is fine


def test_references_are_built_only_to_the_end_of_the_run():
    s = load_scenario(data="task: {t_end: 10000}")
    started = time.perf_counter()
    t, r = plan_run(s, 0.05).robots[0].samples
    assert time.perf_counter() - started < 5.0 and t.size == 7   # ticks 0 .. 6 of h = 9 ms
    t_full, r_full = plan_run(load_scenario()).robots[0].samples
    assert (r == r_full[:7]).all() and (t == t_full[:7]).all()


@pytest.mark.parametrize("text, start", [
    ('control_period: !!python/object/apply:os.system ["echo hi"]', "the tag "),
    ("plant: !Variant {a: 1}", "plant.a is not a known field of plant"),
    ("control_period: 0.009\x00", "invalid YAML: unacceptable character"),
    ("[" * 100_000, "invalid YAML"),
    ("a: 1\n---\nb: 2", "invalid YAML: expected a single document"),
    ("? [1, 2]\n: 3", "invalid YAML"),
    ("x: &a [*a]", "invalid YAML: an alias refers to its own anchor"),
    ("- 1\n- 2", "scenario must be a mapping of fields"),
])
def test_garbage_documents_are_one_line_errors(text, start):
    assert _refused(text).startswith(start)


def test_the_range_machinery_covers_ints_optionals_and_nested_lists():
    from dataclasses import dataclass, field

    from drake_coop.scenario.bounds import check_numbers

    @dataclass
    class Sensor:
        bits: int = 12
        noise: float | None = None

    @dataclass
    class Rig:
        sensors: list[Sensor] = field(default_factory=lambda: [Sensor(), Sensor()])

    bounds = {"sensors[].bits": Bound(1, 32, "bit"), "sensors[].noise": Bound(0.0, 1.0, "rad")}
    rig = Rig()
    check_numbers(rig, bounds, {})                     # unset optional: not checked
    rig.sensors[1].noise = 2.0
    with pytest.raises(ValueError, match=r"^sensors\[1\]\.noise must be a finite number in "
                                         r"\[0, 1\] rad, got 2\.0$"):
        check_numbers(rig, bounds, {})
    rig.sensors[1].noise, rig.sensors[0].bits = 0.5, 12.5
    with pytest.raises(ValueError, match=r"^sensors\[0\]\.bits must be an integer in "
                                         r"\[1, 32\] bit, got 12\.5$"):
        check_numbers(rig, bounds, {})
    assert numeric_fields(Rig) == ["sensors[].bits", "sensors[].noise"]


# ---------------------------------------------------------------- object_model.control_point


@pytest.mark.parametrize("text, start", [
    ("plant: {object_mode: contact}\nobject_model: {mode: known, control_point: surface}",
     "object_model.control_point must be one of auto, centre, contact"),
    ("object_model: {control_point: contact}",           # the paper's control: no object model
     "object_model.control_point: contact needs object_model.mode known or estimated"),
    ("plant: {object_mode: rigid}\nobject_model: {mode: known, control_point: contact}",
     "object_model.control_point: contact needs"),
])
def test_a_bad_control_point_is_refused_naming_it(text, start):
    assert _refused(text).startswith(start)


def _ur5_contact(control_point: str) -> str:
    from drake_coop.control.arm_plant import description_packages
    from drake_coop.scenario.resources import scenarios_dir

    if "example-robot-data" not in description_packages():
        pytest.skip("example-robot-data is not installed")
    text = (scenarios_dir() / "two_ur5.yaml").read_text()
    text = text.replace("  object_mode: planes", "  object_mode: contact")
    return text + f"object_model: {{mode: known, control_point: {control_point}}}\n"


def test_the_contact_point_is_accepted_on_an_arm_holding_its_pads_pose():
    # Two UR5s hold their pads' orientation (6 joints, ee_rpy_deg): pad_control "pose".
    assert load_scenario(data=_ur5_contact("contact")).object_model.control_point == "contact"


def test_the_contact_point_is_refused_on_an_arm_that_cannot_follow_it(monkeypatch):
    # An arm whose reference holds neither its pad's orientation nor a posture per point
    # (a 4- or 5-joint arm with a position-only task: pose_task.pad_control "centre"; the
    # arms shipped and example-robot-data's all have 3 or >= 6 joints, so one is faked).
    import drake_coop.kinematics.pose_task as pose_task

    text = _ur5_contact("contact")
    monkeypatch.setattr(pose_task, "pad_control", lambda kinematics: "centre")
    assert _refused(text).startswith(
        "object_model.control_point: contact needs arms whose references can follow the pad's "
        "material point: robots[0] (robot1) is redundant with a position-only task")


@pytest.fixture
def copied_momentum(monkeypatch):
    """A copy of the momentum observer's registry entry under another name (how a user adds
    an estimator): the registry is all that knows it."""
    from dataclasses import replace

    from drake_coop.control import registry

    copy = replace(registry.source("force", "momentum"), name="momentum_copy")
    monkeypatch.setattr(registry, "SOURCES", registry.SOURCES + (copy,))
    return copy


def test_a_copied_source_with_a_bad_option_is_refused_with_the_fields_path(copied_momentum):
    """Validation asks the selected source's registry entry (its ``check``), not its name: a
    copied estimator with ``momentum_gain: 5000`` (beyond 1/h) is refused at loading, naming
    the field; within 1/h it loads."""
    text = ("robots:\n- {name: robot1, force_source: momentum_copy, "
            "gains: {momentum_gain: 5000.0}}\n" + f"- {ROBOT2}\n")
    message = _refused(text)
    assert message.startswith("robots[0].gains.momentum_gain must be at most 1/h = ")
    assert "force_source: momentum_copy" in message and message.endswith("got 5000")
    ok = load_scenario(data=text.replace("5000.0", "100.0"))
    assert ok.robots[0].force_source == "momentum_copy"


def test_an_option_of_a_source_not_selected_is_refused_by_the_registry():
    """``difference_cutoff_hz`` is the difference source's option (its registry entry's
    ``options``): set with another velocity source it is refused, naming the field."""
    message = _refused(f"robots:\n- {{name: robot1, difference_cutoff_hz: 20.0}}\n- {ROBOT2}\n")
    assert message == ("robots[0].difference_cutoff_hz applies to velocity_source: difference "
                       "only; set it to null or use difference")
    message = _refused("robots:\n- {name: robot1, velocity_source: difference, "
                       f"difference_cutoff_hz: 1.0e4}}\n- {ROBOT2}\n")
    assert message.startswith("robots[0].difference_cutoff_hz must be null or in (0, ")


def test_the_registry_answers_which_inputs_a_robot_needs(copied_momentum):
    """The inputs from outside the block each selected source declares (a real arm's driver
    gives neither velocities nor a wrist force)."""
    from drake_coop.control.registry import missing_inputs

    s = load_scenario()
    robot = s.robots[0]
    assert missing_inputs(robot) == []                     # the paper's observers
    robot.velocity_source, robot.force_source = "measured", "sensor"
    assert missing_inputs(robot) == [("velocity_source", "measured", "state"),
                                     ("force_source", "sensor", "lambda_sensor")]
    assert missing_inputs(robot, available=("state", "lambda_sensor")) == []
    robot.velocity_source, robot.force_source = "observer", "momentum_copy"
    assert missing_inputs(robot) == []
