"""Generates the collision scenes' data: the twisted strip's OBJ sequence and the rubber band.

cloth_twist/twist_NNNN.obj: a 1 m x 0.4 m strip along x (20 x 8 vertices, horizontal), whose
two short edges (x = 0 and x = 1) are pinned and turn about the strip's axis in opposite
directions, half a turn per second each (one full relative turn per second), while they
approach each other by 0.1 m per second, for 2 s at 60 frames per second. Only the pinned
vertices follow the sequence; the others keep the frame-0 positions as rest shape.

rubber_band.obj: a closed strip (2 x 96 vertices, 2 cm wide) around a stadium enclosing two bars
of radius 0.02 m along z at x = -0.15 and x = +0.15, 0.005 m off their surfaces.

Run from this directory: python3 make_data.py
"""
import math

NU, NV = 20, 8
LENGTH, WIDTH = 1.0, 0.4
FPS, SECONDS = 60, 2.0


def twist_frame(t):
    verts = []
    for i in range(NV):
        for j in range(NU):
            x = LENGTH * j / (NU - 1)
            z = WIDTH * i / (NV - 1) - WIDTH / 2
            y = 0.5
            if j == 0 or j == NU - 1:
                sign = -1.0 if j == 0 else 1.0
                angle = sign * math.pi * t  # half a turn per second each
                # Turn about the axis (y = 0.5, z = 0) and approach the middle.
                zz = z * math.cos(angle)
                yy = 0.5 + z * math.sin(angle)
                x = x - sign * 0.05 * t
                verts.append((x, yy, zz))
            else:
                verts.append((x, y, z))
    return verts


def faces():
    out = []
    for i in range(NV - 1):
        for j in range(NU - 1):
            a = i * NU + j + 1
            b = a + 1
            c = a + NU
            d = c + 1
            out.append((a, b, d))
            out.append((a, d, c))
    return out


def write_obj(path, verts, fs):
    with open(path, "w") as f:
        for v in verts:
            f.write("v %.17g %.17g %.17g\n" % v)
        for t in fs:
            f.write("f %d %d %d\n" % t)


fs = faces()
for frame in range(int(FPS * SECONDS) + 1):
    write_obj("cloth_twist/twist_%04d.obj" % frame, twist_frame(frame / FPS), fs)

# The rubber band: a closed strip 2 cm wide (two rings of N vertices at z = -0.01 and +0.01,
# joined by triangles) around a stadium (two half circles joined by straight runs). A strip
# rather than an `l` loop: the core's OBJ reader (through tobj) triangulates `l` lines.
R, GAP, N = 0.02 + 0.005, 0.15, 96
straight = 2 * GAP
arc = math.pi * R
perimeter = 2 * straight + 2 * arc
pts = []
for k in range(N):
    s = perimeter * k / N
    if s < straight:  # bottom run, left to right
        pts.append((-GAP + s, -R))
    elif s < straight + arc:  # right half circle
        a = -math.pi / 2 + (s - straight) / R
        pts.append((GAP + R * math.cos(a), R * math.sin(a)))
    elif s < 2 * straight + arc:  # top run, right to left
        pts.append((GAP - (s - straight - arc), R))
    else:  # left half circle
        a = math.pi / 2 + (s - 2 * straight - arc) / R
        pts.append((-GAP + R * math.cos(a), R * math.sin(a)))
verts = [(x, y, -0.01) for x, y in pts] + [(x, y, 0.01) for x, y in pts]
band_faces = []
for k in range(N):
    a, b = k + 1, (k + 1) % N + 1
    band_faces.append((a, b, b + N))
    band_faces.append((a, b + N, a + N))
write_obj("rubber_band.obj", verts, band_faces)
