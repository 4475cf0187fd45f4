"""Local stability of the sampled closed loop: the one-period map, its monodromy matrix Φ by
central differences with the Simulator, ρ(Φ) at operating points and over grids of scenario
paths (``drake-coop stability``).

Modules: :mod:`~drake_coop.stability.state` (the loop's state, generically),
:mod:`~drake_coop.stability.period_map` (map, equilibrium, Φ, modes),
:mod:`~drake_coop.stability.operating` (free and held operating points),
:mod:`~drake_coop.stability.grid` (grids on worker processes or Ray),
:mod:`~drake_coop.stability.output` (``stability.csv``, maps), :mod:`~drake_coop.stability.cli`.
"""

from drake_coop.stability.period_map import MapReport, PeriodMap, analyse

__all__ = ["MapReport", "PeriodMap", "analyse"]
