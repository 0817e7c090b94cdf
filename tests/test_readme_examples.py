"""The README's Python examples run as written, in order, in one namespace (a user pastes them
into one session), and what they compute is what the README says they compute."""

import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_the_readme_examples_run_and_give_what_they_claim():
    blocks = _python_blocks()
    assert len(blocks) >= 3  # GP, filter on a user's model, fusion over it
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    # the filter example: posterior per step of the 30-step run, tracking the simulated truth
    run, truth, model = namespace["run"], namespace["truth"], namespace["model"]
    assert run.mu_e.shape == (30, 4) and run.C_e.shape == (30, 4, 4)
    errors = run.mu_e - truth
    nees = np.einsum("ti,tij,tj->t", errors, np.linalg.inv(run.C_e), errors)
    assert np.mean(nees) < 3 * model.state_dim  # consistent to within a generous factor of E[NEES] = D
    # the fusion example: every requested method has an estimate at every step
    fused = namespace["fused"]
    assert set(fused.methods) >= {"cmf", "dmf", "cc", "ci"}
    for method in ("cmf", "dmf", "cc", "ci"):
        assert fused.means(method).shape == (30, 4)
    assert fused.audit.full_column_rank.shape == (30, 2) and fused.audit.gap_norm.shape == (30,)
    # the GP example: a learned model with the system's prior as every starting belief
    gp_fused = namespace["gp_fused"]
    for method in ("cmf", "dmf"):
        assert gp_fused.means(method).shape == (5, 4) and np.isfinite(gp_fused.means(method)).all()
