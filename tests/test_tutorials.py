"""The tutorials run top to bottom (nbclient) and print what they promise."""

import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

TUTORIALS = Path(__file__).resolve().parents[1] / "tutorials"


def _run(name):
    nb = nbformat.read(TUTORIALS / name, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(TUTORIALS)}}).execute()
    return "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                   for o in c.outputs)


def test_tutorial_01_plant_measures_the_commanded_push():
    text = _run("01_plant.ipynb")
    assert "planes  robot1: measured λ =  20.00" in text
    assert "moved" in text


def test_tutorial_02_observers_shows_21_equals_22():
    text = _run("02_observers.ipynb")
    assert "completed 26 s" in text and "difference" in text


@pytest.mark.slow
def test_tutorial_03_runs_the_paper_experiment():
    text = _run("03_paper_experiment.ipynb")
    assert "completed 90 s" in text and "force_error" in text


@pytest.mark.slow
def test_tutorial_04_runs_the_general_system():
    text = _run("04_general_system.ipynb")
    assert text.count("completed 8 s") == 3 and "completed 4 s" in text
    assert "task dimension 6" in text
    assert "m = 3" in text and "robot4" in text


def test_tutorial_05_runs_the_control_on_a_users_own_plant():
    text = _run("05_your_own_plant.ipynb")
    assert "arm1: estimated squeeze λ̂ = 10.00 N, felt squeeze = 8.61 N" in text
    assert "forced update matches (15)-(16)" in text
    assert "refused: K_R: 3 diagonal entries" in text and "refused: period:" in text
    assert "wrote my_two_arm_diagram.dot arm1_control.dot" in text
    # one block alone: the velocity observer under Drake's PD (against the plant's true q̇),
    # each force source with its own parameters only
    alone = text.split("velocity observer alone under a PD: RMS |q̇̂ − q̇| ")[1].splitlines()[0]
    rms_error = float(alone.split(" rad/s")[0])
    rms_speed = float(alone.split("RMS joint speed of ")[1].split(" rad/s")[0])
    late = float(alone.split("at the step); ")[1].split(" rad/s")[0])
    assert rms_error < 0.3 * rms_speed and late < 1e-2, alone
    assert "SensedForce: λ̂ = 9.50 N, ΔF̃ after one tick = -0.0045 N·s" in text
    assert "NoForceEstimate: λ̂ = 10.00 N" in text
    assert "MomentumObserver inputs: ['q', 'qdot_hat', 'tau', 'reference']" in text


def _have_robots() -> bool:
    from drake_coop.control.arm_plant import description_packages

    return "example-robot-data" in description_packages()


@pytest.mark.slow
@pytest.mark.skipif(not _have_robots(),
                    reason='example-robot-data is not installed (pip install -e ".[robots]")')
def test_tutorial_06_runs_two_pandas_from_example_robot_data():
    text = _run("06_your_lab_arms.ipynb")
    assert "7 joints, 7 actuators; pad: True  F/T sensor weld: True" in text
    assert "scenario valid" in text and "free: rho = 0.88" in text and "(stable)" in text
    assert "completed 14 s" in text and text.count(" circle: |x - x_d|") == 2


@pytest.mark.parametrize("name", sorted(p.name for p in TUTORIALS.glob("*.ipynb")))
def test_tutorial_is_stored_with_its_outputs_and_says_what_it_shows_and_how_long(name):
    nb = nbformat.read(TUTORIALS / name, as_version=4)
    intro = nb.cells[0]
    assert intro.cell_type == "markdown"
    assert "**Shows:**" in intro.source and re.search(r"\*\*Runs in\*\* about \d+ s", intro.source)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(c.execution_count is not None for c in code if c.source.strip())
    assert sum(bool(c.outputs) for c in code) >= len(code) - 1


def test_the_notebooks_extra_installs_jupyter_and_a_kernel():
    import tomllib

    pyproject = tomllib.loads((TUTORIALS.parent / "pyproject.toml").read_text(encoding="utf-8"))
    extra = " ".join(pyproject["project"]["optional-dependencies"]["notebooks"])
    assert all(name in extra for name in ("notebook", "ipykernel", "nbclient"))
