#!/usr/bin/env python3
"""Experiment: the drape solved by Newton's method on the primal (position) system with the
geometric stiffness, each Newton step a sparse direct solve. numpy + scipy. See README.md.

usage: primal.py N SUBSTEPS NEWTON [--compliance ALPHA] [--frames 120] [--trace] [--amg CG]
                 [--rebuild R [--galerkin]] [--gmg [--coarsest NODES] [--coarse-every K]
                 [--rot [--rot-from LEVEL] [--coarse-block 3|6]] [--schwarz] [--smooth-p]]
                 [--pbd-start K]
                 [--cost]

Per substep, implicit Euler on stiff springs (compliance ALPHA m/N, default 1e-8: the strain
the compliance itself allows is ~1e-6 at the pins):

  minimise  Phi(x) = |x - x~|_M^2 / (2 h^2) + sum_e (l_e - L_e)^2 / (2 ALPHA)

from the prediction x~, by NEWTON Newton iterations, each a sparse LU solve of

  H = M / h^2 + sum_e (1 / ALPHA) [n n^T + max(0, 1 - L/l) (I - n n^T)]

(the edge's Hessian with its geometric stiffness, clamped to tension so that H stays positive
definite), with a backtracking line search on Phi. This system is never singular (the mass
term), unlike the multipliers' `J W J^T` of ncg.py and twogrid.py: it answers whether a global
solve converges from the flat start once the system is well posed, before any multigrid is
built for it. Prints the peers' strain metrics and the Newton iterations and line-search
halvings per frame.

With `--amg CG`, each Newton step is instead CG iterations (at most CG) preconditioned by one
V-cycle of smoothed-aggregation algebraic multigrid (pyamg, built anew for every Newton step,
the six rigid-body modes as its near-null space): the iterative solver a plugin would need.
Prints CG iterations, relative residuals and the hierarchy's operator complexity too.

With `--rebuild R`, the AMG hierarchy is built only every R-th Newton step and reused between
(frozen, or with `--galerkin` its prolongators kept and its coarse operators recomputed); with
`--gmg`, a geometric hierarchy fixed by the rest mesh (the `stretch_hierarchy` kind's
coarsening) with Galerkin operators for every Hessian: what the `stretch_newton` kind builds
(`--coarse-every K`: the coarse levels recomputed only every K-th Newton step). `--rot` gives
every coarse particle a rotation about its current position as well (six unknowns), each
dropped particle moved by its parents' rigid motions, the prolongators rebuilt from the current
shape every Newton step: the kind's `rotations = true`. `--schwarz` smooths the finest level by
overlapping Schwarz over each particle's star instead of block Gauss-Seidel; `--smooth-p` smooths
every prolongator by one damped block-Jacobi step on its level's operator (smoothed aggregation's
coarse space, on the geometric hierarchy).

With `--pbd-start K`, each substep's Newton steps start not from the prediction but from it
after K hard Gauss-Seidel passes over the edges (plain PBD, colour by colour): the
`stretch_newton` kind's `start_passes`.

With `--cost`, after the run: what one such CG iteration costs on the Hessian of the last
positions (the hanging cloth), on one thread (run with OMP_NUM_THREADS=1), best of 5 repeats:
the Hessian's product (3 x 3 block sparse, scipy BSR), one V-cycle and the hierarchy's setup.
"""
import argparse
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from drape import StrainLog, drape_grid, edge_colour_sets, pbd_passes

p = argparse.ArgumentParser()
p.add_argument("N", type=int)
p.add_argument("S", type=int)
p.add_argument("newton", type=int)
p.add_argument("--compliance", type=float, default=1e-8)
p.add_argument("--frames", type=int, default=120)
p.add_argument("--trace", action="store_true")
p.add_argument("--amg", type=int, default=0, metavar="CG",
               help="solve each Newton step by at most CG iterations of AMG-preconditioned CG")
p.add_argument("--rebuild", type=int, default=1, metavar="R",
               help="with --amg: build the hierarchy only every R-th Newton step; between builds "
               "reuse it (its prolongators), see --galerkin")
