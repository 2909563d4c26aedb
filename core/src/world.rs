//! The simulation: particle state, the groups built by plugins, and the step.
//!
//! Per substep of length `h` the step runs these stages, in this order:
//!
//! 1. `kinematic` — each object's pin transform at `t + h` (its pinned/animated particles
//!    reach their targets, with the velocity that takes them there, in `predict`);
//! 2. `forces` — `v += h g` for dynamic particles, then every group's `force` stage;
//! 3. `predict` — `x0 = x; x = x0 + h v` (kinematic particles: `x = target`); without force
//!    groups, gravity and the prediction are one loop over the particles; then the pushes are
//!    zeroed (kept only when a group takes them and one gives them: `Stages::TAKES_PUSHES`,
//!    `Stages::GIVES_PUSHES`);
//! 4. `begin` — every group's `begin_substep`;
//! 5. `solve` — the schedule: each group's `project`, `importance × iterations` times,
//!    interleaved by order (paper, Figures 9–13);
//! 6. `velocities` — `v = (x − x0) / h`, in the same loop as the finite check of the last
//!    call of the schedule (every other call is checked on its own);
//! 7. `end` — the kicks zeroed, every group's `end_substep` (restitution, friction), then
//!    global damping.
//!
//! This is the paper's implicit-velocity / explicit-position scheme (symplectic Euler).
//! Only the stages a group implements are called; empty groups are never scheduled. The
//! step loop allocates nothing.
//!
//! **Threads.** A substep holds the process's one thread team ([`nucleus_sdk::team`]; its size
//! is `RAYON_NUM_THREADS`, default the machine's cores). The core's particle loops (gravity,
//! prediction, velocities, damping, the finite checks after every call) split over it from
//! [`PARALLEL_MIN_PARTICLES`] particles up, each part its own contiguous range, and every
//! group receives it as `ctx.team` for its passes. Each particle's arithmetic is the same
//! whatever the split, so a scene gives the same bits on any number of threads. Measured on
//! the 2-core VM, 128 × 128 drape at 40 × 1 on two threads: 15.0 → 12.7 ms per frame (median)
//! once the core's loops share the team the stretch plugin used alone before; 64 × 64 at
//! 160 × 1: 18.2 → 14.2 ms.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use abi_stable::std_types::{RResult, RSlice, RSliceMut, RStr};
use glam::{DQuat, DVec3};
use nucleus_sdk::team::{self, SharedArray, TeamRef};
use nucleus_sdk::{
    Attribute, EdgePair, GroupBox, ObjectView, Residual, SceneView, SolveContext, Stage, Stages,
    TrianglePair, FLAG_KINEMATIC,
};

use crate::complex::Complex;
use crate::error::{BuildError, PluginLoadError, StepError};
use crate::plugins::Registry;
use crate::scene::{PinMotion, Scene, SolverSettings};
use crate::schedule::{schedule, Call, Slot};

/// An object's topology in global particle indices, as plugins see it.
#[derive(Debug, Clone, Default)]
pub struct ObjectData {
    /// Name.
    pub name: String,
    /// First particle.
    pub first: u32,
    /// Number of particles.
    pub count: u32,
    /// Isolated points.
    pub points: Vec<u32>,
    /// All edges.
    pub edges: Vec<[u32; 2]>,
    /// Triangles per edge.
    pub edge_triangle_count: Vec<u32>,
    /// All triangles, oriented.
    pub triangles: Vec<[u32; 3]>,
    /// Tets per triangle.
    pub triangle_tet_count: Vec<u32>,
    /// Triangles on the surface (not shared by two tets), for output and collisions.
    pub surface_triangles: Vec<[u32; 3]>,
    /// Curve edges (in no triangle), for output.
    pub curve_edges: Vec<[u32; 2]>,
    /// Tets.
    pub tets: Vec<[u32; 4]>,
    /// Triangle pairs.
    pub triangle_pairs: Vec<TrianglePair>,
    /// Curve edge pairs.
    pub edge_pairs: Vec<EdgePair>,
    /// Boundary edges.
    pub boundary_edges: Vec<[u32; 2]>,
    /// Closed surface.
    pub closed: bool,
    /// Manifold.
    pub manifold: bool,
    /// Motion of the pinned vertices.
    pub pin_motion: PinMotion,
    /// Positions per frame of an animated mesh (local vertex order); empty if not animated.
    pub sequence: Vec<Vec<[f64; 3]>>,
}

impl ObjectData {
    fn from_complex(name: &str, first: u32, complex: &Complex) -> ObjectData {
        let g = |i: u32| i + first;
        let edges: Vec<[u32; 2]> = complex.edges().iter().map(|e| [g(e[0]), g(e[1])]).collect();
        let edge_triangle_count = complex.edge_triangle_count();
        let triangles: Vec<[u32; 3]> = complex
            .triangles_oriented()
            .iter()
            .map(|t| [g(t[0]), g(t[1]), g(t[2])])
            .collect();
        let triangle_tet_count: Vec<u32> = (0..triangles.len())
            .map(|i| complex.valence(2, i) as u32)
            .collect();
        let surface_triangles = triangles
            .iter()
            .enumerate()
            .filter(|(i, _)| complex.valence(2, *i) < 2)
            .map(|(_, t)| *t)
            .collect();
        let curve_edges = edges
            .iter()
            .zip(&edge_triangle_count)
            .filter(|(_, &c)| c == 0)
            .map(|(e, _)| *e)
            .collect();
        ObjectData {
            name: name.to_string(),
            first,
            count: complex.n_vertices() as u32,
            points: complex.isolated_points().iter().map(|&p| g(p)).collect(),
            edges,
            edge_triangle_count,
            triangles,
            triangle_tet_count,
            surface_triangles,
            curve_edges,
            tets: complex
                .tets()
                .iter()
                .map(|t| [g(t[0]), g(t[1]), g(t[2]), g(t[3])])
                .collect(),
            triangle_pairs: complex
                .triangle_pairs()
                .iter()
                .map(|p| TrianglePair {
                    triangles: p.triangles,
                    edge: [g(p.edge[0]), g(p.edge[1])],
                    opposite: [g(p.opposite[0]), g(p.opposite[1])],
                })
                .collect(),
            edge_pairs: complex
                .edge_pairs()
                .iter()
                .map(|p| EdgePair {
                    vertices: [g(p[0]), g(p[1]), g(p[2])],
                })
                .collect(),
            boundary_edges: complex
                .boundary_edges()
                .iter()
                .map(|e| [g(e[0]), g(e[1])])
                .collect(),
            closed: complex.is_closed(),
            manifold: complex.is_manifold(),
            pin_motion: PinMotion::default(),
            sequence: Vec::new(),
        }
    }

