//! The `rigid` group: every rigid body of the scene as one SoA batch (their particles, rest
//! positions and masses concatenated, body by body), each body shape-matched in turn by one
//! `project` call.

use glam::{DQuat, DVec3};
use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use nucleus_sdk::serde_json::{self, Value};
use serde::{Deserialize, Serialize};

use crate::matching::{
    answer_pushes, answer_pushes_about, classify_pins, fit_frame, goal_distances, mass_properties,
    pivot_properties, project_goals, rigidify_velocities, Anchor, BodyRef, Frame, Push, PushWork,
};

/// The parameters of the `rigid` kind, as written in a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidParams {
    /// Compliance of the shape match (s², ≥ 0): each particle is held to its goal by a spring
    /// of stiffness `mᵢ/α`, so a deformation springs back with angular frequency `1/√α`.
    /// Default 0: perfectly rigid.
    pub compliance: f64,
    /// Angular velocity (rad/s) given to every body at the first substep of the run, about
    /// its centre of mass (about the centroid of its pins if it has any). Default 0.
    pub initial_angular_velocity: [f64; 3],
    /// Vertex groups, each a rigid body: `{ object, indices | box, name, compliance,
    /// initial_angular_velocity }`. Default empty: every target object is one body.
    pub groups: Vec<BodySpec>,
}

impl Default for RigidParams {
    fn default() -> Self {
        Self {
            compliance: 0.0,
            initial_angular_velocity: [0.0; 3],
            groups: Vec::new(),
        }
    }
}

/// One rigid body given as a vertex group of an object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// The object the particles belong to (one of the group's target objects).
    pub object: String,
    /// Name of the body in the stats. Default: the object's name, then `#2`, `#3`... for
    /// further bodies of the same object.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Vertex indices within the object (0-based).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indices: Option<Vec<i64>>,
    /// Every vertex inside this axis-aligned box in the rest pose (m).
    #[serde(default, rename = "box", skip_serializing_if = "Option::is_none")]
    pub region: Option<RegionBox>,
    /// Compliance of this body (s²). Default: the group's `compliance`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<f64>,
    /// Initial angular velocity of this body (rad/s). Default: the group's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_angular_velocity: Option<[f64; 3]>,
}

/// An axis-aligned box in the rest pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionBox {
    /// Corner (m).
    pub min: [f64; 3],
    /// Opposite corner (m).
    pub max: [f64; 3],
}

