#!/usr/bin/env python3
"""Run one of our cloth scenes in Blender's cloth solver (bpy) and write its frames as ours does.

usage: blender_run.py SCENE --out DIR [--set KEY=VALUE ...] [--threads 1] [--tension T] ...

Run with the benchmark's virtual environment (bench/blender/blender.sh makes it: bpy + numpy).
Builds SCENE (our TOML, read by scene_spec.py) in an empty Blender scene, steps it frame by
frame, and writes DIR/frame_NNNN.obj (the `v` lines in our vertex order and our y-up axes;
frame 0 is the initial state), DIR/stats.csv (frame, wall_s = the wall time of that frame's
`scene.frame_set`, cpu_s = the process CPU time of it, and the CG's convergence) and
DIR/run.json (every Blender setting used). Only the frame step is timed; reading the
evaluated mesh and writing the files happen outside it.

How our scene maps onto Blender (bench/blender/README.md gives the reasons and measurements):

* axes: ours are y-up, Blender's z-up: (x, y, z) -> (x, -z, y), a rotation.
* time: Blender's cloth advances `time_scale` time units a frame and scales gravity by 1e-3,
  so one unit is 1/sqrt(1000) s; `time_scale = sqrt(1000) / frame_rate` makes a frame last
  1/frame_rate s for gravity, springs and drag alike (the scene's fps is not read at all).
* mass: Blender's `mass` is per vertex (kg). Its forces (springs, damping) are not divided by
  the mass, so only their ratio to it matters; its defaults are made for about 0.3 kg a
  vertex, and its float32 CG stalls (the cloth hangs) at our 1e-4 kg with any stiffness that
  holds the cloth. So Blender runs at `--mass` (default its 0.3 kg) a vertex, and everything
  that depends on mass is expressed in that unit: the air drag and a compliant stretch.
* stretch: a hard edge (compliance 0) gets `--tension` (the stiffest at which the drape still
  falls as the inextensible reference does, see the README); a compliant one k = 1/compliance.
* collisions: cloth `distance_min` + the collider's `thickness_outer` = our thickness r (+ the
  collider's); `self_distance_min` = r (Blender keeps 2 x that apart, as we keep 2r);
  friction = 100 x our dynamic coefficient (Blender's friction impulse is 0.01 x it x the
  normal one). The sphere is an icosphere enlarged so that its faces lie on or outside the
  analytic sphere; the plane a 4 m square.
* an initial velocity (cloth_heap) has no Blender setting: a pre-roll of `--preroll` frames
  under a gravity along the velocity, from a start moved back by the distance it covers, hands
  Blender the cloth at our start with our velocity (the free fall of an unstretched cloth is
  exact in its solver).
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene_spec import load_spec  # noqa: E402

# Blender time units per second: its cloth gravity is scene gravity x 1e-3 per unit^2.
ALPHA = math.sqrt(1000.0)
# The collider's `thickness_outer` can be no smaller.
MIN_OUTER = 0.001


def to_blender(p):
    """Our y-up coordinates (n, 3) to Blender's z-up ones."""
    p = np.asarray(p, float).reshape(-1, 3)
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], 1)


def from_blender(b):
    """Blender's z-up coordinates (n, 3) back to our y-up ones."""
    b = np.asarray(b, float).reshape(-1, 3)
    return np.stack([b[:, 0], b[:, 2], -b[:, 1]], 1)


def limit_threads(n):
    """Make Blender's task scheduler (TBB) start with n workers: it sizes itself from the
    process's CPU affinity when bpy is imported. The affinity is restored afterwards, so the
    n threads may run on any core, as ours do."""
    allowed = os.sched_getaffinity(0)
    os.sched_setaffinity(0, set(sorted(allowed)[:n]))
    import bpy  # noqa: F401  (initialises the scheduler with n workers)
    os.sched_setaffinity(0, allowed)


def preroll(spec, frames, quality):
    """Gravity along the initial velocity that brings a cloth at rest to that velocity in
    `frames` frames of Blender's implicit Euler with drag, and the displacement meanwhile:
    (gravity, displacement), both our axes."""
    v0 = np.array(spec.velocity, float)
    dt = 1.0 / (spec.frame_rate * quality)
    q = 1.0 / (1.0 + spec.damping * dt)
    speed, disp = 0.0, 0.0     # for a unit gravity
    for _ in range(frames * quality):
        speed = (speed + dt) * q
        disp += dt * speed
    g = v0 / speed
    return g, g * disp


def mean_edge_length(spec):
    t = spec.triangles
    e = np.unique(np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [0, 2]]]), 1), axis=0)
    return float(np.linalg.norm(spec.positions[e[:, 0]] - spec.positions[e[:, 1]], axis=1).mean())


