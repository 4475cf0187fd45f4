"""Names that moved to the module that defines them, still found at their old path for a
while: in the manner of Drake's deprecation (``pydrake.common.deprecation``: the old spelling
keeps working and warns, naming the new one and the date it will be removed), a module's
``__getattr__`` answers for the names it no longer holds.

Use in a module that gave up a re-export::

    _MOVED = {"time_grid": "drake_coop.experiment.ticks"}

    def __getattr__(name):
        return moved(__name__, name, _MOVED)
"""

from __future__ import annotations

import importlib
import warnings

#: When the old import paths of :func:`moved` stop working.
REMOVAL_DATE = "2027-03-01"


def moved(module: str, name: str, table: dict[str, str]):
    """The object ``name`` from its defining module, with a :class:`DeprecationWarning`
    naming that module and :data:`REMOVAL_DATE`; for a module-level ``__getattr__``.

    Parameters
    ----------
    module : str
        The old module's name (``__name__``).
    name : str
        The attribute asked for.
    table : dict of str to str
        Moved name -> the module that defines it.

    Returns
    -------
    object
        The object, from its defining module.

    Raises
    ------
    AttributeError
        ``name`` did not move from ``module`` (the ordinary missing attribute).
    """
    if name not in table:
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    new = table[name]
    warnings.warn(f"{module}.{name} moved to {new}.{name}; import it from there (the old "
                  f"path is removed on {REMOVAL_DATE})", DeprecationWarning, stacklevel=3)
    return getattr(importlib.import_module(new), name)
