//! The constraint groups: parameters, building the SoA batches from the scene view, and the
//! per-pass loops over them. All numerics live in the pure functions of [`crate::angle`],
//! [`crate::dihedral`] and [`crate::bergou2006_isometric`].

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use nucleus_sdk::colour::{colour_batches, greedy_colours, independent_sets_order};
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::{span, SharedArray, TeamRef};
use serde::{Deserialize, Serialize};

use crate::angle::edge_angle;
use crate::bergou2006_isometric::{curvature_vector, isometric_weights};
use crate::dihedral::{dihedral_angle, wrap_angle};
use crate::lanes::{
    project_colour, project_one_by_one, Dihedral, EdgeAngle, Isometric, Lanes, PassTerms,
};

/// Which constraints a group holds; one per kind of this plugin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `bend`: the dihedral angle of every surface hinge (type 3) and the angle at every
    /// inner curve vertex (type 2).
    Bend,
    /// `bend_isometric`: Bergou's isometric bending on every surface hinge (flat rest).
    BendIsometric,
    /// `shear`: the angle at every corner of every surface triangle (type 2).
    Shear,
    /// `twist`: the dihedral angle of three consecutive curve edges (type 3).
    Twist,
}

impl Kind {
    /// The kind's name in scenes.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Bend => "bend",
            Kind::BendIsometric => "bend_isometric",
            Kind::Shear => "shear",
            Kind::Twist => "twist",
        }
    }

    /// The default compliance (rad/(N·m)).
    pub fn default_compliance(self) -> f64 {
        match self {
            Kind::Bend | Kind::BendIsometric | Kind::Twist => presets::COTTON,
            Kind::Shear => 0.0,
        }
    }
}

/// Bend compliance presets (rad/(N·m)) for cloth of areal density 1 kg/m² (a 1 m × 1 m cloth
/// of 1 kg), from the fabrics' Peirce bending lengths `c` through `α = 1/(ρ g c³)`. For a
/// density ρ (kg/m²), divide by ρ to keep the same drape. See the README for the derivation.
pub mod presets {
    /// Silk, chiffon: bending length ≈ 1.0 cm.
    pub const SILK: f64 = 1e5;
    /// Medium cotton (shirting): ≈ 2.7 cm. The default of `bend`, `bend_isometric`, `twist`.
    pub const COTTON: f64 = 5e3;
    /// Denim, canvas: ≈ 4.7 cm.
    pub const DENIM: f64 = 1e3;
    /// Garment leather, felt: ≈ 10 cm.
    pub const LEATHER: f64 = 1e2;
}

/// The parameters of every kind of this plugin, as written in a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BendParams {
    /// Compliance α of each angle constraint (rad/(N·m), ≥ 0): the inverse of the hinge's
    /// angular stiffness. 0 is rigid in that mode.
    pub compliance: f64,
}

impl BendParams {
    /// The default parameters of `kind`.
    pub fn default_for(kind: Kind) -> Self {
        Self {
            compliance: kind.default_compliance(),
        }
    }

    /// The self-description of every parameter of `kind`.
    pub fn specs(kind: Kind) -> Vec<ParamSpec> {
        let doc = match kind {
            Kind::Bend | Kind::BendIsometric => {
                "compliance of each hinge (1/bending stiffness; for a regular grid ≈ 1/D, D the \
                 cloth's bending rigidity in N·m); 0 is rigid. Presets at 1 kg/m²: silk 1e5, \
                 cotton 5e3, denim 1e3, leather 1e2"
            }
            Kind::Shear => {
                "compliance of each triangle corner angle (1/angular stiffness); 0 keeps the \
                 corner angles rigid"
            }
            Kind::Twist => {
                "compliance of each twist hinge (1/torsional stiffness per joint); 0 is rigid"
            }
        };
        vec![ParamSpec::number("compliance", kind.default_compliance())
            .doc(doc)
            .unit("rad/(N·m)")
            .range(0.0, f64::INFINITY)]
    }

    /// Checks the values against [`specs`](Self::specs); an error names the parameter.
    pub fn validate(&self, kind: Kind) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs(kind))
    }
}

/// How the four-particle constraints of a group are solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum QuadModel {
    /// Signed dihedral angle towards a rest angle ([`crate::dihedral`]).
    Dihedral,
    /// Bergou's isometric bending towards flat ([`crate::bergou2006_isometric`]).
    Isometric,
}

