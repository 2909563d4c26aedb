//! The `stretch` group: one SoA batch holding the distance constraint of every edge of the
//! objects the group is applied to, projected Gauss-Seidel in index order.

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use serde::{Deserialize, Serialize};

use crate::chebyshev::{Chebyshev, MAX_RHO};
use crate::distance::EdgeMaterial;
use crate::lanes::{
    project_colour_compliant, project_colour_hard, project_edges_compliant_one_by_one,
    project_edges_hard_one_by_one,
};
use nucleus_sdk::colour::{colour_batches, greedy_colours, independent_sets_order};
use nucleus_sdk::team::{span, SharedArray};

/// Smallest valid `rest_length_scale`: the scale must be positive, and a bound that prints
/// as a plain number keeps the host's parameter tables and messages readable.
pub const MIN_REST_LENGTH_SCALE: f64 = 1e-6;

/// The parameters of the `stretch` kind, as written in a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StretchParams {
    /// Compliance when stretched, `C > 0` (m/N, ≥ 0). Default 0: inextensible.
    pub compliance: f64,
    /// Compliance when compressed, `C < 0` (m/N, ≥ 0). Default 0: incompressible. Set it high
    /// to let cloth buckle instead of compressing.
    pub compression_compliance: f64,
    /// Rest length = scale × rest-shape length (dimensionless, ≥ 1e-6). Default 1.
    pub rest_length_scale: f64,
    /// Damper in parallel with each compliant edge (N·s/m, ≥ 0). Default 0: none.
    pub damping: f64,
    /// Chebyshev acceleration of the passes within a substep (see [`crate::chebyshev`]):
    /// the estimated spectral radius `ρ` of one pass (dimensionless, 0 to 0.9999). Default 0:
    /// off. Only acts with more than `chebyshev_delay` passes per substep.
    pub chebyshev_rho: f64,
    /// Passes per substep left unaccelerated before the Chebyshev weights start (≥ 1).
    /// Default 2.
    pub chebyshev_delay: i64,
    /// Under-relaxation `γ` of the accelerated passes (dimensionless, in (0, 1]). Default 1.
    pub chebyshev_gamma: f64,
    /// How a pass solves the edges ([`Blocks`]): `"edges"` (default), one after another;
    /// `"stars"`, all the edges at each particle at once ([`crate::star`]): ten times the work
    /// of a pass, for loads carried through particles far lighter than their neighbours.
    pub blocks: String,
}

/// How a `stretch` pass solves its edges (the `blocks` parameter).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blocks {
    /// One edge after another ([`StretchGroup`]).
    Edges,
    /// All the edges at a particle at once ([`crate::star::StarGroup`]).
    Stars,
}

impl Default for StretchParams {
    fn default() -> Self {
        Self {
            compliance: 0.0,
            compression_compliance: 0.0,
            rest_length_scale: 1.0,
            damping: 0.0,
            chebyshev_rho: 0.0,
            chebyshev_delay: 2,
            chebyshev_gamma: 1.0,
            blocks: "edges".into(),
        }
    }
}

impl StretchParams {
    /// The self-description of every parameter: name, doc, unit, default and valid range.
    pub fn specs() -> Vec<ParamSpec> {
        let d = Self::default();
        vec![
            ParamSpec::number("compliance", d.compliance)
                .doc("compliance when stretched (inverse stiffness); 0 is inextensible")
                .unit("m/N")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("compression_compliance", d.compression_compliance)
                .doc("compliance when compressed; set it high to let cloth buckle, 0 is incompressible")
                .unit("m/N")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("rest_length_scale", d.rest_length_scale)
                .doc("rest length of each edge as a multiple of its length in the rest shape")
                .range(MIN_REST_LENGTH_SCALE, f64::INFINITY),
            ParamSpec::number("damping", d.damping)
                .doc("damper in parallel with each compliant edge, resisting changes of its length; no effect when the compliance is 0")
                .unit("N·s/m")
                .range(0.0, f64::INFINITY),
            ParamSpec::number("chebyshev_rho", d.chebyshev_rho)
                .doc("Chebyshev acceleration of the passes of a substep (Wang 2015): estimated spectral radius of one pass; 0 is off. Measured on the drape: substeps pay more than accelerated passes")
                .range(0.0, MAX_RHO),
            ParamSpec::integer("chebyshev_delay", d.chebyshev_delay)
                .doc("passes per substep left unaccelerated before the Chebyshev weights start")
                .range(1.0, 1e6),
            ParamSpec::number("chebyshev_gamma", d.chebyshev_gamma)
                .doc("under-relaxation of the accelerated passes")
                .range(1e-3, 1.0),
            ParamSpec::text("blocks", &d.blocks)
                .doc("how a pass solves the edges: \"edges\", one after another, or \"stars\", all the edges at each particle at once (ten times the work of a pass; converges where loads pass through particles far lighter than their neighbours, which stalls edge passes)"),
        ]
    }

