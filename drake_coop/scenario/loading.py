"""Loading a scenario from YAML and writing it back.

Loading reads the file as bytes with a size limit and parses it with bounded aliases and no
duplicate keys (:mod:`drake_coop.scenario.safe_yaml`), checks its structure (unknown keys, wrong types,
``null`` sections), fills the dataclasses with :func:`pydrake.common.yaml.yaml_load_typed` and
then runs :func:`drake_coop.scenario.validation.validate`. Every problem is reported as a
:class:`ScenarioError` whose one-line message (at most 300 characters) names the field and
what is allowed.
"""

import copy
import dataclasses
import functools
from pathlib import Path

from drake_coop.scenario.bounds import one_line, optional_of, show
from drake_coop.scenario.schema import Robot, Scenario, ScenarioError
from drake_coop.scenario.validation import validate


def load_scenario(path: str | Path | None = None, *, data: str | None = None,
                  before_validation=None, cache: dict | None = None) -> Scenario:
    """Load and validate a scenario from a YAML file (or a YAML string).

    Parameters
    ----------
    path : str or Path, optional
        YAML file (UTF-8, at most :data:`drake_coop.scenario.safe_yaml.MAX_BYTES`). ``None`` with
        ``data=None`` loads the shipped ``paper.yaml`` (the numbers of
        :func:`default_scenario`). A relative ``controller_model`` is looked up beside the
        file first (:func:`drake_coop.scenario.resources.resolve_models`), then among the shipped models.
    data : str, optional
        YAML text instead of a file.
    before_validation : callable, optional
        Called with the typed scenario before it is validated (``drake-coop gains`` sizes a
        placeholder ``K_R`` there: deriving it is its job).

    cache : dict, optional
        The reachability check's results shared between loadings (a study's cases:
        :func:`~drake_coop.scenario.validation.validate`'s ``cache``).

    Returns
    -------
    Scenario
        The validated scenario. Without a ``robots`` key, the paper's two robots.

    Raises
    ------
    ScenarioError
        With a one-line message naming the offending field and what is allowed.
    """
    from pydrake.common.yaml import yaml_load_typed

    from drake_coop.scenario.resources import default_scenario_path, resolve_models
    from drake_coop.scenario.safe_yaml import MAX_BYTES, YamlInputError, read_text_file

    if path is None and data is None:
        return load_scenario(default_scenario_path(), before_validation=before_validation,
                             cache=cache)             # the shipped paper.yaml
    else:
        try:
            if path is not None:
                data = read_text_file(path)
            elif len(data) > MAX_BYTES:
                raise YamlInputError(f"scenario text is longer than {MAX_BYTES} characters")
        except YamlInputError as exc:
            raise ScenarioError(str(exc)) from None
        untyped = _load_untyped(data)
        if untyped is None:          # 0 bytes, blanks or comments only: never the defaults
            where = f"the scenario file {one_line(str(path), 200)}" if path is not None \
                else "the scenario"
            raise ScenarioError(f"{where} is empty: it must be a mapping of fields "
                                f"({', '.join(f.name for f in dataclasses.fields(Scenario))})")
        _check_structure(untyped, Scenario, "")
        try:
            scenario = yaml_load_typed(
                schema=Scenario, data=data, allow_schema_with_no_yaml=True
            )
        except Exception as exc:  # yaml_load_typed raises plain RuntimeError/TypeError
            raise ScenarioError(_yaml_message(exc)) from None
        if "robots" not in untyped:
            scenario.robots = paper_robots()
    resolve_models(scenario, Path(path).resolve().parent if path is not None else Path.cwd())
    if before_validation is not None:
        before_validation(scenario)
    validate(scenario, cache=cache)
    return scenario


def _load_untyped(data: str):
    """The YAML document as plain data, with bounded aliases and no duplicate keys."""
    from drake_coop.scenario.safe_yaml import YamlInputError, load_untrusted

    try:
        return load_untrusted(data)
    except YamlInputError as exc:
        raise ScenarioError(str(exc)) from None


def _check_structure(data, schema, path: str) -> None:
    """Unknown keys, wrong types and ``null`` sections, reported with the field's dotted path."""
    import typing

    where = path or "scenario"
    if optional_of(schema) is not schema:       # X | None: null allowed
        if data is None:
            return
        schema = optional_of(schema)
    if dataclasses.is_dataclass(schema):
        hints = typing.get_type_hints(schema)
        if not isinstance(data, dict):
            raise ScenarioError(f"{where} must be a mapping of fields ({', '.join(hints)}), "
                                f"got {show(data)}")
        for key, value in data.items():
            if key not in hints:
                allowed = ", ".join(hints)
                key_text = one_line(key if isinstance(key, str) else show(key), 60)
                raise ScenarioError(f"{path + '.' if path else ''}{key_text} is not a known "
                                    f"field of {where}; allowed: {allowed}")
            _check_structure(value, hints[key], f"{path + '.' if path else ''}{key}")
        return
    origin = typing.get_origin(schema)
    if origin is dict:
        if not isinstance(data, dict):
            raise ScenarioError(f"{where} must be a mapping, got {show(data)}")
        key_type, value_type = typing.get_args(schema)
        for key, value in data.items():
            if not isinstance(key, str):
                raise ScenarioError(f"{where} keys must be names, got {show(key)}")
            _check_structure(value, value_type, f"{path}[{one_line(key, 40)}]")
    elif origin is list:
        if not isinstance(data, list):
            raise ScenarioError(f"{where} must be a list, got {show(data)}")
        (item,) = typing.get_args(schema)
        for i, value in enumerate(data):
            _check_structure(value, item, f"{path}[{i}]")
    elif schema is float:
        # As yaml_load_typed: ints and floats, and strings that Python's float() reads
        # (YAML 1.1 reads '1e-3' as a string). The range is checked by validate().
        if isinstance(data, bool) or not isinstance(data, (int, float, str)):
            raise ScenarioError(f"{where} must be a number, got {show(data)}")
        try:
            float(data)
        except OverflowError:
            raise ScenarioError(f"{where} must be a finite number, got {show(data)}") from None
        except ValueError:
            raise ScenarioError(f"{where} must be a number, got {show(data)}") from None
    elif schema is int:
        if isinstance(data, bool) or not (isinstance(data, int) or (
                isinstance(data, float) and data.is_integer())):
            raise ScenarioError(f"{where} must be an integer, got {show(data)}")
    elif schema is bool:
        if not isinstance(data, bool):
            raise ScenarioError(f"{where} must be true or false, got {show(data)}")
    elif schema is str:
        if not isinstance(data, str):
            raise ScenarioError(f"{where} must be a string, got {show(data)}")


def _yaml_message(exc: Exception) -> str:
    return f"invalid scenario: {one_line(exc, 200)}"


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as YAML text (round-trips through :func:`load_scenario`).

    Parameters
    ----------
    scenario : Scenario
        The scenario to write.
    """
    from pydrake.common.yaml import yaml_dump_typed

    return yaml_dump_typed(scenario)


def paper_robots() -> list[Robot]:
    """The two robots of Section IV with the paper's gains (β is ours), read from
    ``scenarios/paper.yaml``.
    """
    return default_scenario().robots


def default_scenario() -> Scenario:
    """The paper's experiment: ``scenarios/paper.yaml`` (the one source of the paper's numbers),
    parsed once and copied on every call.
    """
    return copy.deepcopy(_paper_scenario())


@functools.lru_cache(maxsize=1)
def _paper_scenario() -> Scenario:
    return load_scenario()
