#!/usr/bin/env python3
"""Experiment: the drape by projective dynamics (Liu, Bargteil, O'Brien, Kavan 2013, "Fast
simulation of mass-spring systems"; Bouaziz et al. 2014), the global matrix factored once.

usage: pd.py N SUBSTEPS ITERATIONS [--stiffness K] [--frames 120] [--chebyshev RHO]
             [--pbd-start P] [--trace] [--cost]

Per substep, implicit Euler on springs of stiffness K (N/m per edge, default 1e8: the drape's
compliance 1e-8), written with an auxiliary edge vector d_e of the rest length:

  minimise  |x - x~|_M^2 / (2 h^2) + sum_e K/2 |x_i - x_j - d_e|^2 over x and |d_e| = L_e

by ITERATIONS local/global iterations: local, d_e = L_e (x_i - x_j) / |x_i - x_j|; global, the
linear solve of (M / h^2 + K sum_e a_e a_e^T) x = M x~ / h^2 + K sum_e a_e d_e, one scalar
matrix for the three coordinates, constant while h and the pins are: factored once for the
whole run (SuperLU here). `--chebyshev RHO`: Wang 2015's Chebyshev acceleration of the
iterates with spectral radius estimate RHO. `--pbd-start P`: P hard Gauss-Seidel passes on the
prediction first. Prints the peers' strain metrics, mean heights after 15 and 30 frames, the
energy (kinetic + gravity + spring) and its largest rise; `--cost` times a factorization and a
solve of three right-hand sides.
"""
import argparse
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "newton_pcg"))
from drape import StrainLog, drape_grid, edge_colour_sets, pbd_passes  # noqa: E402

p = argparse.ArgumentParser()
p.add_argument("N", type=int)
p.add_argument("S", type=int)
p.add_argument("iterations", type=int)
p.add_argument("--stiffness", type=float, default=1e8)
p.add_argument("--frames", type=int, default=120)
p.add_argument("--chebyshev", type=float, default=0.0)
p.add_argument("--pbd-start", type=int, default=0)
p.add_argument("--trace", action="store_true")
p.add_argument("--cost", action="store_true")
a = p.parse_args()
N = a.N
X, E, struct = drape_grid(N)
ea, eb = E[:, 0], E[:, 1]
L = np.linalg.norm(X[ea] - X[eb], axis=1)
nv = N * N
ne = len(E)
mass = np.full(nv, 1.0 / nv)
pinned = np.zeros(nv, bool)
pinned[0] = pinned[N - 1] = True
free = ~pinned
k = a.stiffness
g = np.array([0.0, -9.81, 0.0])
dt = 1.0 / 60 / a.S

# Edge-node incidence: (x_i - x_j) = G x.
G = sp.csr_matrix((np.r_[np.ones(ne), -np.ones(ne)], (np.r_[np.arange(ne), np.arange(ne)],
                                                       np.r_[ea, eb])), shape=(ne, nv))
A = (sp.diags(mass / dt ** 2) + k * (G.T @ G)).tocsc()
fidx = np.flatnonzero(free)
Aff = A[fidx][:, fidx].tocsc()
Afp = A[fidx][:, np.flatnonzero(pinned)]
t0 = time.perf_counter()
lu = spl.splu(Aff, permc_spec="MMD_AT_PLUS_A")
t_fact = time.perf_counter() - t0
print(f"factor nnz L+U {lu.L.nnz + lu.U.nnz}, factorization {t_fact * 1e3:.0f} ms")
W = np.where(pinned, 0.0, 1.0 / mass)


colour_sets = edge_colour_sets(E, nv) if a.pbd_start else []


def energy(x, v):
    l = np.linalg.norm(x[ea] - x[eb], axis=1)
    return (0.5 * (mass[:, None] * v ** 2).sum() - (mass * x[:, 1]).sum() * g[1]
            + 0.5 * k * ((l - L) ** 2).sum())


def global_solve(d, xt, xp):
    rhs = (mass / dt ** 2)[:, None] * xt + k * (G.T @ d)
    r = rhs[fidx] - Afp @ xp
    out = np.empty((nv, 3))
    out[pinned] = xp
    out[fidx] = lu.solve(np.asfortranarray(r))
    return out


x = X.copy()
v = np.zeros_like(x)
log = StrainLog(ea, eb, L, struct)
heights, energies = [], []
for fr in range(a.frames):
    for s in range(a.S):
        xo = x.copy()
        v[free] += dt * g
        xt = x + dt * v * free[:, None]
        xp = xt[pinned]
        y = pbd_passes(xt.copy(), a.pbd_start, colour_sets, E, L, W)
        prev, omega = y.copy(), 1.0
        for it in range(a.iterations):
            dv = y[ea] - y[eb]
            d = L[:, None] * dv / np.linalg.norm(dv, axis=1)[:, None]
            new = global_solve(d, xt, xp)
            if a.chebyshev:
                if it == 0:
                    omega = 1.0
                elif it == 1:
                    omega = 2.0 / (2.0 - a.chebyshev ** 2)
                else:
                    omega = 4.0 / (4.0 - a.chebyshev ** 2 * omega)
                new = omega * (new - prev) + prev
            prev, y = y, new
        x = y
        v = (x - xo) / dt
    heights.append(x[:, 1].mean())
    energies.append(energy(x, v))
    if not log.frame(x, fr, a.trace):
        break
strain_max, strain_rms = log.means()
e = np.array(energies)
rise = (e - np.minimum.accumulate(e)).max()
print(f"N={N} S={a.S} iterations={a.iterations} k={k:g} cheb={a.chebyshev} "
      f"pbd={a.pbd_start}: max {strain_max:.3f}% rms {strain_rms:.4f}%, mean height after "
      f"{min(15, len(heights))} / {min(30, len(heights))} frames "
      f"{heights[min(14, len(heights) - 1)]:.3f} / {heights[min(29, len(heights) - 1)]:.3f} m, energy end "
      f"{e[-1]:.3f} J, largest rise {rise:.3f} J at frame {np.argmax(e - np.minimum.accumulate(e))}")
if a.cost:
    r = np.asfortranarray(np.random.rand(len(fidx), 3))
    best = min((lambda t: (lu.solve(r), time.perf_counter() - t)[1])(time.perf_counter())
               for _ in range(5))
    print(f"solve of 3 right-hand sides: {best * 1e3:.2f} ms (SuperLU, one thread)")
