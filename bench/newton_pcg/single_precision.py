#!/usr/bin/env python3
"""Can the Newton step's multigrid store its 3 x 3 blocks in single precision? numpy + scipy.

usage: single_precision.py

The drape's primal Hessian (as primal.py assembles it: k = 1e8 N/m springs with their geometric
stiffness, plus m/h^2 on the diagonal, 2 substeps a frame) at a wrinkled, folded state, N = 33,
65 and 129, rounded to float32 and back; prints |A v| and |(A32 - A) v| for a translation of
the whole cloth (held only by inertia: A v = m/h^2 v), a rotation and a smooth bend. Where
k / (m/h^2) exceeds float32's 1/epsilon (1.7e7), the rounding of the stiff blocks no longer
cancels on the motions that do not stretch the springs, and the error swamps the inertia that
is all A holds them by.
"""
import numpy as np
import scipy.sparse as sp

for N in (33, 65, 129):
    h = 1.0 / (N - 1)
    X = np.array([(j * h, 0.0, i * h) for i in range(N) for j in range(N)])
    E = []
    for i in range(N):
        for j in range(N):
            if j + 1 < N: E.append((i*N+j, i*N+j+1))
            if i + 1 < N: E.append((i*N+j, (i+1)*N+j))
            if i + 1 < N and j + 1 < N: E.append((i*N+j, (i+1)*N+j+1))
    E = np.array(E); ea, eb = E[:,0], E[:,1]
    L = np.linalg.norm(X[ea]-X[eb], axis=1)
    rng = np.random.default_rng(1)
    x = X + 0.2 * h * rng.standard_normal(X.shape)   # a wrinkled state
    x[:, 1] += 0.3 * np.sin(4 * X[:, 0]) * X[:, 2]     # and a fold
    nv = N * N; m = 1.0 / nv; k = 1e8; dt = 1 / 120
    d = x[ea] - x[eb]; l = np.linalg.norm(d, axis=1); n = d / l[:, None]
    nn = n[:, :, None] * n[:, None, :]
    K = k * (nn + np.maximum(0, 1 - L / l)[:, None, None] * (np.eye(3) - nn))
    bi = np.concatenate([ea, eb, ea, eb]); bj = np.concatenate([ea, eb, eb, ea])
    rr = (3*bi[:,None,None] + np.arange(3)[None,:,None]).repeat(3, axis=2).ravel()
    cc = (3*bj[:,None,None] + np.arange(3)[None,None,:]).repeat(3, axis=1).ravel()
    H = sp.csr_matrix((np.concatenate([K, K, -K, -K]).ravel(), (rr, cc)), shape=(3*nv, 3*nv)) + sp.diags(np.full(3*nv, m / dt**2))
    H32 = H.astype(np.float32).astype(np.float64)
    for name, v in [("translation", np.tile([0.0, 1.0, 0.0], nv)),
                    ("rotation", np.cross(np.array([0.0, 0.0, 1.0]), x - x.mean(0)).ravel()),
                    ("smooth bend", np.repeat(np.sin(np.pi * X[:, 0]) * np.sin(np.pi * X[:, 2]), 3) * np.tile([0, 1.0, 0], nv))]:
        ex = H @ v; err = (H32 - H) @ v
        print(f"N={N} m/h^2={m/dt**2:.3g} k={k:g}: {name:12s} |Av| {np.linalg.norm(ex):.3e}, |(A32-A)v| {np.linalg.norm(err):.3e}, ratio {np.linalg.norm(err)/np.linalg.norm(ex):.2e}")
