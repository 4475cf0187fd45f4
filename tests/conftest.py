"""Shared fixtures: short versions of the paper's scenario (same gains, compressed phases)."""

import pytest

from drake_coop.scenario import Task, default_scenario


def short_scenario(mode: str = "planes", time_step: float = 0.001, **task):
    """The paper's scenario with its phases compressed to 8 s (free 1 s, lift 1 s, circle 4 s,
    put-down 1 s, return 1 s). Gains, h = 9 ms and the geometry are the paper's."""
    s = default_scenario()
    s.plant.object_mode = mode
    s.plant.time_step = time_step
    params = dict(t_pregrasp=0.6, t_grasp=1.0, t_circle_start=2.0, t_circle_end=6.0,
                  t_release=7.0, t_end=8.0)
    params.update(task)
    s.task = Task(**params)
    return s


@pytest.fixture
def make_short_scenario():
    return short_scenario