    fn view(&self) -> ObjectView<'_> {
        ObjectView {
            name: RStr::from(self.name.as_str()),
            first: self.first,
            count: self.count,
            points: RSlice::from_slice(&self.points),
            edges: RSlice::from_slice(&self.edges),
            edge_triangle_count: RSlice::from_slice(&self.edge_triangle_count),
            triangles: RSlice::from_slice(&self.triangles),
            triangle_tet_count: RSlice::from_slice(&self.triangle_tet_count),
            tets: RSlice::from_slice(&self.tets),
            triangle_pairs: RSlice::from_slice(&self.triangle_pairs),
            edge_pairs: RSlice::from_slice(&self.edge_pairs),
            boundary_edges: RSlice::from_slice(&self.boundary_edges),
            closed: self.closed as u8,
            manifold: self.manifold as u8,
        }
    }
}

/// Particle state in struct-of-arrays form.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Particles {
    /// Positions (m).
    pub x: Vec<[f64; 3]>,
    /// Positions at the start of the substep (m).
    pub x0: Vec<[f64; 3]>,
    /// Velocities (m/s).
    pub v: Vec<[f64; 3]>,
    /// Inverse masses (1/kg); 0 for kinematic particles.
    pub inv_mass: Vec<f64>,
    /// Masses (kg), including those of kinematic particles (for reporting).
    pub mass: Vec<f64>,
    /// Object index.
    pub object: Vec<u32>,
    /// Flags (`FLAG_*`).
    pub flags: Vec<u32>,
    /// Rest positions (m).
    pub rest: Vec<[f64; 3]>,
    /// Displacements by constraints against kinematic colliders since the force stage (m),
    /// one per particle when a group takes them ([`Stages::TAKES_PUSHES`]), else empty.
    pub pushes: Vec<[f64; 3]>,
    /// Velocity changes by the same since the force stage (m/s), likewise.
    pub kicks: Vec<[f64; 3]>,
}

impl Particles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
}

/// A constraint group as the core holds it.
pub struct Group {
    /// Group name.
    pub name: String,
    /// Kind.
    pub kind: String,
    /// Plugin name.
    pub plugin: String,
    /// Plugin library.
    pub path: PathBuf,
    /// The group object.
    pub group: GroupBox,
    /// Stages it implements.
    pub stages: Stages,
    /// Order.
    pub order: i32,
    /// Importance (before the `iterations` multiplier).
    pub importance: u32,
    /// Number of constraints.
    pub len: u64,
    /// Residual unit.
    pub residual_unit: String,
}

impl Group {
    /// Whether the step calls this group's `stage`: it implements the stage and holds at
    /// least one constraint (an empty group is never scheduled).
    pub fn runs(&self, stage: Stage) -> bool {
        self.declares(stage.flag())
    }

    /// Whether the group holds at least one constraint and declares every flag of `flags`.
    pub fn declares(&self, flags: Stages) -> bool {
        self.len > 0 && self.stages.contains(flags)
    }
}

/// The whole simulation.
pub struct Simulation {
    /// Solver settings.
    pub settings: SolverSettings,
    /// Objects.
    pub objects: Vec<ObjectData>,
    /// Particle state.
    pub particles: Particles,
    /// Groups, in scene order.
    pub groups: Vec<Group>,
    /// The call sequence of one substep.
    pub calls: Vec<Call>,
    /// Groups with a force stage, begin stage, end stage.
    force_groups: Vec<usize>,
    begin_groups: Vec<usize>,
    end_groups: Vec<usize>,
    /// Kinematic particles whose object has a pin motion or an animated mesh.
    moving_pins: Vec<u32>,
    /// Scratch: each object's pin transform at the current target time.
    object_transforms: Vec<(DQuat, DVec3)>,
    /// Simulated time (s).
    pub time: f64,
    /// Frames done.
    pub frame: u64,
    /// Threads of the step's team (`RAYON_NUM_THREADS`, default the machine's cores; see
    /// [`nucleus_sdk::team`]), read when the simulation is built.
    pub threads: usize,
}

/// Below this many particles the core's particle loops run on the calling thread: a loop over
/// 4,096 particles takes a few microseconds, a few times the team's hand-off. Chosen, not
/// tuned.
pub const PARALLEL_MIN_PARTICLES: usize = 4096;

// The particle loops of one range, as functions of distinct slices: the compiler may then
// assume they do not overlap and vectorise each loop without checks (measured: the free-fall
// substep of 4,096 particles 20.0 µs with the loops written inside the range closures, on
// slices made from raw pointers, against 18.4 µs before the split).

