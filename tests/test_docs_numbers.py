"""The docs' measured numbers come from their commands (``docs/_ext/results_role.py``).

* every ``{result}`` role of every page resolves against the shipped results files (a role
  that names a missing column, a missing row, several rows or an unknown unit fails);
* the role reads the file's value (checked against an independent ``csv`` read) and scales
  it to the stated unit;
* the claims pages (``docs/claims/``), the object, robot and lab-arms guides, the
  stability, identification and benchmark pages and the README hold no measured number
  typed by hand: prose digits followed by a physical unit or a percentage, outside a role, math, code
  and links. The inputs a page states (the scenario's fields: the control period, the run's
  length, the object's mass, ...) are listed in :data:`INPUTS` with the reason;
* the detector finds typed numbers (it is run on a sample page that has them).
"""

from __future__ import annotations

import csv
import os
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

# The role is a Sphinx extension (docutils): without the docs extra these tests skip, unless
# DRAKE_COOP_REQUIRE_DOCS=1 (CI's docs environment), where a missing docutils fails them.
if os.environ.get("DRAKE_COOP_REQUIRE_DOCS") != "1":
    pytest.importorskip("docutils", reason="the docs extra is not installed")
import results_role  # noqa: E402

#: The pages that must hold no hand-typed measured number (the README's numbers are
#: ``VALUE<!-- result: SPEC -->``, checked by test_the_readme_writes_each_number_beside_its_source).
CHECKED = sorted((DOCS / "claims").glob("*.md")) + [
    DOCS / "guide" / "object.md", DOCS / "guide" / "real_robot.md", DOCS / "guide" / "lab_arms.md",
    DOCS / "stability.md", DOCS / "identification.md", DOCS / "benchmark.md", ROOT / "README.md"]


def _rel(page: Path) -> str:
    return str(page.relative_to(DOCS)) if DOCS in page.parents else page.name

UNIT = (r"(?:MPa|kPa|Pa|N/s|N\s?m|mN|N|mm/s|m/s|mm|cm|µm|um|nm|m|ms|µs|s|kg|g|mrad/s|rad/s|mrad|rad|Hz|"
        r"°|%|×|x(?=\s)|dB|min|h)")
#: digits (a range, a decimal, an exponent) then a unit: a number a measurement would print.
MEASURED = re.compile(r"(?<![\w.\-/])(?:[~≈<>≤≥][ \u00a0]?)?\d(?:[\d.]|[ ,](?=\d{3}\b))*"
                      r"(?:[eE][-−+]?\d+)?(?:[ \u00a0]?[–-][ \u00a0]?\d[\d.]*)?[ \u00a0]?"
                      + UNIT + r"(?![\w/])")