impl RigidParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::number("compliance", d.compliance)
                .doc("inverse rigidity: each particle is held to its rigid goal by a spring of stiffness m/compliance, so deformations spring back at 1/sqrt(compliance) rad/s; 0 is perfectly rigid")
                .unit("s²")
                .range(0.0, f64::INFINITY),
            ParamSpec::vec3("initial_angular_velocity", d.initial_angular_velocity)
                .doc("spin given to every body at the first substep, about its centre of mass (about its pins' centroid if pinned)")
                .unit("rad/s"),
            ParamSpec::any("groups", Value::Array(Vec::new()))
                .doc("vertex groups, each one rigid body: [{ object = \"name\", indices = [..] or box = { min, max } (rest pose), name, compliance, initial_angular_velocity }]; empty: each target object is one body"),
        ]
    }

    /// Checks the values against [`specs`](Self::specs) and each group's own values; an error
    /// names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())?;
        for (k, g) in self.groups.iter().enumerate() {
            let bad = |m: String| {
                PluginError::bad_parameter(
                    "groups",
                    format!("entry {k} (object `{}`): {m}", g.object),
                )
            };
            if let Some(a) = g.compliance {
                if !a.is_finite() || a < 0.0 {
                    return Err(bad(format!("compliance {a} must be finite and ≥ 0")));
                }
            }
            if let Some(w) = g.initial_angular_velocity {
                if !w.iter().all(|c| c.is_finite()) {
                    return Err(bad("initial_angular_velocity must be finite".into()));
                }
            }
            if g.indices.is_some() && g.region.is_some() {
                return Err(bad("give `indices` or `box`, not both".into()));
            }
            if let Some(b) = g.region {
                if !b.min.iter().chain(&b.max).all(|c| c.is_finite()) {
                    return Err(bad("box corners must be finite".into()));
                }
            }
            if let Some(name) = &g.name {
                if name.is_empty() || name.contains([',', '"', '\n', '\r']) {
                    return Err(bad(format!(
                        "name {name:?} must be non-empty, without commas, quotes or line breaks (it names stats columns)"
                    )));
                }
            }
        }
        Ok(())
    }

    /// Parses validated JSON parameters; a malformed group entry names `groups` and the entry.
    pub fn parse(json: &str) -> Result<Self, PluginError> {
        let mut value: Value = serde_json::from_str(json)
            .map_err(|e| PluginError::bad_parameter("", format!("not valid JSON: {e}")))?;
        let groups = match value.as_object_mut().and_then(|m| m.remove("groups")) {
            None | Some(Value::Null) => Vec::new(),
            Some(Value::Array(list)) => list
                .into_iter()
                .enumerate()
                .map(|(k, g)| {
                    serde_json::from_value::<BodySpec>(g).map_err(|e| {
                        PluginError::bad_parameter("groups", format!("entry {k}: {e}"))
                    })
                })
                .collect::<Result<_, _>>()?,
            Some(other) => {
                return Err(PluginError::bad_parameter(
                    "groups",
                    format!("expected a list of tables, found {other}"),
                ))
            }
        };
        if let Some(m) = value.as_object_mut() {
            m.insert("groups".into(), Value::Array(Vec::new()));
        }
        let mut params: Self = params::parse(&value.to_string())?;
        params.groups = groups;
        Ok(params)
    }
}

/// One body of the batch: its slice of the SoA arrays and its own settings and state.
#[derive(Clone, Debug)]
struct Body {
    /// Name in the stats.
    name: String,
    /// Its particles are `ids[start..end]`, the first `pinned` of them pinned.
    start: usize,
    end: usize,
    pinned: usize,
    anchor: Anchor,
    /// Compliance (s²).
    alpha: f64,
    /// Initial angular velocity (rad/s).
    spin: DVec3,
    /// The rest reference point (world, m): the rest positions are stored relative to it.
    rest_origin: DVec3,
    /// The rotation of the last fit: warm start and tie-break of the next.
    rotation: DQuat,
    /// The largest distance of a particle from the rest reference point (m).
    extent: f64,
    /// The rigid motion this substep's answers to pushes have moved the body by so far,
    /// `x ↦ R x + d` as `(R, d)` ([`PushScratch`]).
    answered: (DQuat, DVec3),
}

/// All the rigid bodies of one `rigid` group, struct-of-arrays.
#[derive(Clone, Debug)]
pub struct RigidGroup {
    bodies: Vec<Body>,
    /// Global particle index of each body particle (body by body, pins first in each).
    ids: Vec<u32>,
    /// Rest position relative to the body's rest reference point (m).
    rest: Vec<DVec3>,
    /// Mass (kg); 0 for pinned particles.
    mass: Vec<f64>,
    /// Displacement applied toward the goal so far in this substep (m): XPBD's `wᵢλᵢ`.
    mu: Vec<DVec3>,
    /// Particle slices must hold more than this index (`None` for an empty group).
    max_index: Option<u32>,
    /// Room to answer the pushes on the largest body without allocating.
    scratch: PushScratch,
}