p.add_argument("--galerkin", action="store_true",
               help="with --rebuild: between builds, recompute the coarse operators R H P and "
               "the smoothers for the current Hessian (otherwise the old V-cycle is used as is)")
p.add_argument("--gmg", action="store_true",
               help="with --amg: instead of smoothed aggregation, a geometric hierarchy fixed at "
               "the start (maximal independent sets of the edge graph, each dropped particle "
               "interpolated from its kept neighbours, as the stretch_hierarchy kind does; the "
               "same weights for x, y, z) with Galerkin operators R H P for every Hessian")
p.add_argument("--rot", action="store_true",
               help="with --gmg: every coarse particle carries a rotation too (six unknowns), "
               "each dropped particle moved by its kept neighbours' rigid motions about their "
               "current positions, the prolongators rebuilt from the current shape every "
               "Newton step")
p.add_argument("--rot-from", type=int, default=1, metavar="LEVEL",
               help="with --rot: the coarse levels from LEVEL on (1: every coarse level) carry "
               "rotations, the finer ones only translations")
p.add_argument("--coarse-block", type=int, default=6, choices=(3, 6),
               help="with --rot: Gauss-Seidel blocks of the rotating levels, 6 (a particle's "
               "translation and rotation together) or 3 (each apart)")
p.add_argument("--coarse-every", type=int, default=1, metavar="K",
               help="with --gmg: recompute the prolongators and coarse operators only every "
               "K-th Newton step (the finest level always the current Hessian)")
p.add_argument("--schwarz", action="store_true",
               help="with --gmg: smooth the finest level by symmetric overlapping Schwarz over "
               "each unknown's row pattern (a particle's star) instead of block Gauss-Seidel")
p.add_argument("--smooth-p", action="store_true",
               help="with --gmg: smooth every prolongator by one damped block-Jacobi step on its "
               "level's operator, P <- (I - omega D^-1 A) P with omega = 4 / (3 rho(D^-1 A)): "
               "coarse motions that relax the stiff fine edges (a smoothed-aggregation-like "
               "coarse space on the geometric hierarchy)")
p.add_argument("--coarsest", type=int, default=60, metavar="NODES",
               help="with --gmg: coarsen until a level has at most NODES particles")
p.add_argument("--pbd-start", type=int, default=0, metavar="K",
               help="before each substep's Newton steps, K Gauss-Seidel passes of hard edge "
               "projections (plain PBD, edge colour by colour) from the prediction")
p.add_argument("--cost", action="store_true",
               help="time a Hessian product, a V-cycle and the AMG setup after the run")
a = p.parse_args()
N = a.N
X, E, struct = drape_grid(N)
ea, eb = E[:, 0], E[:, 1]
L = np.linalg.norm(X[ea] - X[eb], axis=1)
nv = N * N
mass = np.full(nv, 1.0 / nv)
pinned = np.zeros(nv, bool)
pinned[0] = pinned[N - 1] = True
free = ~pinned
free_dofs = np.flatnonzero(np.repeat(free, 3))
k = 1.0 / a.compliance
g = np.array([0.0, -9.81, 0.0])
dt = 1.0 / 60 / a.S