#: Inputs a page states in prose (not measurements): (page, exact text, reason).
INPUTS: list[tuple[str, str, str]] = [
    ("*", "9 ms", "the control period h, the scenario's control_period"),
    ("*", "1 ms", "the plant's time step, the scenario's plant.time_step"),
    ("*", "65 s", "the run's end, the study's t_end"),
    ("*", "66 s", "the run's end, a command's --t-end"),
    ("*", "15 s", "the grasp's time in the scenario's timeline"),
    ("*", "25–65 s", "the circle phase of the scenario's timeline"),
    ("*", "15–25 s", "the lift phase of the scenario's timeline"),
    ("*", "1 s", "the squeeze ramps' length, a fixed input of the reference"),
    ("*", "0.5 kg", "the object's mass, an input of scenarios/contact.yaml"),
    ("*", "2 kg", "the object's mass of the case first reported, an input"),
    ("*", "50 %", "the estimated model's prior: prior_mass_factor 1.5, an input"),
    ("*", "1 N/s", "squeeze_rate's default, an input"),
    ("*", "20 N/s", "the shared squeeze's rise limit, a constant of the block"),
    ("*", "1.5×", "the prior's factor, prior_mass_factor 1.5, an input"),
    ("*", "1.8 s", "the forgetting horizon 200 ticks x 9 ms, from the inputs"),
    ("*", "14–50 N", "the paper's force profile (29), an input"),
    ("*", "32–50 N", "the paper's force profile (29) over the circle, an input"),
    ("claims/force_sensing.md", "0.1 N", "a swept noise level (force_sensor.noise_std)"),
    ("claims/force_sensing.md", "0.3 N", "a swept noise level (force_sensor.noise_std)"),
    ("claims/force_sensing.md", "1 N", "a swept noise level (force_sensor.noise_std)"),
    ("claims/force_sensing.md", "3 N", "a swept noise level (force_sensor.noise_std)"),
    ("claims/force_sensing.md", "35 s", "the old runs' end (t_end), an input"),
    ("claims/gain_map.md", "3 ms", "the earlier runs' plant step (plant.time_step), an input"),
    ("claims/gain_map.md", "35 s", "the earlier runs' end (t_end), an input"),
    ("claims/gain_map.md", "10 s", "a window of the timeline, an input"),
    ("claims/model_mismatch.md", "10 %", "a percentile (the table's header)"),
    ("claims/model_mismatch.md", "90 %", "a percentile (the table's header)"),
    ("claims/model_mismatch.md", "30 %", "the draws' range U(0.7, 1.3), an input"),
    ("claims/model_mismatch.md", "1 N", "the friction draws' range U(0, 1) N·m, an input"),
    ("claims/model_mismatch.md", "10 N", "a threshold the sentence counts the cases against"),
    ("claims/model_mismatch.md", "20 N", "a threshold the sentence counts the cases against"),
    ("claims/model_mismatch.md", "3 ms", "the earlier runs' plant step, an input"),
    ("claims/model_mismatch.md", "35 s", "the earlier runs' end (t_end), an input"),
    ("claims/model_mismatch.md", "10 s", "a window of the timeline, an input"),
    ("claims/object_carry.md", "10 mm", "the stand's lowering, plant.stand_clearance, an input"),
    ("claims/object_carry.md", "3 ms", "the contact scenario's plant step, an input"),
    ("claims/object_carry.md", "18 N", "the force profile's amplitude (29), an input"),
    ("claims/object_carry.md", "10 %", "the nominal models' mass error, mass_scale 1.1, an input"),
    ("claims/object_carry.md", "0.5 mm", "the target, a requirement"),
    ("claims/object_carry.md", "5 %", "the convergence band of mass_convergence_time, a definition"),
    ("claims/object_carry.md", "20 mm", "the 'carried' criterion, a definition"),
    ("claims/object_carry.md", "2 mm", "a slip's length, the metric's definition"),
    ("claims/object_carry.md", "≥ 2 cm", "a drop's distance, the metric's definition"),
    ("claims/object_carry.md", "10 cm", "the lift's height, task.lift_height, an input"),
    ("claims/object_carry.md", "32 N", "the force profile's mean (29), an input"),
    ("claims/object_carry.md", "14 N", "the force profile's least value in the circle, 32 − 18 N"),
    ("claims/object_carry.md", "≥ 0.5 N", "a grasp's least pressing force, the metric's definition"),
    ("claims/object_carry.md", "1 N", "a squeeze a test of the metric sets, an input"),
    ("claims/object_carry.md", "65–75 s", "the put-down and release in the timeline, an input"),
    ("claims/index.md", "35 s", "the earlier runs' end (t_end), an input"),
    ("claims/index.md", "10 s", "a window of the timeline (and the speed study's t_end), an input"),
    ("claims/index.md", "3 ms", "a plant step, an input"),
    ("claims/index.md", "1 N", "a sensor noise level of study 4, an input"),
    ("claims/index.md", "30 %", "study 5's draws' range, an input"),
    ("*", "5 MPa", "the shipped pads' modulus, an input of the arm's model file"),
    ("guide/object.md", "15 mm", "the pads' radius, an input of the arm's model file"),
    ("guide/object.md", "10 %", "a requirement (the benchmark's bar) and study 6's model error"),
    ("guide/object.md", "5 %", "the convergence band of mass_convergence_time, a definition"),
    ("guide/object.md", "1 mm", "object_metrics.REST_HEIGHT, a definition"),
    ("guide/object.md", "1e-9 rad", "the tolerance of tests/results/test_object_turn.py"),
    ("guide/object.md", "20 N", "a constructed example's shoulder torque limit (20 N·m), an input"),
    ("guide/object.md", "3 N", "a constructed example's elbow torque limit (3 N·m), an input"),
    ("guide/object.md", "0.001 N", "the squeeze grid of tests/control/test_squeeze_limits.py"),
    ("guide/object.md", "32 N", "the creep measurement's squeeze, the mean of (29), an input"),
    ("guide/object.md", "3 ms", "contact.yaml's plant step (plant.time_step), an input"),
    ("guide/object.md", "90 s", "creep per 90 s: the paper's task length, a definition"),
    ("guide/object.md", "≤ 0.3 N", "the bar for the squeeze error, a target"),
    ("guide/object.md", "≤ 0.5 mm", "the bar for the box's position error, a target"),
    ("guide/object.md", "≤ 0.3°", "the bar for the box's turn, a target"),
    ("guide/object.md", "1.5 kg", "the heavier box's mass, an input of bench/lab_arms_object.py"),
    ("guide/object.md", "1–1.5 kg", "the required range of the heavier boxes' masses, a requirement"),
    ("claims/sampling_period.md", "5 ms", "a swept control period h (the table's header)"),
    ("claims/sampling_period.md", "12 ms", "a swept control period h (the table's header)"),
    ("claims/sampling_period.md", "16 ms", "a swept control period h (the table's header)"),
    ("claims/sampling_period.md", "20 ms", "a swept control period h (the table's header)"),
    ("claims/sampling_period.md", "25 – 50 ms", "swept control periods h (the table's header)"),
    ("claims/sampling_period.md", "35 s", "the old runs' end (t_end), an input"),
    ("claims/sampling_period.md", "10 s", "a window of the timeline, an input"),
    ("claims/force_sensing.md", "10 s", "a window of the timeline, an input"),
    ("README.md", "90 s", "the paper's experiment's length, an input"),
    ("README.md", "65–75 s", "the put-down in the timeline, an input"),
    ("README.md", "0–50 N", "the axis range of Figures 3–4, a plotting choice"),
    ("README.md", "20 ms", "a swept control period h, an input of the stability grid"),
    ("README.md", "≈ 20 ms", "a swept control period h, an input of the stability grid"),
    ("README.md", "21 ms", "a swept control period h, an input of the stability grid"),
    ("README.md", "1 N", "a swept noise level (force_sensor.noise_std)"),
    ("README.md", "30 %", "study 5's draws' range, an input"),
    ("README.md", "2 kg", "the box's mass in study 6's heavy case, an input"),
    ("README.md", "10 %", "the nominal models' mass error, mass_scale 1.1, an input"),
    ("README.md", "10 s", "the identification's excitation length, an input"),
    ("README.md", "2 ms", "a swept computation delay, an input of the stability grid"),
    ("README.md", "8 ms", "a swept computation delay, an input of the stability grid"),
    ("README.md", "1.1 ms", "the jitter's mean lateness, an input of the jitter runs"),
    ("README.md", "5 ms", "the jitter's p99 lateness, an input of the jitter runs"),
    ("README.md", "0–6 ms", "the uniform jitter's range, an input of the jitter runs"),
    # the stability and identification pages (one block)
    ("stability.md", "0.5 ms", "the second map's plant step (plant.time_step), an input"),
    ("stability.md", "2 ms", "a swept computation delay; the driver's cable delay, two 1 kHz cycles"),
    ("stability.md", "3 ms", "the prediction horizon p and a swept delay; the earlier runs' plant step"),
    ("stability.md", "4 ms", "a swept computation delay or horizon, an input"),
    ("stability.md", "6 ms", "a swept computation delay, an input"),
    ("stability.md", "7 ms", "a swept computation delay, an input"),
    ("stability.md", "8 ms", "a swept computation delay, an input"),
    ("stability.md", "10 ms", "a swept control period h, an input"),
    ("stability.md", "20 ms", "a swept control period h, an input"),
    ("stability.md", "21 ms", "a swept control period h, an input"),
    ("stability.md", "25 ms", "a swept control period h, an input"),
    ("stability.md", "1–3 ms", "a range of the swept computation delays, an input"),
    ("stability.md", "2–3 ms", "the swept delays between which the map's ρ crosses 1"),
    ("stability.md", "2–5 ms", "a range of the swept computation delays, an input"),
    ("stability.md", "3–8 ms", "a range of the swept computation delays, an input"),
    ("stability.md", "7–8 ms", "a range of the swept computation delays, an input"),
    ("stability.md", "30 %", "the model errors ×0.7 and ×1.3 (model_error scales), an input"),
    ("stability.md", "10 %", "the clock-skew bar, a requirement"),
    ("stability.md", "0.478 kg", "robot 2's slow joint's inertia J of the one-joint closed form, an input"),
    ("stability.md", "35 s", "the earlier runs' end (t_end), an input"),
    ("stability.md", "45 s", "the delay-compensation study's t_end, an input"),
    ("stability.md", "20 s", "the circle's first 20 s that study runs (25–45 s), an input"),
    ("stability.md", "2–4 s", "the clock-skew runs' compressed circle, an input"),
    ("stability.md", "0.25 ms", "the clock-skew runs' plant step and a swept skew, inputs"),
    ("stability.md", "0.125 ms", "the drivers' clock phase in the clock-skew runs, an input"),
    ("stability.md", "0.75 ms", "a swept clock skew, an input"),
    ("stability.md", "0–0.75 ms", "the swept clock skews, an input"),
    ("stability.md", "1.1 ms", "the exponential jitter's scale (jitter_scale), an input"),
    ("stability.md", "0–3 ms", "a uniform jitter's range (jitter_scale), an input"),
    ("stability.md", "0–6 ms", "a uniform jitter's range (jitter_scale), an input"),
    ("stability.md", "0–9 ms", "a uniform jitter's range (jitter_scale), an input"),
    ("identification.md", "2 s", "a swept excitation length (identify --duration), an input"),
    ("identification.md", "5 s", "a swept excitation length (identify --duration), an input"),
    ("identification.md", "10 s", "the excitation length (identify --duration's default), an input"),
    ("identification.md", "20 s", "a swept excitation length (identify --duration), an input"),
    ("identification.md", "60 s", "a swept excitation length (identify --duration), an input"),
    ("identification.md", "135 ms", "the smoothing window, 15 samples of h = 9 ms, an input"),
    ("identification.md", "3 ms", "the earlier runs' plant step (plant.time_step), an input"),
    ("identification.md", "35 s", "the earlier runs' end (t_end), an input"),
    ("identification.md", "90 s", "the paper's task's length (t_end), an input"),
    ("identification.md", "25–35 s", "the circle's window of the runs to 35 s, an input"),
    ("identification.md", "10 %", "realistic.yaml's model errors (mass_scale 1.1, 0.9); a bar"),
    ("identification.md", "30 %", "a controller model's error (model_error scales), an input"),
    ("identification.md", "0–1 N", "the draws' Coulomb friction range U(0, 1) N·m, an input"),
    ("identification.md", "0.5 N", "a Coulomb friction and a prior floor (N·m), a test's tolerance"),
    ("identification.md", "≤ 0.5 N", "the squeeze-error bar, a requirement"),
    ("identification.md", "0.3 N", "a Coulomb friction the identification test sets, an input"),
    ("identification.md", "0.08 N", "the identification test's Coulomb tolerance, a requirement"),
    ("identification.md", "0.1 N", "the identification test's viscous tolerance, a requirement"),
    ("identification.md", "1 %", "the identification test's torque-error tolerance, a requirement"),
    ("identification.md", "2 %", "a test's first-moment tolerance; the saturation study's margin"),
    ("identification.md", "10×", "the coarser encoders' factor (counts_per_rev / 10), an input"),
    ("identification.md", "90 %", "a percentile (the table's header)"),
    ("identification.md", "60 %", "the excitation's torque budget, a constant of its design"),
    ("identification.md", "0.1 rad", "the excitation's margin to the joint limits, a constant"),
    ("identification.md", "20 rad/s", "the tracking law's bandwidth, a constant of the experiment"),
    ("identification.md", "0.1 kg", "a prior floor (0.1 kg·m), a constant of the estimate"),
    ("identification.md", "0.05 kg", "a prior floor (0.05 kg·m²), a constant of the estimate"),
    ("identification.md", "0.01 rad/s", "the preflight's at-rest threshold, a constant"),
    ("identification.md", "20 ms", "the clearance query's period; 1/K_O at the default gain"),
    ("identification.md", "0.04 m", "the clearance check's capsule radius, a constant"),
    ("identification.md", "25 N", "the force the momentum test applies, an input"),
    ("identification.md", "1 mrad", "the encoder noise level (noise_std) of the DIDIM runs, an input"),
    # the benchmark page: run lengths and repeats of the commands it quotes, and its targets
    ("benchmark.md", "90 s", "the paper's experiment's length, the benchmark's --t-end"),
    ("benchmark.md", "10 s", "the attribution's runs, the benchmark's --t-attribution"),
    ("benchmark.md", "20 s", "the contact runs' length, the benchmark's --t-scenario"),
    ("benchmark.md", "30 s", "the lab-arm runs' length, the benchmark's --t-object-arms"),
    ("benchmark.md", "5 s", "the circle's share of a 30 s run (circle from 25 s), an input"),
    ("benchmark.md", "16.5 s", "the F/T sensor timing test's run length, an input of the test"),
    ("benchmark.md", "1e-9 N", "the tolerance of tests/plant/test_grasp_ground_truth.py"),
    ("benchmark.md", "≤ 60 µs", "a target: the control block per robot and tick"),
    ("benchmark.md", "≤ 10 %", "a target: the ground truth's share of the plant's cost"),
    ("benchmark.md", "≤ 40 µs", "a target: one tick of one robot's three equations alone"),
    ("benchmark.md", "≤ 15 %", "a target: the contact ground truth's share of its plant"),
    ("benchmark.md", "≤ 20 %", "a target: the object blocks' own cost on lab arms (the bar)"),
    ("benchmark.md", "20 %", "the same bar named in a sentence, a target"),
    ("benchmark.md", "≤ 1.3×", "a target: serve's tick against the batch tick (the bar)"),
    # the lab-arms page: the scenarios' and the benches' inputs, and the bars
    ("guide/lab_arms.md", "1990s", "the paper's arms' decade, a date"),
    ("guide/lab_arms.md", "0.2 kg", "the tool's F/T sensor mass, an input of the prepared model"),
    ("guide/lab_arms.md", "0.05 s", "the joint-limit check's grid, a constant of the validation"),
    ("guide/lab_arms.md", "18 N", "the force profile's amplitude (29), an input"),
    ("guide/lab_arms.md", "0.5–0.55 m", "the shipped scenarios' base placement, an input"),
    ("guide/lab_arms.md", "25 %", "the stability check's margin on K_R (x 1.25), an input of drake-coop gains"),
    ("guide/lab_arms.md", "0.15 m", "a base height or a box width, inputs of the scenarios"),
    ("guide/lab_arms.md", "0.2 m", "the UR5s' base height, an input of two_ur5.yaml"),
    ("guide/lab_arms.md", "≤ 0.1 mm", "a target of the shipped scenarios' table"),
    ("guide/lab_arms.md", "≤ 0.1 N", "a target of the shipped scenarios' table"),
    ("guide/lab_arms.md", "90 s", "the task's length, an input"),
    ("guide/lab_arms.md", "45 mm", "tool.pad_xyz's default, an input"),
    ("guide/lab_arms.md", "0.04 m", "the Panda's locked finger position, an input"),
    ("guide/lab_arms.md", "330 N", "the URDF's effort limit (330 N·m), an input of the model file"),
    ("guide/lab_arms.md", "30 s", "a run's --t-end, an input"),
    ("guide/lab_arms.md", "0.9 kg", "the how-to's xArm7 box mass, an input of its scenario"),
    ("guide/lab_arms.md", "0.35 kg", "the how-to's Z1 box mass, an input of its scenario"),
    ("guide/lab_arms.md", "0.09 m", "the how-to's Z1 box width, an input of its scenario"),
    ("guide/lab_arms.md", "0.08 m", "the box's depth, an input of the contact plant"),
    ("guide/lab_arms.md", "0.10 m", "the box's height, an input of the contact plant"),
    ("guide/lab_arms.md", "0.535 m", "the grasp height, circle_top_z - lift_height, inputs"),
    ("guide/lab_arms.md", "0.635 m", "the path's top, an input of the task"),
    ("guide/lab_arms.md", "5 cm", "the circle's radius, an input of the task"),
    ("guide/lab_arms.md", "1.1 m", "a base distance in the refusal's example, an input"),
    ("guide/lab_arms.md", "180°", "a roll of the pad's orientation, an input"),
    ("guide/lab_arms.md", "90°", "a roll of the pad's orientation, an input"),
    ("guide/lab_arms.md", "0.3°", "the bar for the box's turn, a target"),
    ("guide/lab_arms.md", "32 N", "the force profile's mean (29), an input"),
    ("guide/lab_arms.md", "10 s", "the lift's length in the task's timeline, an input"),
    ("guide/lab_arms.md", "0.74 m", "the every-arm pairs' contact point, an input of bench/every_arm.py"),
    ("guide/lab_arms.md", "0.11 m", "the every-arm pairs' box width, an input of bench/every_arm.py"),
    ("guide/lab_arms.md", "≤ 0.3 N", "the bar for the squeeze error, a target"),
    ("guide/lab_arms.md", "≤ 0.5 mm", "the bar for the box's position error, a target"),
    ("guide/lab_arms.md", "0.05 kg", "a lighter box's mass tried, an input"),
    ("guide/lab_arms.md", "50 N", "the force profile's top (29), an input"),
    ("guide/lab_arms.md", "1e-5 kg", "an assumed rotor inertia J_m (kg·m²), an input of bench/gear_reductions.py"),
    ("guide/lab_arms.md", "5e-5 kg", "an assumed rotor inertia J_m (kg·m²), an input of bench/gear_reductions.py"),
    # the robot guide: the drivers', the wire's and the benches' inputs, and the bars
    ("guide/real_robot.md", "0.1 s", "the drivers' command expiry (--expire_sec) or cell.start_ramp's default, inputs"),
    ("guide/real_robot.md", "0.2 s", "a command's age a driver test sends, an input of the test"),
    ("guide/real_robot.md", "0.3 rad/s", "the arms' speed a driver or cell test sets, an input of the test"),
    ("guide/real_robot.md", "3 s", "a test's bound or a slow test's paced length, an input of the test"),
    ("guide/real_robot.md", "0.3 s", "the lockstep test's run length, an input"),
    ("guide/real_robot.md", "2.5 N", "drake-franka-driver's damping gains (N·m·s/rad), inputs of its source"),
    ("guide/real_robot.md", "1e-9 N", "a test's tolerance (N·m)"),
    ("guide/real_robot.md", "1 µs", "the command stamp's offset, a constant of the wire"),
    ("guide/real_robot.md", "0.1 ms", "the lockstep driver's wait past a tick, a constant"),
    ("guide/real_robot.md", "30 Hz", "drake-franka-driver's default --low_pass_freq, an input of its source"),
    ("guide/real_robot.md", "1000 N", "libfranka's torque rate limit (1000 N·m/s), an input of its source"),
    ("guide/real_robot.md", "1 N", "libfranka's rate limit per 1 ms cycle (1 N·m), from the input above"),
    ("guide/real_robot.md", "10 s", "--status-wait's default or a run's length, inputs"),
    ("guide/real_robot.md", "1.5 ×", "pacing.png's axis end, a plotting choice"),
    ("guide/real_robot.md", "20–100 ms", "garbage-collector pauses other projects report, quoted, not measured here"),
    ("guide/real_robot.md", "2 ms", "a delay of the stability grid, the gc slack threshold or two 1 kHz cycles, inputs"),
    ("guide/real_robot.md", "3 ms", "a delay of the grid, the prediction horizon, the contact plant step, inputs"),
    ("guide/real_robot.md", "0.5 ms", "a plant step of the maps or the computation bar, inputs"),
    ("guide/real_robot.md", "≤ 0.5 ms", "the computation bar (p99), a target"),
    ("guide/real_robot.md", "6 ms", "the margin bench/paced_split.py uses (MARGIN), an input"),
    ("guide/real_robot.md", "≤ 3 ms", "the loop delay bar, half the 6 ms margin, a target"),
    ("guide/real_robot.md", "8 ms", "the sleep between paced ticks (h less the tick), an input of the tick-cost bench"),
    ("guide/real_robot.md", "50 ms", "max_status_age's default or a heartbeat period, inputs"),
    ("guide/real_robot.md", "10 rad/s", "the CRS arms' URDF velocity limit, an input of the model file"),
    ("guide/real_robot.md", "0.09 rad", "that limit over one 9 ms tick, from the inputs"),
    ("guide/real_robot.md", "0.5 rad", "a joint jump a watchdog test sends, an input of the test"),
    ("guide/real_robot.md", "2000 N", "the CRS URDFs' placeholder effort limit (2000 N·m), an input of the model file"),
    ("guide/real_robot.md", "27 ms", "three ticks at h = 9 ms, from the inputs"),
    ("guide/real_robot.md", "30 ms", "a pause longer than three ticks, an example"),
    ("guide/real_robot.md", "0.05 rad", "cell.start_max_offset's default, an input"),
    ("guide/real_robot.md", "0.05 rad/s", "cell.start_max_speed's default, an input"),
    ("guide/real_robot.md", "5 s", "a run's length, a timeout or the circle's first seconds, inputs"),
    ("guide/real_robot.md", "10 %", "the bar for the split run against the simulated one, a target"),
    ("guide/real_robot.md", "2–4 s", "the compressed task's circle, an input of the robot tests"),
    ("guide/real_robot.md", "1.5 s", "the compressed task's grasp, an input of the robot tests"),
    ("guide/real_robot.md", "90 s", "the paper's task length, an input"),
    ("guide/real_robot.md", "40 ms", "TCP's delayed acknowledgement bound, a constant of the kernel"),
    ("guide/real_robot.md", "2 s", "a test's paced length or the driver's extra run time, inputs"),
    ("guide/real_robot.md", "92 s", "the sim-driver's --t-end in the paced bench, an input"),
    ("guide/real_robot.md", "30 %", "study 5's draws' range, an input"),
    ("guide/real_robot.md", "30 s", "the contact runs' --t-end, an input"),
    ("guide/real_robot.md", "1.3×", "the bar for serve's tick against the batch, a target"),
    ("guide/real_robot.md", "≤ 1.3×", "the bar for serve's tick against the batch, a target"),
]