/// What answering the pushes on one body needs: the pushes as the body sees them and the
/// solver's state ([`answer_pushes`]); and, per particle of the group, the pushes taken off
/// it this substep so far (`total`, zeroed at the substep's start).
///
/// Every answer answers *all* of the substep's pushes on the body at once: it first takes back
/// the motion the substep's earlier answers gave the body, then answers the sum of the pushes
/// taken so far. Pushes answered apart would not add up: friction, pushed after the normal
/// pushes were answered, would then turn a sliding block about its base (the normal pushes no
/// longer holding it), and the next substep's normal pushes, undoing that turn, would weigh
/// more than the block — measured, a slab then slowed at 1.08 `μd g`; answered together it
/// slows at `μd g`.
#[derive(Clone, Debug, Default)]
struct PushScratch {
    pushes: Vec<Push>,
    work: Vec<PushWork>,
    total: Vec<DVec3>,
}

impl PushScratch {
    /// Takes the pushes (or kicks) `deltas` waiting on the free particles of `body` (whose
    /// first particle is at offset `first` in the group's arrays) off them: each entry back to
    /// 0 and the positions `x` back by it, to where the body had the particle; adds them to
    /// the particles' `total`, turned by `back` (the rotation that takes back the substep's
    /// earlier answers). Each entry counts as `scale` times itself (`h` for a kick: a velocity
    /// change moved the particle by `h Δv` in the prediction). Returns whether any was
    /// waiting.
    fn undo(
        &mut self,
        body: &BodyRef<'_>,
        first: usize,
        x: &mut [DVec3],
        deltas: &mut [DVec3],
        back: DQuat,
        scale: f64,
    ) -> bool {
        let mut any = false;
        for (k, &i) in body.ids.iter().enumerate().skip(body.pinned) {
            let i = i as usize;
            // Read first, write only what was pushed: most particles of a body are not.
            if deltas[i] != DVec3::ZERO {
                let d = std::mem::take(&mut deltas[i]) * scale;
                x[i] -= d;
                self.total[first + k] += back * d;
                any = true;
            }
        }
        any
    }

    /// The body's answer ([`answer_pushes`]) to the `total` pushes on its particles, at the
    /// positions `x`: its centre of mass and the motion `(t, θ)`; `scale` is a thousandth of
    /// what the sweeps may fall short by.
    fn answer(
        &mut self,
        body: &BodyRef<'_>,
        first: usize,
        x: &[DVec3],
        scale: f64,
    ) -> (DVec3, DVec3, DVec3) {
        // A body held by its pins turns about its pivot; a free one also translates.
        let pivot = pivot_properties(body, x);
        let (c, m, inertia) = match pivot {
            Some((p, inertia, _)) => (p, f64::INFINITY, inertia),
            None => mass_properties(body, x),
        };
        self.pushes.clear();
        let total = &self.total[first..first + body.ids.len()];
        for (&i, &by) in body.ids.iter().zip(total).skip(body.pinned) {
            if by != DVec3::ZERO {
                self.pushes.push(Push {
                    r: x[i as usize] - c,
                    by,
                });
            }
        }
        let (t, theta) = match pivot {
            Some((_, _, axis)) => (
                DVec3::ZERO,
                answer_pushes_about(&inertia, axis, &self.pushes, &mut self.work),
            ),
            None => answer_pushes(m, &inertia, &self.pushes, 1e-3 * scale, &mut self.work),
        };
        (c, t, theta)
    }

    /// Forgets the substep's pushes (a new substep).
    fn forget(&mut self) {
        self.total.fill(DVec3::ZERO);
    }
}

/// The report columns of each body, in order.
pub const REPORT_COLUMNS: [&str; 13] = [
    "tx", "ty", "tz", "qw", "qx", "qy", "qz", "cx", "cy", "cz", "lx", "ly", "lz",
];

