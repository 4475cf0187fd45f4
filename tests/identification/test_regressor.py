"""The base-parameter rank of every shipped arm against an independent count: the largest
relative gap of the singular values of the *unscaled* regressor."""

from pathlib import Path

import numpy as np
import pytest

from drake_coop.identification.regressor import (
    Regressor,
    column_scale,
    condition_number,
    identifiable_basis,
    load_structure,
)

URDFS = sorted((Path(__file__).resolve().parents[2] / "urdf").glob("*.urdf"))


def _regressor(urdf: Path, N: int = 120, seed: int = 0) -> np.ndarray:
    s = load_structure(urdf, "base_link", payload_mass=0.5)
    rng = np.random.default_rng(seed)
    n = s.n
    q, v, a = (rng.uniform(-lim, lim, (N, n)) for lim in (1.0, 2.0, 4.0))
    return Regressor(s).matrix(q, v, a)


def _gap_rank(Y: np.ndarray) -> tuple[int, float]:
    """The rank where log σ drops most (σ of Y itself, no scaling), and that drop; σ floored
    at machine precision times σ_1 (exact zeros and round-off are one level)."""
    sv = np.linalg.svd(Y, compute_uv=False)
    sv = np.maximum(sv, np.finfo(float).eps * sv[0])
    drops = sv[:-1] / sv[1:]
    k = int(np.argmax(drops))
    return k + 1, float(drops[k])


def test_every_shipped_arm_is_found():
    assert {p.name for p in URDFS} >= {"crs_a465_3dof.urdf", "crs_a255_3dof.urdf",
                                       "coop6_6dof.urdf"}


@pytest.mark.parametrize("urdf", URDFS, ids=lambda p: p.stem)
def test_rank_is_the_singular_value_gap_of_the_unscaled_regressor(urdf):
    Y = _regressor(urdf)
    expected, drop = _gap_rank(Y)
    assert drop > 1e8               # a clear gap: the reference count is unambiguous
    cond, rank = condition_number(Y)
    assert rank == expected
    assert 1.0 <= cond < 1e6
    _, V = identifiable_basis(Y)
    assert V.shape[1] == expected


@pytest.mark.parametrize("urdf", ["crs_a465_3dof.urdf", "crs_a255_3dof.urdf"])
def test_the_crs_arms_have_22_base_parameters_and_a_round_off_column_is_not_one(urdf):
    Y = _regressor(Path(__file__).resolve().parents[2] / "urdf" / urdf)
    norms = np.linalg.norm(Y, axis=0)
    tiny = (norms > 0) & (norms < 1e-10 * norms.max())
    assert tiny.any()               # the round-off column exists (5e-15 against 10¹–10⁴)
    assert np.isinf(column_scale(Y)[tiny]).all()
    assert condition_number(Y)[1] == 22
    # Scaling that column up to a unit column (the old rule) would count one direction more.
    naive = norms.copy()
    naive[naive == 0.0] = 1.0
    sv = np.linalg.svd(Y / naive, compute_uv=False)
    assert int(np.sum(sv > 1e-8 * sv[0])) == 23


def _scenario_arms():
    """Every robot model of the shipped scenarios (the lab arms when the robots extra is
    installed), once each: (model, (urdf path, base frame, sensor joint))."""
    from drake_coop.plant.arms import shipped_arm_models

    return sorted(shipped_arm_models().items())


@pytest.mark.parametrize("where", [pytest.param(w, id=m.rsplit("/", 1)[-1])
                                   for m, w in _scenario_arms()])
def test_rank_is_the_singular_value_gap_on_every_scenario_arm(where):
    urdf, base, sensor = where
    s = load_structure(urdf, base, payload_mass=0.5, sensor_joint=sensor)
    rng = np.random.default_rng(0)
    N = 30 * s.n
    q, v, a = (rng.uniform(-lim, lim, (N, s.n)) for lim in (1.0, 2.0, 4.0))
    Y = Regressor(s).matrix(q, v, a)
    expected, drop = _gap_rank(Y)
    assert drop > 1e8
    assert condition_number(Y)[1] == expected
