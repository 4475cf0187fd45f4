"""The pads' spin about the grasp line (bench/lab_arms_object.py: turn_sources), against the
integral of a closed-form angular velocity: a pad whose orientation cones (it yaws and pitches
about axes normal to the grasp line, by a small angle, and comes back) spins about the line by
a growing angle although its finite twist about it stays small: the spin is what a patch that
does not slide in torsion gives the box."""

from __future__ import annotations

import numpy as np
import pytest

from bench.lab_arms_object import turn_sources
from tests.results.test_object_metrics import DEPTH, GAMMA, _run, _ry, _rz

BETA, RATE = 0.15, 2.0 * np.pi * 0.8    # the coning's angle (rad) and rate (rad/s)


def _u(t):
    return BETA * np.sin(RATE * t)


def _v(t):
    return BETA * (1.0 - np.cos(RATE * t))


def _omega(t, R_B):
    """The pad's angular velocity in the world for R = R_B Rz(u) Ry(v) (closed form)."""
    u, du = _u(t), BETA * RATE * np.cos(RATE * t)
    dv = BETA * RATE * np.sin(RATE * t)
    return R_B @ np.array([-dv * np.sin(u), dv * np.cos(u), du])


def test_the_pads_spin_is_the_integral_of_their_angular_velocity_about_the_line():
    t, logs, meta = _run()
    R_B = _rz(GAMMA)
    k0 = int(np.searchsorted(t, 1.0 - 1e-9))
    # The grasp line: through the pads' contact points at the grasp (each centre DEPTH inside
    # its face's outward normal), computed here from the constructed pads.
    points = [logs[name]["x"][k0] - DEPTH * side * R_B[:, 0]
              for name, side in (("robot1", -1.0), ("robot2", 1.0))]
    a = (points[1] - points[0]) / np.linalg.norm(points[1] - points[0])
    for name in logs:
        logs[name]["pad_rotation"] = np.array([R_B @ _rz(_u(tk)) @ _ry(_v(tk)) for tk in t])
    out = turn_sources(logs, meta)
    # The reference: ∫ ω·a dt from the grasp, by the trapezoid rule on a 100x finer grid.
    circle = (t >= 4.0) & (t < 8.0)
    fine = np.linspace(t[k0], t[-1], 100 * (t.size - k0 - 1) + 1)
    rate = np.array([_omega(tk, R_B) @ a for tk in fine])
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(fine))])
    spin = np.interp(t, fine, integral)
    expected_rms = float(np.sqrt(np.mean(spin[circle] ** 2)))
    expected_max = float(np.max(np.abs(spin[circle])))
    for name in logs:
        assert out["pad_spin_rms"][name] == pytest.approx(expected_rms, rel=1e-3)
        assert out["pad_spin_max"][name] == pytest.approx(expected_max, rel=1e-3)
        # The finite twist stays small while the spin grows: they are different quantities.
        assert out["pad_twist_max"][name] < 0.2 * out["pad_spin_max"][name]
    assert expected_max > 0.05                       # the coning spins the pad measurably