def strip_page(text: str) -> str:
    """A page's prose: without code blocks, math, roles, code spans, links' targets,
    comments and the tables a directive generates."""
    text = results_role.COMMENTED.sub(" ", text)        # VALUE<!-- result: SPEC -->
    text = re.sub(r"<!--.*?-->", " ", text, flags=re.S)
    # fenced blocks that are not prose: code, math, generated tables, toctrees
    text = re.sub(r"^(`{3,}|~{3,})\s*(?:\{(?:math|code|code-block|toctree|literalinclude|"
                  r"eval-rst|result-table)\}|[\w+-]*)[^\n]*\n.*?^\1\s*$", " ", text,
                  flags=re.S | re.M)
    text = re.sub(r"\$\$.*?\$\$", " ", text, flags=re.S)
    text = re.sub(r"\{[\w:-]+\}`[^`]*`", " ", text)          # roles ({result}, {math}, refs)
    # code spans (may wrap a line, never a paragraph)
    text = re.sub(r"(`+)(?!`)(?:(?!\n[ \t]*\n).)*?(?<!`)\1(?!`)", " ", text, flags=re.S)
    text = re.sub(r"(?<![\\$])\$(?!\s)[^$\n]+?(?<!\s)\$", " ", text)      # inline math
    text = re.sub(r"\]\([^)]*\)", "]", text)                 # link targets
    return text


