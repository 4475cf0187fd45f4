"""The stability page's step-size and along-the-path numbers: ρ(Φ) of the paper's loop at
9 ms for several central-difference steps (free and held; held with a computation delay; held
with measured velocities; held with one sample of encoder delay in ``realistic.yaml``), the
``analyse`` check at an absurd step, and the held map of the measured-velocity loop frozen at
several times of the path.

    python studies/stability/step_and_path.py docs/results/stability_steps_path.json

Each map is built as ``drake-coop stability`` builds it (:func:`operating_point` on the
scenario, the equilibrium by :func:`analyse` at the default step) and then differentiated at
each step (:func:`step_sensitivity`). Minutes of CPU.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from drake_coop.scenario.loading import load_scenario
from drake_coop.stability.operating import operating_point
from drake_coop.stability.period_map import analyse, step_sensitivity

ROOT = Path(__file__).resolve().parents[2]
STEPS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
DELAY_STEPS = (1e-2, 3e-3, 1e-3, 5e-4, 3e-4, 1e-4, 1e-5)


def _scenario(name: str, velocity: str = "observer", delay: float = 0.0, encoder: int = 0):
    s = load_scenario(ROOT / "scenarios" / f"{name}.yaml")
    for robot in s.robots:
        robot.velocity_source = velocity
        robot.timing.computation_delay = delay
        robot.encoders.delay_samples = encoder
    return s


def _key(eps: float) -> str:
    return f"{eps:.0e}".replace("-0", "-")


def steps(scenario, point: str, epsilons, t_star: float | None = None) -> dict:
    """``{ε: {"rho", "max_diff"}}`` at the equilibrium the default step finds."""
    F = operating_point(scenario, point, t_star).map
    report = analyse(F, check=False)
    rows = step_sensitivity(F, F.x0, report.dynamic, epsilons)
    return {_key(e): {"rho": r, "max_diff": d} for e, r, d in rows}


def main(argv: list[str]) -> int:
    """Write the document to ``argv[0]``."""
    out: dict = {"paper_free": steps(_scenario("paper"), "free", STEPS),
                 "paper_held": steps(_scenario("paper"), "held", STEPS),
                 "measured_held": steps(_scenario("paper", "measured"), "held", STEPS)}
    out["delay_held"] = {f"d{ms}": steps(_scenario("paper", delay=ms * 1e-3), "held",
                                         DELAY_STEPS) for ms in (2, 3, 4, 5, 6, 8)}
    out["realistic_encoder1_held"] = steps(_scenario("realistic", encoder=1), "held",
                                           (1e-5, 1e-4, 1e-3, 3e-3, 1e-2))
    F = operating_point(_scenario("paper"), "free").map
    absurd = analyse(F, epsilon=1e-16)
    fine = analyse(operating_point(_scenario("paper"), "free").map, epsilon=1e-5)
    out["check"] = {"eps_1e-16": {"rho": absurd.rho, "rho_check": absurd.rho_check},
                    "eps_1e-5": {"rho": fine.rho, "rho_check": fine.rho_check,
                                 "difference": abs(fine.rho - fine.rho_check)}}
    out["measured_held_path"] = {
        f"t{t:g}".replace(".", "p"): analyse(operating_point(
            _scenario("paper", "measured"), "held", t).map).rho
        for t in (15.5, 20.0, 25.0, 27.5, 30.0, 32.5, 35.0, 45.0)}
    Path(argv[0]).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