/// `v += g` (`g` = gravity × h) for every free particle; pins keep their velocity. A select
/// rather than a branch, so the loop vectorises.
fn gravity_range(v: &mut [[f64; 3]], inv_mass: &[f64], g: [f64; 3]) {
    for (v, &w) in v.iter_mut().zip(inv_mass) {
        let free = w > 0.0;
        for (c, g) in v.iter_mut().zip(g) {
            *c = if free { *c + g } else { *c };
        }
    }
}

/// `x0 = x`, then `x += h v` for every free particle; with `gravity` (`g` = gravity × h),
/// first `v += g` for every free particle, in the same loop: [`gravity_range`]'s arithmetic,
/// so the same bits, one pass over the velocities instead of two.
fn predict_range(
    x: &mut [[f64; 3]],
    x0: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    inv_mass: &[f64],
    h: f64,
    gravity: Option<[f64; 3]>,
) {
    debug_assert!(x0.len() == x.len() && v.len() == x.len() && inv_mass.len() == x.len());
    // `x0` is written in the same loop as `x` (each position read once): a separate copy
    // first was a sixth of the 128 x 128 drape's substep on 2 threads, the arrays streaming
    // from beyond the core's cache twice.
    match gravity {
        Some(g) => {
            for (((x, x0), v), &w) in x.iter_mut().zip(x0).zip(v).zip(inv_mass) {
                let free = w > 0.0;
                *x0 = *x;
                for ((x, v), g) in x.iter_mut().zip(v.iter_mut()).zip(g) {
                    *v = if free { *v + g } else { *v };
                    *x = if free { *x + *v * h } else { *x };
                }
            }
        }
        None => {
            for (((x, x0), v), &w) in x.iter_mut().zip(x0).zip(&*v).zip(inv_mass) {
                let free = w > 0.0;
                *x0 = *x;
                for (x, v) in x.iter_mut().zip(v) {
                    *x = if free { *x + v * h } else { *x };
                }
            }
        }
    }
}

/// `v = (x − x0) / h`, component by component over the flat arrays.
fn velocity_range(v: &mut [[f64; 3]], x: &[[f64; 3]], x0: &[[f64; 3]], inv_h: f64) {
    let (x, x0) = (x.as_flattened(), x0.as_flattened());
    for ((v, x), x0) in v.as_flattened_mut().iter_mut().zip(x).zip(x0) {
        *v = (x - x0) * inv_h;
    }
}

/// Where moving pin `i` of object `o` goes at `frame_pos` (time in frames): its rest position
/// under the object's pin transform `(rotation, translation)` about the pivot, or the object's
/// animated mesh sequence, interpolated between the two frames around `frame_pos`.
fn pin_target(
    o: &ObjectData,
    (rot, trans): (DQuat, DVec3),
    rest: [f64; 3],
    i: usize,
    frame_pos: f64,
) -> DVec3 {
    if o.sequence.is_empty() {
        let pivot = DVec3::from_array(o.pin_motion.pivot);
        pivot + rot * (DVec3::from_array(rest) - pivot) + trans
    } else {
        let last = o.sequence.len() - 1;
        let f = (frame_pos.floor().max(0.0) as usize).min(last);
        let g = (f + 1).min(last);
        let s = (frame_pos - f as f64).clamp(0.0, 1.0);
        let local = i - o.first as usize;
        DVec3::from_array(o.sequence[f][local]).lerp(DVec3::from_array(o.sequence[g][local]), s)
    }
}

/// [`TeamRef::for_ranges`] from [`PARALLEL_MIN_PARTICLES`] particles on.
fn for_ranges(team: TeamRef<'_>, n: usize, f: &(dyn Fn(std::ops::Range<usize>) + Sync)) {
    team.for_ranges(n, PARALLEL_MIN_PARTICLES, f);
}

/// [`TeamRef::for_ranges_mut`] from [`PARALLEL_MIN_PARTICLES`] particles on.
fn for_ranges_mut<T: Send>(
    team: TeamRef<'_>,
    items: &mut [T],
    f: &(dyn Fn(std::ops::Range<usize>, &mut [T]) + Sync),
) {
    team.for_ranges_mut(items, PARALLEL_MIN_PARTICLES, f);
}

/// The most `project` calls one substep may make (iterations × the groups' importances). The
/// schedule is laid out as a list of calls, so a scene asking for billions would exhaust memory
/// before its first step; a million calls a substep is already seconds a substep.
pub const MAX_CALLS_PER_SUBSTEP: u64 = 1 << 20;

/// The process's thread team while a substep holds it ([`team::shared`]).
type TeamGuard = std::sync::MutexGuard<'static, Option<team::Team>>;

/// The team a held guard lends, or the serial team when none is held.
fn team_ref(guard: &Option<TeamGuard>) -> TeamRef<'_> {
    guard
        .as_ref()
        .and_then(|g| g.as_ref())
        .map_or(TeamRef::serial(), TeamRef::new)
}

/// What a finite check found, over the parts of the team: a non-finite position, velocity.
#[derive(Default)]
struct NonFinite {
    x: AtomicBool,
    v: AtomicBool,
}

impl NonFinite {
    /// Checks one range's positions and velocities, recording what is not finite; whether
    /// both were finite.
    fn check(&self, x: &[[f64; 3]], v: &[[f64; 3]]) -> bool {
        let (good_x, good_v) = (all_finite(x), all_finite(v));
        if !good_x {
            self.x.store(true, Ordering::Relaxed);
        }
        if !good_v {
            self.v.store(true, Ordering::Relaxed);
        }
        good_x && good_v
    }
}

