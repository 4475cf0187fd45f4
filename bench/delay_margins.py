"""The delay margin of shipped and lab arms, without and with delay compensation.

``python -m bench.delay_margins --out docs/results/delay_margins.json`` computes
:func:`drake_coop.stability.margin.delay_margins` (the free point's one-period map at each
computation delay, whole plant steps up to the control period) for the shipped scenarios
``paper``, ``two_ur5`` and ``two_pandas`` (their gains as shipped) and for a UR10 given the UR5's
gains (``two_ur5`` with the UR10's URDF: the margin it does not have, and the line saying why).
Each case is written as it ends (the file keeps the other cases).
"""

from __future__ import annotations

import argparse
import json
import time
from importlib.metadata import version
from pathlib import Path


def cases() -> dict:
    """Case name → a function returning its scenario."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import find_scenario

    def shipped(name):
        return lambda: load_scenario(find_scenario(name))

    def ur10():
        text = find_scenario("two_ur5").read_text().replace("ur5_robot.urdf", "ur10_robot.urdf")
        return load_scenario(data=text)

    return {"paper": shipped("paper"), "ur10_with_ur5_gains": ur10,
            "two_ur5": shipped("two_ur5"), "two_pandas": shipped("two_pandas")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--case", action="append", default=None)
    args = parser.parse_args()
    from drake_coop.stability.margin import delay_margins

    out = Path(args.out)
    data = json.loads(out.read_text()) if out.exists() else {"cases": {}}
    for name, make in cases().items():
        if args.case and name not in args.case:
            continue
        start = time.perf_counter()
        m = delay_margins(make())
        entry = m.as_dict()
        entry.update(wall_time_s=time.perf_counter() - start, drake=version("drake"))
        data["cases"][name] = entry
        out.write_text(json.dumps(data, indent=1) + "\n")
        print(f"{name}: {entry['line']}", flush=True)


if __name__ == "__main__":
    main()
