"""The particle-flow report page: the paired decision rule, and rendering from tiny runs."""

import numpy as np

from gpfverify.experiments import bearing, pff1d
from gpfverify.experiments.runner import run_experiment
from gpfverify.report.document import Figure, Table
from gpfverify.report.sections.particle_flow import _params, claims, paired_comparison, render


def test_paired_comparison_decides_by_the_paired_t_test():
    rng = np.random.default_rng(0)
    worse = list(rng.normal(5.0, 1.0, 30))
    assert paired_comparison([w - 1.0 + 0.01 * rng.normal() for w in worse], worse)[0] is True
    assert paired_comparison([w + 1.0 + 0.01 * rng.normal() for w in worse], worse)[0] is False
    assert paired_comparison([w + rng.normal() for w in worse], worse)[0] is None
    # a divergence where the competitor stayed finite loses the claim, whatever the other runs say
    assert paired_comparison([None] + [w - 1.0 for w in worse[1:]], worse)[0] is False
    assert paired_comparison([None, None], [None, 1.0])[0] is False


def test_render_from_tiny_runs(tmp_path):
    pff = run_experiment(pff1d, _params(pff1d, ["--steps", "5", "--table-q", "0.1", "10", "--table-r", "1",
                                               "--dlambda", "0.05", "--gamma-r", "0.1", "1",
                                               "--gamma-main-r", "0.1", "--gamma-dlambda", "0.05"]),
                         3, 1, tmp_path / "pff", show_progress=False)
    brg = run_experiment(bearing, _params(bearing, ["--duration", "8"]), 3, 1, tmp_path / "brg",
                         show_progress=False)
    section = render({"pff1d": pff, "bearing": brg}, tmp_path / "page")
    figures = [b for b in section.blocks if isinstance(b, Figure)]
    assert len(figures) == 3 and all(f.path.exists() for f in figures)
    verdicts = [c.held for c in claims(pff, brg)]
    assert len(verdicts) == 5 and all(v in (True, False, None) for v in verdicts)
    assert any(isinstance(b, Table) and b.caption.startswith("Table 2") for b in section.blocks)
