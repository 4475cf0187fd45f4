"""``gains``' refusal says why a map is not below 1: no steady state, or its slowest mode."""

from __future__ import annotations

import numpy as np

from drake_coop.stability.gains import map_failure_reason
from drake_coop.stability.period_map import MapReport, Mode


def _report(residual: float, mode: Mode | None) -> MapReport:
    return MapReport(rho=mode.magnitude if mode else float("inf"), Phi=np.zeros((0, 0)),
                     labels=[], dynamic=[], counters=[], locked=[], overwritten=[],
                     residual=residual, epsilon=1e-5, evaluations=0, slowest=mode)


def test_no_steady_state_is_named_with_its_residual():
    reason = map_failure_reason(_report(23.09, None))
    assert reason.startswith("no steady state of the loop found there")
    assert "residual 23.1 > 1e-06" in reason


def test_a_real_unstable_mode_names_its_state_entries():
    mode = Mode(2.364 + 0j, 2.364, float("inf"), 0.0,
                ["plant:so101_2::wrist_roll_w", "so101_2_velocity_observer[1][4]"])
    reason = map_failure_reason(_report(4e-14, mode))
    assert reason == ("slowest mode |mu| = 2.36 (real: diverges without oscillating) in "
                      "so101_2::wrist_roll_w, so101_2_velocity_observer[1][4]")


def test_an_oscillating_mode_gives_its_frequency():
    mode = Mode(-1.2 + 0.5j, abs(-1.2 + 0.5j), float("inf"), 41.5, ["plant:a::j1_w"])
    assert "oscillating at 41.5 Hz" in map_failure_reason(_report(0.0, mode))