/// All the angle constraints of one group, struct-of-arrays, in two batches: hinges of four
/// particles and angles of three.
#[derive(Clone, Debug)]
pub struct BendGroup {
    kind: Kind,
    quad_model: QuadModel,
    /// Hinges `[i, j, k, l]` (axis i→j, wings k and l), global particle indices.
    quads: Vec<[u32; 4]>,
    /// Rest dihedral angle of each hinge (rad, in (−π, π]); 0 for the isometric model.
    quad_rest: Vec<f64>,
    /// Isometric weights K' of each hinge (1/m); empty for the dihedral model.
    quad_weights: Vec<[f64; 4]>,
    /// Multiplier of each hinge accumulated over the passes of the substep.
    quad_lambda: Vec<f64>,
    /// The hinges' colours, in order ([`colour_order`]).
    quad_batches: Batches,
    /// Angles `[i, j, k]` at `j`, global particle indices.
    triples: Vec<[u32; 3]>,
    /// Rest angle of each (rad, in [0, π]).
    triple_rest: Vec<f64>,
    /// Multiplier of each.
    triple_lambda: Vec<f64>,
    /// The angles' colours, in order.
    triple_batches: Batches,
    /// Compliance α of every constraint (rad/(N·m)).
    compliance: f64,
    /// Constraints not built because their rest shape is degenerate.
    dropped: u64,
    /// Constraints skipped in the last pass (degenerate now; for the isometric model, flat).
    skipped: u64,
    /// Particle slices must hold more than this index (`None` for an empty group).
    max_index: Option<u32>,
}

/// Whether the triangle `t` of `object` is a surface of its own (in no tet). Views built
/// without tet counts count as surfaces.
fn is_surface(object: &ObjectView<'_>, t: u32) -> bool {
    !matches!(object.triangle_tet_count.as_slice().get(t as usize), Some(&c) if c != 0)
}

/// The four-particle chains `[b, c, a, d]` of three consecutive curve edges a–b, b–c, c–d
/// (as a hinge: axis b→c, wings a and d), each once, from the curve's edge pairs. Sorted.
fn curve_chains(pairs: &[EdgePairView]) -> Vec<[u32; 4]> {
    // Curve neighbours of every vertex that is the middle of some pair.
    let mut neighbours: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
    for &[i, j, k] in pairs {
        let n = neighbours.entry(j).or_default();
        n.push(i);
        n.push(k);
    }
    for n in neighbours.values_mut() {
        n.sort_unstable();
        n.dedup();
    }
    let mut chains = Vec::new();
    for (&b, nb) in &neighbours {
        for &c in nb.iter().filter(|&&c| c > b) {
            let Some(nc) = neighbours.get(&c) else {
                continue;
            };
            for &a in nb.iter().filter(|&&a| a != c) {
                for &d in nc.iter().filter(|&&d| d != b && d != a) {
                    chains.push([b, c, a, d]);
                }
            }
        }
    }
    chains
}

type EdgePairView = [u32; 3];

/// The order that lists constraints of `N` particles colour by colour (each colour in the
/// given order), and its batches: consecutive runs of one colour, flagged `true` when its
/// constraints share no particle (every colour but the overflow; see
/// [`nucleus_sdk::colour`]). Deterministic; a pass over this order is plain sequential
/// Gauss-Seidel, and each real colour may be split over threads with the same bits.
fn colour_order<const N: usize>(ids: &[[u32; N]], particles: usize) -> (Vec<usize>, Batches) {
    let colours = greedy_colours(ids.len(), particles, |k| {
        ids[k].into_iter().map(|p| p as usize)
    });
    let order = independent_sets_order(&colours);
    let batches = colour_batches(&colours, &order);
    (order, batches)
}

/// Consecutive ranges of a group's constraints of one colour each, `true` when they share no
/// particle (see [`colour_order`]).
type Batches = Vec<(Range<usize>, bool)>;

/// Colours of at least this many constraints are split over the host's thread team (as
/// `stretch` does with its edges: below it, the team's hand-off costs more than it saves).
const PARALLEL_MIN_CONSTRAINTS: usize = 256;

