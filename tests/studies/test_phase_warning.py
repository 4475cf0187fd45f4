"""A study whose ``t_end`` stops its cases before the phase it measures is told so in one
line (``drake-coop study``), with the phase's start read from the case's scenario."""

import pytest

from drake_coop.studies import expand, load_study
from drake_coop.studies.cli import phase_warning


@pytest.mark.parametrize("t_end, phase, warned", [
    (5.0, "circle", True), (25.0, "circle", True), (26.0, "circle", False),
    (5.0, "free", False), (5.0, "all", False), (None, "circle", False)])
def test_a_t_end_before_the_measured_phase_is_warned(tmp_path, t_end, phase, warned):
    (tmp_path / "s.yaml").write_text(
        f"grid:\n  robots.*.gains.k_d: [20]\nphase: {phase}\n"
        + (f"t_end: {t_end}\n" if t_end is not None else ""))
    study = load_study(tmp_path / "s.yaml")
    (case,) = expand(study)
    text = phase_warning(study, case)
    assert bool(text) == warned
    if warned:
        assert text == (f"the cases stop at t_end = {t_end:g} s, before phase circle starts "
                        "(25 s): its metrics in results.csv and the plots will be empty; give "
                        "--t-end > 25 (or a study with an earlier phase)")