def measured_numbers(text: str) -> list[str]:
    """The measured-looking numbers in a page's prose (see :data:`MEASURED`)."""
    return [m.group(0).strip() for m in MEASURED.finditer(strip_page(text))]


def _allowed(page: str, found: str) -> bool:
    norm = " ".join(found.replace("\u00a0", " ").split())
    return any(p in ("*", page) and norm == text for p, text, _ in INPUTS)


def test_the_detector_finds_typed_numbers_and_skips_roles_math_and_code():
    page = ("The error is 0.047 N RMS (56 % less), 20.1 µm at most, 3–5 mm.\n"
            "Equation (22), the year 2026, [ref](a/1 s.md), `h = 0.009 s`, $x = 3 N$,\n"
            "{result}`force_sensing:count(status) as .0f`.\n```yaml\nt_end: 65 s\n```\n")
    assert measured_numbers(page) == ["0.047 N", "56 %", "20.1 µm", "3–5 mm"]


@pytest.mark.parametrize("page", CHECKED, ids=_rel)
def test_no_hand_typed_measured_number(page):
    rel = _rel(page)
    found = [n for n in measured_numbers(page.read_text()) if not _allowed(rel, n)]
    assert not found, (f"{rel}: measured numbers typed by hand (use a {{result}} role, keep the "
                       f"sentence qualitative, or list an input in INPUTS): {found}")