/// Whether every component is finite: no component has an all-ones exponent (NaN or ±∞).
///
/// The check runs after every group call, so it is written for speed: an OR over integers
/// (a sum of `x·0` is one long chain of dependent floating-point additions), and without a
/// 64-bit comparison, which the baseline x86-64 vector instructions lack: adding one to the
/// exponent field carries into the sign bit exactly when the field is all ones. Measured on
/// the 128 × 128 drape at 40 × 1 on two threads, the checks took 2.4 ms of a 15.9 ms frame in
/// the comparison form.
pub fn all_finite(xs: &[[f64; 3]]) -> bool {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    const EXPONENT_ONE: u64 = 0x0010_0000_0000_0000;
    let carried = xs.as_flattened().iter().fold(0u64, |bad, v| {
        bad | (v.to_bits() & EXPONENT).wrapping_add(EXPONENT_ONE)
    });
    carried >> 63 == 0
}

/// The first parameter (by name, in key order) holding a NaN or an infinity, anywhere in its
/// value, and that number.
fn non_finite(table: &toml::Table) -> Option<(String, f64)> {
    fn find(v: &toml::Value) -> Option<f64> {
        match v {
            toml::Value::Float(f) if !f.is_finite() => Some(*f),
            toml::Value::Array(a) => a.iter().find_map(find),
            toml::Value::Table(t) => t.values().find_map(find),
            _ => None,
        }
    }
    table
        .iter()
        .find_map(|(k, v)| find(v).map(|x| (k.clone(), x)))
}

fn toml_to_json(v: &toml::Value) -> serde_json::Value {
    match v {
        toml::Value::String(s) => serde_json::Value::from(s.as_str()),
        toml::Value::Integer(i) => serde_json::Value::from(*i),
        toml::Value::Float(f) => serde_json::Number::from_f64(*f)
            .map_or(serde_json::Value::Null, serde_json::Value::Number),
        toml::Value::Boolean(b) => serde_json::Value::from(*b),
        toml::Value::Datetime(d) => serde_json::Value::from(d.to_string()),
        toml::Value::Array(a) => serde_json::Value::Array(a.iter().map(toml_to_json).collect()),
        toml::Value::Table(t) => serde_json::Value::Object(
            t.iter()
                .map(|(k, v)| (k.clone(), toml_to_json(v)))
                .collect(),
        ),
    }
}

