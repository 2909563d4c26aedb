"""What the three drape experiments share: the peers' strain metrics, frame by frame."""
import numpy as np


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
