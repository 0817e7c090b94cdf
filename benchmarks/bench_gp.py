"""predict_uncertain and fit: gpfverify against a plain reference implementation.

The reference follows the paper's formulas literally: loops over outputs and output pairs, explicit
inverses of K_a, Σ + Λ_a and R, and the Q matrices built entry-block by entry-block (seed 000 eq.
8–11, 20). Both give the same numbers (checked below before timing).
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

import numpy as np

from _timing import markdown_table, median_seconds
from gpfverify.gp import GaussianProcess
from gpfverify.gp.moments import moment_match


def reference_moments(X, Y, ell, s2, n2, mu, sigma):
    n, d = X.shape
    e = Y.shape[1]
    inv_k, beta = [], []
    for a in range(e):
        diff = (X[:, None, :] - X[None, :, :]) / ell[a]
        k = s2[a] * np.exp(-0.5 * np.sum(diff**2, -1)) + n2[a] * np.eye(n)
        inv_k.append(np.linalg.inv(k))
        beta.append(inv_k[a] @ Y[:, a])
    nu = X - mu
    mean = np.zeros(e)
    cross = np.zeros((d, e))
    for a in range(e):
        lam = np.diag(ell[a] ** 2)
        inv_sl = np.linalg.inv(sigma + lam)
        q = s2[a] / np.sqrt(np.linalg.det(sigma @ np.linalg.inv(lam) + np.eye(d))) * np.exp(
            -0.5 * np.einsum("id,dk,ik->i", nu, inv_sl, nu))
        mean[a] = beta[a] @ q
        cross[:, a] = sigma @ inv_sl @ (nu.T @ (beta[a] * q))
    cov = np.zeros((e, e))
    for a in range(e):
        for b in range(e):
            il_a, il_b = np.diag(1 / ell[a] ** 2), np.diag(1 / ell[b] ** 2)
            r = sigma @ (il_a + il_b) + np.eye(d)
            r_inv_s = np.linalg.inv(r) @ sigma
            ka = s2[a] * np.exp(-0.5 * np.einsum("id,dk,ik->i", nu, il_a, nu))
            kb = s2[b] * np.exp(-0.5 * np.einsum("id,dk,ik->i", nu, il_b, nu))
            z = (nu @ il_a)[:, None, :] + (nu @ il_b)[None, :, :]
            qab = np.outer(ka, kb) / np.sqrt(np.linalg.det(r)) * np.exp(
                0.5 * np.einsum("ijd,dk,ijk->ij", z, r_inv_s, z))
            cov[a, b] = beta[a] @ qab @ beta[b] - mean[a] * mean[b]
            if a == b:
                cov[a, a] += s2[a] - np.trace(inv_k[a] @ qab)
    return mean, cov, cross


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    rows = []
    d, e = 2, 4
    mu, sigma = np.array([0.2, -0.1]), np.array([[0.3, 0.1], [0.1, 0.2]])
    for n in (100, 300, 1000):
        X = rng.uniform(-3, 3, (n, d))
        Y = np.sin(X @ rng.normal(size=(d, e)))
        ell, s2, n2 = rng.uniform(0.5, 2, (e, d)), rng.uniform(0.5, 2, e), np.full(e, 0.01)
        gp = GaussianProcess(X, Y, ell, s2, n2)
        ours = moment_match(gp, mu, sigma)
        ref = reference_moments(X, Y, ell, s2, n2, mu, sigma)
        agree = max(np.abs(ours.mean - ref[0]).max(), np.abs(ours.cov - ref[1]).max(),
                    np.abs(ours.cross_cov - ref[2]).max())
        reps = max(3, args.repeats // (10 if n == 1000 else 1))
        t_ours = median_seconds(lambda gp=gp: moment_match(gp, mu, sigma), reps)
        t_ref = median_seconds(lambda args=(X, Y, ell, s2, n2): reference_moments(*args, mu, sigma),
                               max(3, reps // 5), warmup=1)
        rows.append([f"predict_uncertain n={n}, D={d}, E={e}", f"{t_ours * 1e3:.3f}", f"{t_ref * 1e3:.2f}",
                     f"{t_ref / t_ours:.1f}x", f"{agree:.1e}"])
    X = rng.uniform(-3, 3, (300, 2))
    y = np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.1 * rng.normal(size=300)
    t_fit = median_seconds(lambda: GaussianProcess.fit(X, y, restarts=3, seed=0), 3, warmup=0)
    rows.append(["fit n=300, D=2, E=1, 3 restarts", f"{t_fit * 1e3:.0f}", "", "", ""])
    table = markdown_table(["case", "gpfverify ms (median)", "reference ms", "speed-up", "max |diff|"], rows)
    header = (f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
              f"numpy {np.__version__}")
    print(header + "\n\n" + table)
    if args.out:
        args.out.write_text(header + "\n\n" + table + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
