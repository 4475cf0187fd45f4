"""Expansion of a study into cases: dotted paths, grid product, Monte Carlo draws, case hashes.

Paths
-----
A path names a scenario field with dots: ``control_period``, ``plant.time_step``,
``robots.0.gains.k_d``. A list index is a number; ``*`` matches every element
(``robots.*.gains.k_d``, ``robots.0.gains.K_R.*``).

Lists of numbers (``K_R``, ``base_xyz``) are set **as a whole or element-wise**:

* ``robots.0.gains.K_R: [[100, 100, 80]]`` (grid) sets the whole list;
* a single number at a list path (``robots.0.gains.K_R: [60, 120]``) sets every element to it;
* ``robots.0.gains.K_R.2`` or ``…K_R.*`` addresses elements.

A grid value that is a mapping at a path that names a mapping is a **variant**: it sets the
fields it lists and keeps the others, so fields that only make sense together vary together
(``robots.*: [{velocity_source: observer}, {velocity_source: difference,
difference_cutoff_hz: 20}]``).

In a grid, ``*`` gives every matched element the same value. In Monte Carlo, ``*`` draws
**independently** for every matched element (``robots.*.model_error.mass_scale`` gives each arm
its own draw); a path without ``*`` draws once: ``{scale_uniform: [lo, hi]}`` at a list path
multiplies the whole list by one factor, ``{uniform: …}`` sets every element to one draw.

Cases
-----
Grid points are the Cartesian product of the grid's lists (first key outermost); each grid point
is combined with every Monte Carlo sample ``i = 0 … n−1`` (the same draws at every grid point:
common random numbers). Draws come from ``numpy.random.default_rng(seed)`` in the order
sample, perturbation (file order), matched element. A case is identified by the SHA-256 of its
canonical scenario YAML (``dump_scenario`` of the validated scenario) and the study's ``t_end``.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import types
import typing
from dataclasses import dataclass, is_dataclass

import numpy as np

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.schema import Scenario, ScenarioError
from drake_coop.studies.spec import Perturbation, Study, StudyError

__all__ = ["Case", "case_hash", "draw", "expand", "get_value", "resolve", "set_value"]

Key = str | int


@dataclass
class Case:
    """One run of a study.

    Attributes
    ----------
    index : int
        Position in the expansion order.
    params : dict
        Grid path -> value, and for Monte Carlo ``sample`` and each drawn concrete path.
    scenario_yaml : str
        The canonical, validated scenario.
    hash : str
        16 hex digits of SHA-256 over ``scenario_yaml`` and ``t_end``.
    """

    index: int
    params: dict
    scenario_yaml: str
    hash: str


def _unwrap_optional(schema):
    """``X | None`` / ``Optional[X]`` -> ``X``."""
    if typing.get_origin(schema) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(schema) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return schema


def resolve(data: dict, path: str, where: str) -> list[tuple[Key, ...]]:
    """Concrete key paths matched by a dotted ``path`` in the scenario dict ``data``.

    Fields are checked against the :class:`~drake_coop.scenario.Scenario` dataclasses (a field
    missing from ``data`` but known to the schema is allowed: it will be created).

    Raises
    ------
    StudyError
        ``"<where>: no such field"`` (with the allowed names) or a bad index.
    """
    results: list[tuple[Key, ...]] = []

    def walk(node, schema, parts: list[str], prefix: tuple[Key, ...]) -> None:
        schema = _unwrap_optional(schema)
        if not parts:
            results.append(prefix)
            return
        head, rest = parts[0], parts[1:]
        shown = ".".join(map(str, prefix + (head,)))
        if is_dataclass(schema):
            hints = typing.get_type_hints(schema)
            if head not in hints:
                raise StudyError(f"{where}: no such field ({shown!r}); allowed here: "
                                 f"{', '.join(hints)}")
            child = node.get(head) if isinstance(node, dict) else None
            walk(child, hints[head], rest, prefix + (head,))
        elif typing.get_origin(schema) is list:
            (item,) = typing.get_args(schema)
            size = len(node) if isinstance(node, list) else 0
            if head == "*":
                indices = range(size)
            elif head.isdigit() and int(head) < size:
                indices = [int(head)]
            else:
                raise StudyError(f"{where}: {shown!r} is not an index of a list of {size} "
                                 f"(use 0 … {size - 1} or *)")
            for i in indices:
                walk(node[i], item, rest, prefix + (i,))
        else:
            raise StudyError(f"{where}: no such field ({shown!r}); "
                             f"{'.'.join(map(str, prefix))} is a value, not a mapping or list")

    walk(data, Scenario, path.split("."), ())
    return results


def get_value(data: dict, keys: tuple[Key, ...]):
    """The value at a concrete key path (None when absent)."""
    node = data
    for k in keys:
        if isinstance(k, int):
            node = node[k] if isinstance(node, list) and k < len(node) else None
        else:
            node = node.get(k) if isinstance(node, dict) else None
        if node is None:
            return None
    return node


def set_value(data: dict, keys: tuple[Key, ...], value) -> None:
    """Set the value at a concrete key path in place.

    A number at a list of numbers sets every element (broadcast); a mapping at a mapping
    updates the fields it names and keeps the others (a *variant*, see :func:`expand`).
    """
    node = data
    for k in keys[:-1]:
        if isinstance(k, str) and (k not in node or node[k] is None):
            node[k] = {}
        node = node[k]
    last = keys[-1]
    old = node.get(last) if isinstance(node, dict) else node[last]
    if isinstance(value, dict) and isinstance(old, dict):
        for k, v in value.items():
            set_value(old, (k,), v)
        return
    if isinstance(old, list) and not isinstance(value, list):
        value = [value] * len(old)
    node[last] = copy.deepcopy(value)


def _scenario_text(data: dict) -> str:
    """Canonical YAML of the scenario dict (validated)."""
    from pydrake.common.yaml import yaml_dump

    return dump_scenario(load_scenario(data=yaml_dump(data)))


def case_hash(scenario_yaml: str, t_end: float | None) -> str:
    """16 hex digits of SHA-256 over the canonical scenario YAML and the study's ``t_end``."""
    text = f"{scenario_yaml}\n# t_end: {t_end!r}\n"
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def draw(p: Perturbation, base, rng: np.random.Generator):
    """One Monte Carlo value of ``p``: uniform ``U(a, b)``, normal ``N(a, b²)``, or
    ``base * U(a, b)`` for ``scale_uniform`` (element-wise on a list base, one factor)."""
    if p.distribution == "uniform":
        return float(rng.uniform(p.a, p.b))
    if p.distribution == "normal":
        return float(rng.normal(p.a, p.b))
    factor = float(rng.uniform(p.a, p.b))
    if isinstance(base, list):
        return [float(v) * factor for v in base]
    return float(base) * factor