ROLE = re.compile(r"\{result\}`([^`]*)`")


def _all_roles() -> list[tuple[str, str]]:
    return [(str(p.relative_to(DOCS)), m.group(1))
            for p in sorted(DOCS.rglob("*.md")) if "_build" not in p.parts
            for m in ROLE.finditer(p.read_text())]


TABLE = re.compile(r"^(`{3,})\{result-table\}\s+(\S+)\s*\n(.*?)^\1\s*$", re.S | re.M)


def _all_tables() -> list[tuple[str, str, dict, list[str]]]:
    """Every ``result-table`` of the docs: (page, source, options, content lines)."""
    out = []
    for p in sorted(DOCS.rglob("*.md")):
        if "_build" in p.parts:
            continue
        for m in TABLE.finditer(p.read_text()):
            options, content = {}, []
            for line in m.group(3).splitlines():
                opt = re.match(r"^:([\w-]+):\s*(.*)$", line)
                if opt and not content:
                    options[opt[1]] = opt[2]
                elif line.strip():
                    content.append(line)
            out.append((str(p.relative_to(DOCS)), m.group(2), options, content))
    return out


def test_pages_write_their_tables_out():
    """A forge shows a ``result-table`` directive as code (its specs, no numbers); the pages
    hold Markdown tables of roles instead (``results_role.py --write --tables PAGE`` writes
    a directive out, each cell's value beside its source)."""
    assert not [(page, source) for page, source, _, _ in _all_tables()]


