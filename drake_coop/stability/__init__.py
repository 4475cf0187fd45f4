"""Local stability of the sampled closed loop: the one-period map, its monodromy matrix Φ by
central differences with the Simulator, ρ(Φ) at operating points and over grids of scenario
paths (``drake-coop stability``).

Modules: :mod:`~drake_coop.stability.state` (the loop's state, generically),
:mod:`~drake_coop.stability.period_map` (map, equilibrium, Φ, modes),
:mod:`~drake_coop.stability.operating` (free and held operating points),
:mod:`~drake_coop.stability.grid` (grids on worker processes or Ray),
:mod:`~drake_coop.stability.output` (``stability.csv``, maps), :mod:`~drake_coop.stability.cli`.
"""

__all__ = ["MapReport", "PeriodMap", "analyse"]


def __getattr__(name: str):
    """The re-exported names, imported on first use: ``drake-coop``'s argument parser imports
    :mod:`drake_coop.stability.cli` at start-up, which must not load pydrake (a Ctrl-C inside
    pydrake's own initialization surfaces as an ImportError, not as an interrupt)."""
    if name in __all__:
        from drake_coop.stability import period_map

        return getattr(period_map, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
