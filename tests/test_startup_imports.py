"""`check --json` without `--out` draws nothing and fuses more than two estimates without a conic
solver: the modules it imports (``python -X importtime``) include neither matplotlib nor cvxpy."""

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
HEAVY = ("matplotlib", "cvxpy")
#: optional extras: loaded only for a system made of their objects (gpfverify.adapters)
EXTRAS = ("stonesoup", "filterpy")


def _imported_modules(args: list[str], cwd: Path) -> set[str]:
    run = subprocess.run([sys.executable, "-X", "importtime", "-m", "gpfverify", *args],
                         capture_output=True, text=True, cwd=cwd)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = [line for line in run.stderr.splitlines() if line.startswith("import time:")]
    return {line.rsplit("|", 1)[1].strip() for line in lines[1:]}  # the first is the header


def test_check_json_with_the_default_methods_imports_no_plotting_and_no_conic_solver(tmp_path):
    modules = _imported_modules(["check", str(EXAMPLES / "three_sensor_system.py") + ":tracker",
                                 "--steps", "2", "--json"], tmp_path)
    assert "gpfverify.experiments.check" in modules and "numpy" in modules  # the parse saw the run
    assert {m.split(".")[0] for m in modules}.isdisjoint(HEAVY + EXTRAS)
    assert "gpfverify.adapters" in modules and "gpfverify.adapters.stonesoup" not in modules


def test_check_with_out_writes_its_figures_with_matplotlib(tmp_path):
    """The other side of the same switch: with ``--out`` the figures are drawn."""
    modules = _imported_modules(["check", str(EXAMPLES / "three_sensor_system.py") + ":tracker",
                                 "--steps", "2", "--methods", "cmf,dmf", "--out", str(tmp_path / "out")], tmp_path)
    assert "matplotlib" in modules
    assert any(p.suffix in (".png", ".svg") for p in (tmp_path / "out").rglob("*"))