    /// Checks the values against [`specs`](Self::specs); an error names the parameter.
    pub fn validate(&self) -> Result<(), PluginError> {
        params::validate_against(self, &Self::specs())?;
        self.blocks().map(|_| ())
    }

    /// The `blocks` parameter; an error names it and lists the valid values.
    pub fn blocks(&self) -> Result<Blocks, PluginError> {
        match self.blocks.as_str() {
            "edges" => Ok(Blocks::Edges),
            "stars" => Ok(Blocks::Stars),
            other => Err(PluginError::bad_parameter(
                "blocks",
                format!("\"{other}\" is not one of \"edges\", \"stars\""),
            )),
        }
    }

    /// Both compliances are 0: the material is hard and keeps no multipliers.
    pub fn is_hard(&self) -> bool {
        self.compliance == 0.0 && self.compression_compliance == 0.0
    }

    /// The Chebyshev acceleration these parameters ask for over the particles of `ids`.
    pub(crate) fn chebyshev(&self, ids: &[[u32; 2]]) -> Option<Chebyshev> {
        (self.chebyshev_rho > 0.0).then(|| {
            Chebyshev::new(
                ids,
                self.chebyshev_rho,
                self.chebyshev_delay as u32,
                self.chebyshev_gamma,
            )
        })
    }

    /// The edge material these parameters describe.
    pub fn material(&self) -> EdgeMaterial {
        EdgeMaterial {
            compliance: self.compliance,
            compression_compliance: self.compression_compliance,
            damping: self.damping,
        }
    }
}

/// All the distance constraints of one `stretch` group, struct-of-arrays.
#[derive(Clone, Debug)]
pub struct StretchGroup {
    /// The two global particle indices of each edge.
    ids: Vec<[u32; 2]>,
    /// Rest length of each edge (m).
    rest: Vec<f64>,
    /// Multiplier of each edge accumulated over the passes of the current substep (N·s²);
    /// empty for a hard material, whose step does not use it.
    lambda: Vec<f64>,
    /// Both compliances are 0: the kernel without compliance terms, and no multipliers.
    hard: bool,
    /// Compliances and damping, shared by the whole group.
    material: EdgeMaterial,
    /// Particle slices must hold more than this index (`None` for an empty group).
    max_index: Option<u32>,
    /// Consecutive index ranges of the batch, each flagged `true` if its edges share no
    /// particle (one colour) and may be projected in parallel.
    batches: Vec<(std::ops::Range<usize>, bool)>,
    /// The Chebyshev acceleration of the passes, when `chebyshev_rho > 0`.
    chebyshev: Option<Chebyshev>,
}

/// Below this many edges a colour is projected on the calling thread: handing it to the
/// spinning team costs more than it saves. The team wakes in about a microsecond, so even
/// small colours pay: measured on the 2-core VM with 2 threads against 4,096, the 64 × 64
/// drape at 160 × 1 runs in 27.0 ms per frame instead of 35.1 (whose colours are all below
/// 4,096 edges), the 32 × 32 one in 7.3 instead of 8.6, and the default demo in 1.14 instead of
/// 1.26 ms; 512 was slower than both on the 32 × 32 drape (9.4 ms).
pub(crate) const PARALLEL_MIN_EDGES: usize = 256;

/// The edges of a `stretch` group's targets, checked, with their rest lengths, in the scene's
/// order: what both ways of solving them ([`Blocks`]) start from.
#[derive(Clone, Debug)]
pub(crate) struct Edges {
    /// The two global particle indices of each edge.
    pub ids: Vec<[u32; 2]>,
    /// Rest length of each edge (m).
    pub rest: Vec<f64>,
    /// The largest particle index of any edge (`None` without edges).
    pub max_index: Option<u32>,
    /// The number of particles of the scene.
    pub particles: usize,
}

impl Edges {
    /// One entry per edge of every target object of `scene`, with rest lengths from the
    /// scene's rest positions. Edges whose two particles both have inverse mass 0 are dropped.
    /// An object listed twice among the targets is used once.
    ///
    /// Errors: a parameter out of range (naming it); an edge outside its object's particle
    /// range, joining a particle to itself, or with a non-finite rest length (naming the
    /// object); a target index outside the scene.
    pub fn collect(params: &StretchParams, scene: &SceneView<'_>) -> Result<Edges, PluginError> {
        params.validate()?;
        Edges::scaled(params.rest_length_scale, scene)
    }