def test_a_table_written_out_holds_the_directives_values():
    directive = ("```{result-table} object_carry\n:header: sample | friction use\n"
                 ":where: robots.*~mass_scale=1.1 and object_model=mode=known squeeze=friction\n"
                 ":each-row:\n{sample as .0f} | {worst.friction_use.max as .6f else none}\n```\n")
    expected = results_role.table_cells(
        "object_carry", ["{sample as .0f} | {worst.friction_use.max as .6f else none}"],
        "robots.*~mass_scale=1.1 and object_model=mode=known squeeze=friction", each_row=True)
    lines = results_role.tables_to_markdown(directive).strip().splitlines()
    assert lines[0] == "| sample | friction use |" and len(lines) == 2 + len(expected)
    for line, row in zip(lines[2:], expected):
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        shown = [results_role.check_written(ROLE.fullmatch(c)[1])[0] if c.startswith("{")
                 else c for c in cells]
        assert shown == row


def test_every_result_table_resolves_with_its_header_width():
    tables = _all_tables()
    failures = []
    for page, source, options, content in tables:
        try:
            body = results_role.table_cells(source, content, options.get("where", ""),
                                            "each-row" in options)
            width = len(options["header"].split(" | "))
            failures += [f"{page}: {source}: a row of {len(r)} cells, header {width}"
                         for r in body if len(r) != width]
        except results_role.ResultError as exc:
            failures.append(f"{page}: {exc}")
    assert not failures, "\n".join(failures)