fn gather<const N: usize>(x: &[DVec3], ids: &[u32; N]) -> [DVec3; N] {
    std::array::from_fn(|k| x[ids[k] as usize])
}

/// Checks that every index of a constraint lies in the object's particles and that they are
/// distinct; an error names the object.
fn check_ids<const N: usize>(
    ids: &[u32; N],
    object: &ObjectView<'_>,
    particles: usize,
    what: &str,
) -> Result<(), PluginError> {
    let range = object.particles();
    for (a, &i) in ids.iter().enumerate() {
        if !range.contains(&(i as usize)) || i as usize >= particles {
            return Err(PluginError::bad_object(
                object.name.as_str(),
                format!(
                    "{what} {ids:?} is outside the object's particles {}..{} (the scene has {particles})",
                    range.start, range.end
                ),
            ));
        }
        if ids[..a].contains(&i) {
            return Err(PluginError::bad_object(
                object.name.as_str(),
                format!("{what} {ids:?} uses particle {i} twice"),
            ));
        }
    }
    Ok(())
}

impl BendGroup {
    /// The group of `kind` over every target object of `scene` (an object listed twice is
    /// used once), with rest angles (or isometric weights) from the scene's rest positions.
    /// Constraints whose particles all have inverse mass 0 are left out; so are those whose
    /// rest shape is degenerate (counted in [`dropped`](Self::dropped)). Objects with nothing
    /// of the kind (a curve for `shear`, a cloth for `twist`) contribute nothing.
    ///
    /// Errors: a parameter out of range (naming it); a constraint outside its object's
    /// particles or using a particle twice (naming the object); a target outside the scene.
    pub fn new(
        kind: Kind,
        params: &BendParams,
        scene: &SceneView<'_>,
    ) -> Result<Self, PluginError> {
        params.validate(kind)?;
        let rest_x = scene.rest_positions();
        let inv_mass = scene.inv_mass.as_slice();
        let particles = rest_x.len().min(inv_mass.len());
        let quad_model = match kind {
            Kind::BendIsometric => QuadModel::Isometric,
            _ => QuadModel::Dihedral,
        };
        let mut group = Self {
            kind,
            quad_model,
            quads: Vec::new(),
            quad_rest: Vec::new(),
            quad_weights: Vec::new(),
            quad_lambda: Vec::new(),
            quad_batches: Vec::new(),
            triples: Vec::new(),
            triple_rest: Vec::new(),
            triple_lambda: Vec::new(),
            triple_batches: Vec::new(),
            compliance: params.compliance,
            dropped: 0,
            skipped: 0,
            max_index: None,
        };
        let all_pinned = |ids: &[u32]| ids.iter().all(|&i| inv_mass[i as usize] == 0.0);

        for (_, object) in scene.unique_targets()? {
            // Hinges: surface triangle pairs (bend, bend_isometric) or curve chains (twist).
            let hinges: Vec<[u32; 4]> = match kind {
                Kind::Bend | Kind::BendIsometric => object
                    .triangle_pairs
                    .iter()
                    .filter(|p| {
                        is_surface(object, p.triangles[0]) && is_surface(object, p.triangles[1])
                    })
                    .map(|p| [p.edge[0], p.edge[1], p.opposite[0], p.opposite[1]])
                    .collect(),
                Kind::Twist => {
                    let pairs: Vec<EdgePairView> =
                        object.edge_pairs.iter().map(|p| p.vertices).collect();
                    for p in &pairs {
                        check_ids(p, object, particles, "edge pair")?;
                    }
                    curve_chains(&pairs)
                }
                Kind::Shear => Vec::new(),
            };
            for ids in hinges {
                check_ids(&ids, object, particles, "hinge")?;
                if all_pinned(&ids) {
                    continue;
                }
                let x = gather(rest_x, &ids);
                match quad_model {
                    QuadModel::Dihedral => match dihedral_angle(&x) {
                        Some(phi) => {
                            group.quads.push(ids);
                            group.quad_rest.push(phi);
                        }
                        None => group.dropped += 1,
                    },
                    QuadModel::Isometric => match isometric_weights(&x) {
                        Some(k) => {
                            group.quads.push(ids);
                            group.quad_rest.push(0.0);
                            group.quad_weights.push(k);
                        }
                        None => group.dropped += 1,
                    },
                }
            }
            // Angles: inner curve vertices (bend) or triangle corners (shear).
            let angles: Vec<[u32; 3]> = match kind {
                Kind::Bend => object.edge_pairs.iter().map(|p| p.vertices).collect(),
                Kind::Shear => object
                    .triangles
                    .iter()
                    .enumerate()
                    .filter(|&(t, _)| is_surface(object, t as u32))
                    .flat_map(|(_, &[a, b, c])| [[c, a, b], [a, b, c], [b, c, a]])
                    .collect(),
                Kind::BendIsometric | Kind::Twist => Vec::new(),
            };
            for ids in angles {
                check_ids(&ids, object, particles, "angle")?;
                if all_pinned(&ids) {
                    continue;
                }
                match edge_angle(&gather(rest_x, &ids)) {
                    Some(phi) => {
                        group.triples.push(ids);
                        group.triple_rest.push(phi);
                    }
                    None => group.dropped += 1,
                }
            }
        }

        let (order, batches) = colour_order(&group.quads, particles);
        group.quad_batches = batches;
        group.quads = order.iter().map(|&k| group.quads[k]).collect();
        group.quad_rest = order.iter().map(|&k| group.quad_rest[k]).collect();
        if quad_model == QuadModel::Isometric {
            group.quad_weights = order.iter().map(|&k| group.quad_weights[k]).collect();
        }
        let (order, batches) = colour_order(&group.triples, particles);
        group.triple_batches = batches;
        group.triples = order.iter().map(|&k| group.triples[k]).collect();
        group.triple_rest = order.iter().map(|&k| group.triple_rest[k]).collect();
        group.quad_lambda = vec![0.0; group.quads.len()];
        group.triple_lambda = vec![0.0; group.triples.len()];
        group.max_index = group
            .quads
            .iter()
            .flatten()
            .chain(group.triples.iter().flatten())
            .copied()
            .max();
        Ok(group)
    }