    /// As [`collect`](Self::collect), with rest lengths `rest_length_scale` times the rest
    /// shape's and no parameters to check: what every kind that solves the edges one way or
    /// another (`stretch`, `stretch_newton`) starts from.
    pub fn scaled(rest_length_scale: f64, scene: &SceneView<'_>) -> Result<Edges, PluginError> {
        let targets = scene.unique_targets()?;
        let rest_x = scene.rest_positions();
        let inv_mass = scene.inv_mass.as_slice();
        let particles = rest_x.len().min(inv_mass.len());
        let edge_count = targets.iter().map(|(_, o)| o.edges.len()).sum();
        let mut edges = Edges {
            ids: Vec::with_capacity(edge_count),
            rest: Vec::with_capacity(edge_count),
            max_index: None,
            particles,
        };
        for &(_, object) in &targets {
            let range = object.particles();
            let bad = |message: String| PluginError::bad_object(object.name.as_str(), message);
            for &[i, j] in object.edges.as_slice() {
                let (iu, ju) = (i as usize, j as usize);
                if i == j {
                    return Err(bad(format!("edge ({i}, {j}) joins a particle to itself")));
                }
                if !range.contains(&iu) || !range.contains(&ju) || iu.max(ju) >= particles {
                    return Err(bad(format!(
                        "edge ({i}, {j}) is outside the object's particles {}..{} \
                         (the scene has {particles})",
                        range.start, range.end
                    )));
                }
                if inv_mass[iu] == 0.0 && inv_mass[ju] == 0.0 {
                    continue;
                }
                let rest = rest_length_scale * (rest_x[ju] - rest_x[iu]).length();
                if !rest.is_finite() {
                    return Err(bad(format!("edge ({i}, {j}) has a non-finite rest length")));
                }
                edges.ids.push([i, j]);
                edges.rest.push(rest);
                edges.max_index = edges.max_index.max(Some(i.max(j)));
            }
        }
        Ok(edges)
    }
}

/// The strain `|l − l0| / l0` of every edge (for `l0 = 0`, the length `l` itself, in m), and
/// the energy `Σ ½ C²/α` stored in its compliant edges (J): the residual of both ways of
/// solving a `stretch` group.
pub(crate) fn edge_residual(
    ids: &[[u32; 2]],
    rest: &[f64],
    material: &EdgeMaterial,
    x: &[DVec3],
) -> Residual {
    let mut out = Residual::default();
    let mut sum_sq = 0.0;
    for (&[i, j], &rest) in ids.iter().zip(rest) {
        let (Some(&xi), Some(&xj)) = (x.get(i as usize), x.get(j as usize)) else {
            continue;
        };
        let len = (xj - xi).length();
        let c = len - rest;
        let strain = if rest > 0.0 { c.abs() / rest } else { len };
        out.count += 1;
        out.max = out.max.max(strain);
        sum_sq += strain * strain;
        let alpha = material.compliance_for(c);
        if alpha > 0.0 {
            out.energy += 0.5 * c * c / alpha;
        }
    }
    if out.count > 0 {
        out.rms = (sum_sq / out.count as f64).sqrt();
    }
    out
}

impl StretchGroup {
    /// One constraint per edge of every target object of `scene`, with rest lengths from the
    /// scene's rest positions. Edges whose two particles both have inverse mass 0 are dropped.
    /// An object listed twice among the targets is used once. The batch is ordered so that
    /// consecutive edges share no particle (see the [crate docs](crate#order-of-the-projection)).
    ///
    /// Errors: a parameter out of range (naming it); an edge outside its object's particle
    /// range, joining a particle to itself, or with a non-finite rest length (naming the
    /// object); a target index outside the scene.
    pub fn new(params: &StretchParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        Ok(Self::from_edges(params, Edges::collect(params, scene)?))
    }

    /// The group of the given `edges` (checked by [`Edges::collect`]).
    pub(crate) fn from_edges(params: &StretchParams, edges: Edges) -> Self {
        let mut group = Self {
            ids: edges.ids,
            rest: edges.rest,
            lambda: Vec::new(),
            material: params.material(),
            hard: params.is_hard(),
            max_index: edges.max_index,
            batches: Vec::new(),
            chebyshev: None,
        };
        let particles = edges.particles;
        let colours = edge_colours(&group.ids, particles);
        let order = independent_sets_order(&colours);
        group.ids = order.iter().map(|&k| group.ids[k]).collect();
        group.rest = order.iter().map(|&k| group.rest[k]).collect();
        group.batches = colour_batches(&colours, &order);
        if !group.hard {
            group.lambda = vec![0.0; group.ids.len()];
        }
        group.chebyshev = params.chebyshev(&group.ids);
        group
    }

