#!/usr/bin/env python3
"""Experiment: ncg.py's global Newton step per substep, its conjugate gradients preconditioned
by a two-grid cycle with a Galerkin coarse operator instead of Jacobi. numpy + scipy. See
README.md.

usage: twogrid.py N SUBSTEPS CG [--smooth NU] [--frames 120] [--jacobi] [--quads] [--trace]

N must be odd (the coarse grid takes every other vertex). Per substep, after the prediction:
one Newton step on all edges, (J W J^T) dl = -C at the predicted positions, solved by CG
iterations from dl = 0, each preconditioned by a symmetric two-grid cycle:

  NU forward Gauss-Seidel sweeps on the edges' linear system (from 0),
  the coarse correction P (P^T A P)^-1 P^T r (exact: a sparse LU of the coarse system),
  NU backward Gauss-Seidel sweeps.

P maps a coarse edge (between vertices of the grid of every other vertex) to the two fine
edges on its path (weight 1) and to the fine edges parallel to it halfway to the next coarse
path (weight 1/2): a tension field on the coarse grid, interpolated. `--jacobi` replaces the
cycle by Jacobi (as ncg.py). Prints the peers' strain metrics (structural edges, means of the
per-frame max and RMS over the last 60 frames), the CG iterations per frame, and an estimate of
the work in sweep-equivalents: per iteration one product with the system (1), 2 NU smoothing
sweeps, the residual (1), restriction and prolongation (0.5), and a coarse solve that a
recursive multigrid would do in about one sweep's time (1).
"""
import argparse

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from drape import StrainLog

p = argparse.ArgumentParser()
p.add_argument("N", type=int)
p.add_argument("S", type=int)
p.add_argument("cg", type=int)
p.add_argument("--smooth", type=int, default=1)
p.add_argument("--frames", type=int, default=120)
p.add_argument("--jacobi", action="store_true")
p.add_argument("--quads", action="store_true", help="no diagonal edges (a quad mesh)")
p.add_argument("--trace", action="store_true")
a = p.parse_args()
N = a.N
assert N % 2 == 1, "N must be odd"
h = 1.0 / (N - 1)
X = np.array([(j * h, 0.0, i * h) for i in range(N) for j in range(N)])

# Edges: horizontal (i,j)-(i,j+1), vertical (i,j)-(i+1,j), diagonal (i,j)-(i+1,j+1).
index = {}
E = []
for i in range(N):
    for j in range(N):
        if j + 1 < N:
            index[("h", i, j)] = len(E)
            E.append((i * N + j, i * N + j + 1))
        if i + 1 < N:
            index[("v", i, j)] = len(E)
            E.append((i * N + j, (i + 1) * N + j))
        if i + 1 < N and j + 1 < N and not a.quads:
            index[("d", i, j)] = len(E)
            E.append((i * N + j, (i + 1) * N + j + 1))
E = np.array(E)
ea, eb = E[:, 0], E[:, 1]
struct = np.array([k[0] != "d" for k in sorted(index, key=index.get)])
L = np.linalg.norm(X[ea] - X[eb], axis=1)
nv, ne = N * N, len(E)
w = np.full(nv, float(nv))
w[0] = 0.0
w[N - 1] = 0.0

# Prolongation: coarse edges of the grid of vertices (2I, 2J).
Nc = (N + 1) // 2
rows, cols, vals = [], [], []
nc = 0
for I in range(Nc):
    for J in range(Nc):
        targets = []
        if J + 1 < Nc:  # horizontal
            i, j = 2 * I, 2 * J
            targets.append([(("h", i, j), 1.0), (("h", i, j + 1), 1.0)]
                           + [(("h", i + s, j + t), 0.5) for s in (-1, 1) for t in (0, 1)])
        if I + 1 < Nc:  # vertical
            i, j = 2 * I, 2 * J
            targets.append([(("v", i, j), 1.0), (("v", i + 1, j), 1.0)]
                           + [(("v", i + t, j + s), 0.5) for s in (-1, 1) for t in (0, 1)])
        if I + 1 < Nc and J + 1 < Nc and not a.quads:  # diagonal
            i, j = 2 * I, 2 * J
            targets.append([(("d", i, j), 1.0), (("d", i + 1, j + 1), 1.0),
                            (("d", i, j + 1), 0.5), (("d", i + 1, j), 0.5)])
        for t in targets:
            for key, weight in t:
                if key in index:
                    rows.append(index[key])
                    cols.append(nc)
                    vals.append(weight)
            nc += 1
