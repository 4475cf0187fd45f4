"""The continuous arm's ρ from two plant steps (``drake_coop.stability.continuous``) against the
one joint integrated exactly across the delayed switch (``dt=None``, an independent
computation): the per-mode extrapolation, the largest-modulus one and where it reads low."""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.stability.continuous import (continuous_rho, continuous_rows,
                                             continuous_spectrum)
from drake_coop.stability.one_joint import one_joint_predicted_phi

# Robot 2's slow joint and the paper's gains (as tests/stability/test_delay_map.py).
J, D, LAMBDA, K_D, K_R, H = 0.478, 1.0, 26.0, 40.0, 100.0, 0.009


def _eig(delay, horizon, dt, scale=1.0):
    return np.linalg.eigvals(one_joint_predicted_phi(J, D, LAMBDA, K_D, K_R, H, delay, horizon,
                                                     dt=dt, model_scale=scale))


@pytest.mark.parametrize("delay, scale", [(0.007, 1.0), (0.004, 1.3)])
def test_per_mode_extrapolation_is_right_where_the_dominant_mode_changes(delay, scale):
    coarse, fine = _eig(delay, 0.003, 1e-3, scale), _eig(delay, 0.003, 5e-4, scale)
    exact = np.max(np.abs(_eig(delay, 0.003, None, scale)))
    # the dominant eigenvalue at Δt is not the one nearest to the dominant one at Δt/2
    top = fine[np.argmax(np.abs(fine))]
    assert np.argmin(np.abs(coarse - top)) != np.argmax(np.abs(coarse))
    per_mode = np.max(np.abs(continuous_spectrum(coarse, fine)))
    largest = continuous_rho(np.max(np.abs(coarse)), np.max(np.abs(fine)))
    assert abs(per_mode - exact) < 5e-4
    assert exact - largest > 1.5e-3              # the largest-modulus form reads low here


@pytest.mark.parametrize("horizon", [None, 0.003])
@pytest.mark.parametrize("scale", [0.7, 1.0, 1.3])
def test_both_forms_agree_with_the_exact_arm_where_no_mode_changes(horizon, scale):
    for delay in (0.0, 0.001, 0.002, 0.003, 0.005, 0.006, 0.008):
        coarse, fine = _eig(delay, horizon, 1e-3, scale), _eig(delay, horizon, 5e-4, scale)
        exact = np.max(np.abs(_eig(delay, horizon, None, scale)))
        error = abs(np.max(np.abs(continuous_spectrum(coarse, fine))) - exact)
        assert error < 1e-3, delay
        if horizon is None:     # the 1 ms plant alone is biased by far more (about Δt/2 of delay)
            assert abs(np.max(np.abs(coarse)) - exact) > 10 * error, delay


def test_rows_mark_a_changed_dominant_mode_and_refuse_bad_spectra():
    rows = [{"plant.time_step": "0.001", "point": "free", "rho": "0.85", "status": "stable",
             "slowest_states": "a b"},
            {"plant.time_step": "0.0005", "point": "free", "rho": "0.86", "status": "stable",
             "slowest_states": "c"}]
    out = continuous_rows(rows, ["plant.time_step"])
    assert out[0]["mode_changed"] is True and out[0]["rho_continuous"] == pytest.approx(0.87)
    rows[1]["slowest_states"] = "b a"
    assert continuous_rows(rows, ["plant.time_step"])[0]["mode_changed"] is False
    del rows[0]["slowest_states"]
    assert continuous_rows(rows, ["plant.time_step"])[0]["mode_changed"] is None
    with pytest.raises(ValueError, match="one size"):
        continuous_spectrum([1.0, 0.5], [1.0])


def test_the_shipped_predictor_terms_are_what_the_closed_forms_give():
    """``docs/results/delay_predictor_terms.json`` (read by the stability page) is what
    ``studies/delay_compensation/predictor_terms.py`` computes now, and says what the page
    says: the observer's feed, not the predicted law inputs, keeps 8 ms stable."""
    import importlib.util
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location(
        "predictor_terms", root / "studies" / "delay_compensation" / "predictor_terms.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    shipped = json.loads((root / "docs" / "results" / "delay_predictor_terms.json").read_text())
    def flat(node, path=""):
        if isinstance(node, dict):
            return {k: v for key, child in node.items() for k, v in flat(child, f"{path}.{key}").items()}
        if isinstance(node, list):
            return {k: v for i, child in enumerate(node) for k, v in flat(child, f"{path}.{i}").items()}
        return {path: node}

    now = flat(json.loads(json.dumps(module.terms())))
    assert flat(shipped).keys() == now.keys()
    assert flat(shipped) == pytest.approx(now, abs=1e-12)
    assert shipped["predictor"]["plant_1ms"]["d8"] < 0.85
    assert shipped["predictor_without_feed"]["plant_1ms"]["d8"] > 1.0
    assert shipped["predictor"]["plant_1ms"]["d8"] == pytest.approx(
        max(abs(np.linalg.eigvals(one_joint_predicted_phi(J, D, LAMBDA, K_D, K_R, H, 0.008,
                                                          0.003, dt=1e-3)))))
    with pytest.raises(ValueError, match="feed"):
        one_joint_predicted_phi(J, D, LAMBDA, K_D, K_R, H, 0.008, 0.003, feed="half")