    /// The edges, as global particle indices.
    pub fn ids(&self) -> &[[u32; 2]] {
        &self.ids
    }

    /// The rest length of each edge (m).
    pub fn rest_lengths(&self) -> &[f64] {
        &self.rest
    }

    /// The multiplier of each edge accumulated in the current substep (N·s²); `λ/h²` is the
    /// edge's force (N), negative in tension. Empty for a hard material (both compliances 0),
    /// whose step never reads it, so it is not kept.
    pub fn lambdas(&self) -> &[f64] {
        &self.lambda
    }

    /// The compliances and damping of the group.
    pub fn material(&self) -> &EdgeMaterial {
        &self.material
    }
}

impl ConstraintGroup for StretchGroup {
    /// `project`, and `begin_substep` where there is something to reset: the multipliers of a
    /// compliant material, or the Chebyshev iterates. A hard group without Chebyshev has no
    /// begin stage, so the core neither calls it nor checks the state after it. With the
    /// multipliers' memset, load and store gone too, the 128 × 128 drape at 40 × 1 runs in
    /// 11.1 ms per frame instead of 12.6 on 2 threads and 20.4 instead of 22.7 on one (medians,
    /// back to back; the same bits).
    fn stages(&self) -> Stages {
        substep_stages(self.hard, &self.chebyshev)
    }

    fn len(&self) -> usize {
        self.ids.len()
    }

    /// Resets every λ to 0: XPBD's λ is the total multiplier of the substep, and the
    /// positions just predicted carry none of it yet.
    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        reset_substep(&mut self.lambda, &mut self.chebyshev);
        Ok(())
    }

    /// One Gauss-Seidel pass over the edges in batch order, colour by colour. A colour of at
    /// least `PARALLEL_MIN_EDGES` (256) edges is split into contiguous parts over the host's
    /// thread team (`ctx.team`: `RAYON_NUM_THREADS`, default the machine's cores; see
    /// [`nucleus_sdk::team`]): its edges share no particle, so every edge reads and writes only
    /// its own two particles and the result is bit-identical whatever the thread count. On the 2-core machine the 128 × 128
    /// drape at 40 × 1 runs 1.5× faster on two threads than on one (22.9 → 15.0 ms per frame).
    /// No allocation after the first pass.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (h, team) = (ctx.substep_length()?, ctx.team);
        ctx.check_holds(self.max_index)?;
        let p = ctx.particles();
        if let Some(c) = self.chebyshev.as_mut() {
            c.before_pass(p.x);
        }
        let (x0, w) = (p.x0, p.inv_mass);
        let x = SharedArray::new(p.x);
        let parts = team.parts();
        let lambda = SharedArray::new(&mut self.lambda);
        let (ids, rest, hard) = (&self.ids[..], &self.rest[..], self.hard);
        let terms = self.material.terms(h);
        // Projects the edges `start..start + len` of the batch. Called below only with a whole
        // batch, or with the disjoint parts of one colour at once.
        let project_range = |start: usize, len: usize, independent: bool| {
            let (ids, rest) = (&ids[start..start + len], &rest[start..start + len]);
            // SAFETY: a whole batch runs on this thread alone; the parts of one colour share
            // no particle and take disjoint ranges of the multipliers (which a compliant group
            // holds one per edge). `x` comes from the exclusive borrow of the positions held for
            // this whole call, and the indices were checked above.
            unsafe {
                if hard && independent {
                    // One colour: four edges at a time where the processor can.
                    project_colour_hard(x, x0, w, ids, rest)
                } else if hard {
                    // The kernel with the shorter dependency chain.
                    project_edges_hard_one_by_one(x, x0, w, ids, rest)
                } else if independent {
                    let lambda = lambda.slice(start, len);
                    project_colour_compliant(x, x0, w, ids, rest, lambda, &terms)
                } else {
                    let lambda = lambda.slice(start, len);
                    project_edges_compliant_one_by_one(x, x0, w, ids, rest, lambda, &terms)
                }
            }
        };
        for (range, independent) in &self.batches {
            match parts {
                2.. if *independent && range.len() >= PARALLEL_MIN_EDGES => {
                    team.run(&|part| {
                        let span = span(part, parts, range.len());
                        project_range(range.start + span.start, span.len(), true)
                    });
                }
                _ => project_range(range.start, range.len(), *independent),
            }
        }
        if let Some(c) = self.chebyshev.as_mut() {
            c.after_pass(p.x, w);
        }
        Ok(())
    }

    /// Strain `|l − l0| / l0` of every edge (for `l0 = 0`, the length `l` itself, in m), and
    /// the energy `Σ ½ C²/α` stored in the compliant edges (J).
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        edge_residual(&self.ids, &self.rest, &self.material, ctx.positions())
    }
}

