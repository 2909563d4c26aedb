"""What the drape experiments share: the scene's grid, the peers' strain metrics frame by frame,
and plain Gauss-Seidel (PBD) passes over the edges."""
import numpy as np


def drape_grid(N):
    """The peers' drape at N x N: vertex (i, j) at (j h, 0, i h), index i N + j, h = 1/(N - 1);
    edges row by row, each vertex's (i,j)-(i,j+1), (i,j)-(i+1,j), then the diagonal
    (i,j)-(i+1,j+1). Returns the positions X, the edges E (ne x 2) and `struct`, True for the
    grid-aligned (structural) edges."""
    h = 1.0 / (N - 1)
    X = np.array([(j * h, 0.0, i * h) for i in range(N) for j in range(N)])
    E, struct = [], []
    for i in range(N):
        for j in range(N):
            if j + 1 < N:
                E.append((i * N + j, i * N + j + 1))
                struct.append(True)
            if i + 1 < N:
                E.append((i * N + j, (i + 1) * N + j))
                struct.append(True)
            if i + 1 < N and j + 1 < N:
                E.append((i * N + j, (i + 1) * N + j + 1))
                struct.append(False)
    return X, np.array(E), np.array(struct)


def edge_colour_sets(E, nv):
    """Greedy colouring of the edges in order: the edges of one colour share no particle."""
    used = [set() for _ in range(nv)]
    colour = np.zeros(len(E), int)
    for e, (i, j) in enumerate(E):
        c = 0
        while c in used[i] or c in used[j]:
            c += 1
        colour[e] = c
        used[i].add(c)
        used[j].add(c)
    return [np.flatnonzero(colour == c) for c in range(colour.max() + 1)]


def pbd_passes(x, passes, colour_sets, E, rest, w):
    """`passes` hard PBD passes over the edges `E` (rest lengths `rest`, inverse masses `w`),
    colour by colour (a colour's edges at once). Moves `x` in place and returns it."""
    ea, eb = E[:, 0], E[:, 1]
    for _ in range(passes):
        for c in colour_sets:
            i, j = ea[c], eb[c]
            d = x[i] - x[j]
            l = np.linalg.norm(d, axis=1)
            wi, wj = w[i], w[j]
            s = (l - rest[c]) / np.maximum(wi + wj, 1e-300) / np.maximum(l, 1e-300)
            x[i] -= (wi * s)[:, None] * d
            x[j] += (wj * s)[:, None] * d
    return x


class StrainLog:
    """|l - L| / L over the structural edges (`struct`), per frame its max and RMS; `means()`
    averages them over the last 60 frames, as the peers' scripts do."""

    def __init__(self, ea, eb, rest, struct):
        self.ea, self.eb, self.rest, self.struct = ea, eb, rest, struct
        self.rows = []

    def frame(self, x, fr, trace=False):
        """Records frame `fr`; prints it every 10 frames with `trace`. Returns False (and says
        so) once the cloth has exploded: NaN, or farther than 100 m."""
        d = x[self.ea] - x[self.eb]
        strain = (np.abs(np.linalg.norm(d, axis=1) - self.rest) / self.rest)[self.struct]
        self.rows.append((strain.max(), np.sqrt((strain ** 2).mean())))
        if trace and fr % 10 == 0:
            print(fr, self.rows[-1], x[:, 1].min(), flush=True)
        if not np.isfinite(x).all() or np.abs(x).max() > 100:
            print("exploded at", fr)
            return False
        return True

    def means(self):
        """Mean max and mean RMS strain (%) over the last 60 frames recorded."""
        r = np.array(self.rows[-60:])
        return 100 * r[:, 0].mean(), 100 * r[:, 1].mean()
