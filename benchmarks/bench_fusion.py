"""Per-fuse time of every fusion rule: gpfverify against straightforward reference versions.

Two configurations: two 2-D sensors (l_m = 2) and eight 6-D sensors (l_m = 3). References follow
the formulas literally: explicit inverses (CMF, DMF with np.linalg.pinv, CC, ICI, EI), a bounded
scalar search (two sensors) or SLSQP on the simplex (N sensors) with explicit inverses for CI, and
an RCC-CI cvxpy problem built afresh for every fuse. Each pair is checked to agree before timing.
The RCC-CI first call (problem construction and DPP compilation) is timed separately.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import time
from pathlib import Path

import cvxpy as cp
import numpy as np
from scipy.optimize import minimize, minimize_scalar

from _timing import markdown_table, median_cpu_seconds, median_seconds
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.synthetic import random_case, random_spd

rcc = importlib.import_module("gpfverify.fusion.rcc_ci")
inv = np.linalg.inv


def ref_cmf(case):
    c = case.central
    return c.mu_p + c.C_xy @ inv(c.C_y) @ (case.y - c.mu_y)


def ref_dmf(case):
    c = case.central
    g = c.C_xy @ inv(c.C_y)
    mean = c.mu_p.copy()
    for block, r in zip(c.blocks, case.locals):
        g_m = g[:, block]
        mean += g_m @ (r.mu_y - c.mu_y[block]) + g_m @ r.C_y @ np.linalg.pinv(r.C_xy) @ (r.mu_e - r.mu_p)
    return mean


def ref_cc(ests):
    infos = [inv(e.cov) for e in ests]
    p = inv(sum(infos))
    return p @ sum(i @ e.mean for i, e in zip(infos, ests))


def ref_ci_trace(ests):
    infos = [inv(e.cov) for e in ests]

    def trace(w):
        return np.trace(inv(sum(wm * i for wm, i in zip(w, infos))))

    if len(ests) == 2:
        res = minimize_scalar(lambda a: trace([a, 1 - a]), bounds=(0, 1), method="bounded")
        w = np.array([res.x, 1 - res.x])
    else:
        n = len(ests)
        res = minimize(trace, np.full(n, 1 / n), method="SLSQP", bounds=[(0, 1)] * n,
                       constraints=[{"type": "eq", "fun": lambda w: np.sum(w) - 1}])
        w = res.x
    p = inv(sum(wm * i for wm, i in zip(w, infos)))
    return p @ sum(wm * i @ e.mean for wm, i, e in zip(w, infos, ests))


def ref_ici_pair(e1, e2, w):
    p1i, p2i = inv(e1.cov), inv(e2.cov)
    mix = inv(w * e1.cov + (1 - w) * e2.cov)
    p = inv(p1i + p2i - mix)
    return Gaussian(p @ ((p1i - w * mix) @ e1.mean + (p2i - (1 - w) * mix) @ e2.mean), p)


def ref_ici(ests):
    fused = ests[0]
    for nxt in ests[1:]:
        res = minimize_scalar(lambda w, a=fused, b=nxt: np.trace(ref_ici_pair(a, b, w).cov), bounds=(0, 1),
                              method="bounded")
        fused = ref_ici_pair(fused, nxt, res.x)
    return fused.mean


def ref_ei(ests):
    fused = ests[0]
    for e2 in ests[1:]:
        e1 = fused
        d1, s1 = np.linalg.eigh(e1.cov)
        inv_half = s1 / np.sqrt(d1)
        d2, s2 = np.linalg.eigh(inv_half.T @ e2.cov @ inv_half)
        t = (s1 * np.sqrt(d1)) @ s2
        gi = inv(t @ np.diag(np.maximum(1.0, d2)) @ t.T)
        p1i, p2i = inv(e1.cov), inv(e2.cov)
        mutual = inv(p1i + p2i - 2 * gi) @ ((p2i - gi) @ e1.mean + (p1i - gi) @ e2.mean)
        p = inv(p1i + p2i - gi)
        fused = Gaussian(p @ (p1i @ e1.mean + p2i @ e2.mean - gi @ mutual), p)
    return fused.mean


def ref_rcc(ests, c):
    d = ests[0].mean.shape[0]
    z = cp.Variable((d + 1, d + 1), PSD=True)
    delta, x = z[:d, :d], z[:d, d]
    cons = [z[d, d] == 1]
    for e in ests:
        a = inv(e.cov)
        cons.append(cp.trace(a @ delta) - 2 * (a @ e.mean) @ x + e.mean @ a @ e.mean - c <= 0)
    cp.Problem(cp.Maximize(cp.trace(delta) - cp.sum_squares(x)), cons).solve(solver=cp.CLARABEL)
    return x.value



def configuration(n, d, l, seed):
    rng = np.random.default_rng(seed)
    case = random_case(rng, d, [l] * n)
    centre = rng.normal(size=d)
    ests = [Gaussian(centre + 0.3 * rng.normal(size=d), random_spd(rng, d)) for _ in range(n)]
    return case, ests


def first_call_seconds(ests):
    rcc._primal_problem.cache_clear()
    rcc._clarabel_program.cache_clear()  # the first call compiles the problem again
    start = time.perf_counter()
    rcc.rcc_ci(ests)
    return time.perf_counter() - start


def rows_for(name, n, d, l, repeats):
    case, ests = configuration(n, d, l, seed=n * d)
    c = rcc.default_size(d)
    first = first_call_seconds(ests)
    pairs = {
        "CMF": (lambda: cmf_update(case.central, case.y).mean, lambda: ref_cmf(case)),
        "DMF (eq. 35)": (lambda: dmf_update(case).mean, lambda: ref_dmf(case)),
        "CC/CW": (lambda: convex_combination(ests).mean, lambda: ref_cc(ests)),
        "CI trace": (lambda: covariance_intersection(ests, "trace").mean, lambda: ref_ci_trace(ests)),
        "ICI trace": (lambda: inverse_covariance_intersection(ests, "trace").mean, lambda: ref_ici(ests)),
        "EI": (lambda: ellipsoidal_intersection(ests).mean, lambda: ref_ei(ests)),
        "RCC-CI": (lambda: rcc.rcc_ci(ests, c).primal_mean, lambda: ref_rcc(ests, c)),
    }
    rows = []
    for method, (ours, ref) in pairs.items():
        a, b = ours(), ref()
        agree = float(np.max(np.abs(a - b)))
        t_ours = median_seconds(ours, repeats)
        cpu_ours = median_cpu_seconds(ours, repeats)
        t_ref = median_seconds(ref, max(3, repeats // 3))
        rows.append([name, method, f"{t_ours * 1e3:.3f}", f"{cpu_ours * 1e3:.3f}", f"{t_ref * 1e3:.3f}",
                     f"{t_ref / t_ours:.1f}x", f"{agree:.1e}"])
    rows.append([name, "RCC-CI first call (build + compile)", f"{first * 1e3:.1f}", "", "", "", ""])
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    rows = rows_for("2 sensors, D=2, l=2", 2, 2, 2, args.repeats) + \
        rows_for("8 sensors, D=6, l=3", 8, 6, 3, args.repeats)
    table = markdown_table(["configuration", "method", "gpfverify ms", "gpfverify CPU ms", "reference ms",
                            "speed-up", "max |difference|"], rows)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    text = f"{table}\n\nmachine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, " \
           f"load average {load}, Python {platform.python_version()}; medians of {args.repeats} fuses; " \
           f"RCC-CI goal <= 3 ms per two-sensor fuse\n"
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
