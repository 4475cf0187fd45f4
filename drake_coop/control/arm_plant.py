"""The controller's own single-arm plant, built from the arm's model file.

:func:`make_arm_controller_plant` parses a URDF or SDFormat file (or a ``package://`` URL) into
a continuous :class:`~pydrake.multibody.plant.MultibodyPlant` with the arm's base welded where
the arm stands, the plant :class:`~drake_coop.control.arm_model.ArmModel` and Drake's
``InverseDynamicsController`` want. Its parser also knows the description packages installed in
the Python environment (:data:`DESCRIPTION_PACKAGES`, :func:`description_packages`,
:func:`add_description_packages`), so ``package://example-robot-data/...`` resolves.
"""

from __future__ import annotations

from pathlib import Path

from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant


#: Description packages found in the Python environment: the package name the URDFs use,
#: and the data folder under ``site-packages`` (``example-robot-data``'s wheel holds no Python
#: module; its ``package.xml`` names it ``example_robot_descriptions``, its URDFs say
#: ``package://example-robot-data/...``).
DESCRIPTION_PACKAGES = {"example-robot-data": "cmeel.prefix/share/example-robot-data"}


def description_packages() -> dict[str, Path]:
    """The installed description packages by the name their URDFs use (folders holding a
    ``package.xml`` under an entry of ``sys.path``); empty when none is installed.

    Returns
    -------
    dict of str to Path
        Package name → its folder.
    """
    import sys

    found = {}
    for name, sub in DESCRIPTION_PACKAGES.items():
        for entry in sys.path:
            folder = Path(entry or ".") / sub
            if (folder / "package.xml").is_file():
                found[name] = folder.resolve()
                break
    return found


def add_description_packages(package_map) -> None:
    """Add :func:`description_packages` to a :class:`~pydrake.multibody.parsing.PackageMap`
    (those it does not know yet), so a parser reads ``package://example-robot-data/...``.

    Parameters
    ----------
    package_map : PackageMap
        The parser's package map.
    """
    for name, folder in description_packages().items():
        if not package_map.Contains(name):
            package_map.Add(name, str(folder))


def make_arm_controller_plant(model_file: str | Path, base_frame: str,
                              X_WB: RigidTransform | None = None) -> MultibodyPlant:
    """The controller's own single-arm plant, as Drake's ``InverseDynamicsController`` wants.

    Parameters
    ----------
    model_file : str or Path
        The arm's URDF or SDFormat file (``package://`` URLs resolved by Drake's parser, which
        also knows the installed description packages, :func:`add_description_packages`).
    base_frame : str
        The frame welded to the world.
    X_WB : RigidTransform, optional
        The base frame's pose in the world of the simulated plant (identity by default).

    Returns
    -------
    MultibodyPlant
        Finalized, continuous (time step 0), the base welded at ``X_WB``.
    """
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    add_description_packages(parser.package_map())
    text = str(model_file)
    if "://" in text:
        parser.AddModelsFromUrl(text)
    else:
        parser.AddModels(text)
    if not plant.HasFrameNamed(base_frame):
        raise ValueError(f"base_frame: {model_file} has no frame named {base_frame!r}")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame),
                     RigidTransform() if X_WB is None else X_WB)
    plant.Finalize()
    return plant
