"""Our scene TOML, read into the plain facts a second solver needs to build the same scene.

`load_spec(path, sets)` reads one of our cloth scenes (a single grid object, `stretch` and
optionally `collision` constraints) and returns a `Spec`: the grid's rest positions and
triangles exactly as `core/src/shapes.rs` builds them (vertex (i, j) at index i*nu + j, each
quad split along the (i, j)-(i+1, j+1) diagonal), per-vertex mass, pinned vertices, initial
velocity, gravity, damping, frames, substeps, and the collision parameters. `sets` are our
`--set KEY=VALUE` overrides (a subset: dotted keys, TOML values), applied to the parsed
table so both solvers see the same change. Anything this reader does not map (another
constraint kind, a mesh object, a box collider) is an error naming the scene, not a silent
mismatch.
"""

import dataclasses
import tomllib

import numpy as np

# The collision plugin's defaults (plugins/collision/src/params.rs), for keys a scene omits.
COLLISION_DEFAULTS = {"thickness": 0.005, "friction_static": 0.1, "friction_dynamic": 0.1,
                      "self_collision": True}
# Kinds that hold every mesh edge at its rest length with `compliance` and
# `compression_compliance` (m/N): they differ in how they solve it, not in the model.
STRETCH_KINDS = ("stretch", "stretch_newton")
PLANES = {"xz": ((1, 0, 0), (0, 0, 1)), "xy": ((1, 0, 0), (0, 1, 0)),
          "yz": ((0, 1, 0), (0, 0, 1))}


@dataclasses.dataclass
class Collider:
    kind: str          # "sphere" or "plane"
    center: tuple      # sphere centre, or a point of the plane (m)
    radius: float      # sphere radius (m); 0 for a plane
    normal: tuple      # plane normal (unit); None for a sphere
    thickness: float   # the collider's own thickness (m)


@dataclasses.dataclass
class Spec:
    name: str
    positions: np.ndarray   # (n, 3) rest positions (m)
    triangles: np.ndarray   # (t, 3) vertex indices
    grid: tuple             # (nu, nv)
    vertex_mass: float      # kg per vertex (the object's mass spread evenly)
    pins: list              # pinned vertex indices
    velocity: tuple         # initial velocity (m/s)
    gravity: tuple          # (m/s^2)
    damping: float          # velocity damping (1/s): v *= exp(-damping h) a substep
    frame_rate: float
    frames: int
    substeps: int
    compliance: float       # stretch compliance when stretched (m/N), 0 = hard
    compression_compliance: float
    collision: bool
    thickness: float = 0.0  # the cloth's collision thickness r (m); 2r within the cloth
    self_collision: bool = False
    friction_static: float = 0.0
    friction_dynamic: float = 0.0
    colliders: list = dataclasses.field(default_factory=list)

    @property
    def n(self):
        return len(self.positions)


class SpecError(Exception):
    """A scene this reader cannot map faithfully."""


def apply_set(table, assignment):
    """One `--set a.0.b=VALUE` override on the parsed TOML table (VALUE is a TOML value)."""
    key, _, value = assignment.partition("=")
    parsed = tomllib.loads(f"v = {value}")["v"]
    *path, last = key.strip().split(".")
    node = table
    for part in path:
        node = node[int(part)] if isinstance(node, list) else node[part]
    if isinstance(node, list):
        node[int(last)] = parsed
    else:
        node[last] = parsed


def grid_geometry(grid):
    """Rest positions and triangles of a grid, as core/src/shapes.rs::grid builds them."""
    nu, nv = grid["resolution"]
    u, v = (np.array(a, float) for a in PLANES[grid.get("plane", "xz")])
    du, dv = grid["size"][0] / (nu - 1), grid["size"][1] / (nv - 1)
    i, j = np.meshgrid(np.arange(nv), np.arange(nu), indexing="ij")
    origin = np.array(grid.get("origin", [0.0, 0.0, 0.0]), float)
    pos = origin + (j.reshape(-1, 1) * du) * u + (i.reshape(-1, 1) * dv) * v
    a = (np.arange(nv - 1)[:, None] * nu + np.arange(nu - 1)[None, :]).ravel()
    b, c = a + 1, a + nu
    d = c + 1
    tris = np.empty((2 * len(a), 3), dtype=np.int64)
    tris[0::2] = np.stack([a, b, d], 1)
    tris[1::2] = np.stack([a, d, c], 1)
    return pos, tris, (nu, nv)


