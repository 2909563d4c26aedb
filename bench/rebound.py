#!/usr/bin/env python3
"""How high a rigid body dropped on the ground bounces back, from a run's stats.csv.

usage: bench/rebound.py RUN_DIR [BODY] [REST_HEIGHT]

BODY defaults to `ball` and REST_HEIGHT (m, the height of its centre resting on the ground:
radius plus the collision thickness) to 0.115, those of bench/rigid_drop.toml. Reads the
body's centre height (`rigid.BODY.cy`) per frame; the first frame after which it rises again
is the impact, and the highest centre in the 40 frames after it is the apex. Prints the
lowest centre at the impact, the apex, and the rebound (apex above rest) as a share of the drop
(the first frame's centre above rest): 0 % for a dead landing, 100 % for an elastic one.
"""
import csv
import sys


def main():
    run = sys.argv[1]
    body = sys.argv[2] if len(sys.argv) > 2 else "ball"
    rest = float(sys.argv[3]) if len(sys.argv) > 3 else 0.115
    with open(f"{run}/stats.csv") as f:
        cy = [float(r[f"rigid.{body}.cy"]) for r in csv.DictReader(f)]
    impact = next((k for k in range(1, len(cy) - 1) if cy[k] < cy[k - 1] and cy[k + 1] > cy[k]), None)
    if impact is None:
        print(f"no rebound: the centre never rises again (last {cy[-1]:.4f} m)")
        return
    apex = max(cy[impact : impact + 40])
    drop = cy[0] - rest
    print(
        f"impact at frame {impact + 1}: centre {cy[impact]:.4f} m (rest {rest:.4f}); "
        f"apex {apex:.4f} m; rebound {100 * (apex - rest) / drop:.1f} % of the {drop:.3f} m drop; "
        f"last frame {cy[-1]:.4f} m"
    )


if __name__ == "__main__":
    main()