impl RigidGroup {
    /// One body per entry of `params.groups`, or per target object if there are none.
    ///
    /// Errors: a parameter out of range, a group naming an object that is not a target, an
    /// index outside its object, a selection with no particle, two bodies with one name (all
    /// naming `groups` or the parameter); a target outside the scene or an object whose
    /// particles lie outside the scene (naming the object).
    pub fn new(params: &RigidParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate()?;
        let targets = scene.unique_targets()?;
        let rest_x = scene.rest_positions();
        let inv_mass = scene.inv_mass.as_slice();

        // (name, global particle indices, compliance, spin) of each body.
        let mut selections: Vec<(String, Vec<u32>, f64, DVec3)> = Vec::new();
        let default_spin = DVec3::from_array(params.initial_angular_velocity);
        if params.groups.is_empty() {
            for &(_, o) in &targets {
                selections.push((
                    o.name.to_string(),
                    o.particles().map(|i| i as u32).collect(),
                    params.compliance,
                    default_spin,
                ));
            }
        } else {
            for (k, g) in params.groups.iter().enumerate() {
                let bad = |m: String| {
                    PluginError::bad_parameter(
                        "groups",
                        format!("entry {k} (object `{}`): {m}", g.object),
                    )
                };
                let Some(&(_, o)) = targets.iter().find(|(_, o)| o.name.as_str() == g.object)
                else {
                    return Err(bad("not one of this constraint's objects".into()));
                };
                let range = o.particles();
                let mut ids: Vec<u32> = match (&g.indices, &g.region) {
                    (Some(list), _) => list
                        .iter()
                        .map(|&i| {
                            if i < 0 || i as usize >= range.len() {
                                Err(bad(format!(
                                    "index {i} is outside the object's {} vertices",
                                    range.len()
                                )))
                            } else {
                                Ok((range.start + i as usize) as u32)
                            }
                        })
                        .collect::<Result<_, _>>()?,
                    (None, Some(b)) => {
                        let (lo, hi) = (DVec3::from_array(b.min), DVec3::from_array(b.max));
                        let (lo, hi) = (lo.min(hi), lo.max(hi));
                        range
                            .clone()
                            .filter(|&i| {
                                let p = rest_x[i];
                                p.cmpge(lo).all() && p.cmple(hi).all()
                            })
                            .map(|i| i as u32)
                            .collect()
                    }
                    (None, None) => range.clone().map(|i| i as u32).collect(),
                };
                ids.sort_unstable();
                ids.dedup();
                if ids.is_empty() {
                    return Err(bad("the selection holds no vertex".into()));
                }
                let same_object = params.groups[..k]
                    .iter()
                    .filter(|h| h.object == g.object)
                    .count();
                let name = g.name.clone().unwrap_or_else(|| {
                    if same_object == 0 {
                        g.object.clone()
                    } else {
                        format!("{}#{}", g.object, same_object + 1)
                    }
                });
                if selections.iter().any(|s| s.0 == name) {
                    return Err(bad(format!("a second body named `{name}`")));
                }
                selections.push((
                    name,
                    ids,
                    g.compliance.unwrap_or(params.compliance),
                    g.initial_angular_velocity
                        .map_or(default_spin, DVec3::from_array),
                ));
            }
        }

        let total: usize = selections.iter().map(|s| s.1.len()).sum();
        let mut group = Self {
            bodies: Vec::with_capacity(selections.len()),
            ids: Vec::with_capacity(total),
            rest: Vec::with_capacity(total),
            mass: Vec::with_capacity(total),
            mu: vec![DVec3::ZERO; total],
            max_index: None,
            scratch: PushScratch::default(),
        };
        for (name, ids, alpha, spin) in selections {
            let (pinned, free): (Vec<u32>, Vec<u32>) =
                ids.iter().partition(|&&i| inv_mass[i as usize] == 0.0);
            let mass_of = |i: u32| {
                let w = inv_mass[i as usize];
                if w > 0.0 && w.is_finite() {
                    1.0 / w
                } else {
                    0.0
                }
            };
            let rest_origin = if pinned.is_empty() {
                let m: f64 = free.iter().map(|&i| mass_of(i)).sum();
                free.iter()
                    .map(|&i| rest_x[i as usize] * mass_of(i))
                    .sum::<DVec3>()
                    / m
            } else {
                pinned.iter().map(|&i| rest_x[i as usize]).sum::<DVec3>() / pinned.len() as f64
            };
            if !rest_origin.is_finite() {
                return Err(PluginError::bad_object(
                    name.as_str(),
                    "the rest positions or masses of the body are not finite".to_string(),
                ));
            }
            let start = group.ids.len();
            for &i in pinned.iter().chain(&free) {
                group.ids.push(i);
                group.rest.push(rest_x[i as usize] - rest_origin);
                group.mass.push(mass_of(i));
                group.max_index = group.max_index.max(Some(i));
            }
            let end = group.ids.len();
            let extent = group.rest[start..end]
                .iter()
                .map(|r| r.length())
                .fold(0.0, f64::max);
            let anchor = classify_pins(&group.rest[start..start + pinned.len()], extent);
            group.bodies.push(Body {
                name,
                start,
                end,
                pinned: pinned.len(),
                anchor,
                alpha,
                spin,
                rest_origin,
                rotation: DQuat::IDENTITY,
                extent,
                answered: (DQuat::IDENTITY, DVec3::ZERO),
            });
        }
        let largest = group.bodies.iter().map(|b| b.end - b.start).max();
        let largest = largest.unwrap_or(0);
        group.scratch.pushes.reserve(largest);
        group.scratch.work.reserve(largest);
        group.scratch.total = vec![DVec3::ZERO; group.ids.len()];
        Ok(group)
    }