    /// The kind of the group.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// The hinges `[i, j, k, l]` (axis i→j, wings k, l), global particle indices.
    pub fn hinges(&self) -> &[[u32; 4]] {
        &self.quads
    }

    /// The rest angle of each hinge (rad, signed, in (−π, π]; 0 for the isometric model).
    pub fn hinge_rest_angles(&self) -> &[f64] {
        &self.quad_rest
    }

    /// The angles `[i, j, k]` at `j`, global particle indices.
    pub fn angles(&self) -> &[[u32; 3]] {
        &self.triples
    }

    /// The rest value of each angle (rad, in [0, π]).
    pub fn angle_rest_values(&self) -> &[f64] {
        &self.triple_rest
    }

    /// Constraints left out because their rest shape is degenerate (zero-length edge,
    /// zero-area triangle, collinear curve points for twist).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Constraints skipped in the last pass.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }
}

/// Projects the constraints `ids[k]` (rest value or weights `rest[k]`) with `K`'s kernels,
/// batch by batch, in order, accumulating each one's multiplier in `lambda[k]`, and returns
/// how many were skipped. An independent batch goes four at a time where the processor can
/// ([`project_colour`], with the bits of one at a time), split over `team` when it holds at
/// least [`PARALLEL_MIN_CONSTRAINTS`]; a batch whose constraints may share particles (the
/// overflow colour) goes one at a time ([`project_one_by_one`]) on this thread.
///
/// # Safety
/// Every index of `ids` is below `x.len()`, each constraint's indices are distinct, and the
/// constraints of a batch flagged independent share no particle (as [`colour_order`] makes
/// them).
unsafe fn project_batches<const N: usize, K: Lanes<N>>(
    team: TeamRef<'_>,
    (x, w): (&mut [DVec3], &[f64]),
    (ids, rest): (&[[u32; N]], &[K::Rest]),
    lambda: &mut [f64],
    batches: &[(Range<usize>, bool)],
    terms: PassTerms,
) -> u64
where
    K::Rest: Sync,
{
    assert!(
        rest.len() == ids.len()
            && lambda.len() == ids.len()
            && batches.last().is_none_or(|b| b.0.end <= ids.len())
    );
    let (xs, lambdas) = (SharedArray::new(x), SharedArray::new(lambda));
    let skipped = AtomicU64::new(0);
    let run = |r: Range<usize>, independent: bool| {
        // SAFETY: `r` is a range of `ids` (and so of `rest` and of the multipliers, one per
        // constraint; asserted) that this call or this part of a split batch owns; indices are
        // in bounds and distinct within each constraint (our caller's contract), and a split
        // batch is independent, so no other part touches these particles meanwhile.
        let skip = unsafe {
            let lambda = lambdas.slice(r.start, r.len());
            let (ids, rest) = (&ids[r.clone()], &rest[r]);
            if independent {
                project_colour::<N, K>(xs, w, ids, rest, lambda, terms)
            } else {
                project_one_by_one::<N, K>(xs, w, ids, rest, lambda, terms)
            }
        };
        skipped.fetch_add(skip, Ordering::Relaxed);
    };
    let parts = team.parts();
    for (range, independent) in batches {
        if parts >= 2 && *independent && range.len() >= PARALLEL_MIN_CONSTRAINTS {
            team.run(&|part| {
                let s = span(part, parts, range.len());
                run(range.start + s.start..range.start + s.end, true)
            });
        } else {
            run(range.clone(), *independent);
        }
    }
    skipped.into_inner()
}