impl Simulation {
    /// Builds the simulation: geometry, particles, and one group per constraint entry through
    /// the plugin providing its kind.
    pub fn build(scene: &Scene, registry: &Registry) -> Result<Simulation, BuildError> {
        let settings = scene.file.solver.clone();
        let mut objects = Vec::new();
        let mut p = Particles::default();
        for (oi, spec) in scene.file.objects.iter().enumerate() {
            let geo = scene.geometry(spec)?;
            let name = spec.name.get_ref();
            let complex = Complex::build(
                geo.positions.len(),
                &geo.points,
                &geo.edges,
                &geo.triangles,
                &geo.tets,
            )
            .map_err(|e| scene.invalid(spec.name.span(), format!("object `{name}`: {e}")))?;
            let pins = scene.pins(spec, &geo)?;
            let masses = scene.masses(spec, &geo)?;
            let first = p.x.len() as u32;
            let mut data = ObjectData::from_complex(name, first, &complex);
            data.pin_motion = spec.pin_motion.clone();
            data.sequence = geo.sequence.clone();
            objects.push(data);
            for (i, (pos, m)) in geo.positions.iter().zip(&masses).enumerate() {
                let pinned = pins.binary_search(&(i as u32)).is_ok();
                p.x.push(*pos);
                p.x0.push(*pos);
                p.rest.push(*pos);
                p.v.push(if pinned { [0.0; 3] } else { spec.velocity });
                p.mass.push(*m);
                p.inv_mass.push(if pinned { 0.0 } else { 1.0 / m });
                p.object.push(oi as u32);
                p.flags.push(if pinned { FLAG_KINEMATIC } else { 0 });
            }
        }
        let moving_pins: Vec<u32> = (0..p.len() as u32)
            .filter(|&i| {
                let o = &objects[p.object[i as usize] as usize];
                p.flags[i as usize] & FLAG_KINEMATIC != 0
                    && (o.pin_motion.is_moving() || !o.sequence.is_empty())
            })
            .collect();
        let object_transforms = vec![(DQuat::IDENTITY, DVec3::ZERO); objects.len()];

        let views: Vec<ObjectView<'_>> = objects.iter().map(ObjectData::view).collect();
        let mut groups = Vec::new();
        let mut kind_counts: std::collections::BTreeMap<String, u32> = Default::default();
        for c in &scene.file.constraints {
            let kind = c.kind.get_ref();
            let location = scene.location(c.kind.span().start);
            let (plugin, info) = registry.find(kind).map_err(|error| BuildError::Plugin {
                location: location.clone(),
                error: Box::new(error),
            })?;
            let n = kind_counts.entry(kind.clone()).or_insert(0);
            *n += 1;
            let name = c.name.clone().unwrap_or_else(|| {
                if *n == 1 {
                    kind.clone()
                } else {
                    format!("{kind}#{n}")
                }
            });
            let targets: Vec<u32> = match &c.objects {
                Some(list) => list
                    .iter()
                    .filter_map(|o| objects.iter().position(|d| &d.name == o.get_ref()))
                    .map(|i| i as u32)
                    .collect(),
                None => (0..objects.len() as u32).collect(),
            };
            let params = toml_to_json(&toml::Value::Table(
                c.params
                    .as_ref()
                    .map(|p| p.get_ref().clone())
                    .unwrap_or_default(),
            ));
            let params_span = c.params.as_ref().map_or(c.kind.span(), |p| p.span());
            // JSON has no NaN or infinity: such a value would reach the plugin as `null`.
            if let Some((key, x)) = c.params.as_ref().and_then(|p| non_finite(p.get_ref())) {
                return Err(scene
                    .invalid(
                        params_span,
                        format!(
                            "constraint `{name}` (kind `{kind}`): parameter `{key}` is {x}; \
                             every number must be finite"
                        ),
                    )
                    .into());
            }
            let validated = nucleus_sdk::params::validate(&params, info.params.as_slice())
                .map_err(|e| {
                    scene.invalid(
                        params_span.clone(),
                        format!("constraint `{name}` (kind `{kind}`): {e}"),
                    )
                })?;
            let json = serde_json::Value::Object(validated).to_string();
            let view = SceneView {
                objects: RSlice::from_slice(&views),
                targets: RSlice::from_slice(&targets),
                rest: RSlice::from_slice(&p.rest),
                inv_mass: RSlice::from_slice(&p.inv_mass),
                attributes: RSlice::from_slice(&[] as &[Attribute<'_>]),
                gravity: settings.gravity,
                frame_dt: 1.0 / settings.frame_rate,
                substeps: settings.substeps,
            };
            let group = plugin.create_group(kind, &json, &view).map_err(|error| {
                let plugin_error = PluginLoadError::Factory {
                    plugin: plugin.info.name.to_string(),
                    path: plugin.path.clone(),
                    group: name.clone(),
                    error: Box::new(error),
                };
                BuildError::Plugin {
                    location: location.clone(),
                    error: Box::new(plugin_error),
                }
            })?;
            let stages = group.stages();
            let len = group.constraint_count();
            groups.push(Group {
                name,
                kind: kind.clone(),
                plugin: plugin.info.name.to_string(),
                path: plugin.path.clone(),
                group,
                stages,
                order: c.order.unwrap_or(info.default_order),
                importance: c.importance.unwrap_or(info.default_importance),
                len,
                residual_unit: info.residual_unit.to_string(),
            });
        }
        drop(views);
        let calls: u64 = groups
            .iter()
            .filter(|g| g.runs(Stage::Project))
            .map(|g| u64::from(g.importance) * u64::from(settings.iterations))
            .sum();
        if calls > MAX_CALLS_PER_SUBSTEP {
            // Point at what made it large: the iterations, or else an importance override.
            let needle = if settings.iterations > 1 {
                "iterations"
            } else {
                "importance"
            };
            return Err(scene
                .invalid_near(
                    needle,
                    format!(
                        "{calls} projection calls per substep (iterations {} × the groups' \
                         importances) is more than the {MAX_CALLS_PER_SUBSTEP} the scheduler \
                         lays out; use fewer iterations or a lower importance",
                        settings.iterations
                    ),
                )
                .into());
        }
        let mut sim = Simulation {
            settings,
            objects,
            particles: p,
            groups,
            calls: Vec::new(),
            force_groups: Vec::new(),
            begin_groups: Vec::new(),
            end_groups: Vec::new(),
            moving_pins,
            object_transforms,
            time: 0.0,
            frame: 0,
            threads: team::configured_threads(),
        };
        sim.reschedule();
        Ok(sim)
    }

    /// Parses scene text (as `inline.toml`) and builds it: a shortcut for tests.
    pub fn from_toml(text: &str, registry: &Registry) -> Result<Simulation, BuildError> {
        let scene = Scene::parse(text, std::path::Path::new("inline.toml"))?;
        Self::build(&scene, registry)
    }

    /// Recomputes the call sequence and stage lists (after changing settings or importances).
    pub fn reschedule(&mut self) {
        let slots: Vec<Slot> = self
            .groups
            .iter()
            .map(|g| Slot {
                order: g.order,
                importance: if g.runs(Stage::Project) {
                    g.importance.saturating_mul(self.settings.iterations)
                } else {
                    0
                },
            })
            .collect();
        self.calls = schedule(&slots, self.settings.schedule);
        let pick = |s: Stage| -> Vec<usize> {
            (0..self.groups.len())
                .filter(|&i| self.groups[i].runs(s))
                .collect()
        };
        self.force_groups = pick(Stage::Force);
        self.begin_groups = pick(Stage::BeginSubstep);
        self.end_groups = pick(Stage::EndSubstep);
        // The pushes exist only for a scene with a group that reads them and one that writes
        // them: elsewhere they are empty slices, which writers and readers skip.
        let any = |flag: Stages| self.groups.iter().any(|g| g.declares(flag));
        let used = any(Stages::TAKES_PUSHES) && any(Stages::GIVES_PUSHES);
        let n = if used { self.particles.x.len() } else { 0 };
        let p = &mut self.particles;
        for a in [&mut p.pushes, &mut p.kicks] {
            a.clear();
            a.resize(n, [0.0; 3]);
        }
    }

    /// Substep length (s).
    pub fn h(&self) -> f64 {
        1.0 / (self.settings.frame_rate * self.settings.substeps as f64)
    }

    /// Runs one frame (all its substeps).
    pub fn step_frame(&mut self) -> Result<(), StepError> {
        for s in 0..self.settings.substeps {
            self.substep(s)?;
        }
        self.frame += 1;
        Ok(())
    }

    /// Runs one substep (stages listed in the module docs).
    ///
    /// The step holds the process's thread team ([`nucleus_sdk::team`]) for the substep: its
    /// own particle loops and every group's passes run on it. When another simulation holds it
    /// (two stepping at once), this one runs on its own thread, with the same results.
    pub fn substep(&mut self, substep: u32) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let h = self.h();
        let t1 = self.time + h;
        self.predict_stages(substep, h, t1, team)?;
        for k in 0..self.begin_groups.len() {
            self.call_group(
                self.begin_groups[k],
                Stage::BeginSubstep,
                substep,
                0,
                1,
                team,
                true,
            )?;
        }
        for k in 0..self.calls.len() {
            let call = self.calls[k];
            let g = call.group as usize;
            let passes = self.groups[g]
                .importance
                .saturating_mul(self.settings.iterations);
            let check = k + 1 < self.calls.len();
            self.call_group(g, Stage::Project, substep, call.pass, passes, team, check)?;
        }
        // The finite check after the last call is made in the velocity update's loop, which
        // reads the same positions (and the velocities it replaces) anyway.
        let last = self.calls.last().map(|call| call.group as usize);
        let found = self.update_velocities(h, team, self.settings.check_finite && last.is_some());
        if let Some(g) = last {
            self.non_finite_error(g, Stage::Project, substep, found)?;
        }
        // The kicks the last substep's end stage recorded were read in this substep's passes.
        self.particles.kicks.fill([0.0; 3]);
        for k in 0..self.end_groups.len() {
            self.call_group(
                self.end_groups[k],
                Stage::EndSubstep,
                substep,
                0,
                1,
                team,
                true,
            )?;
        }
        self.damp(h, team);
        self.time = t1;
        Ok(())
    }

    /// The process's thread team for one substep, if this simulation uses more than one
    /// thread and another simulation does not hold the team: a scene without groups and too
    /// small to split its own loops does not ask for it.
    fn team_guard(&self) -> Option<TeamGuard> {
        let wanted = !self.groups.is_empty() || self.particles.len() >= PARALLEL_MIN_PARTICLES;
        if self.threads > 1 && wanted {
            team::shared(self.threads)
        } else {
            None
        }
    }

    /// The stages of a substep before the groups' `begin_substep`: the pins' transforms at the
    /// substep's end `t1`, gravity, the force groups, then the prediction.
    fn predict_stages(
        &mut self,
        substep: u32,
        h: f64,
        t1: f64,
        team: TeamRef<'_>,
    ) -> Result<(), StepError> {
        self.update_pin_transforms(t1);
        if self.force_groups.is_empty() {
            // Nothing acts between gravity and the prediction: one loop for both.
            self.predict(h, t1, Some(self.gravity_step(h)), team);
            self.forget_pushes();
            return Ok(());
        }
        self.apply_gravity(h, team);
        for k in 0..self.force_groups.len() {
            self.call_group(
                self.force_groups[k],
                Stage::Force,
                substep,
                0,
                1,
                team,
                true,
            )?;
        }
        self.predict(h, t1, None, team);
        self.forget_pushes();
        Ok(())
    }

    /// Zeroes the pushes (nothing when no group takes them): the substep's own are recorded
    /// from here on.
    fn forget_pushes(&mut self) {
        self.particles.pushes.fill([0.0; 3]);
    }

    /// For benchmarks and tests that time or inspect one group's stages: the first stages of
    /// substep `substep` exactly as [`Simulation::substep`] runs them (pins, gravity, force
    /// groups, the prediction `x0 = x`, `x += h v`), stopping before any group's
    /// `begin_substep`. The time does not advance. Follow it with [`Simulation::run_stage`].
    pub fn predict_substep(&mut self, substep: u32) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let h = self.h();
        let t1 = self.time + h;
        self.predict_stages(substep, h, t1, team)
    }