    /// The number of bodies.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// The names of the bodies, in order.
    pub fn body_names(&self) -> impl Iterator<Item = &str> {
        self.bodies.iter().map(|b| b.name.as_str())
    }

    /// How the pins hold each body, in order.
    pub fn anchors(&self) -> impl Iterator<Item = Anchor> + '_ {
        self.bodies.iter().map(|b| b.anchor)
    }

    fn body_ref(&self, b: &Body) -> BodyRef<'_> {
        body_ref(&self.ids, &self.rest, &self.mass, b)
    }

    fn is_movable(b: &Body) -> bool {
        b.end - b.start > b.pinned
    }

    /// Whether the body answers pushes with its own mass ([`Self::take_position_pushes`]): a
    /// fully rigid body (compliance 0) that is free, or held by its pins at one point (it
    /// turns about it) or along a line (it turns about the line). A body held by three pins
    /// or more does not move, and a compliant body deforms under a push as loose particles
    /// would.
    fn answers_pushes(b: &Body) -> bool {
        b.alpha == 0.0 && b.anchor != Anchor::Full && Self::is_movable(b)
    }

    /// Whether pushes (or kicks) may wait for this group: the slice is the core's (one entry
    /// per particle) and some body answers them.
    fn takes(&self, deltas: &[DVec3]) -> bool {
        self.max_index.is_some_and(|m| (m as usize) < deltas.len())
            && self.bodies.iter().any(Self::answers_pushes)
    }

    /// Every body that answers pushes takes those waiting on its particles and moves as a
    /// whole to answer them with its mass ([`answer_pushes`]); returns whether any body moved.
    ///
    /// The kicks (velocity changes the last substep's `end_substep` made) are taken as the
    /// pushes `h Δv` they made in this substep's prediction.
    fn take_position_pushes(
        &mut self,
        x: &mut [DVec3],
        pushes: &mut [DVec3],
        kicks: &mut [DVec3],
        h: f64,
    ) -> bool {
        if !self.takes(pushes) || kicks.len() != pushes.len() {
            return false;
        }
        let mut moved = false;
        for b in &mut self.bodies {
            if !Self::answers_pushes(b) {
                continue;
            }
            let body = body_ref(&self.ids, &self.rest, &self.mass, b);
            let (r0, d0) = b.answered;
            let back = r0.inverse();
            let pushed = self.scratch.undo(&body, b.start, x, pushes, back, 1.0);
            let kicked = self.scratch.undo(&body, b.start, x, kicks, back, h);
            if !pushed && !kicked {
                continue;
            }
            // Take back this substep's earlier answers: all its pushes are answered at once.
            if (r0, d0) != (DQuat::IDENTITY, DVec3::ZERO) {
                for &i in &body.ids[body.pinned..] {
                    x[i as usize] = back * (x[i as usize] - d0);
                }
            }
            let (c, t, theta) = self.scratch.answer(&body, b.start, x, b.extent);
            let turn = DQuat::from_scaled_axis(theta);
            for &i in &body.ids[body.pinned..] {
                let i = i as usize;
                x[i] = c + t + turn * (x[i] - c);
            }
            // x ↦ turn (x − c) + c + t, after x ↦ r0 x + d0 was taken back.
            b.answered = (turn, c + t - turn * c);
            moved = true;
        }
        moved
    }
}