P = sp.csr_matrix((vals, (rows, cols)), shape=(ne, nc))

g = np.array([0.0, -9.81, 0.0])
dt = 1.0 / 60 / a.S
x = X.copy()
v = np.zeros_like(x)
free = w > 0
log = StrainLog(ea, eb, L, struct)
iterations = 0
er = np.arange(ne)


def system(n):
    """A = J W J^T for unit directions n (one row per edge)."""
    J = sp.csr_matrix(
        (np.concatenate([n, -n], axis=1).ravel(),
         (np.repeat(er, 6), np.concatenate([3 * ea[:, None] + np.arange(3), 3 * eb[:, None] + np.arange(3)], axis=1).ravel())),
        shape=(ne, 3 * nv),
    )
    Wd = sp.diags(np.repeat(w, 3))
    return J, (J @ Wd @ J.T).tocsr()


def pcg(A, b, precondition, iterations):
    """The iterates of preconditioned conjugate gradients on A y = b from y = 0."""
    y = np.zeros(len(b))
    r = b.copy()
    z = precondition(r)
    pp = z.copy()
    rz = r @ z
    out = []
    for k in range(iterations):
        Ap = A @ pp
        al = rz / (pp @ Ap)
        y = y + al * pp
        out.append(y)
        if k + 1 == iterations:
            break
        r = r - al * Ap
        z = precondition(r)
        rz2 = r @ z
        pp = z + (rz2 / rz) * pp
        rz = rz2
    return out


for fr in range(a.frames):
    for s in range(a.S):
        xo = x.copy()
        v[free] += dt * g
        x = x + dt * v * free[:, None]
        d = x[ea] - x[eb]
        l = np.linalg.norm(d, axis=1)
        n = d / l[:, None]
        b = -(l - L)
        J, A = system(n)
        diag = A.diagonal()
        if a.jacobi:
            def precondition(r):
                return r / diag
        else:
            lower = sp.tril(A, format="csr")
            upper = sp.triu(A, format="csr")
            Ac = (P.T @ A @ P).tocsc()
            Ac = Ac + sp.diags(1e-9 * Ac.diagonal().max() * np.ones(nc))
            coarse = spl.splu(Ac)

            def precondition(r):
                z = np.zeros(ne)
                for _ in range(a.smooth):
                    z += spl.spsolve_triangular(lower, r - A @ z, lower=True)
                z += P @ coarse.solve(P.T @ (r - A @ z))
                for _ in range(a.smooth):
                    z += spl.spsolve_triangular(upper, r - A @ z, lower=False)
                return z
        y = pcg(A, b, precondition, a.cg)[-1]
        iterations += a.cg
        x = x + (w[:, None] * (J.T @ y).reshape(-1, 3))
        v = (x - xo) / dt
    if not log.frame(x, fr, a.trace):
        break
strain_max, strain_rms = log.means()
per_frame = iterations / len(log.rows)
per_iteration = 1.0 if a.jacobi else 2 * a.smooth + 3.5
print(f"N={N} S={a.S} cg={a.cg} {'jacobi' if a.jacobi else f'two-grid nu={a.smooth}'}: "
      f"max {strain_max:.3f}% rms {strain_rms:.4f}%  "
      f"CG iterations/frame {per_frame:.0f}, ~{per_frame * per_iteration:.0f} sweep-equivalents/frame")
