#!/usr/bin/env python3
"""Experiment: the drape's hard stretch solved by a global Newton step per substep, its linear
system solved by a few iterations of Jacobi-preconditioned conjugate gradients (inexact
Newton-PCG), against the plugin's Gauss-Seidel passes. numpy only. See README.md.

usage: ncg.py N SUBSTEPS NEWTON CG [--warm BETA] [--frames 120] [--trace]

The peers' drape (1 m cloth, N x N, the two corners of the z = 0 edge pinned, total mass 1 kg,
gravity 9.81, 120 frames at 60 fps). Per substep: v += h g, x~ = x + h v; then NEWTON times:
C = |x_i - x_j| - L, n = unit edge directions at the current x, solve (J W J^T) dl = -C by CG
iterations from dl = BETA * (the previous substep's multipliers) (BETA = 0: from zero), and
x += W J^T dl; then v = (x - x_old) / h. Prints the peers' strain metrics (structural edges,
per-frame max and RMS, means over the last 60 frames) and the matrix-vector products per
frame (each one gather and one scatter over the edges: at least the cost of one Gauss-Seidel
pass).
"""
import numpy as np, sys, time, argparse
from drape import StrainLog, drape_grid
p = argparse.ArgumentParser()
p.add_argument('N', type=int); p.add_argument('S', type=int); p.add_argument('newton', type=int)
p.add_argument('cg', type=int); p.add_argument('--warm', type=float, default=0.0)
p.add_argument('--frames', type=int, default=120); p.add_argument('--gs', type=int, default=0)
p.add_argument('--trace', action='store_true')
a = p.parse_args()
N=a.N
X, E, struct = drape_grid(N)
ea, eb = E[:,0], E[:,1]
L = np.linalg.norm(X[ea]-X[eb],axis=1)
w = np.full(N*N, float(N*N)); w[0]=0; w[N-1]=0
keep = (w[ea]+w[eb])>0
ea,eb,L,struct = ea[keep],eb[keep],L[keep],struct[keep]
ne=len(ea); nv=N*N
g=np.array([0,-9.81,0.0]); dt=1.0/60/a.S
x=X.copy(); v=np.zeros_like(x)
lam_prev=np.zeros(ne)
def scatter_fast(y,n):
    yn=y[:,None]*n
    f=np.empty((nv,3))
    for k in range(3):
        f[:,k]=np.bincount(ea,yn[:,k],nv)-np.bincount(eb,yn[:,k],nv)
    return f
def Amul(y,n):
    u=w[:,None]*scatter_fast(y,n)
    return np.einsum('ij,ij->i', n, u[ea]-u[eb])
log=StrainLog(ea, eb, L, struct); matvecs=0
for fr in range(a.frames):
    for s in range(a.S):
        xo=x.copy()
        v[w>0]+=dt*g
        x=x+dt*v*(w[:,None]>0)
        total=np.zeros(ne)
        for it in range(a.newton):
            d=x[ea]-x[eb]; l=np.linalg.norm(d,axis=1); n=d/l[:,None]; C=l-L
            b=-C
            diag=w[ea]+w[eb]
            if it == 0 and a.warm != 0.0:
                y = a.warm*lam_prev
                r = b-Amul(y,n); matvecs += 1
            else:
                y = np.zeros(ne); r = b.copy()
            z=r/diag; pp=z.copy(); rz=r@z
            for k in range(a.cg):
                Ap=Amul(pp,n); matvecs+=1
                al=rz/(pp@Ap); y+=al*pp; r-=al*Ap
                z=r/diag; rz2=r@z; pp=z+(rz2/rz)*pp; rz=rz2
            x=x+w[:,None]*scatter_fast(y,n)
            total+=y
        lam_prev=total
        v=(x-xo)/dt
    if not log.frame(x, fr, a.trace):
        break
strain_max, strain_rms = log.means()
print(f"N={N} S={a.S} newton={a.newton} cg={a.cg} warm={a.warm}: max {strain_max:.3f}% rms {strain_rms:.4f}%  matvecs/frame {matvecs/len(log.rows):.0f} miny {x[:,1].min():.3f}")