def stiffness(compliance, hard, mass_scale, avg_len):
    """Blender's tension/compression stiffness for our compliance (m/N): the spring
    k = 1/compliance in Blender's mass unit and time unit (it divides by the mean spring
    length), at most `hard`, the stiffest it solves (also for compliance 0)."""
    if compliance == 0.0:
        return hard
    return min(hard, (1.0 / compliance) * mass_scale * avg_len / ALPHA**2)


def clear_scene(bpy):
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)


def add_mesh(bpy, name, verts, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def sphere_mesh(center, radius, subdivisions):
    """An icosphere whose faces all lie at or outside `radius` (its vertices a little beyond)."""
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=1.0)
    verts = np.array([v.co[:] for v in bm.verts])
    faces = [[v.index for v in f.verts] for f in bm.faces]
    bm.free()
    inner = min(np.linalg.norm(verts[f].mean(0)) for f in faces)
    return verts * (radius / inner) + np.asarray(center), faces


def plane_mesh(point, normal, half=2.0, cells=16):
    """A square of side 2*half through `point`, perpendicular to `normal` (Blender axes)."""
    n = np.asarray(normal, float)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    s = np.linspace(-half, half, cells + 1)
    verts = [np.asarray(point) + a * u + b * v for b in s for a in s]
    faces = [[i * (cells + 1) + j, i * (cells + 1) + j + 1, (i + 1) * (cells + 1) + j + 1,
              (i + 1) * (cells + 1) + j] for i in range(cells) for j in range(cells)]
    return verts, faces


def add_collider(bpy, c, friction, subdivisions):
    """A static collision object for our analytic collider `c`."""
    center = to_blender([c.center])[0]
    if c.kind == "sphere":
        verts, faces = sphere_mesh(center, c.radius, subdivisions)
    else:
        verts, faces = plane_mesh(center, to_blender([c.normal])[0])
    obj = add_mesh(bpy, c.kind, verts, faces)
    obj.modifiers.new("Collision", "COLLISION")
    obj.collision.thickness_outer = MIN_OUTER
    obj.collision.cloth_friction = friction
    return obj


def configure_cloth(mod, spec, a, frames):
    """The cloth modifier's settings for `spec`; returns them as a dict for run.json."""
    s, cc = mod.settings, mod.collision_settings
    mass_scale = a.mass / spec.vertex_mass
    avg = mean_edge_length(spec)
    s.quality = a.quality
    s.time_scale = ALPHA / spec.frame_rate
    s.mass = a.mass
    s.tension_stiffness = stiffness(spec.compliance, a.tension, mass_scale, avg)
    s.compression_stiffness = stiffness(spec.compression_compliance, a.tension, mass_scale, avg)
    s.air_damping = 100.0 * spec.damping * a.mass / ALPHA
    if a.bending is not None:
        s.bending_stiffness = a.bending
    if a.spring_damping is not None:
        s.tension_damping = s.compression_damping = s.shear_damping = a.spring_damping
    s.vertex_group_mass = "pin" if spec.pins else ""
    mu = 100.0 * spec.friction_dynamic
    cc.use_collision = bool(spec.colliders)
    cc.distance_min = max(MIN_OUTER, spec.thickness - MIN_OUTER) if spec.collision else 0.015
    cc.use_self_collision = spec.self_collision
    if spec.self_collision:
        cc.self_distance_min = spec.thickness
        cc.self_friction = mu
    mod.point_cache.frame_start = 1
    mod.point_cache.frame_end = frames + 1
    keys = ["quality", "time_scale", "mass", "tension_stiffness", "compression_stiffness",
            "shear_stiffness", "bending_model", "bending_stiffness", "tension_damping",
            "compression_damping", "bending_damping", "air_damping"]
    out = {k: getattr(s, k) for k in keys}
    out.update({f"collision.{k}": getattr(cc, k) for k in
                ["use_collision", "distance_min", "collision_quality", "use_self_collision",
                 "self_distance_min", "self_friction"]})
    out["collider.cloth_friction"] = mu
    out["collider.thickness_outer"] = MIN_OUTER
    return out


def key_gravity(scene, frame_gravity):
    """Scene gravity keyed at frames {frame: (x, y, z)}. The cloth reads it once a frame, at
    whole frames only, so keying every frame where it changes or holds makes the curve's
    interpolation irrelevant."""
    for frame, g in sorted(frame_gravity.items()):
        scene.gravity = tuple(g)
        scene.keyframe_insert("gravity", frame=frame)