def _number_or_list(value, where: str) -> None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok and not (isinstance(value, list) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise StudyError(f"{where}: scale_uniform needs a numeric base value, got {value!r}")


def _base_dict(study: Study) -> dict:
    from pydrake.common.yaml import yaml_load

    try:
        scenario = load_scenario(data=study.base_yaml) if study.base_yaml else load_scenario()
    except ScenarioError as exc:
        raise StudyError(f"base: {exc}") from None
    return yaml_load(data=dump_scenario(scenario))


def _validated(data: dict, where: str) -> str:
    try:
        return _scenario_text(data)
    except ScenarioError as exc:
        raise StudyError(f"{where}: {exc}") from None


def _samples(study: Study, base: dict) -> list[dict[tuple[Key, ...], object]]:
    """Monte Carlo draws per sample: concrete key path -> value (one empty sample: no MC)."""
    mc = study.monte_carlo
    if mc is None:
        return [{}]
    targets = [(p, resolve(base, p.path, f"monte_carlo.perturb.{p.path}")) for p in mc.perturb]
    rng = np.random.default_rng(mc.seed)
    samples = []
    for _ in range(mc.n):
        values = {}
        for p, matches in targets:
            for keys in matches:
                base_value = get_value(base, keys)
                if p.distribution == "scale_uniform":
                    _number_or_list(base_value, f"monte_carlo.perturb.{p.path}")
                values[keys] = draw(p, base_value, rng)
        samples.append(values)
    return samples


def expand(study: Study) -> list[Case]:
    """All cases of ``study``, each scenario validated, in order (grid outer, samples inner).

    Raises
    ------
    StudyError
        A bad path (``grid.robots.0.gains.k_x: no such field …``) or a value the scenario
        rejects (``grid.control_period: control_period must be > 0, got -1``), before any run.
    """
    base = _base_dict(study)
    grid_targets = {path: resolve(base, path, f"grid.{path}") for path in study.grid}
    for path, values in study.grid.items():     # each value alone: names the bad one
        for value in values:
            data = copy.deepcopy(base)
            for keys in grid_targets[path]:
                set_value(data, keys, value)
            _validated(data, f"grid.{path} = {value!r}")
    samples = _samples(study, base)
    cases = []
    keys_order = list(study.grid)
    for point in itertools.product(*(study.grid[k] for k in keys_order)):
        grid_params = dict(zip(keys_order, point))
        for s, values in enumerate(samples):
            data = copy.deepcopy(base)
            for path, value in grid_params.items():
                for keys in grid_targets[path]:
                    set_value(data, keys, value)
            for keys, value in values.items():
                set_value(data, keys, value)
            params = dict(grid_params)
            if study.monte_carlo is not None:
                params["sample"] = s
                params.update({".".join(map(str, k)): v for k, v in values.items()})
            label = ", ".join(f"{k}={v!r}" for k, v in params.items())
            text = _validated(data, f"case {len(cases)} ({label})")
            cases.append(Case(index=len(cases), params=params, scenario_yaml=text,
                              hash=case_hash(text, study.t_end)))
    return cases
