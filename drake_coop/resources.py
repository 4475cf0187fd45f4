"""Where the package's data lives: the arm models (URDF) and the shipped scenarios (YAML).

The top-level ``urdf/`` and ``scenarios/`` folders of the repository are the one source. A
wheel carries copies of them as package data (``drake_coop/data/urdf``,
``drake_coop/data/scenarios``, mapped in ``pyproject.toml``), so an installed package finds
them next to its modules; a source checkout (editable install, ``PYTHONPATH``) reads the
top-level folders directly. Everything that needs a model or a shipped scenario asks this
module.

Lookup order of a data folder ``kind`` (``urdf`` or ``scenarios``):

1. ``$DRAKE_COOP_URDF_DIR`` (models only), as before;
2. the installed package data ``drake_coop/data/<kind>`` (wheel installs);
3. the checkout's ``<repo>/<kind>`` (editable installs and ``PYTHONPATH`` runs).
"""

from __future__ import annotations

import os
from importlib import resources as _resources
from pathlib import Path
from typing import TYPE_CHECKING

from drake_coop.scenario import ScenarioError

if TYPE_CHECKING:
    from drake_coop.scenario import Scenario

__all__ = ["data_dir", "urdf_dir", "scenarios_dir", "shipped_scenarios", "scenario_summary",
           "find_scenario", "default_scenario_path", "resolve_model", "resolve_models"]

#: A file each data folder must hold (tells a real folder from a stray one).
_MARKERS = {"urdf": "crs_a465_3dof.urdf", "scenarios": "paper.yaml"}


def data_dir(kind: str) -> Path:
    """The folder of the package's ``urdf`` or ``scenarios`` data.

    Parameters
    ----------
    kind : str
        ``"urdf"`` or ``"scenarios"``.

    Returns
    -------
    Path
        The installed package data if present, else the source checkout's top-level folder.

    Raises
    ------
    FileNotFoundError
        Neither exists (a broken installation); the message says where it looked.
    """
    marker = _MARKERS[kind]
    packaged = Path(str(_resources.files("drake_coop") / "data" / kind))
    checkout = Path(__file__).resolve().parents[1] / kind
    for folder in (packaged, checkout):
        if (folder / marker).is_file():
            return folder
    raise FileNotFoundError(f"drake_coop's {kind} folder is missing (looked for {marker} in "
                            f"{packaged} and {checkout}); reinstall the package")


def urdf_dir() -> Path:
    """Folder of the robot models: ``$DRAKE_COOP_URDF_DIR`` if set, else the shipped one."""
    env = os.environ.get("DRAKE_COOP_URDF_DIR")
    return Path(env) if env else data_dir("urdf")


def scenarios_dir() -> Path:
    """Folder of the shipped scenarios (``paper.yaml`` and its variants)."""
    return data_dir("scenarios")


def default_scenario_path() -> Path:
    """The shipped ``paper.yaml``: the default scenario of ``drake-coop run``."""
    return scenarios_dir() / "paper.yaml"


def shipped_scenarios() -> dict[str, Path]:
    """Shipped scenarios by name (file stem), sorted by name."""
    return {p.stem: p for p in sorted(scenarios_dir().glob("*.yaml"))}


def scenario_summary(path: Path) -> str:
    """The first comment line of a scenario file, without its ``#`` (empty if none)."""
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            return line.lstrip("#").strip()
    return ""