def build(bpy, spec, a):
    """The Blender scene for `spec`: (scene, cloth object, settings dict, pre-roll frames)."""
    clear_scene(bpy)
    scene = bpy.context.scene
    moving = any(spec.velocity)
    pre = a.preroll if moving else 0
    start = spec.positions
    if moving:
        g_pre, disp = preroll(spec, pre, a.quality)
        start = spec.positions - disp
        keys = {f: to_blender([g_pre])[0] for f in range(1, pre + 2)}
        keys.update({f: to_blender([spec.gravity])[0] for f in (pre + 2, spec.frames + pre + 1)})
        key_gravity(scene, keys)
    else:
        scene.gravity = tuple(to_blender([spec.gravity])[0])
    scene.use_gravity = True
    frames = spec.frames + pre
    scene.frame_start, scene.frame_end = 1, frames + 1
    cloth = add_mesh(bpy, "cloth", to_blender(start), spec.triangles)
    if spec.pins:
        cloth.vertex_groups.new(name="pin").add(spec.pins, 1.0, "REPLACE")
    mod = cloth.modifiers.new("Cloth", "CLOTH")
    settings = configure_cloth(mod, spec, a, frames)
    for c in spec.colliders:
        add_collider(bpy, c, settings["collider.cloth_friction"], a.sphere_subdivisions)
    settings["preroll_frames"] = pre
    return scene, cloth, settings, pre


def positions(bpy, cloth):
    """The evaluated cloth's vertex positions now, our axes (n, 3)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = cloth.evaluated_get(depsgraph).data
    buf = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", buf)
    return from_blender(buf)


def solver_state(bpy, cloth):
    """(converged, max CG iterations) of the last frame's solves."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    r = cloth.evaluated_get(depsgraph).modifiers["Cloth"].solver_result
    return int("NO_CONVERGENCE" not in r.status), int(r.max_iterations)


def simulate(bpy, scene, cloth, spec, pre):
    """Step every frame; only `frame_set` is timed. Returns (frames, rows): frames[k] is the
    state after k of our frames, rows one per frame 1..F."""
    scene.frame_set(1)
    for f in range(2, pre + 2):                 # the pre-roll: not ours, not timed
        scene.frame_set(f)
    frames, rows = [positions(bpy, cloth)], []
    for k in range(1, spec.frames + 1):
        w0, c0 = time.perf_counter(), time.process_time()
        scene.frame_set(pre + 1 + k)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        frames.append(positions(bpy, cloth))
        converged, iterations = solver_state(bpy, cloth)
        rows.append((k, wall, cpu, converged, iterations))
    return frames, rows


def write_output(out, spec, frames, rows, info):
    os.makedirs(out, exist_ok=True)
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in spec.triangles)
    for k, p in enumerate(frames):
        with open(os.path.join(out, f"frame_{k:04d}.obj"), "w") as f:
            f.write(f"# Blender cloth frame {k}\n")
            f.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in p.tolist()))
            f.write(faces)
    with open(os.path.join(out, "stats.csv"), "w") as f:
        f.write("frame,wall_s,cpu_s,cg_converged,cg_iterations_max\n")
        for r in rows:
            f.write(",".join(str(x) for x in r) + "\n")
    with open(os.path.join(out, "run.json"), "w") as f:
        json.dump(info, f, indent=1)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("--out", required=True)
    p.add_argument("--set", action="append", default=[], help="our --set KEY=VALUE overrides")
    p.add_argument("--frames", type=int, help="override the scene's frame count")
    p.add_argument("--threads", type=int, default=1, help="Blender's worker threads")
    p.add_argument("--quality", type=int, default=5, help="Blender's steps a frame (default 5)")
    p.add_argument("--mass", type=float, default=0.3, help="Blender's mass a vertex (kg)")
    p.add_argument("--tension", type=float, default=400.0,
                   help="tension/compression stiffness of a hard edge (default 400)")
    p.add_argument("--bending", type=float,
                   help="bending stiffness (default: Blender's, 0.5; our scenes have no bend)")
    p.add_argument("--spring-damping", type=float,
                   help="tension, compression and shear damping (default: Blender's, 5)")
    p.add_argument("--preroll", type=int, default=6,
                   help="frames of pre-roll that give the cloth its initial velocity")
    p.add_argument("--sphere-subdivisions", type=int, default=5,
                   help="of the icosphere standing for a sphere (5: 5120 faces, its "
                   "vertices 0.34 mm outside it at r = 0.3 m)")
    return p.parse_args(argv)


def main(argv=None):
    a = parse_args(argv)
    limit_threads(a.threads)
    import bpy
    spec = load_spec(a.scene, a.set)
    if a.frames is not None:
        spec.frames = a.frames
    scene, cloth, settings, pre = build(bpy, spec, a)
    frames, rows = simulate(bpy, scene, cloth, spec, pre)
    info = {"solver": "blender", "blender": bpy.app.version_string, "scene": a.scene,
            "set": a.set, "threads": a.threads, "frames": spec.frames, "settings": settings}
    write_output(a.out, spec, frames, rows, info)
    print(json.dumps({"out": a.out, "wall_per_frame_s": sum(r[1] for r in rows) / len(rows)}))


if __name__ == "__main__":
    main()