# Sparsity pattern of the 3x3 blocks (i,i), (j,j), (i,j), (j,i) of every edge.
bi = np.concatenate([ea, eb, ea, eb])
bj = np.concatenate([ea, eb, eb, ea])
rr = (3 * bi[:, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2).ravel()
cc = (3 * bj[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1).ravel()


def rigid_modes(x):
    """The six rigid-body modes of the particles `x` (3 translations, 3 rotations about the
    centroid), one row per degree of freedom: the near-null space AMG's aggregates keep."""
    c = x - x.mean(0)
    b = np.zeros((len(x), 3, 6))
    for axis in range(3):
        b[:, axis, axis] = 1.0
    b[:, 0, 3], b[:, 1, 3] = -c[:, 1], c[:, 0]
    b[:, 1, 4], b[:, 2, 4] = -c[:, 2], c[:, 1]
    b[:, 0, 5], b[:, 2, 5] = c[:, 2], -c[:, 0]
    return b.reshape(-1, 6)


def amg_hierarchy(Hf, x_free):
    """Smoothed aggregation for the free block `Hf` of the Hessian at the free particles
    `x_free` (pyamg), keeping their rigid-body modes."""
    import pyamg

    return pyamg.smoothed_aggregation_solver(Hf.tocsr(), B=rigid_modes(x_free),
                                             strength=("symmetric", {"theta": 0.0}),
                                             max_coarse=200)


def geometric_prolongators(x_free, edges_free, coarsest):
    """Per level, the scalar interpolation (CSR, fine x coarse) of the free particles'
    hierarchy: a greedy maximal independent set kept (by index), each dropped particle moved by
    its kept neighbours weighted by inverse rest length; the next level's graph joins kept
    particles within three edges through dropped ones. Returns (P, kept) per level, P scalar;
    `gmg_hierarchy` Kronecker's it with I3 for x, y, z (or adds rotations: `--rot`)."""
    n = len(x_free)
    graph = [dict() for _ in range(n)]
    for u, w in edges_free:
        d = np.linalg.norm(x_free[u] - x_free[w])
        graph[u][w] = graph[w][u] = d
    out = []
    while n > coarsest:
        state = np.zeros(n, np.int8)
        for v in range(n):
            if state[v] == 0:
                state[v] = 1
                for u in graph[v]:
                    if state[u] == 0:
                        state[u] = 2
        kept = np.flatnonzero(state == 1)
        ci = -np.ones(n, int)
        ci[kept] = np.arange(len(kept))
        rows, cols, vals = [], [], []
        for v in range(n):
            if ci[v] >= 0:
                rows.append(v); cols.append(ci[v]); vals.append(1.0)
                continue
            par = [(ci[u], 1.0 / l) for u, l in graph[v].items() if ci[u] >= 0]
            tot = sum(w for _, w in par)
            for c, w in par:
                rows.append(v); cols.append(c); vals.append(w / tot)
        P = sp.csr_matrix((vals, (rows, cols)), shape=(n, len(kept)))
        out.append((P, kept))
        coarse = [dict() for _ in range(len(kept))]
        for a_, v in enumerate(kept):
            frontier = {v: 0.0}
            for _ in range(3):
                nxt = {}
                for f, lf in frontier.items():
                    for u, l in graph[f].items():
                        if u == v:
                            continue
                        if ci[u] >= 0:
                            b_ = ci[u]
                            coarse[a_][b_] = min(coarse[a_].get(b_, np.inf), lf + l)
                        elif lf + l < nxt.get(u, np.inf):
                            nxt[u] = lf + l
                frontier = nxt
        graph, n = coarse, len(kept)
    return out


def galerkin_hierarchy(Hf, prolongators, sweep, coarse=None):
    """The V-cycle over `Hf` and its Galerkin operators `R A P`, level by level for the
    `(P, R)` pairs (finest first), smoothed by `sweep` before and after. `coarse`, if given,
    holds those operators already computed (one per pair), so they are not formed again."""
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers

    levels, A = [], Hf.tocsr()
    for k, (P, R) in enumerate(prolongators):
        lv = MultilevelSolver.Level()
        lv.A, lv.P, lv.R = A, P, R
        A = coarse[k] if coarse is not None else (R @ A @ P).tocsr()
        levels.append(lv)
    lv = MultilevelSolver.Level()
    lv.A = A
    levels.append(lv)
    ml = MultilevelSolver(levels, coarse_solver="pinv")
    change_smoothers(ml, sweep, sweep)
    return ml


def rotational_prolongator(P, xf, xc, fine_dofs):
    """The scalar interpolation `P` (fine x coarse particles) with each coarse particle's
    rotation about its position `xc` added: a fine particle at `xf` moves by
    sum_j w_j (t_j + theta_j x (xf - xc_j)); its own rotation (`fine_dofs` = 6) by
    sum_j w_j theta_j. Rigid motions of the current shape are interpolated exactly."""
    P = P.tocsr()
    rows = np.repeat(np.arange(P.shape[0]), np.diff(P.indptr))
    r = xf[rows] - xc[P.indices]
    w = P.data
    blk = np.zeros((len(w), fine_dofs, 6))
    for axis in range(3):
        blk[:, axis, axis] = w
    # theta x r = -[r]_x theta
    blk[:, 0, 4], blk[:, 0, 5] = w * r[:, 2], -w * r[:, 1]
    blk[:, 1, 3], blk[:, 1, 5] = -w * r[:, 2], w * r[:, 0]
    blk[:, 2, 3], blk[:, 2, 4] = w * r[:, 1], -w * r[:, 0]
    if fine_dofs == 6:
        for axis in range(3):
            blk[:, 3 + axis, 3 + axis] = w
    return sp.bsr_matrix((blk, P.indices, P.indptr),
                         shape=(fine_dofs * P.shape[0], 6 * P.shape[1])).tocsr()


def gmg_sweeps(sizes):
    """The geometric hierarchy's smoothers, level by level for `sizes` unknowns per particle:
    symmetric block Gauss-Seidel (blocks of at most `--coarse-block`), or overlapping Schwarz on
    the finest level with `--schwarz`."""
    sweeps = [("block_gauss_seidel", {"sweep": "symmetric", "blocksize": min(b, a.coarse_block)})
              for b in sizes]
    if a.schwarz:
        sweeps[0] = ("schwarz", {"sweep": "symmetric"})
    return sweeps


def smoothed(A, P, b):
    """`P` after one damped block-Jacobi step on `A` (blocks of `b` unknowns):
    (I - omega D^-1 A) P, omega = 4 / (3 rho(D^-1 A)) (rho by power iteration)."""
    from pyamg.util.linalg import approximate_spectral_radius

    A = A.tocsr()
    n = A.shape[0] // b
    Ab = A.tobsr(blocksize=(b, b))
    D = np.zeros((n, b, b))
    for i in range(n):
        for k in range(Ab.indptr[i], Ab.indptr[i + 1]):
            if Ab.indices[k] == i:
                D[i] = Ab.data[k]
    Dinv = sp.block_diag([np.linalg.inv(d) for d in D], format="csr")
    DA = (Dinv @ A).tocsr()
    omega = 4.0 / (3.0 * approximate_spectral_radius(DA))
    return (P - omega * (DA @ P)).tocsr()


def gmg_hierarchy(Hf, x_free):
    """The geometric hierarchy's V-cycle for `Hf` at the free particles `x_free`: Galerkin
    operators over the scalar prolongators (Kronecker'd with I3), or with `--rot` from level
    `--rot-from` on the rotational ones fitted to `x_free`. Keeps the levels' unknowns per
    particle as `block_sizes`, for `--coarse-every`'s smoothers."""
    pr, xf, dofs, sizes, A, coarse = [], x_free, 3, [3], Hf.tocsr(), []
    for level, (P, kept) in enumerate(gmg_prolongators):
        fine_dofs = dofs
        if not a.rot or level + 1 < a.rot_from:
            R = sp.kron(P, sp.eye(3), format="csr")
        else:
            R = rotational_prolongator(P, xf, xf[kept], dofs)
            dofs = 6
        if a.smooth_p:
            # Each smoothed prolongator needs its level's operator, so the Galerkin products
            # are formed here, once, and handed on.
            R = smoothed(A, R, fine_dofs)
            A = (R.T @ A @ R).tocsr()
            coarse.append(A)
        pr.append((R, R.T.tocsr()))
        xf = xf[kept]
        sizes.append(dofs)
    ml = galerkin_hierarchy(Hf, pr, gmg_sweeps(sizes), coarse if a.smooth_p else None)
    ml.block_sizes = sizes
    return ml


def galerkin_update(ml, Hf):
    """`ml`'s prolongators kept, its operators recomputed for `Hf` (R A P level by level) and
    its smoothers set up anew: the hierarchy reused for a new Hessian."""
    return galerkin_hierarchy(Hf, [(lv.P, lv.R) for lv in ml.levels if hasattr(lv, "P")],
                              ("block_gauss_seidel", {"sweep": "symmetric"}))


def amg_solve(Hf, rhs, x_free):
    """At most `a.amg` iterations of CG on `Hf s = rhs` from 0, preconditioned by a V-cycle of
    smoothed aggregation; records the iterations, residual reduction and complexity. The
    hierarchy is built every `a.rebuild`-th call, reused (frozen or Galerkin-updated) between."""
    global amg_cached
    own = True  # whether the V-cycle's finest operator is Hf itself
    if a.gmg and (amg_cached is None or amg_state["calls"] % a.coarse_every == 0):
        amg_cached = ml = gmg_hierarchy(Hf, x_free)
    elif a.gmg:
        from pyamg.relaxation.smoothing import change_smoothers

        ml = amg_cached
        ml.levels[0].A = Hf.tocsr()
        sweeps = gmg_sweeps(ml.block_sizes)
        change_smoothers(ml, sweeps, sweeps)
    elif amg_cached is None or amg_state["calls"] % a.rebuild == 0:
        amg_cached = ml = amg_hierarchy(Hf, x_free)
    elif a.galerkin:
        ml = galerkin_update(amg_cached, Hf)
    else:
        ml, own = amg_cached, False
    amg_state["calls"] += 1
    res = []
    if own:
        s = ml.solve(rhs, x0=np.zeros(len(rhs)), tol=1e-14, maxiter=a.amg, accel="cg",
                     residuals=res)
    else:
        s = cg_frozen(ml, Hf, rhs, res)
    amg_log.append((len(res) - 1, res[-1] / res[0], ml.operator_complexity()))
    return s


def cg_frozen(ml, Hf, rhs, res):
    """CG on `Hf s = rhs` from 0 preconditioned by `ml`'s V-cycle, `ml` built for another
    Hessian; residual norms appended to `res`."""
    M = ml.aspreconditioner(cycle="V")
    s = np.zeros(len(rhs))
    r = rhs.copy()
    z = M @ r
    d = z.copy()
    rz = r @ z
    res.append(np.linalg.norm(r))
    for _ in range(a.amg):
        q = Hf @ d
        alpha = rz / (d @ q)
        s += alpha * d
        r -= alpha * q
        res.append(np.linalg.norm(r))
        z = M @ r
        rz, rz_old = r @ z, rz
        d = z + (rz / rz_old) * d
    return s


def best_time(f, repeats):
    """The least mean wall time (s) of `f()` over 5 runs of `repeats` calls."""
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeats):
            f()
        best = min(best, (time.perf_counter() - t0) / repeats)
    return best


def print_cost(x):
    """What one AMG-preconditioned CG iteration costs on the Hessian at `x`."""
    _, H = gradient_and_hessian(x, x)
    Hf = H[free_dofs][:, free_dofs].tocsr()
    v = np.random.default_rng(1).standard_normal(Hf.shape[0])
    bsr = sp.bsr_matrix(Hf, blocksize=(3, 3))
    product = best_time(lambda: bsr @ v, 50)
    t0 = time.perf_counter()
    ml = amg_hierarchy(Hf, x[free])
    setup = time.perf_counter() - t0
    cycle = ml.aspreconditioner(cycle="V")
    v_cycle = best_time(lambda: cycle @ v, 10)
    print(f"cost: {Hf.shape[0]} unknowns, {Hf.nnz} non-zeros; product (BSR) "
          f"{product * 1e3:.3f} ms, V-cycle {v_cycle * 1e3:.2f} ms, AMG setup "
          f"{setup * 1e3:.0f} ms, operator complexity {ml.operator_complexity():.2f}")


def phi(x, xt):
    d = x[ea] - x[eb]
    l = np.linalg.norm(d, axis=1)
    return (mass[:, None] * (x - xt) ** 2).sum() / (2 * dt * dt) + ((l - L) ** 2).sum() * k / 2


def gradient_and_hessian(x, xt):
    d = x[ea] - x[eb]
    l = np.linalg.norm(d, axis=1)
    n = d / l[:, None]
    f = (k * (l - L))[:, None] * n
    grad = (mass[:, None] * (x - xt)) / (dt * dt)
    np.add.at(grad, ea, f)
    np.add.at(grad, eb, -f)
    nn = n[:, :, None] * n[:, None, :]
    geo = np.maximum(0.0, 1.0 - L / l)[:, None, None] * (np.eye(3)[None] - nn)
    K = k * (nn + geo)
    blocks = np.concatenate([K, K, -K, -K])
    H = sp.csc_matrix((blocks.ravel(), (rr, cc)), shape=(3 * nv, 3 * nv))
    H = H + sp.diags(np.repeat(mass, 3) / (dt * dt))
    return grad.ravel(), H


W = np.where(pinned, 0.0, 1.0 / mass)


colour_sets = edge_colour_sets(E, nv) if a.pbd_start else []
x = X.copy()
v = np.zeros_like(x)
log = StrainLog(ea, eb, L, struct)
newton_steps, halvings = 0, 0
heights = []  # the particles' mean height after each frame (m)
amg_log = []
amg_cached, amg_state = None, {"calls": 0}
if a.gmg:
    fi = -np.ones(nv, int)
    fi[free] = np.arange(free.sum())
    keep = free[ea] & free[eb]
    gmg_prolongators = geometric_prolongators(X[free], np.c_[fi[ea[keep]], fi[eb[keep]]],
                                              a.coarsest)
    print("geometric levels:", [P.shape for P, _ in gmg_prolongators])
for fr in range(a.frames):
    for s in range(a.S):
        xo = x.copy()
        v[free] += dt * g
        xt = x + dt * v * free[:, None]
        x = pbd_passes(xt.copy(), a.pbd_start, colour_sets, E, L, W)
        for it in range(a.newton):
            grad, H = gradient_and_hessian(x, xt)
            Hf = H[free_dofs][:, free_dofs]
            step = np.zeros(3 * nv)
            if a.amg:
                step[free_dofs] = amg_solve(Hf, -grad[free_dofs], x[free])
            else:
                step[free_dofs] = spl.splu(Hf.tocsc()).solve(-grad[free_dofs])
            step = step.reshape(-1, 3)
            f0, t = phi(x, xt), 1.0
            while phi(x + t * step, xt) > f0 and t > 1e-6:
                t *= 0.5
                halvings += 1
            x = x + t * step
            newton_steps += 1
        v = (x - xo) / dt
    heights.append(x[:, 1].mean())
    if not log.frame(x, fr, a.trace):
        break
strain_max, strain_rms = log.means()
print(f"N={N} S={a.S} newton={a.newton} compliance={a.compliance:g}: max {strain_max:.3f}% "
      f"rms {strain_rms:.4f}%  Newton steps/frame {newton_steps / len(log.rows):.0f}, "
      f"halvings/frame {halvings / len(log.rows):.1f}, lowest point {x[:, 1].min():.3f} m, "
      f"mean height after {min(15, len(heights))} / {min(30, len(heights))} frames "
      f"{heights[min(15, len(heights)) - 1]:.3f} / {heights[min(30, len(heights)) - 1]:.3f} m")
if amg_log:
    its, red, cx = np.array(amg_log).T
    print(f"AMG-CG: {its.mean():.1f} iterations per Newton step, residual reduced "
          f"{np.median(red):.1e} (median) / {red.max():.1e} (worst), operator complexity "
          f"{cx.mean():.2f} (mean) / {cx.max():.2f} (max)")
if a.cost:
    print_cost(x)