def test_a_table_prints_the_files_values_and_a_fallback_only_where_one_is_missing():
    rows = _csv_rows("object_carry")
    body = results_role.table_cells(
        "object_carry", ["{sample as .0f} | {worst.friction_use.max as .6f else none}"],
        "robots.*~mass_scale=1.1 and object_model=mode=known squeeze=friction", each_row=True)
    picked = [r for r in rows if "mass_scale=1.1" in r["robots.*"]
              and r["object_model"] == "mode=known squeeze=friction"]
    assert [b[0] for b in body] == [r["sample"] for r in picked]
    assert [b[1] for b in body] == [f"{float(r['worst.friction_use.max']):.6f}"
                                    if r["worst.friction_use.max"] else "none" for r in picked]
    assert "none" in [b[1] for b in body]
    with pytest.raises(results_role.ResultError, match="matches none"):
        results_role.table_cells("object_carry", ["{no_such_column else —}"], "index=0")


def test_every_result_role_resolves_to_the_value_written_beside_it():
    """Each role is ``{result}`VALUE <SPEC>```: the page read as plain Markdown (on a forge)
    shows VALUE, and VALUE is what SPEC's file gives (a short source name defined in the
    page's ``result sources`` comment). ``python docs/_ext/results_role.py --write PAGE``
    writes the values."""
    roles = _all_roles()
    assert roles, "no {result} role in the docs"
    failures, bare = [], []
    sources = {}
    for page, spec in roles:
        if page not in sources:
            sources[page] = results_role.page_sources((DOCS / page).read_text())
        if results_role._WRITTEN.match(spec) is None:
            bare.append(f"{page}: {spec}")
        try:
            results_role.check_written(spec, sources[page])
        except results_role.ResultError as exc:
            failures.append(f"{page}: {exc}")
    assert not failures, "\n".join(failures)
    assert not bare, "roles without their written value (run results_role.py --write):\n" \
        + "\n".join(bare)


