#!/usr/bin/env python3
"""What one iteration of the AMG-preconditioned CG of `primal.py --amg` costs on the N x N
drape: the primal Hessian's product (3 x 3 block sparse, scipy BSR), one smoothed-aggregation
V-cycle and the hierarchy's setup (pyamg), on one thread, best of 5 repeats. The Hessian is
taken at the flat cloth with a tiny random perturbation and rest lengths 0.1 % short (so every
edge is in tension and the geometric term is present): its sparsity and the hierarchy's size
are those of the hanging cloth's. numpy + scipy + pyamg. See README.md.

usage: OMP_NUM_THREADS=1 amg_cost.py N
"""
import sys, time, numpy as np, scipy.sparse as sp, pyamg
N = int(sys.argv[1])
h = 1.0/(N-1)
X = np.array([(j*h, 0.0, i*h) for i in range(N) for j in range(N)])
rng = np.random.default_rng(1)
x = X + 1e-3*h*rng.standard_normal(X.shape)
E=[]
for i in range(N):
    for j in range(N):
        if j+1<N: E.append((i*N+j,i*N+j+1))
        if i+1<N: E.append((i*N+j,(i+1)*N+j))
        if i+1<N and j+1<N: E.append((i*N+j,(i+1)*N+j+1))
E=np.array(E); ea,eb=E[:,0],E[:,1]
L=np.linalg.norm(X[ea]-X[eb],axis=1)*(1-1e-3)
nv=N*N; k=1e8; m=1.0/nv; dt=1/60
d=x[ea]-x[eb]; l=np.linalg.norm(d,axis=1); n=d/l[:,None]
nn=n[:,:,None]*n[:,None,:]
K=k*(nn+np.maximum(0,1-L/l)[:,None,None]*(np.eye(3)[None]-nn))
bi=np.concatenate([ea,eb,ea,eb]); bj=np.concatenate([ea,eb,eb,ea])
rr=(3*bi[:,None,None]+np.arange(3)[None,:,None]).repeat(3,axis=2).ravel()
cc=(3*bj[:,None,None]+np.arange(3)[None,None,:]).repeat(3,axis=1).ravel()
H=sp.csr_matrix((np.concatenate([K,K,-K,-K]).ravel(),(rr,cc)),shape=(3*nv,3*nv))+sp.diags(np.full(3*nv,m/dt/dt))
free=np.ones(nv,bool); free[0]=free[N-1]=False
fd=np.flatnonzero(np.repeat(free,3))
Hf=H[fd][:,fd].tocsr()
B=sp.bsr_matrix(Hf,blocksize=(3,3))
v=rng.standard_normal(Hf.shape[0])
def t(f,r=50):
    best=1e9
    for _ in range(5):
        t0=time.perf_counter()
        for _ in range(r): f()
        best=min(best,(time.perf_counter()-t0)/r)
    return best
tm=t(lambda: B@v)
c=x[free]-x[free].mean(0); b=np.zeros((free.sum(),3,6))
for a in range(3): b[:,a,a]=1
b[:,0,3],b[:,1,3]=-c[:,1],c[:,0]; b[:,1,4],b[:,2,4]=-c[:,2],c[:,1]; b[:,0,5],b[:,2,5]=c[:,2],-c[:,0]
t0=time.perf_counter()
ml=pyamg.smoothed_aggregation_solver(Hf,B=b.reshape(-1,6),strength=("symmetric",{"theta":0.0}),max_coarse=200)
ts=time.perf_counter()-t0
M=ml.aspreconditioner(cycle='V')
tv=t(lambda: M@v,10)
print(f"N={N}: {Hf.shape[0]} unknowns, {Hf.nnz} nnz; BSR matvec {tm*1e3:.3f} ms, V-cycle {tv*1e3:.2f} ms, AMG setup {ts*1e3:.0f} ms, op complexity {ml.operator_complexity():.2f}")