def select_pins(selectors, grid, n, where):
    """Vertex indices of pin selectors: indices, corners:/edge: of a row/col, all, boxes."""
    nu, nv = grid
    lines = {"row0": [j for j in range(nu)], "rowN": [(nv - 1) * nu + j for j in range(nu)],
             "col0": [i * nu for i in range(nv)], "colN": [i * nu + nu - 1 for i in range(nv)]}
    out = []
    for s in selectors:
        if isinstance(s, int):
            out.append(s)
        elif s == "all":
            out.extend(range(n))
        elif isinstance(s, str) and ":" in s and s.split(":")[1] in lines:
            kind, edge = s.split(":")
            line = lines[edge]
            out.extend(line if kind == "edge" else [line[0], line[-1]])
        else:
            raise SpecError(f"{where}: pin selector {s!r} is not mapped by this benchmark")
    return sorted(set(out))


def read_collision(params, where):
    """The collision group's thickness, friction, self-collision flag and colliders."""
    p = dict(COLLISION_DEFAULTS, **params)
    unknown = set(p) - set(COLLISION_DEFAULTS) - {"colliders", "objects_settings"}
    if unknown:
        raise SpecError(f"{where}: collision parameters {sorted(unknown)} are not mapped")
    for settings in p.get("objects_settings", {}).values():
        if "thickness" in settings:
            p["thickness"] = settings["thickness"]
        if "self_collision" in settings:
            p["self_collision"] = settings["self_collision"]
    colliders = []
    for c in p.get("colliders", []):
        if c["type"] == "sphere":
            colliders.append(Collider("sphere", tuple(c["center"]), c["radius"], None,
                                      c.get("thickness", 0.0)))
        elif c["type"] == "plane":
            nrm = np.array(c["normal"], float)
            colliders.append(Collider("plane", tuple(c["point"]), 0.0,
                                      tuple(nrm / np.linalg.norm(nrm)), c.get("thickness", 0.0)))
        else:
            raise SpecError(f"{where}: collider type {c['type']!r} is not mapped")
        if any(k in c for k in ("velocity", "angular_velocity", "keys")):
            raise SpecError(f"{where}: moving colliders are not mapped")
    return p, colliders


def load_spec(path, sets=()):
    """The Spec of the scene file at `path`, after the `--set` overrides `sets`."""
    with open(path, "rb") as f:
        table = tomllib.load(f)
    for s in sets:
        apply_set(table, s)
    objects = table.get("objects", [])
    if len(objects) != 1 or "grid" not in objects[0]:
        raise SpecError(f"{path}: one grid object expected")
    obj = objects[0]
    if "mass" not in obj or any(k in obj for k in ("density", "vertex_mass", "mass_map")):
        raise SpecError(f"{path}: only a total `mass` spread evenly is mapped")
    pos, tris, grid = grid_geometry(obj["grid"])
    solver = table.get("solver", {})
    kinds = {c["kind"]: c.get("params", {}) for c in table.get("constraints", [])}
    stretch_kinds = [k for k in kinds if k in STRETCH_KINDS]
    if set(kinds) - set(STRETCH_KINDS) - {"collision"} or len(stretch_kinds) != 1:
        raise SpecError(f"{path}: constraint kinds {sorted(kinds)}: one stretch kind "
                        f"({', '.join(STRETCH_KINDS)}) and optionally collision are mapped")
    stretch = kinds[stretch_kinds[0]]
    spec = Spec(
        name=str(path).rsplit("/", 1)[-1].removesuffix(".toml"),
        positions=pos, triangles=tris, grid=grid,
        vertex_mass=obj["mass"] / len(pos),
        pins=select_pins(obj.get("pins", []), grid, len(pos), path),
        velocity=tuple(obj.get("velocity", (0.0, 0.0, 0.0))),
        gravity=tuple(solver.get("gravity", (0.0, -9.81, 0.0))),
        damping=solver.get("damping", 0.0),
        frame_rate=solver.get("frame_rate", 60.0),
        frames=solver.get("frames", 120),
        substeps=solver.get("substeps", 10),
        compliance=stretch.get("compliance", 0.0),
        compression_compliance=stretch.get("compression_compliance", 0.0),
        collision="collision" in kinds,
    )
    if spec.collision:
        p, spec.colliders = read_collision(kinds["collision"], path)
        spec.thickness = p["thickness"]
        spec.self_collision = bool(p["self_collision"])
        spec.friction_static = p["friction_static"]
        spec.friction_dynamic = p["friction_dynamic"]
    return spec