/// Body `b`'s slices of the group's arrays.
fn body_ref<'a>(ids: &'a [u32], rest: &'a [DVec3], mass: &'a [f64], b: &Body) -> BodyRef<'a> {
    BodyRef {
        ids: &ids[b.start..b.end],
        rest: &rest[b.start..b.end],
        mass: &mass[b.start..b.end],
        pinned: b.pinned,
        anchor: b.anchor,
    }
}

impl ConstraintGroup for RigidGroup {
    fn stages(&self) -> Stages {
        let mut s = Stages::PROJECT | Stages::REPORT;
        if self.bodies.iter().any(|b| b.alpha > 0.0) {
            s = s | Stages::BEGIN_SUBSTEP;
        }
        if self.bodies.iter().any(|b| b.alpha == 0.0) {
            s = s | Stages::END_SUBSTEP;
        }
        if self.bodies.iter().any(|b| b.spin != DVec3::ZERO) {
            s = s | Stages::FORCE;
        }
        if self.bodies.iter().any(Self::answers_pushes) {
            s = s | Stages::TAKES_PUSHES;
        }
        s
    }

    fn len(&self) -> usize {
        self.bodies.len()
    }

    /// At the first substep of the run only: `vᵢ += ω × (xᵢ − c)` for the free particles of
    /// every body with an initial angular velocity `ω`, `c` its frame's centre.
    fn force(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        if ctx.frame != 0 || ctx.substep != 0 {
            return Ok(());
        }
        ctx.check_holds(self.max_index)?;
        let p = ctx.particles();
        for b in &self.bodies {
            if b.spin == DVec3::ZERO || !Self::is_movable(b) {
                continue;
            }
            let frame = fit_frame(&self.body_ref(b), p.x, b.rotation);
            for &i in &self.ids[b.start + b.pinned..b.end] {
                let i = i as usize;
                if p.inv_mass[i] > 0.0 {
                    p.v[i] += b.spin.cross(p.x[i] - frame.centre);
                }
            }
        }
        Ok(())
    }