    /// For benchmarks and tests: calls group `group`'s `stage` as [`Simulation::substep`]
    /// does — the same context (its passes are the group's importance times the iterations),
    /// the same thread team and the same finite check — as pass `pass` of substep `substep`.
    /// The core's own stages between the groups' (the velocity update, damping) are not run.
    pub fn run_stage(
        &mut self,
        group: usize,
        stage: Stage,
        substep: u32,
        pass: u32,
    ) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let passes = match stage {
            Stage::Project => self.groups[group]
                .importance
                .saturating_mul(self.settings.iterations),
            _ => 1,
        };
        self.call_group(group, stage, substep, pass, passes, team, true)
    }

    /// Each object's pin transform at time `t`, for the moving pins' targets (see
    /// [`pin_target`]; `predict` moves the pins).
    fn update_pin_transforms(&mut self, t: f64) {
        if self.moving_pins.is_empty() {
            return;
        }
        for (o, tr) in self.objects.iter().zip(&mut self.object_transforms) {
            *tr = o.pin_motion.transform(t);
        }
    }

    /// Gravity's velocity change over a substep of length `h` (m/s).
    fn gravity_step(&self, h: f64) -> [f64; 3] {
        (DVec3::from_array(self.settings.gravity) * h).to_array()
    }

    fn apply_gravity(&mut self, h: f64, team: TeamRef<'_>) {
        let g = self.gravity_step(h);
        let p = &mut self.particles;
        let inv_mass = &p.inv_mass;
        for_ranges_mut(team, &mut p.v, &|r, v| gravity_range(v, &inv_mass[r], g));
    }

    /// `x0 = x`, then `x += h v` for every free particle, over the flat arrays (which the
    /// compiler vectorises), after `v += g` when `gravity` is given (a scene without force
    /// groups: [`predict_range`]); then each moving pin goes to its target at `t`, with the
    /// velocity that takes it there. The moving pins are listed in particle order, so those of a range
    /// are a run of the list, and the part that owns the range moves them (a pins-only scene of
    /// 4,096 moving pins was 1.3× slower on two threads than on one while the main thread moved
    /// them after the split loop: it had to fetch every pin's position back from the other
    /// core's cache).
    fn predict(&mut self, h: f64, t: f64, gravity: Option<[f64; 3]>, team: TeamRef<'_>) {
        let frame_pos = t * self.settings.frame_rate;
        let (objects, transforms, pins) =
            (&self.objects, &self.object_transforms, &self.moving_pins);
        let p = &mut self.particles;
        let (inv_mass, object, rest) = (&p.inv_mass, &p.object, &p.rest);
        let n = p.x.len();
        let (x, x0, v) = (
            SharedArray::new(&mut p.x),
            SharedArray::new(&mut p.x0),
            SharedArray::new(&mut p.v),
        );
        for_ranges(team, n, &|r| {
            // SAFETY: each range is its own part of `x`, `x0` and `v` (exclusively borrowed for
            // this call; every particle array has the same length).
            let (x, x0, v) = unsafe {
                (
                    x.slice(r.start, r.len()),
                    x0.slice(r.start, r.len()),
                    v.slice(r.start, r.len()),
                )
            };
            predict_range(x, x0, v, &inv_mass[r.clone()], h, gravity);
            let first = pins.partition_point(|&i| (i as usize) < r.start);
            let end = pins.partition_point(|&i| (i as usize) < r.end);
            for &i in &pins[first..end] {
                let i = i as usize;
                let oi = object[i] as usize;
                let target = pin_target(&objects[oi], transforms[oi], rest[i], i, frame_pos);
                let k = i - r.start;
                v[k] = ((target - DVec3::from_array(x0[k])) / h).to_array();
                x[k] = target.to_array();
            }
        });
    }

    /// `v = (x − x0) / h` for every particle, block by block; with `check`, each block's
    /// positions and the velocities it replaces are first checked to be finite: the check the
    /// schedule's last call would make ([`NonFinite`]), in the same pass over the positions.
    /// On a non-finite value the velocities are left as they are from that block on, and the
    /// caller stops the step with the error.
    fn update_velocities(&mut self, h: f64, team: TeamRef<'_>, check: bool) -> NonFinite {
        /// Particles checked and updated at a time: the block's positions, start positions and
        /// velocities (72 KiB) stay in the core's cache between the check and the update.
        const BLOCK: usize = 1024;
        let p = &mut self.particles;
        let inv_h = 1.0 / h;
        let (x, x0) = (&p.x, &p.x0);
        let found = NonFinite::default();
        for_ranges_mut(team, &mut p.v, &|r, v| {
            let (x, x0) = (&x[r.clone()], &x0[r]);
            for ((v, x), x0) in v
                .chunks_mut(BLOCK)
                .zip(x.chunks(BLOCK))
                .zip(x0.chunks(BLOCK))
            {
                if check && !found.check(x, v) {
                    return;
                }
                velocity_range(v, x, x0, inv_h);
            }
        });
        found
    }

    fn damp(&mut self, h: f64, team: TeamRef<'_>) {
        if self.settings.damping <= 0.0 {
            return;
        }
        let k = (-self.settings.damping * h).exp();
        for_ranges_mut(team, &mut self.particles.v, &|_, v| {
            for v in v.as_flattened_mut() {
                *v *= k;
            }
        });
    }

    /// Calls group `g`'s `stage`, then checks that every position and velocity is finite
    /// (unless the scene turned the check off, or `check` is false: the caller checks).
    #[allow(clippy::too_many_arguments)]
    fn call_group(
        &mut self,
        g: usize,
        stage: Stage,
        substep: u32,
        pass: u32,
        passes: u32,
        team: TeamRef<'_>,
        check: bool,
    ) -> Result<(), StepError> {
        let p = &mut self.particles;
        let mut ctx = SolveContext {
            x: RSliceMut::from_mut_slice(&mut p.x),
            v: RSliceMut::from_mut_slice(&mut p.v),
            x0: RSlice::from_slice(&p.x0),
            inv_mass: RSlice::from_slice(&p.inv_mass),
            object: RSlice::from_slice(&p.object),
            flags: RSlice::from_slice(&p.flags),
            attributes: RSlice::from_slice(&[]),
            h: 1.0 / (self.settings.frame_rate * self.settings.substeps as f64),
            time: self.time,
            gravity: self.settings.gravity,
            frame: self.frame,
            substep,
            substeps: self.settings.substeps,
            pass,
            passes,
            team,
            pushes: RSliceMut::from_mut_slice(&mut p.pushes),
            kicks: RSliceMut::from_mut_slice(&mut p.kicks),
        };
        let group = &mut self.groups[g];
        let result = match stage {
            Stage::Force => group.group.force(&mut ctx),
            Stage::BeginSubstep => group.group.begin_substep(&mut ctx),
            Stage::Project => group.group.project(&mut ctx),
            Stage::EndSubstep => group.group.end_substep(&mut ctx),
            Stage::Report => RResult::ROk(()),
        };
        if let RResult::RErr(error) = result {
            return Err(StepError::Plugin {
                plugin: group.plugin.clone(),
                path: group.path.clone(),
                group: group.name.clone(),
                stage,
                frame: self.frame,
                substep,
                error: Box::new(error),
            });
        }
        if check && self.settings.check_finite {
            let found = NonFinite::default();
            // `x` and `v` have one length: every particle array does.
            let (x, v) = (&self.particles.x, &self.particles.v);
            for_ranges(team, x.len(), &|r| {
                found.check(&x[r.clone()], &v[r]);
            });
            self.non_finite_error(g, stage, substep, found)?;
        }
        Ok(())
    }

    /// The error naming group `g` and its `stage` if `found` saw a non-finite position (first)
    /// or velocity.
    fn non_finite_error(
        &self,
        g: usize,
        stage: Stage,
        substep: u32,
        found: NonFinite,
    ) -> Result<(), StepError> {
        let what = if found.x.into_inner() {
            "position"
        } else if found.v.into_inner() {
            "velocity"
        } else {
            return Ok(());
        };
        let group = &self.groups[g];
        Err(StepError::NonFinite {
            plugin: group.plugin.clone(),
            path: group.path.clone(),
            group: group.name.clone(),
            stage,
            frame: self.frame,
            substep,
            what,
        })
    }

    fn read_context(&mut self) -> SolveContext<'_> {
        let p = &mut self.particles;
        SolveContext {
            x: RSliceMut::from_mut_slice(&mut p.x),
            v: RSliceMut::from_mut_slice(&mut p.v),
            x0: RSlice::from_slice(&p.x0),
            inv_mass: RSlice::from_slice(&p.inv_mass),
            object: RSlice::from_slice(&p.object),
            flags: RSlice::from_slice(&p.flags),
            attributes: RSlice::from_slice(&[]),
            h: 1.0 / (self.settings.frame_rate * self.settings.substeps as f64),
            time: self.time,
            gravity: self.settings.gravity,
            frame: self.frame,
            substep: 0,
            substeps: self.settings.substeps,
            pass: 0,
            passes: 1,
            team: TeamRef::serial(),
            pushes: RSliceMut::from_mut_slice(&mut p.pushes),
            kicks: RSliceMut::from_mut_slice(&mut p.kicks),
        }
    }

    /// Every group's residual at the current positions.
    pub fn residuals(&mut self) -> Result<Vec<Residual>, StepError> {
        let frame = self.frame;
        let mut groups = std::mem::take(&mut self.groups);
        let mut out = Vec::with_capacity(groups.len());
        let mut failure = None;
        {
            let ctx = self.read_context();
            for g in &mut groups {
                match g.group.residual(&ctx) {
                    RResult::ROk(r) => out.push(r),
                    RResult::RErr(error) => {
                        failure = Some(StepError::Plugin {
                            plugin: g.plugin.clone(),
                            path: g.path.clone(),
                            group: g.name.clone(),
                            stage: Stage::Report,
                            frame,
                            substep: 0,
                            error: Box::new(error),
                        });
                        break;
                    }
                }
            }
        }
        self.groups = groups;
        match failure {
            Some(e) => Err(e),
            None => Ok(out),
        }
    }

    /// Named values each group reports (prefixed `group.`).
    pub fn reports(&mut self) -> Result<Vec<(String, f64)>, StepError> {
        let frame = self.frame;
        let groups = std::mem::take(&mut self.groups);
        let mut out = Vec::new();
        let mut failure = None;
        {
            let ctx = self.read_context();
            for g in groups.iter().filter(|g| g.stages.contains(Stages::REPORT)) {
                match g.group.report(&ctx) {
                    RResult::ROk(stats) => out.extend(
                        stats
                            .iter()
                            .map(|s| (format!("{}.{}", g.name, s.name), s.value)),
                    ),
                    RResult::RErr(error) => {
                        failure = Some(StepError::Plugin {
                            plugin: g.plugin.clone(),
                            path: g.path.clone(),
                            group: g.name.clone(),
                            stage: Stage::Report,
                            frame,
                            substep: 0,
                            error: Box::new(error),
                        });
                        break;
                    }
                }
            }
        }
        self.groups = groups;
        match failure {
            Some(e) => Err(e),
            None => Ok(out),
        }
    }

    /// Kinetic energy of the dynamic particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        let p = &self.particles;
        p.v.iter()
            .zip(&p.inv_mass)
            .filter(|(_, &w)| w > 0.0)
            .map(|(v, &w)| 0.5 * DVec3::from_array(*v).length_squared() / w)
            .sum()
    }

    /// Gravitational potential energy of the dynamic particles relative to the origin (J).
    pub fn gravity_energy(&self) -> f64 {
        let g = DVec3::from_array(self.settings.gravity);
        let p = &self.particles;
        p.x.iter()
            .zip(&p.inv_mass)
            .filter(|(_, &w)| w > 0.0)
            .map(|(x, &w)| -g.dot(DVec3::from_array(*x)) / w)
            .sum()
    }

    /// Positions as glam vectors.
    pub fn positions(&self) -> &[DVec3] {
        nucleus_sdk::view::as_dvec3(&self.particles.x)
    }

    /// Velocities as glam vectors.
    pub fn velocities(&self) -> &[DVec3] {
        nucleus_sdk::view::as_dvec3(&self.particles.v)
    }

    /// The object named `name`.
    pub fn object(&self, name: &str) -> Option<&ObjectData> {
        self.objects.iter().find(|o| o.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::all_finite;

    #[test]
    fn all_finite_finds_one_nan_or_infinity_anywhere_and_accepts_every_finite_value() {
        let finite = [
            0.0,
            -0.0,
            1.0,
            -1e300,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
        ];
        let mut xs: Vec<[f64; 3]> = (0..1001)
            .map(|k| [finite[k % 8], finite[(k + 3) % 8], 2.0])
            .collect();
        assert!(all_finite(&xs));
        assert!(all_finite(&[]));
        for bad in [f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for (k, c) in [(0, 0), (500, 1), (1000, 2), (3, 2)] {
                let keep = xs[k][c];
                xs[k][c] = bad;
                assert!(!all_finite(&xs), "{bad} at [{k}][{c}]");
                xs[k][c] = keep;
            }
        }
        assert!(all_finite(&xs));
    }
}
