"""The exact model's squeeze error on published study 5 draws, in the data budgets' setting.

    python studies/identification/exact_draws.py docs/results/identification_exact_draws.json 0 3

For each draw named (its sample number in ``docs/figures/studies/model_mismatch_results.csv``)
the draw's scenario as ``bench/identified_sources.py --budgets`` runs it (the paper's scenario,
the draw's unknown Coulomb friction per joint in the simulated arms, plant step 3 ms, to 35 s)
but with the controller models exact (mass, inertia and damping scales 1), observer (22): the
worst robot's circle-phase RMS of λ − λ_d, the figure the budgets table compares the
identified models with.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from bench.identified_sources import (PUBLISHED_T_END, PUBLISHED_TIME_STEP,  # noqa: E402
                                      published_cases, squeeze_error, with_plant_step)
from drake_coop.scenario.loading import dump_scenario, load_scenario  # noqa: E402


def exact_yaml(scenario_yaml: str) -> str:
    """The draw's scenario with every controller model exact (its Coulomb friction kept)."""
    s = load_scenario(data=scenario_yaml)
    for robot in s.robots:
        e = robot.model_error
        e.mass_scale = e.inertia_scale = e.damping_scale = 1.0
    return dump_scenario(s)


def main(argv: list[str]) -> int:
    """Run the draws ``argv[1:]`` and write the document to ``argv[0]``."""
    wanted = [int(a) for a in argv[1:]]
    cases = {sample: yaml for sample, yaml, _ in published_cases(max(wanted) + 1)}
    out: dict = {"t_end_s": PUBLISHED_T_END, "plant_time_step_s": PUBLISHED_TIME_STEP,
                 "squeeze_error_exact": {}}
    for sample in wanted:
        yaml = with_plant_step(exact_yaml(cases[sample]), PUBLISHED_TIME_STEP)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "scenario.yaml"
            path.write_text(yaml)
            subprocess.run([sys.executable, "-m", "drake_coop", "run", str(path), "--out",
                            str(Path(tmp) / "run"), "--quiet", "--no-replay", "--t-end",
                            str(PUBLISHED_T_END)], check=True, cwd=ROOT)
            metrics = json.loads((Path(tmp) / "run" / "metrics.json").read_text())
        out["squeeze_error_exact"][f"draw{sample}"] = squeeze_error(metrics)
    Path(argv[0]).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