    /// Resets the accumulated displacements `μ` (XPBD's `wλ`) to 0.
    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        self.mu.fill(DVec3::ZERO);
        Ok(())
    }

    /// The velocities of every fully rigid body (compliance 0) projected onto rigid motion,
    /// keeping its linear and angular momentum ([`rigidify_velocities`]).
    fn end_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        ctx.check_holds(self.max_index)?;
        let h = ctx.h;
        let p = ctx.particles();
        if h > 0.0 && self.take_position_pushes(p.x, p.pushes, p.kicks, h) {
            // The bodies moved after the velocity update: their velocities follow.
            for b in self.bodies.iter().filter(|b| Self::answers_pushes(b)) {
                for &i in &self.ids[b.start + b.pinned..b.end] {
                    let i = i as usize;
                    p.v[i] = (p.x[i] - p.x0[i]) / h;
                }
            }
        }
        for b in &self.bodies {
            if b.alpha == 0.0 && Self::is_movable(b) {
                rigidify_velocities(&self.body_ref(b), p.x, p.v, p.inv_mass);
            }
        }
        Ok(())
    }

    /// One shape-matching pass over every body in order: fit its frame, move its free
    /// particles toward their goals. Deterministic, no allocation.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.substep_length()?;
        ctx.check_holds(self.max_index)?;
        let first_pass = ctx.pass == 0;
        let p = ctx.particles();
        if first_pass && self.takes(p.pushes) {
            // A new substep: its pushes are answered from the body's pose now.
            self.scratch.forget();
            for b in &mut self.bodies {
                b.answered = (DQuat::IDENTITY, DVec3::ZERO);
            }
        }
        self.take_position_pushes(p.x, p.pushes, p.kicks, h);
        let Self {
            bodies,
            ids,
            rest,
            mass,
            mu,
            ..
        } = self;
        for b in bodies.iter_mut() {
            if !Self::is_movable(b) {
                continue;
            }
            let body = body_ref(ids, rest, mass, b);
            let frame = fit_frame(&body, p.x, b.rotation);
            b.rotation = frame.rotation;
            let alpha_tilde = b.alpha / (h * h);
            project_goals(
                &body,
                &frame,
                p.x,
                p.inv_mass,
                &mut mu[b.start..b.end],
                alpha_tilde,
            );
        }
        Ok(())
    }

    /// The distance of every free particle from its rigid goal (m), and the energy
    /// `Σ ½ mᵢ |xᵢ − gᵢ|² / α` of the compliant bodies (J).
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let mut out = Residual::default();
        if ctx.check_holds(self.max_index).is_err() {
            return out;
        }
        let mut sum_sq = 0.0;
        for b in &self.bodies {
            if !Self::is_movable(b) {
                continue;
            }
            let body = self.body_ref(b);
            let frame = fit_frame(&body, x, b.rotation);
            let mut energy = 0.0;
            goal_distances(&body, &frame, x, |k, d| {
                out.count += 1;
                out.max = out.max.max(d);
                sum_sq += d * d;
                energy += body.mass[k] * d * d;
            });
            if b.alpha > 0.0 {
                out.energy += 0.5 * energy / b.alpha;
            }
        }
        if out.count > 0 {
            out.rms = (sum_sq / out.count as f64).sqrt();
        }
        out
    }

    /// Per body (`<body>.<column>`, [`REPORT_COLUMNS`]): the rigid transform of its rest pose
    /// `t, q` (a rest-pose point `p` is now at `q·p + t`, m), its centre of mass `c` (m), and
    /// its angular momentum about `c`, `L = Σ mᵢ (xᵢ − c) × vᵢ` (kg·m²/s), free particles only.
    fn report(&self, ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let (x, v) = (ctx.positions(), ctx.velocities());
        if ctx.check_holds(self.max_index).is_err() {
            return;
        }
        for b in &self.bodies {
            let body = self.body_ref(b);
            let frame: Frame = fit_frame(&body, x, b.rotation);
            let t = frame.centre - frame.rotation * b.rest_origin;
            let free = &self.ids[b.start + b.pinned..b.end];
            let free_mass = &self.mass[b.start + b.pinned..b.end];
            let m: f64 = free_mass.iter().sum();
            let c = if m > 0.0 {
                free.iter()
                    .zip(free_mass)
                    .map(|(&i, &mi)| (x[i as usize] - frame.centre) * mi)
                    .sum::<DVec3>()
                    / m
                    + frame.centre
            } else {
                frame.centre
            };
            let l: DVec3 = free
                .iter()
                .zip(free_mass)
                .map(|(&i, &mi)| (x[i as usize] - c).cross(v[i as usize]) * mi)
                .sum();
            let q = frame.rotation;
            let values = [
                t.x, t.y, t.z, q.w, q.x, q.y, q.z, c.x, c.y, c.z, l.x, l.y, l.z,
            ];
            for (col, value) in REPORT_COLUMNS.iter().zip(values) {
                out.push((format!("{}.{col}", b.name), value));
            }
        }
    }
}

/// The factory of the `rigid` kind.
pub(crate) fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params = RigidParams::parse(params_json)?;
    Ok(Box::new(RigidGroup::new(&params, scene)?))
}
