//! The parameters of the `collision` kind, as written in a scene, their self-description
//! ([`CollisionParams::specs`]) and their validation. Every error names the parameter (and,
//! inside the tables, the object or the collider entry).

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use nucleus_sdk::serde_json::{self, Value};
use serde::Deserialize;

use crate::colliders::motion::{Key, Motion};
use crate::colliders::shapes::{Collider, Shape};

/// Default thickness (m): the collision radius of every vertex, edge and face.
pub const DEFAULT_THICKNESS: f64 = 0.005;

/// Default push-out speed (m/s): how fast a vertex, edge or face that starts a substep deeper
/// inside an analytic collider than its thickness is moved out ([`CollisionParams::push_out_speed`]).
pub const DEFAULT_PUSH_OUT_SPEED: f64 = 1.0;

/// Default collision layers: layer 0 only (bit 0), so that everything collides with
/// everything until a scene says otherwise.
pub const DEFAULT_LAYERS: u32 = 1;

/// The parameters of the `collision` kind.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionParams {
    /// Collision radius of every vertex, edge and face of the target objects (m, ≥ 0). Two
    /// simplices are kept `thickness_a + thickness_b` apart.
    pub thickness: f64,
    /// Whether each object also collides with itself. Default true.
    pub self_collision: bool,
    /// Elastic/inelastic blend of the normal velocity at an impact (0: inelastic, 1: elastic).
    pub restitution: f64,
    /// Static friction coefficient μs: contacts stick while `|tangential| ≤ μs·normal`.
    pub friction_static: f64,
    /// Dynamic friction coefficient μd: sliding contacts lose `μd·normal` of tangential motion.
    pub friction_dynamic: f64,
    /// Per-object overrides `{ name = { thickness, vertex, edge, face, self_collision } }`.
    pub objects_settings: Value,
    /// Analytic colliders (list of tables with a `type`).
    pub colliders: Value,
    /// Object pairs that never collide with each other: `[["a", "b"], ...]`.
    pub exclude: Value,
    /// Depenetration speed limit (m/s, > 0): a primitive that starts a substep deeper inside
    /// an analytic collider than its contact distance (a cloth placed through a collider, a
    /// collider keyed to jump into it) leaves it by at most `push_out_speed · h` a substep
    /// instead of all at once, so its neighbours follow without tearing (PhysX's
    /// `maxDepenetrationVelocity`, Maya's push-out). Once out, it keeps none of the outward
    /// speed the pushes gave it (it rests on the surface instead of flying on). Primitives
    /// that start outside are unaffected. Default 1 m/s.
    pub push_out_speed: f64,
    /// The most candidate pairs the group may hold in a substep before the substep fails with
    /// an error (0: automatic, 64 per primitive or 8 per pair within reach at rest, at least
    /// 2²⁰). Default 0.
    pub max_candidates: u64,
    /// Collision layers (a bitmask, bit `k` = layer `k`) of every target object and
    /// collider unless overridden (`objects_settings`, a collider's `layers`). Two objects,
    /// or an object and a collider, collide only if their masks share a bit. Default 1.
    pub layers: u32,
}

impl Default for CollisionParams {
    fn default() -> Self {
        Self {
            thickness: DEFAULT_THICKNESS,
            self_collision: true,
            restitution: 0.0,
            friction_static: 0.1,
            friction_dynamic: 0.1,
            objects_settings: Value::Object(Default::default()),
            colliders: Value::Array(Vec::new()),
            exclude: Value::Array(Vec::new()),
            push_out_speed: DEFAULT_PUSH_OUT_SPEED,
            max_candidates: 0,
            layers: DEFAULT_LAYERS,
        }
    }
}