impl ConstraintGroup for BendGroup {
    fn stages(&self) -> Stages {
        Stages::BEGIN_SUBSTEP | Stages::PROJECT | Stages::REPORT
    }

    fn len(&self) -> usize {
        self.quads.len() + self.triples.len()
    }

    /// Resets every λ to 0: XPBD's λ is the total multiplier of the substep.
    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        self.quad_lambda.fill(0.0);
        self.triple_lambda.fill(0.0);
        Ok(())
    }

    /// One Gauss-Seidel pass: every hinge, then every angle, colour by colour
    /// (`colour_order`). A colour of at least `PARALLEL_MIN_CONSTRAINTS` (256) constraints is
    /// split into contiguous parts over the host's thread team (`ctx.team`): its constraints
    /// share no particle, so each reads and writes only its own, and the bits are the same on
    /// any thread count. Hinges (dihedral or isometric) and angles of a colour go four at a
    /// time through AVX2's lanes where the processor has them (the `lanes` module), with the same bits.
    /// Deterministic, no allocation.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (h, team) = (ctx.substep_length()?, ctx.team);
        ctx.check_holds(self.max_index)?;
        let p = ctx.particles();
        let (x, w) = (p.x, p.inv_mass);
        let alpha = self.compliance;
        let (quads, batches) = (&self.quads[..], &self.quad_batches[..]);
        let hinges = &mut self.quad_lambda[..];
        // The contract of `project_batches`, for the three calls below: the group's largest
        // index was checked against the state above; `new` refused constraints that use a
        // particle twice (and `curve_chains` makes none) and ordered each by `colour_order`.
        let terms = PassTerms { alpha, h };
        // Four constraints at a time where the processor can, with the same bits.
        // SAFETY: the contract, as said above; one rest value (or set of weights) per
        // constraint.
        let mut skipped = unsafe {
            match self.quad_model {
                QuadModel::Dihedral => project_batches::<4, Dihedral>(
                    team,
                    (x, w),
                    (quads, &self.quad_rest),
                    hinges,
                    batches,
                    terms,
                ),
                QuadModel::Isometric => project_batches::<4, Isometric>(
                    team,
                    (x, w),
                    (quads, &self.quad_weights),
                    hinges,
                    batches,
                    terms,
                ),
            }
        };
        // SAFETY: as for the hinges.
        skipped += unsafe {
            project_batches::<3, EdgeAngle>(
                team,
                (x, w),
                (&self.triples, &self.triple_rest),
                &mut self.triple_lambda,
                &self.triple_batches,
                terms,
            )
        };
        self.skipped = skipped;
        Ok(())
    }

    /// The angle error `|C|` of every constraint whose angle is defined (rad): for the
    /// isometric model, the hinge's actual dihedral angle away from flat, so both bend
    /// models are measured alike. `energy` is `Σ ½ C²/α` (`C = |v|` for the isometric model;
    /// 0 when `α = 0`), in J.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let mut out = Residual::default();
        let mut sum_sq = 0.0;
        let inv_alpha = if self.compliance > 0.0 {
            1.0 / self.compliance
        } else {
            0.0
        };
        let in_range = |ids: &[u32]| ids.iter().all(|&i| (i as usize) < x.len());
        let mut add = |error: f64, energy_c: f64| {
            out.count += 1;
            out.max = out.max.max(error);
            sum_sq += error * error;
            out.energy += 0.5 * energy_c * energy_c * inv_alpha;
        };
        for (n, ids) in self.quads.iter().enumerate() {
            if !in_range(ids) {
                continue;
            }
            let xs = gather(x, ids);
            let Some(phi) = dihedral_angle(&xs) else {
                continue;
            };
            match self.quad_model {
                QuadModel::Dihedral => {
                    let c = wrap_angle(phi - self.quad_rest[n]);
                    add(c.abs(), c);
                }
                QuadModel::Isometric => {
                    let v = curvature_vector(&xs, &self.quad_weights[n]);
                    add(phi.abs(), v.length());
                }
            }
        }
        for (ids, &rest) in self.triples.iter().zip(&self.triple_rest) {
            if !in_range(ids) {
                continue;
            }
            if let Some(phi) = edge_angle(&gather(x, ids)) {
                let c = phi - rest;
                add(c.abs(), c);
            }
        }
        if out.count > 0 {
            out.rms = (sum_sq / out.count as f64).sqrt();
        }
        out
    }

    /// `skipped`: constraints skipped in the last pass (degenerate now; for
    /// `bend_isometric` also hinges that are exactly flat). `dropped`: constraints left out
    /// at build time because their rest shape is degenerate.
    fn report(&self, _ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        out.push(("skipped".into(), self.skipped as f64));
        out.push(("dropped".into(), self.dropped as f64));
    }
}