def find_scenario(name_or_path: str | Path) -> Path:
    """A scenario file from a path, or from the name of a shipped scenario.

    An existing file wins; otherwise ``paper`` or ``paper.yaml`` names a shipped scenario.

    Raises
    ------
    ScenarioError
        Neither a file nor a shipped scenario (the message lists the shipped names).
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_scenarios()
    stem = path.name[:-5] if path.name.endswith(".yaml") else path.name
    if path.parent == Path(".") and stem in shipped:
        return shipped[stem]
    raise ScenarioError(f"scenario file not found: {path} (shipped scenarios: "
                        f"{', '.join(shipped)})")


#: Bodies and joints the package reads by name in an arm model: the controller's model needs
#: the base and the pad; the simulated arm also its wrist force sensor.
CONTROLLER_MODEL_NEEDS = ("base_link", "pad")
SIMULATED_MODEL_NEEDS = ("base_link", "pad", "force_sensor", "flange_sensor_weld")


def _check_model_file(field_name: str, path: Path,
                      needs: tuple[str, ...] = CONTROLLER_MODEL_NEEDS) -> Path:
    """Raise a one-line ScenarioError unless ``path`` is a readable model Drake parses, with
    the named bodies/joints ``needs`` and three actuated joints."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    if not path.is_file():
        raise ScenarioError(f"{field_name}: model file not found: {path}")
    try:
        path.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{field_name}: model file {path} cannot be read: "
                            f"{exc.strerror}") from None
    try:
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(path))
    except Exception as exc:  # Drake's parser raises RuntimeError with a multi-line text
        first = next((ln.strip() for ln in str(exc).splitlines() if ln.strip()), "")
        raise ScenarioError(f"{field_name}: model file {path} is not a valid model: "
                            f"{first}") from None
    missing = [n for n in needs if not (plant.HasBodyNamed(n) or plant.HasJointNamed(n))]
    if missing or plant.num_actuators() != 3:
        raise ScenarioError(
            f"{field_name}: model file {path} is not a 3-joint arm model like urdf/*.urdf "
            f"(needs bodies/joints {', '.join(needs)} and 3 actuators; missing "
            f"{', '.join(missing) or 'none'}, {plant.num_actuators()} actuators)")
    return path


def resolve_model(field_name: str, value: str, base_dir: Path | None = None) -> Path:
    """The model file a scenario field names, checked.

    Parameters
    ----------
    field_name : str
        The field, for the message (e.g. ``robots[1].controller_model``).
    value : str
        An absolute path, or a path relative to ``base_dir`` (the scenario file's folder) or
        to :func:`urdf_dir` (the shipped models), tried in that order.
    base_dir : Path, optional
        Folder of the scenario file.

    Returns
    -------
    Path
        The existing, readable and parseable model file.

    Raises
    ------
    ScenarioError
        One line naming the field and the path.
    """
    p = Path(value).expanduser()
    if p.is_absolute():
        return _check_model_file(field_name, p)
    candidates = ([base_dir / p] if base_dir is not None else []) + [urdf_dir() / p]
    for c in candidates:
        if c.is_file():
            return _check_model_file(field_name, c)
    raise ScenarioError(f"{field_name}: model file not found: {value} (looked in "
                        f"{', '.join(str(c.parent) for c in candidates)})")


def resolve_models(scenario: Scenario, base_dir: Path | None = None) -> None:
    """Check every robot's model files; make controller models beside the scenario absolute.

    The simulated arm is ``<urdf_dir>/<model>_3dof.urdf``. A relative ``controller_model``
    found beside the scenario file is rewritten as an absolute path (the arms look relative
    paths up in :func:`urdf_dir`), so a run's saved ``scenario.yaml`` still finds it.

    Raises
    ------
    ScenarioError
        A missing, unreadable or unparseable model file, naming the field and the path.
    """
    for i, robot in enumerate(scenario.robots):
        try:
            folder = urdf_dir()
        except FileNotFoundError as exc:
            raise ScenarioError(f"robots[{i}].model: {exc}") from None
        _check_model_file(f"robots[{i}].model", folder / f"{robot.model}_3dof.urdf",
                          SIMULATED_MODEL_NEEDS)
        if robot.controller_model:
            value = robot.controller_model
            found = resolve_model(f"robots[{i}].controller_model", value, base_dir)
            if not Path(value).is_absolute() and found != folder / value:
                robot.controller_model = str(found.resolve())