/// Per-object collision settings after applying the overrides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectSettings {
    /// Collision radius (m).
    pub thickness: f64,
    /// Vertices collide (as spheres of radius `thickness`).
    pub vertex: bool,
    /// Edges collide (as cylinders of radius `thickness`).
    pub edge: bool,
    /// Faces collide (as slabs offset by `thickness`).
    pub face: bool,
    /// The object collides with itself.
    pub self_collision: bool,
    /// Collision layers (bitmask): collides with objects and colliders sharing a bit.
    pub layers: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectOverride {
    thickness: Option<f64>,
    vertex: Option<bool>,
    edge: Option<bool>,
    face: Option<bool>,
    self_collision: Option<bool>,
    layers: Option<Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ColliderSpec {
    #[serde(rename = "type")]
    ty: String,
    point: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
    center: Option<[f64; 3]>,
    radius: Option<f64>,
    half_extents: Option<[f64; 3]>,
    rotation: Option<[f64; 3]>,
    a: Option<[f64; 3]>,
    b: Option<[f64; 3]>,
    velocity: Option<[f64; 3]>,
    angular_velocity: Option<[f64; 3]>,
    keys: Option<Vec<KeySpec>>,
    pivot: Option<[f64; 3]>,
    thickness: Option<f64>,
    layers: Option<Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeySpec {
    time: f64,
    #[serde(default)]
    translate: [f64; 3],
    #[serde(default)]
    rotate: [f64; 3],
}

/// The largest coordinate or size (m) a collider may have: a 1,000 km sphere is still
/// accepted, while a radius of 1e308 (a scene fuzz mutant) overflowed the contact maths to
/// infinity, sent the cloth there, and made tens of millions of pairs before the substep
/// failed.
pub const MAX_COLLIDER_EXTENT: f64 = 1e6;

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

/// A layer bitmask from JSON: an integer in `[0, 2³² − 1]`.
fn layer_mask(v: &Value) -> Result<u32, String> {
    match v.as_u64() {
        Some(m) if m <= u64::from(u32::MAX) => Ok(m as u32),
        _ => Err(format!(
            "`layers` must be an integer bitmask in [0, {}] (bit k = layer k), found {v}",
            u32::MAX
        )),
    }
}

impl CollisionParams {
    /// The self-description of every parameter.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::number("thickness", d.thickness)
                .doc("collision radius of every vertex (sphere), edge (cylinder) and face (offset slab); two simplices are kept the sum of their thicknesses apart (Maya's nCloth thickness, in metres); a self-colliding object may be at most 4 times as thick as its mean edge length")
                .unit("m")
                .range(0.0, 1e3),
            ParamSpec::boolean("self_collision", d.self_collision)
                .doc("whether each object also collides with itself (per object: objects_settings)"),
            ParamSpec::number("restitution", d.restitution)
                .doc("bounce: 0 inelastic, 1 elastic; the normal velocity after an impact is -restitution x the one before")
                .range(0.0, 1.0),
            ParamSpec::number("friction_static", d.friction_static)
                .doc("static friction coefficient: a contact sticks while its tangential motion is at most this times its normal correction")
                .range(0.0, 1e3),
            ParamSpec::number("friction_dynamic", d.friction_dynamic)
                .doc("dynamic friction coefficient: a sliding contact loses this times its normal correction of tangential motion")
                .range(0.0, 1e3),
            ParamSpec::any("objects_settings", d.objects_settings)
                .doc("per-object overrides: { name = { thickness = m, vertex = bool, edge = bool, face = bool, self_collision = bool, layers = bitmask } }"),
            ParamSpec::any("colliders", d.colliders)
                .doc("analytic colliders: [{ type = \"plane\", point, normal } | { type = \"sphere\", center, radius } | { type = \"box\", center, half_extents, rotation (deg, xyz) } | { type = \"capsule\", a, b, radius }], each with optional velocity (m/s) and angular_velocity (rad/s) about its pivot (default its centre), or keys = [{ time, translate, rotate (axis-angle, rad) }] as in pin_motion, thickness (m) and layers (bitmask, default the group's layers)"),
            ParamSpec::any("exclude", d.exclude)
                .doc("object pairs that never collide with each other: [[\"a\", \"b\"], ...]"),
            ParamSpec::number("push_out_speed", d.push_out_speed)
                .doc("depenetration speed limit: a vertex, edge or face that starts a substep deeper inside an analytic collider than its thickness (a cloth placed through a collider) is moved out by at most this speed times the substep, so its neighbours follow without tearing, and once out keeps none of the speed the pushes gave it; primitives outside are unaffected (PhysX's maxDepenetrationVelocity, Maya's push-out)")
                .unit("m/s")
                .range(1e-6, 1e6),
            ParamSpec::integer("max_candidates", d.max_candidates as i64)
                .doc("the most candidate pairs the group may hold in a substep; more fails the substep with an error naming the object that moves too far (a typo in gravity or a velocity); 0 = automatic: 64 per collision primitive or 8 per pair within reach at rest, at least 2^20")
                .unit("pairs")
                .range(0.0, 1e12),
            ParamSpec::integer("layers", i64::from(d.layers))
                .doc("collision layers of every target object and collider, as a bitmask (bit k = layer k; 1 = layer 0, 6 = layers 1 and 2); two objects, or an object and a collider, collide only if their masks share a bit; per object: objects_settings, per collider: its own layers; 0 collides with nothing (an object's self_collision still applies)")
                .unit("bitmask")
                .range(0.0, f64::from(u32::MAX)),
        ]
    }

    /// Parses validated JSON parameters.
    pub fn parse(json: &str) -> Result<Self, PluginError> {
        let p: Self = params::parse(json)?;
        p.validate_numbers()?;
        Ok(p)
    }

    /// Checks the numbers against their ranges (parameters built in Rust skip the host's check).
    pub fn validate_numbers(&self) -> Result<(), PluginError> {
        let check = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v >= lo && v <= hi {
                Ok(())
            } else {
                Err(PluginError::bad_parameter(
                    name,
                    format!("{v} is outside the valid range [{lo}, {hi}]"),
                ))
            }
        };
        check("thickness", self.thickness, 0.0, 1e3)?;
        check("restitution", self.restitution, 0.0, 1.0)?;
        check("friction_static", self.friction_static, 0.0, 1e3)?;
        check("friction_dynamic", self.friction_dynamic, 0.0, 1e3)?;
        check("push_out_speed", self.push_out_speed, 1e-6, 1e6)
    }

    /// The settings of each object named in `names` (overrides applied). Unknown names in
    /// `objects_settings` are an error naming the parameter and the object.
    pub fn object_settings(&self, names: &[&str]) -> Result<Vec<ObjectSettings>, PluginError> {
        let base = ObjectSettings {
            thickness: self.thickness,
            vertex: true,
            edge: true,
            face: true,
            self_collision: self.self_collision,
            layers: self.layers,
        };
        let mut out = vec![base; names.len()];
        let table = match &self.objects_settings {
            Value::Null => return Ok(out),
            Value::Object(m) => m,
            other => {
                return Err(PluginError::bad_parameter(
                    "objects_settings",
                    format!("expected a table keyed by object name, found {other}"),
                ))
            }
        };
        for (name, value) in table {
            let Some(k) = names.iter().position(|n| n == name) else {
                return Err(PluginError::bad_parameter(
                    "objects_settings",
                    format!(
                        "`{name}` is not an object of this group (objects: {})",
                        names.join(", ")
                    ),
                ));
            };
            let o: ObjectOverride = serde_json::from_value(value.clone()).map_err(|e| {
                PluginError::bad_parameter("objects_settings", format!("`{name}`: {e}"))
            })?;
            let s = &mut out[k];
            if let Some(t) = o.thickness {
                if !(t.is_finite() && (0.0..=1e3).contains(&t)) {
                    return Err(PluginError::bad_parameter(
                        "objects_settings",
                        format!("`{name}`: thickness must be in [0, 1000] m, found {t}"),
                    ));
                }
                s.thickness = t;
            }
            s.vertex = o.vertex.unwrap_or(s.vertex);
            s.edge = o.edge.unwrap_or(s.edge);
            s.face = o.face.unwrap_or(s.face);
            s.self_collision = o.self_collision.unwrap_or(s.self_collision);
            if let Some(l) = &o.layers {
                s.layers = layer_mask(l).map_err(|e| {
                    PluginError::bad_parameter("objects_settings", format!("`{name}`: {e}"))
                })?;
            }
        }
        Ok(out)
    }

    /// The excluded object pairs, as indices into `names` (each pair sorted).
    pub fn excluded_pairs(&self, names: &[&str]) -> Result<Vec<[u32; 2]>, PluginError> {
        let list = match &self.exclude {
            Value::Null => return Ok(Vec::new()),
            Value::Array(a) => a,
            other => {
                return Err(PluginError::bad_parameter(
                    "exclude",
                    format!("expected a list of [\"a\", \"b\"] pairs, found {other}"),
                ))
            }
        };
        let mut out = Vec::new();
        for entry in list {
            let pair: [String; 2] = serde_json::from_value(entry.clone()).map_err(|_| {
                PluginError::bad_parameter(
                    "exclude",
                    format!("expected a pair of object names, found {entry}"),
                )
            })?;
            let mut ids = [0u32; 2];
            for (k, n) in pair.iter().enumerate() {
                ids[k] = names.iter().position(|m| m == n).ok_or_else(|| {
                    PluginError::bad_parameter(
                        "exclude",
                        format!("`{n}` is not an object of this group"),
                    )
                })? as u32;
            }
            ids.sort_unstable();
            out.push(ids);
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    /// The analytic colliders.
    pub fn colliders(&self) -> Result<Vec<Collider>, PluginError> {
        let list = match &self.colliders {
            Value::Null => return Ok(Vec::new()),
            Value::Array(a) => a,
            other => {
                return Err(PluginError::bad_parameter(
                    "colliders",
                    format!("expected a list of tables, found {other}"),
                ))
            }
        };
        list.iter()
            .enumerate()
            .map(|(i, v)| parse_collider(i, v, self.layers))
            .collect()
    }
}

fn parse_collider(i: usize, v: &Value, default_layers: u32) -> Result<Collider, PluginError> {
    let bad = |m: String| PluginError::bad_parameter("colliders", format!("colliders[{i}]: {m}"));
    let s: ColliderSpec = serde_json::from_value(v.clone()).map_err(|e| bad(e.to_string()))?;
    let too_far = |name: &str, v: f64| {
        bad(format!(
            "`{name}` has {v:e} m; a collider's coordinates and sizes must be within \
             {MAX_COLLIDER_EXTENT:e} m"
        ))
    };
    // A direction (the plane's normal): any finite length.
    let direction = |name: &str, v: Option<[f64; 3]>| -> Result<DVec3, PluginError> {
        match v {
            Some(v) if finite3(&v) => Ok(DVec3::from_array(v)),
            Some(_) => Err(bad(format!("`{name}` must be finite"))),
            None => Err(bad(format!("a {} needs `{name}`", s.ty))),
        }
    };
    // A position or a size: within the extent.
    let vec3 = |name: &str, v: Option<[f64; 3]>| -> Result<DVec3, PluginError> {
        let v = direction(name, v)?;
        match v.abs().max_element() {
            big if big > MAX_COLLIDER_EXTENT => Err(too_far(name, big)),
            _ => Ok(v),
        }
    };
    let positive = |name: &str, v: Option<f64>| -> Result<f64, PluginError> {
        match v {
            Some(r) if r > MAX_COLLIDER_EXTENT && r.is_finite() => Err(too_far(name, r)),
            Some(r) if r.is_finite() && r > 0.0 => Ok(r),
            Some(r) => Err(bad(format!("`{name}` must be positive, found {r}"))),
            None => Err(bad(format!("a {} needs `{name}`", s.ty))),
        }
    };
    let unused = |names: &[(&str, bool)]| -> Result<(), PluginError> {
        for (n, given) in names {
            if *given {
                return Err(bad(format!("a {} has no `{n}`", s.ty)));
            }
        }
        Ok(())
    };
    let (shape, pivot) = match s.ty.as_str() {
        "plane" => {
            unused(&[
                ("center", s.center.is_some()),
                ("radius", s.radius.is_some()),
                ("half_extents", s.half_extents.is_some()),
                ("rotation", s.rotation.is_some()),
                ("a", s.a.is_some()),
                ("b", s.b.is_some()),
            ])?;
            let point = vec3("point", s.point)?;
            let normal = direction("normal", s.normal)?;
            if normal.length() < 1e-12 {
                return Err(bad("`normal` must not be zero".into()));
            }
            (
                Shape::Plane {
                    point,
                    normal: normal.normalize(),
                },
                point,
            )
        }
        "sphere" => {
            unused(&[
                ("point", s.point.is_some()),
                ("normal", s.normal.is_some()),
                ("half_extents", s.half_extents.is_some()),
                ("rotation", s.rotation.is_some()),
                ("a", s.a.is_some()),
                ("b", s.b.is_some()),
            ])?;
            let center = vec3("center", s.center)?;
            let radius = positive("radius", s.radius)?;
            (Shape::Sphere { center, radius }, center)
        }
        "box" => {
            unused(&[
                ("point", s.point.is_some()),
                ("normal", s.normal.is_some()),
                ("radius", s.radius.is_some()),
                ("a", s.a.is_some()),
                ("b", s.b.is_some()),
            ])?;
            let center = vec3("center", s.center)?;
            let half = vec3("half_extents", s.half_extents)?;
            if half.min_element() <= 0.0 {
                return Err(bad("`half_extents` must be positive".into()));
            }
            let rot = match s.rotation {
                Some(r) if finite3(&r) => {
                    crate::colliders::motion::euler_xyz_degrees(DVec3::from_array(r))
                }
                Some(_) => return Err(bad("`rotation` must be finite".into())),
                None => glam::DQuat::IDENTITY,
            };
            (
                Shape::Box {
                    center,
                    half_extents: half,
                    rotation: rot,
                },
                center,
            )
        }
        "capsule" => {
            unused(&[
                ("point", s.point.is_some()),
                ("normal", s.normal.is_some()),
                ("center", s.center.is_some()),
                ("half_extents", s.half_extents.is_some()),
                ("rotation", s.rotation.is_some()),
            ])?;
            let a = vec3("a", s.a)?;
            let b = vec3("b", s.b)?;
            let radius = positive("radius", s.radius)?;
            (Shape::Capsule { a, b, radius }, 0.5 * (a + b))
        }
        other => {
            return Err(bad(format!(
                "unknown type `{other}` (plane, sphere, box, capsule)"
            )))
        }
    };
    let pivot = match s.pivot {
        Some(p) => vec3("pivot", Some(p))?,
        None => pivot,
    };
    let moving = s.velocity.is_some() || s.angular_velocity.is_some();
    let motion = match (&s.keys, moving) {
        (Some(_), true) => {
            return Err(bad(
                "give either velocity/angular_velocity or keys, not both".into(),
            ))
        }
        (Some(keys), false) => {
            if keys.is_empty() {
                return Err(bad("`keys` must not be empty".into()));
            }
            let mut out = Vec::with_capacity(keys.len());
            for k in keys {
                if !(k.time.is_finite() && finite3(&k.translate) && finite3(&k.rotate)) {
                    return Err(bad(
                        "every key needs a finite time, translate and rotate".into()
                    ));
                }
                if out.last().is_some_and(|l: &Key| l.time >= k.time) {
                    return Err(bad("key times must increase".into()));
                }
                out.push(Key {
                    time: k.time,
                    translate: DVec3::from_array(k.translate),
                    rotate: DVec3::from_array(k.rotate),
                });
            }
            Motion::Keys { pivot, keys: out }
        }
        (None, true) => {
            let v = s.velocity.unwrap_or([0.0; 3]);
            let w = s.angular_velocity.unwrap_or([0.0; 3]);
            if !(finite3(&v) && finite3(&w)) {
                return Err(bad("velocity and angular_velocity must be finite".into()));
            }
            Motion::Constant {
                pivot,
                velocity: DVec3::from_array(v),
                angular_velocity: DVec3::from_array(w),
            }
        }
        (None, false) => Motion::Static,
    };
    let thickness = match s.thickness {
        Some(t) if t.is_finite() && t >= 0.0 => t,
        Some(t) => return Err(bad(format!("`thickness` must be >= 0, found {t}"))),
        None => 0.0,
    };
    let layers = match &s.layers {
        Some(l) => layer_mask(l).map_err(bad)?,
        None => default_layers,
    };
    Ok(Collider {
        shape,
        motion,
        thickness,
        layers,
    })
}