def test_the_readme_writes_each_number_beside_its_source():
    """The README (a forge's landing page, which renders no role) writes a measured number
    as ``VALUE<!-- result: SPEC -->``; each must equal its file's."""
    text = (ROOT / "README.md").read_text()
    found = list(results_role.COMMENTED.finditer(text))
    assert found, "no number with its source in the README"
    sources = results_role.page_sources(text)
    failures = []
    for m in found:
        try:
            printed = results_role.resolve(results_role.expand(m["spec"], sources))
        except results_role.ResultError as exc:
            failures.append(str(exc))
            continue
        if not results_role._same(m["value"], printed):
            failures.append(f"written {m['value']!r}, the file gives {printed!r} ({m['spec']})")
    assert not failures, "\n".join(failures)


def test_a_written_value_that_its_file_no_longer_gives_fails():
    spec = "force_sensing:count(status where status=ok)"
    value = results_role.resolve(spec)
    assert results_role.check_written(f"{value} <{spec}>")[0] == value
    with pytest.raises(results_role.ResultError, match="the file gives"):
        results_role.check_written(f"{int(value) + 1} <{spec}>")
    sources = results_role.page_sources("<!-- result sources:\nfs = force_sensing\n-->")
    assert results_role.check_written(f"{value} <fs:count(status where status=ok)>",
                                      sources)[0] == value
    with pytest.raises(results_role.ResultError, match="NAME = SOURCE"):
        results_role.page_sources("<!-- result sources:\nfs force_sensing\n-->")
    page = f"a {{result}}`force_sensing:count(status where status=ok)` b"
    assert results_role.write_values(page) == f"a {{result}}`{value} <{spec}>` b"


def _csv_rows(name: str) -> list[dict]:
    with (DOCS / "figures" / "studies" / f"{name}_results.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_a_role_prints_the_files_value_in_its_unit():
    rows = [r for r in _csv_rows("force_sensing")
            if r["robots.*.force_source"] == "sensor"
            and float(r["robots.*.force_sensor.noise_std"]) == 3.0]
    assert len(rows) == 1
    expected = float(rows[0]["worst.position_error.max"]) * 1e6
    text = results_role.resolve("force_sensing:worst.position_error.max where "
                                "force_source=sensor and noise_std=3 as .4f µm")
    assert text == f"{expected:.4f} µm"
    values = [float(r["robot1.force_error.rms"]) for r in _csv_rows("force_sensing")]
    text = results_role.resolve("force_sensing:range(robot1.force_error.rms) as .4f mN")
    assert text == f"{min(values) * 1e3:.4f}–{max(values) * 1e3:.4f} mN"
    assert results_role.resolve("force_sensing:count(status where status=ok)") == str(
        sum(r["status"] == "ok" for r in _csv_rows("force_sensing")))


@pytest.mark.parametrize("spec, message", [
    ("force_sensing:no_such_column", "matches none"),
    ("no_such_study:worst.force_error.rms", "no file"),
    ("force_sensing:worst.force_error.rms", "values where one was meant"),
    ("force_sensing:worst.force_error.rms where force_source=nothing", "no row"),
    ("force_sensing:max(worst.force_error.rms) as .3f parsec", "unit 'parsec'"),
    ("force_sensing:spread(worst.force_error.rms)", "is not one of"),
    ("force_sensing:max(worst.force_error.rms) as .3q N", "format"),
    ("force_sensing:max(x_tilde.rms)", "ambiguous"),
    ("tests/golden/paper_run.json:no.such.key", "no key"),
])
def test_a_role_that_does_not_resolve_says_why(spec, message):
    with pytest.raises(results_role.ResultError, match=re.escape(message)):
        results_role.resolve(spec)


def test_percentiles_are_numpys_linear_rule():
    np = pytest.importorskip("numpy")
    values = [float(r["worst.force_error.rms"]) for r in _csv_rows("model_mismatch")]
    for p in (10, 50, 90):
        assert results_role.resolve(f"model_mismatch:p{p}(worst.force_error.rms) as .6f N") \
            == f"{np.percentile(values, p):.6f} N"


def test_every_listed_input_is_still_on_its_page():
    """An exception that no page needs any more is removed, not kept."""
    found = {_rel(p): {" ".join(n.replace("\u00a0", " ").split())
                                        for n in measured_numbers(p.read_text())}
             for p in CHECKED}
    stale = [(page, text) for page, text, _ in INPUTS
             if not any(text in numbers for p, numbers in found.items()
                        if page in ("*", p))]
    assert not stale, stale
