#!/usr/bin/env python3
"""Warm-started Gauss-Seidel on a linearised hanging chain: why the plain warm start diverges
and why splitting the substep (a velocity-level pass plus a drift pass that adds no velocity)
does not. The model behind the "warm start" entries of bench/README.md.

usage: python3 bench/warm_start_chain/chain.py        (needs numpy)

The chain: n unit masses below a pin, moving along the vertical only; edge e joins mass e-1
(the pin for e = 0) and mass e, C_e = u_e - u_(e-1) (its stretch). One substep, with p = h v:

  y = u + p + g                      predict (g = gravity h^2)
  y += W J^T (beta lambda)           warm start: the share beta of last substep's multipliers
  one Gauss-Seidel pass, top down    plain: towards C = 0; split: towards C = C(u), the start
                                     lengths, accumulating the multipliers acc
  p = y - u                          velocity
  split only: one pass towards C = 0 on y, after the velocity (adds no velocity)
  u = y, lambda = beta lambda + acc

Prints (1) the spectral radius of the plain warm-started substep for several beta (above 1:
diverges), and (2) the largest edge stretch after 3,000 substeps under gravity, as a share of
plain passes' (beta = 0), for the split substep.
"""

import numpy as np


def gs_pass(y, target, acc=None):
    """One top-down Gauss-Seidel pass over the chain's edges, towards C_e = target_e."""
    n = len(y)
    for e in range(n):
        a = e - 1
        c = y[e] - (y[a] if a >= 0 else 0.0) - target[e]
        dl = -c / ((1.0 if a >= 0 else 0.0) + 1.0)
        if a >= 0:
            y[a] -= dl
        y[e] += dl
        if acc is not None:
            acc[e] += dl


def stretch(u):
    return np.diff(np.concatenate([[0.0], u]))


def substep(u, p, lam, beta, split, g):
    n = len(u)
    y = u + p + g
    for e in range(n):
        if e >= 1:
            y[e - 1] -= beta * lam[e]
        y[e] += beta * lam[e]
    acc = np.zeros(n)
    if split:
        gs_pass(y, stretch(u), acc)
        p = y - u
        gs_pass(y, np.zeros(n))
    else:
        gs_pass(y, np.zeros(n), acc)
        p = y - u
    return y, p, beta * lam + acc


def spectral_radius(n, beta, split):
    dim = 3 * n
    m = np.zeros((dim, dim))
    for k in range(dim):
        s = np.zeros(dim)
        s[k] = 1.0
        y, p, lam = substep(s[:n].copy(), s[n:2 * n].copy(), s[2 * n:].copy(), beta, split, 0.0)
        m[:, k] = np.concatenate([y, p, lam])
    return max(abs(np.linalg.eigvals(m)))


def final_max_stretch(n, beta, split, steps=3000, g=1e-3):
    u, p, lam = np.zeros(n), np.zeros(n), np.zeros(n)
    for _ in range(steps):
        u, p, lam = substep(u, p, lam, beta, split, g)
    return np.abs(stretch(u)).max()


def main():
    print("plain warm start: spectral radius of one substep")
    for n in (16, 32):
        row = ", ".join(f"beta {b}: {spectral_radius(n, b, False):.4f}"
                        for b in (0.0, 0.3, 0.5, 0.7, 1.0))
        print(f"  n = {n}: {row}")
    print("split substep: spectral radius of one substep")
    for n in (16, 32):
        print(f"  n = {n}, beta 1: {spectral_radius(n, 1.0, True):.4f}")
    print("largest stretch after 3,000 substeps, as a share of plain passes' (beta 0)")
    for n in (16, 64):
        base = final_max_stretch(n, 0.0, False)
        for beta in (0.9, 1.0):
            r = final_max_stretch(n, beta, True) / base
            print(f"  n = {n}, split, beta {beta}: {r:.3g}")


if __name__ == "__main__":
    main()
