"""Property-based fuzzing of scenario files: every malformed field is named, nothing crashes.

Hypothesis mutates ``scenarios/paper.yaml`` one place at a time (a section, a field, a list
entry, or an extra key) with wrong types, NaN, ±inf, zero, negative, tiny, huge and long
values, strings, nulls, lists and mappings. Each mutated file must either load (a valid
scenario) or be refused with a :class:`ScenarioError` whose message is one line of at most 300
characters naming the mutated field. A few cases also go through the console script in a
subprocess (exit 2, one line, no traceback), and valid extremes of the gains are simulated
briefly (the run ends "ok" or "diverged", never with an exception).
"""

import copy
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_coop.scenario import BOUNDS, ScenarioError, load_scenario
from drake_coop.scenario.bounds import MAX_MESSAGE

PAPER = Path(__file__).resolve().parents[2] / "scenarios" / "paper.yaml"
PAPER_DATA = yaml.safe_load(PAPER.read_text())


def _places(data, path=()):
    """Every section, field and list entry of the document, as key paths."""
    if path:
        yield path
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _places(value, path + (key,))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _places(value, path + (i,))


PLACES = list(_places(PAPER_DATA))
SPECIAL = [None, "", "x", "robot1", True, False, [], {}, [1, 2], [[1]], {"a": 1},
           float("nan"), float("inf"), float("-inf"), 0, 0.0, -1, -1e-9, 1e-300, 1e300, -1e300,
           10 ** 400, -(10 ** 400), "1e300", "nan", "9" * 500, "x" * 2000, 0.5, 2.0, 1e4]
VALUES = st.one_of(
    st.sampled_from(SPECIAL),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(),
    st.text(max_size=30),
    st.lists(st.floats(-10, 10), max_size=4),
)


def _set(data, path, value):
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value


def _names(path) -> list[str]:
    """What the message must mention: the mutated field's name (the last key)."""
    keys = [k for k in path if isinstance(k, str)]
    return [keys[-1]]


def _check_message(message: str, expected: list[str]) -> None:
    assert "\n" not in message and len(message) <= MAX_MESSAGE, message
    assert "Traceback" not in message
    assert any(name in message for name in expected), (expected, message)


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(place=st.sampled_from(PLACES), value=VALUES)
def test_a_mutated_field_is_named_or_the_scenario_is_valid(place, value):
    data = copy.deepcopy(PAPER_DATA)
    _set(data, place, value)
    text = yaml.safe_dump(data)
    try:
        load_scenario(data=text)
    except ScenarioError as exc:
        _check_message(str(exc), _names(place))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(place=st.sampled_from([p for p in PLACES if not isinstance(p[-1], int)]),
       value=st.sampled_from([1, "x", None]))
def test_an_unknown_key_is_named(place, value):
    data = copy.deepcopy(PAPER_DATA)
    parent = data
    for key in place[:-1]:
        parent = parent[key]
    if not isinstance(parent, dict):
        return
    parent["bogus_key"] = value
    with pytest.raises(ScenarioError) as info:
        load_scenario(data=yaml.safe_dump(data))
    _check_message(str(info.value), ["bogus_key"])


@pytest.mark.parametrize("place, value", [
    (("robots", 0, "controller_model"), "/etc/passwd"),
    (("plant", "time_step"), 1e-300),
    (("task", "t_end"), 10 ** 400),
])
def test_console_script_refuses_mutations_without_traceback(tmp_path, place, value):
    data = copy.deepcopy(PAPER_DATA)
    _set(data, place, value)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "drake_coop", "run", str(path), "--out",
                           str(out), "--quiet"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert place[-1] in proc.stderr
    assert not out.exists() and not list(tmp_path.glob(".out.*"))


@pytest.mark.parametrize("gain", ["Lambda", "k_d", "K_R"])
def test_gains_at_their_upper_bound_run_or_diverge_cleanly(gain):
    from drake_coop.experiment.simulate import simulate

    s = load_scenario()
    for r in s.robots:
        hi = BOUNDS[f"robots[].gains.{gain}" + ("[]" if gain == "K_R" else "")].hi
        setattr(r.gains, gain, [hi] * 3 if gain == "K_R" else hi)
    result = simulate(s, t_end=0.2)
    assert result.meta["status"] in ("ok", "diverged"), result.meta
    assert len(result.meta["message"]) <= MAX_MESSAGE