/// Greedy colouring of the edges in their given order ([`greedy_colours`]): the edges of one
/// colour (below [`OVERFLOW_COLOUR`](nucleus_sdk::colour::OVERFLOW_COLOUR)) share no particle.
pub(crate) fn edge_colours(ids: &[[u32; 2]], particles: usize) -> Vec<usize> {
    greedy_colours(ids.len(), particles, |k| {
        ids[k].into_iter().map(|p| p as usize)
    })
}

/// The stages of a `stretch` group, edges or stars: `begin_substep` only where there is
/// something to reset, multipliers (a compliant material) or Chebyshev's iterates.
pub(crate) fn substep_stages(hard: bool, chebyshev: &Option<Chebyshev>) -> Stages {
    if hard && chebyshev.is_none() {
        Stages::PROJECT
    } else {
        Stages::BEGIN_SUBSTEP | Stages::PROJECT
    }
}

/// The `begin_substep` of a `stretch` group: XPBD's multipliers are the substep's totals, and
/// Chebyshev restarts with the substep.
pub(crate) fn reset_substep(lambda: &mut [f64], chebyshev: &mut Option<Chebyshev>) {
    lambda.fill(0.0);
    if let Some(c) = chebyshev.as_mut() {
        c.begin_substep();
    }
}

/// The factory of the `stretch` kind.
pub(crate) fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params: StretchParams = params::parse(params_json)?;
    Ok(match params.blocks()? {
        Blocks::Edges => Box::new(StretchGroup::new(&params, scene)?),
        Blocks::Stars => Box::new(crate::star::StarGroup::new(&params, scene)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nucleus_sdk::colour::OVERFLOW_COLOUR;

    /// The edges of a `n × n` vertex grid with one diagonal per quad, sorted as a scene
    /// lists them.
    fn grid_edges(n: u32) -> Vec<[u32; 2]> {
        let mut ids = Vec::new();
        for r in 0..n {
            for c in 0..n {
                let a = r * n + c;
                if c + 1 < n {
                    ids.push([a, a + 1]);
                }
                if r + 1 < n {
                    ids.push([a, a + n]);
                }
                if c + 1 < n && r + 1 < n {
                    ids.push([a, a + n + 1]);
                }
            }
        }
        ids.sort_unstable();
        ids
    }

    #[test]
    fn edges_of_one_colour_share_no_particle() {
        let ids = grid_edges(6);
        let colours = edge_colours(&ids, 36);
        assert!(colours.iter().all(|&c| c < OVERFLOW_COLOUR));
        for (a, &ca) in ids.iter().zip(&colours) {
            for (b, &cb) in ids.iter().zip(&colours) {
                if a != b && ca == cb {
                    assert!(!a.iter().any(|p| b.contains(p)), "{a:?} and {b:?}");
                }
            }
        }
        // Greedy colouring needs at most 2·(max valence − 1) + 1 colours (valence 6 here).
        assert!(colours.iter().max().is_some_and(|&c| c < 11));
    }

    #[test]
    fn order_lists_colours_in_turn_keeping_the_given_order_within_each() {
        let ids = grid_edges(5);
        let colours = edge_colours(&ids, 25);
        let order = independent_sets_order(&edge_colours(&ids, 25));
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..ids.len()).collect::<Vec<_>>(), "a permutation");
        for w in order.windows(2) {
            let (a, b) = (w[0], w[1]);
            assert!(colours[a] < colours[b] || (colours[a] == colours[b] && a < b));
        }
    }

    #[test]
    fn a_particle_with_more_than_64_colours_of_edges_overflows_safely() {
        // A star: 70 edges at particle 0 need 70 colours; the last 6 share the overflow one.
        let ids: Vec<[u32; 2]> = (1..=70).map(|k| [0, k]).collect();
        let colours = edge_colours(&ids, 71);
        assert_eq!(colours.iter().filter(|&&c| c == OVERFLOW_COLOUR).count(), 6);
        assert_eq!(
            independent_sets_order(&edge_colours(&ids, 71)),
            (0..70).collect::<Vec<_>>()
        );
    }
}