fn build(
    kind: Kind,
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: BendParams = params::parse(params_json)?;
    Ok(Box::new(BendGroup::new(kind, &params, scene)?))
}

/// The factory of `bend`.
pub(crate) fn build_bend(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    build(Kind::Bend, params_json, scene)
}

/// The factory of `bend_isometric`.
pub(crate) fn build_isometric(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    build(Kind::BendIsometric, params_json, scene)
}

/// The factory of `shear`.
pub(crate) fn build_shear(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    build(Kind::Shear, params_json, scene)
}

/// The factory of `twist`.
pub(crate) fn build_twist(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    build(Kind::Twist, params_json, scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_of_a_polyline_are_its_consecutive_quadruples() {
        // 0-1-2-3-4: pairs at 1, 2, 3.
        let pairs = [[0, 1, 2], [1, 2, 3], [2, 3, 4]];
        assert_eq!(curve_chains(&pairs), vec![[1, 2, 0, 3], [2, 3, 1, 4]]);
    }

    #[test]
    fn chains_of_a_closed_loop_and_a_branch() {
        // A closed square 0-1-2-3-0: four middle edges, each with one chain.
        let pairs = [[1, 0, 3], [0, 1, 2], [1, 2, 3], [0, 3, 2]];
        let chains = curve_chains(&pairs);
        assert_eq!(chains.len(), 4, "{chains:?}");
        // A triangle loop 0-1-2-0 has no chain of four distinct points.
        assert!(curve_chains(&[[1, 0, 2], [0, 1, 2], [0, 2, 1]]).is_empty());
        // A Y: 0-1, 1-2, 1-3, 3-4: chains through the middle edge 1-3 from 0 and from 2.
        let y = [[0, 1, 2], [0, 1, 3], [2, 1, 3], [1, 3, 4]];
        assert_eq!(curve_chains(&y), vec![[1, 3, 0, 4], [1, 3, 2, 4]]);
    }

    #[test]
    fn constraints_of_one_colour_share_no_particle() {
        // Hinges of a strip of triangles.
        let ids: Vec<[u32; 4]> = (0..40).map(|k| [k, k + 1, k + 2, k + 3]).collect();
        let (order, batches) = colour_order(&ids, 43);
        assert!(batches.iter().all(|(_, independent)| *independent));
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..40).collect::<Vec<_>>(), "a permutation");
        // Consecutive constraints in the new order share no particle, except at the
        // boundaries between colours.
        let shared = order
            .windows(2)
            .filter(|w| ids[w[0]].iter().any(|p| ids[w[1]].contains(p)))
            .count();
        assert!(shared <= 4, "{shared} shared neighbours");
    }
}
