//! Stretch solved a particle's star at a time (`stretch` with `blocks = "stars"`): one Newton
//! step on *all* the edges at a particle at once, instead of one edge after another.
//!
//! ## Why
//!
//! Edge-by-edge Gauss-Seidel moves each edge's lighter particle. Where a load passes through a
//! particle far lighter than its neighbours (a light seam between heavy panels, a mass ratio of
//! 1 : 10⁶), the edge on its left moves it toward the left neighbour, the edge on its right
//! moves it back, and the heavy particles on either side, which must come together, move by
//! the mass ratio times less: the pass converges as `1 − m_light/m_heavy` per pass, never in
//! practice, and the cloth tears (the stress suite's mass-ratio case: strain 175 with edges).
//! Solving the edges of the light particle's star *together* finds the one correction that
//! satisfies all of them, and that moves the heavy neighbours.
//!
//! ## The step
//!
//! For the star of particle `c` (inverse mass `w_c > 0`) with spokes `e = (c, k)`: the constraint
//! `C_e = |x_k − x_c| − l_e`, its current direction `n_e`, and the corrections along it (written
//! `û_e`, with `cos_e = n_e·û_e = 1`, for the general form)
//!
//! ```text
//! Δx_k = w_k û_e Δλ_e,    Δx_c = −w_c U,    U = Σ_e û_e Δλ_e
//! ```
//!
//! The linearised XPBD equations of all the spokes at once, each divided by its `1 + γ_e`:
//!
//! ```text
//! Λ_e Δλ_e + w_c n_e·U = r_e,   Λ_e = w_k cos_e + α̃_e/(1 + γ_e),
//!                               r_e = (−C_e − α̃_e λ_e − γ_e n_e·(Δx_k − Δx_c since x0)) / (1 + γ_e)
//! ```
//!
//! Eliminating `Δλ_e = (r_e − w_c n_e·U)/Λ_e` leaves a 3 × 3 system for `U`:
//!
//! ```text
//! (I + w_c Σ_e û_e n_eᵀ / Λ_e) U = Σ_e û_e r_e / Λ_e
//! ```
//!
//! so a star of any size costs one pass over its spokes, one 3 × 3 solve and a second pass: no
//! `d × d` factorisation. For one spoke it is exactly the edge's XPBD step. A spoke to a pinned
//! particle with a hard material has `Λ_e = 0` (the centre alone must satisfy it): `Λ_e` is
//! floored at [`LAMBDA_FLOOR`]` · w_c`, which makes that spoke hold to a relative 10⁻⁹.
//! Every correction runs along a spoke, equal and opposite at its two ends (weighted by the
//! inverse masses), so linear momentum is conserved exactly.
//!
//! **Directions.** The edge step corrects along the edge's direction at the start of the
//! substep (SHAKE; it conserves angular momentum exactly too). A star does not: with start
//! directions its system `N W Ûᵀ` is not symmetric, block Gauss-Seidel on it is no longer a
//! descent, and a curtain whose heavy hem was caught by tethers kept ~25 J in motion that edge
//! passes let settle. Along the current directions the system is `J W Jᵀ`, symmetric. The price
//! is angular momentum conserved only up to the edges' turn within the substep.
//!
//! **Trust region.** Where the star is nearly degenerate the linearisation lies: a particle
//! on the straight line between two pins its hard spokes' rest lengths apart (a taut string)
//! can, to first order, relieve a small stretch by moving *across* the line, and the Newton step
//! moved it centimetres for a stretch of 10⁻⁴ m, pumping energy into a hanging cloth (300 J in
//! a 3 × 3 test that holds 70). So no particle moves farther than one edge step could move it,
//! `maxₑ |rₑ(1 + γₑ)|`: a longer step is scaled down as a whole, which keeps its momentum
//! balance. A single spoke is never scaled, so it stays exactly the edge step along `n`. Then
//! the step is halved (at most [`LINE_SEARCH_HALVINGS`] times, else dropped) until the star's
//! `Σ (C + α̃λ)²` is no larger than before it. With the sum `Σₑ |rₑ(1 + γₑ)|` as the bound
//! instead of the largest, a curtain whose 1,000-times-heavier hem is caught by tethers gained
//! 1.4 %/s of its energy (max speed 70 m/s); with the largest, 0.07 %/s (59 m/s).
//!
//! ## The pass
//!
//! Every particle with `w > 0` and at least one edge has a star; a star writes its centre and
//! its neighbours, so two stars are independent when their centres are more than two edges
//! apart. The stars are coloured greedily by that rule (at most 64 colours; a 128 × 128 cloth
//! needs about 13) and projected colour by colour in the centres' order, each colour split
//! over the host's thread team: bit-identical for any thread count. Each edge lies in two stars
//! (one if an end is pinned), so a pass does about twice the work of an edge pass; a star of
//! more than [`MAX_SPOKES`] edges is solved in chunks of that many.

use glam::{DMat3, DVec3};
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::{span, SharedArray};

use crate::chebyshev::Chebyshev;
use crate::distance::{EdgeMaterial, XpbdTerms, MIN_LENGTH};
use crate::group::{
    edge_residual, reset_substep, substep_stages, Edges, StretchParams, PARALLEL_MIN_EDGES,
};
use nucleus_sdk::colour::{colour_batches, greedy_colours, independent_sets_order};

/// A star's spokes are solved together in chunks of at most this many (a stack buffer).
pub const MAX_SPOKES: usize = 32;

/// The most times a star's step is halved before it is dropped for this pass.
pub const LINE_SEARCH_HALVINGS: u32 = 6;

/// Smallest `Λ_e` relative to the centre's inverse mass: a hard spoke to a pinned particle
/// holds to this relative tolerance instead of making the 3 × 3 system singular.
pub const LAMBDA_FLOOR: f64 = 1e-9;

/// One spoke of a star: the input the step reads and the output it writes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spoke {
    /// Position of the spoke's far particle `k` (m).
    pub x: DVec3,
    /// Its position at the start of the substep (m).
    pub x0: DVec3,
    /// Its inverse mass (1/kg).
    pub w: f64,
    /// The edge's rest length (m).
    pub rest: f64,
    /// The edge's multiplier accumulated so far in the substep (N·s²); ignored when hard.
    pub lambda: f64,
    /// Output: the displacement of particle `k` (m).
    pub dx: DVec3,
    /// Output: the increment of the edge's multiplier (N·s²).
    pub delta_lambda: f64,
    // Scratch between the two passes over the spokes.
    n: DVec3,
    u: DVec3,
    big_lambda: f64,
    r: f64,
    g: f64,
    alpha_tilde: f64,
}

impl Spoke {
    /// A spoke to particle `k` at `x` (start `x0`, inverse mass `w`) with rest length `rest`
    /// and multiplier `lambda`.
    pub fn new(x: DVec3, x0: DVec3, w: f64, rest: f64, lambda: f64) -> Spoke {
        Spoke {
            x,
            x0,
            w,
            rest,
            lambda,
            ..Spoke::default()
        }
    }
}

/// One Newton step on all the `spokes` of the star centred at `xc` (start `x0c`, inverse mass
/// `wc`) at once (see the [module docs](self)): fills each spoke's `dx` and `delta_lambda` and
/// returns the centre's displacement. A spoke whose particles (nearly) coincide is left out
/// (zero output), as the edge step skips it. Returns zero and leaves every output zero when
/// `wc` is not positive or the system is not solvable in floating point. Never NaN for finite
/// input.
pub fn project_star(
    xc: DVec3,
    x0c: DVec3,
    wc: f64,
    spokes: &mut [Spoke],
    terms: &XpbdTerms,
) -> DVec3 {
    for s in spokes.iter_mut() {
        s.dx = DVec3::ZERO;
        s.delta_lambda = 0.0;
        s.big_lambda = 0.0;
    }
    if wc.is_nan() || wc <= 0.0 {
        return DVec3::ZERO;
    }
    let mut m = DMat3::IDENTITY;
    let mut b = DVec3::ZERO;
    let mut any = false;
    // The trust region: the largest |rₑ|, what one edge step could move a particle.
    let mut reach: f64 = 0.0;
    for s in spokes.iter_mut() {
        let d = s.x - xc;
        let len = d.length();
        if !len.is_finite() || len < MIN_LENGTH || s.w.is_nan() || s.w < 0.0 {
            continue;
        }
        // Along the current direction, not the start direction the edge step takes: with it
        // the star's system is not symmetric, and the block steps pumped energy into a heavy
        // hem caught by tethers (see the module docs).
        let n = d / len;
        let (u, cos) = (n, 1.0);
        let c = len - s.rest;
        let side = usize::from(c < 0.0);
        let (alpha_tilde, gamma) = (terms.alpha_tilde[side], terms.gamma[side]);
        let mut r = -c - alpha_tilde * s.lambda;
        if gamma > 0.0 {
            r -= gamma * n.dot((s.x - s.x0) - (xc - x0c));
        }
        let big_lambda = (s.w * cos + alpha_tilde / (1.0 + gamma)).max(LAMBDA_FLOOR * wc);
        if !big_lambda.is_finite() {
            continue;
        }
        s.n = n;
        s.u = u;
        s.big_lambda = big_lambda;
        s.r = r / (1.0 + gamma);
        s.g = c + alpha_tilde * s.lambda;
        s.alpha_tilde = alpha_tilde;
        reach = f64::max(reach, r.abs());
        // M += w_c û nᵀ / Λ (columns: û scaled by the components of n).
        let f = wc / big_lambda;
        m.x_axis += u * (f * n.x);
        m.y_axis += u * (f * n.y);
        m.z_axis += u * (f * n.z);
        b += u * (s.r / big_lambda);
        any = true;
    }
    if !any {
        return DVec3::ZERO;
    }
    let Some(big_u) = solve3(m, b) else {
        for s in spokes.iter_mut() {
            s.big_lambda = 0.0;
        }
        return DVec3::ZERO;
    };
    let mut farthest = wc * big_u.length();
    for s in spokes.iter_mut() {
        if s.big_lambda > 0.0 {
            let delta_lambda = (s.r - wc * s.n.dot(big_u)) / s.big_lambda;
            s.delta_lambda = delta_lambda;
            s.dx = s.u * (s.w * delta_lambda);
            farthest = farthest.max(s.dx.length());
        }
    }
    // The step, scaled into the trust region, then halved until the star's constraints are
    // no more violated than before it (at most `LINE_SEARCH_HALVINGS` times, else no step).
    let dxc = -wc * big_u;
    let mut scale = (reach / farthest).min(1.0);
    let before: f64 = spokes
        .iter()
        .filter(|s| s.big_lambda > 0.0)
        .map(|s| s.g * s.g)
        .sum();
    let mut halvings = 0;
    loop {
        let after: f64 = spokes
            .iter()
            .filter(|s| s.big_lambda > 0.0)
            .map(|s| {
                let c = (s.x + s.dx * scale - xc - dxc * scale).length() - s.rest;
                let g = c + s.alpha_tilde * (s.lambda + scale * s.delta_lambda);
                g * g
            })
            .sum();
        if after <= before {
            break;
        }
        if halvings == LINE_SEARCH_HALVINGS {
            scale = 0.0;
            break;
        }
        scale *= 0.5;
        halvings += 1;
    }
    // Scaling the whole step keeps its momentum balance.
    if scale < 1.0 {
        for s in spokes.iter_mut() {
            s.dx *= scale;
            s.delta_lambda *= scale;
        }
    }
    dxc * scale
}

/// Solves `m u = b` by Gaussian elimination with partial pivoting: backward stable, so a
/// system dominated by a floored spoke (entries ~10⁹ times the rest) keeps the other spokes'
/// digits. Cofactors are not: on such a star their determinant lost every digit to
/// cancellation, and the cloth blew up. `None` for a singular or non-finite system.
pub fn solve3(m: DMat3, b: DVec3) -> Option<DVec3> {
    // Rows of [m | b].
    let mut rows = [
        [m.x_axis.x, m.y_axis.x, m.z_axis.x, b.x],
        [m.x_axis.y, m.y_axis.y, m.z_axis.y, b.y],
        [m.x_axis.z, m.y_axis.z, m.z_axis.z, b.z],
    ];
    for col in 0..3 {
        let pivot = (col..3)
            .max_by(|&p, &q| rows[p][col].abs().total_cmp(&rows[q][col].abs()))
            .unwrap_or(col);
        rows.swap(col, pivot);
        let p = rows[col][col];
        if !p.is_finite() || p.abs() <= f64::MIN_POSITIVE {
            return None;
        }
        let pivot_row = rows[col];
        for row in rows.iter_mut().skip(col + 1) {
            let f = row[col] / p;
            for (a, b) in row.iter_mut().zip(pivot_row).skip(col) {
                *a -= f * b;
            }
        }
    }
    let mut u = [0.0; 3];
    for r in (0..3).rev() {
        let tail: f64 = (r + 1..3).map(|c| rows[r][c] * u[c]).sum();
        u[r] = (rows[r][3] - tail) / rows[r][r];
    }
    let u = DVec3::from(u);
    u.is_finite().then_some(u)
}

/// A `stretch` group solved a star at a time (`blocks = "stars"`): the same constraints as
/// [`crate::StretchGroup`], the same residual, another pass.
#[derive(Clone, Debug)]
pub struct StarGroup {
    /// The two global particle indices of each edge, in the scene's order.
    ids: Vec<[u32; 2]>,
    /// Rest length of each edge (m).
    rest: Vec<f64>,
    /// Multiplier of each edge accumulated over the passes of the substep (N·s²); empty for a
    /// hard material.
    lambda: Vec<f64>,
    /// Both compliances are 0.
    hard: bool,
    /// Compliances and damping, shared by the whole group.
    material: EdgeMaterial,
    /// Particle slices must hold more than this index (`None` for an empty group).
    max_index: Option<u32>,
    /// The centre of each star, in projection order.
    centre: Vec<u32>,
    /// Star `s`'s spokes are `first[s]..first[s + 1]`.
    first: Vec<u32>,
    /// The far particle of each spoke.
    other: Vec<u32>,
    /// The edge of each spoke (index into `ids`, `rest`, `lambda`).
    edge: Vec<u32>,
    /// Consecutive ranges of stars, flagged `true` if they write no common particle (one
    /// colour) and may be projected in parallel.
    batches: Vec<(std::ops::Range<usize>, bool)>,
    /// The Chebyshev acceleration of the passes, when `chebyshev_rho > 0`.
    chebyshev: Option<Chebyshev>,
}

/// The centres of the stars over `edges`: every particle with `w > 0` and an edge, in order.
pub(crate) fn centres(edges: &Edges, inv_mass: &[f64]) -> Vec<u32> {
    let mut centre = vec![false; edges.particles];
    for &[i, j] in &edges.ids {
        centre[i as usize] |= inv_mass[i as usize] > 0.0;
        centre[j as usize] |= inv_mass[j as usize] > 0.0;
    }
    (0..edges.particles as u32)
        .filter(|&p| centre[p as usize])
        .collect()
}

impl StarGroup {
    /// The group of `blocks = "stars"` over the target objects' edges (the edges and errors of
    /// [`crate::StretchGroup::new`]): a star at every particle with `w > 0` and an edge.
    pub fn new(params: &StretchParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        let edges = Edges::collect(params, scene)?;
        let centres = centres(&edges, scene.inv_mass.as_slice());
        Ok(Self::from_edges(params, edges, &centres))
    }

    /// Stars at `centres` (particles with `w > 0`, in increasing order; [`centres`] gives every
    /// one with an edge) over `edges`. The stars are coloured so that those of one colour write
    /// no common particle, and listed colour by colour in the centres' order.
    pub(crate) fn from_edges(params: &StretchParams, edges: Edges, centres: &[u32]) -> Self {
        let particles = edges.particles;
        let mut is_centre = vec![false; particles];
        for &c in centres {
            is_centre[c as usize] = true;
        }
        // The spokes of every centre, in the edges' order (counting sort: deterministic).
        let mut start = vec![0u32; particles + 1];
        for &[i, j] in &edges.ids {
            for p in [i, j] {
                if is_centre[p as usize] {
                    start[p as usize + 1] += 1;
                }
            }
        }
        for p in 0..particles {
            start[p + 1] += start[p];
        }
        let mut fill = start.clone();
        let spokes = start[particles] as usize;
        let (mut spoke_other, mut spoke_edge) = (vec![0u32; spokes], vec![0u32; spokes]);
        for (e, &[i, j]) in edges.ids.iter().enumerate() {
            for (a, b) in [(i, j), (j, i)] {
                if is_centre[a as usize] {
                    let slot = fill[a as usize] as usize;
                    spoke_other[slot] = b;
                    spoke_edge[slot] = e as u32;
                    fill[a as usize] += 1;
                }
            }
        }
        let spokes_of = |p: usize| start[p] as usize..start[p + 1] as usize;
        // A star writes its centre and its neighbours.
        let colours = greedy_colours(centres.len(), particles, |s| {
            let c = centres[s] as usize;
            std::iter::once(c).chain(spokes_of(c).map(|k| spoke_other[k] as usize))
        });
        let order = independent_sets_order(&colours);
        let hard = params.is_hard();
        let mut group = StarGroup {
            lambda: if hard {
                Vec::new()
            } else {
                vec![0.0; edges.ids.len()]
            },
            chebyshev: params.chebyshev(&edges.ids),
            ids: edges.ids,
            rest: edges.rest,
            hard,
            material: params.material(),
            max_index: edges.max_index,
            centre: Vec::with_capacity(centres.len()),
            first: vec![0],
            other: Vec::with_capacity(spokes),
            edge: Vec::with_capacity(spokes),
            batches: Vec::new(),
        };
        for &s in &order {
            let c = centres[s] as usize;
            group.centre.push(c as u32);
            group.other.extend_from_slice(&spoke_other[spokes_of(c)]);
            group.edge.extend_from_slice(&spoke_edge[spokes_of(c)]);
            group.first.push(group.other.len() as u32);
        }
        group.batches = colour_batches(&colours, &order);
        group
    }

    /// The number of stars (particles with `w > 0` and at least one edge).
    pub fn stars(&self) -> usize {
        self.centre.len()
    }

    /// The number of colours the stars were split into.
    pub fn colours(&self) -> usize {
        self.batches.len()
    }
}

/// Projects the stars `range` of `group`'s arrays, in order.
///
/// # Safety
/// `x` points to at least `max index + 1` positions and `lambda` to one multiplier per edge
/// (or is empty for a hard group), both valid for the duration of the call, and no other thread
/// reads or writes the positions these stars write, or their edges' multipliers, meanwhile.
#[allow(clippy::too_many_arguments)]
unsafe fn project_stars(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    lambda: SharedArray<f64>,
    group: &StarArrays<'_>,
    range: std::ops::Range<usize>,
    terms: &XpbdTerms,
) {
    let mut buffer = [Spoke::default(); MAX_SPOKES];
    for s in range {
        let c = group.centre[s] as usize;
        let spokes = group.first[s] as usize..group.first[s + 1] as usize;
        let mut chunk_start = spokes.start;
        while chunk_start < spokes.end {
            let chunk = chunk_start..spokes.end.min(chunk_start + MAX_SPOKES);
            let buffer = &mut buffer[..chunk.len()];
            for (b, k) in buffer.iter_mut().zip(chunk.clone()) {
                let (o, e) = (group.other[k] as usize, group.edge[k] as usize);
                // SAFETY: indices are in bounds (checked before the pass) and the caller
                // guarantees exclusive access to this star's particles and edges.
                let (xo, lambda) =
                    unsafe { (*x.at(o), if group.hard { 0.0 } else { *lambda.at(e) }) };
                *b = Spoke::new(xo, x0[o], w[o], group.rest[e], lambda);
            }
            // SAFETY: as above.
            let xc = unsafe { *x.at(c) };
            let dxc = project_star(xc, x0[c], w[c], buffer, terms);
            // SAFETY: as above.
            unsafe {
                *x.at(c) = xc + dxc;
                for (b, k) in buffer.iter().zip(chunk.clone()) {
                    let (o, e) = (group.other[k] as usize, group.edge[k] as usize);
                    *x.at(o) += b.dx;
                    if !group.hard {
                        *lambda.at(e) += b.delta_lambda;
                    }
                }
            }
            chunk_start = chunk.end;
        }
    }
}

/// The read-only arrays of a [`StarGroup`] a pass needs, borrowed apart from its multipliers.
struct StarArrays<'a> {
    centre: &'a [u32],
    first: &'a [u32],
    other: &'a [u32],
    edge: &'a [u32],
    rest: &'a [f64],
    hard: bool,
}

impl ConstraintGroup for StarGroup {
    /// As [`crate::StretchGroup`]: `project`, and `begin_substep` for the multipliers of a
    /// compliant material or the Chebyshev iterates.
    fn stages(&self) -> Stages {
        substep_stages(self.hard, &self.chebyshev)
    }

    fn len(&self) -> usize {
        self.ids.len()
    }

    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        reset_substep(&mut self.lambda, &mut self.chebyshev);
        Ok(())
    }

    /// One block Gauss-Seidel pass over the stars, colour by colour; a colour of at least 256
    /// stars is split into contiguous parts over the host's thread team. The stars of a colour
    /// write no common particle or multiplier, so the result is bit-identical whatever the
    /// thread count. No allocation.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (h, team) = (ctx.substep_length()?, ctx.team);
        ctx.check_holds(self.max_index)?;
        if let Some(c) = self.chebyshev.as_mut() {
            c.before_pass(ctx.particles().x);
        }
        let p = ctx.particles();
        let (x0, w) = (p.x0, p.inv_mass);
        let x = SharedArray::new(p.x);
        let lambda = SharedArray::new(&mut self.lambda);
        let arrays = StarArrays {
            centre: &self.centre,
            first: &self.first,
            other: &self.other,
            edge: &self.edge,
            rest: &self.rest,
            hard: self.hard,
        };
        let terms = self.material.terms(h);
        let parts = team.parts();
        for (range, independent) in &self.batches {
            // SAFETY: a whole batch runs on this thread alone; the parts of one colour write no
            // common particle or multiplier (the colouring). `x` and `lambda` come from
            // exclusive borrows held for this whole call, and the indices were checked above.
            match parts {
                2.. if *independent && range.len() >= PARALLEL_MIN_EDGES => {
                    team.run(&|part| {
                        let span = span(part, parts, range.len());
                        let part = range.start + span.start..range.start + span.end;
                        unsafe { project_stars(x, x0, w, lambda, &arrays, part, &terms) }
                    });
                }
                _ => unsafe { project_stars(x, x0, w, lambda, &arrays, range.clone(), &terms) },
            }
        }
        if let Some(c) = self.chebyshev.as_mut() {
            c.after_pass(p.x, w);
        }
        Ok(())
    }

    /// As [`crate::StretchGroup`]: the strain of every edge and the energy of the compliant
    /// ones.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        edge_residual(&self.ids, &self.rest, &self.material, ctx.positions())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::{project_distance, EdgeMaterial};
    use crate::group::{Edges, StretchParams};
    use nucleus_sdk::testing::Rng;

    const H: f64 = 1.0 / 240.0;

    fn material(alpha: f64, damping: f64) -> EdgeMaterial {
        EdgeMaterial {
            compliance: alpha,
            compression_compliance: alpha * 2.0,
            damping,
        }
    }

    #[test]
    fn a_star_of_one_spoke_is_the_edge_step() {
        // The edge step runs along the start direction, the star along the current one: the
        // two agree when the edge has not turned within the substep (it may have moved and
        // changed length, which the damping sees).
        let mut rng = Rng(7);
        for case in 0..500 {
            let xc = rng.vec3(1.0);
            let xk = xc + rng.vec3(0.3);
            let shift = rng.vec3(0.02);
            let x0c = xc + shift;
            let x0k = xc + shift + (xk - xc) * rng.range(0.9, 1.1);
            let (wc, wk) = (rng.range(0.1, 5.0), rng.range(0.0, 5.0));
            let rest = rng.range(0.05, 0.4);
            let lambda = rng.range(-1e-4, 1e-4);
            let m = [EdgeMaterial::HARD, material(1e-6, 0.0), material(1e-5, 2.0)][case % 3];
            let edge = project_distance([xc, xk], [x0c, x0k], [wc, wk], rest, &m, lambda, H)
                .expect("a projectable edge");
            let mut spokes = [Spoke::new(xk, x0k, wk, rest, lambda)];
            let dxc = project_star(xc, x0c, wc, &mut spokes, &m.terms(H));
            let scale = edge.dxi.length().max(1e-12);
            assert!(
                (dxc - edge.dxi).length() <= 1e-9 * scale,
                "case {case}: centre"
            );
            assert!((spokes[0].dx - edge.dxj).length() <= 1e-9 * scale.max(spokes[0].dx.length()));
            let dl = edge.delta_lambda.abs().max(1e-12);
            assert!((spokes[0].delta_lambda - edge.delta_lambda).abs() <= 1e-9 * dl);
        }
    }

    /// The linearised equations the step solves, for random stars: every spoke's
    /// `Λ_e Δλ_e + w_c n_e·U = r_e` holds for the returned corrections.
    #[test]
    fn the_step_solves_every_spokes_linearised_equation_at_once() {
        let mut rng = Rng(11);
        let mut whole = 0;
        for case in 0..300 {
            let xc = rng.vec3(1.0);
            let wc = rng.range(0.1, 1e3);
            let count = 1 + rng.pick(8);
            let m = [EdgeMaterial::HARD, material(1e-5, 1.0)][case % 2];
            let terms = m.terms(H);
            let mut spokes: Vec<Spoke> = (0..count)
                .map(|_| {
                    let xk = xc + rng.unit() * rng.range(0.05, 0.3);
                    Spoke::new(xk, xk, rng.range(1e-3, 2.0), rng.range(0.05, 0.3), 0.0)
                })
                .collect();
            let dxc = project_star(xc, xc, wc, &mut spokes, &terms);
            // With x = x0 the damping term vanishes and `û = n`, so each spoke's equation is
            // C_e + (1 + γ_e) n_e·(Δx_k − Δx_c) + α̃_e Δλ_e = 0 — for the whole step. A step
            // scaled by σ (the trust region, the line search) leaves (1 − σ) C_e, the same σ
            // for every spoke.
            let mut left = None;
            for (e, s) in spokes.iter().enumerate() {
                let d = s.x - xc;
                let n = d.normalize();
                let c = d.length() - s.rest;
                let side = usize::from(c < 0.0);
                let (at, g) = (terms.alpha_tilde[side], terms.gamma[side]);
                let lhs = c + (1.0 + g) * n.dot(s.dx - dxc) + at * s.delta_lambda;
                let share = lhs / c;
                let first = *left.get_or_insert(share);
                assert!(
                    (-1e-9..1.0).contains(&first),
                    "case {case}: σ = {}",
                    1.0 - first
                );
                assert!(
                    (share - first).abs() <= 1e-9,
                    "case {case} spoke {e}: {share} ≠ {first}"
                );
            }
            whole += usize::from(left.is_some_and(|l: f64| l.abs() <= 1e-9));
        }
        assert!(whole > 100, "only {whole} of 300 steps were whole");
    }

    /// A light particle between two heavy ones on a line, both edges stretched: the edge step
    /// moves the light particle back and forth; the star moves the heavy ones together, and
    /// one step satisfies both edges to first order.
    #[test]
    fn a_light_centre_between_heavy_neighbours_brings_them_together() {
        let (wl, wh) = (1e6, 1.0);
        let xc = DVec3::ZERO;
        let left = DVec3::new(-1.01, 0.0, 0.0);
        let right = DVec3::new(1.01, 0.0, 0.0);
        let mut spokes = [
            Spoke::new(left, left, wh, 1.0, 0.0),
            Spoke::new(right, right, wh, 1.0, 0.0),
        ];
        let dxc = project_star(xc, xc, wl, &mut spokes, &EdgeMaterial::HARD.terms(H));
        let (l, r, c) = (left + spokes[0].dx, right + spokes[1].dx, xc + dxc);
        assert!(((c - l).length() - 1.0).abs() < 1e-9);
        assert!(((r - c).length() - 1.0).abs() < 1e-9);
        assert!((spokes[0].dx.x - 0.01).abs() < 1e-6, "{:?}", spokes[0].dx);
        // Momentum: Σ m Δx = 0.
        let p = spokes[0].dx / wh + spokes[1].dx / wh + dxc / wl;
        assert!(p.length() < 1e-12, "{p:?}");
    }

    #[test]
    fn spokes_to_pinned_particles_hold_and_the_centre_alone_moves() {
        // Three pinned neighbours around a centre off their plane: the centre must satisfy
        // three hard edges by itself.
        let pins = [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(-0.5, 0.866, 0.0),
            DVec3::new(-0.5, -0.866, 0.0),
        ];
        let rest = (1.0f64 + 0.25).sqrt();
        let mut xc = DVec3::new(0.05, -0.02, 0.6);
        for _ in 0..20 {
            let mut spokes = pins.map(|p| Spoke::new(p, p, 0.0, rest, 0.0));
            xc += project_star(xc, xc, 1.0, &mut spokes, &EdgeMaterial::HARD.terms(H));
            assert!(spokes.iter().all(|s| s.dx == DVec3::ZERO));
        }
        for p in pins {
            assert!(((xc - p).length() - rest).abs() < 1e-7, "{xc:?}");
        }
    }

    #[test]
    fn degenerate_input_gives_no_correction_and_no_nan() {
        let terms = EdgeMaterial::HARD.terms(H);
        let x = DVec3::new(0.1, 0.2, 0.3);
        // Coincident spoke, a pinned centre, an empty star.
        let mut coincident = [Spoke::new(x, x, 1.0, 0.1, 0.0)];
        assert_eq!(
            project_star(x, x, 1.0, &mut coincident, &terms),
            DVec3::ZERO
        );
        assert_eq!(coincident[0].dx, DVec3::ZERO);
        let mut one = [Spoke::new(x + DVec3::X, x, 1.0, 0.5, 0.0)];
        assert_eq!(project_star(x, x, 0.0, &mut one, &terms), DVec3::ZERO);
        assert_eq!(project_star(x, x, 1.0, &mut [], &terms), DVec3::ZERO);
        // Huge and tiny inverse masses stay finite.
        let mut spokes = [
            Spoke::new(x + DVec3::X, x, 1e-300, 0.5, 0.0),
            Spoke::new(x - DVec3::X, x, 1e300, 0.5, 0.0),
        ];
        let dxc = project_star(x, x, 1e300, &mut spokes, &terms);
        assert!(dxc.is_finite() && spokes.iter().all(|s| s.dx.is_finite()));
    }

    /// A real star of the 3 × 3 drape whose diagonal runs to a pin: the floored spoke makes the
    /// 3 × 3 system's entries ~10⁹. The expected correction is the solution of the star's
    /// 6 × 6 linearised system `(diag(max(w_k, 10⁻⁹ w_c)) + w_c N Nᵀ) Δλ = −C` (numpy,
    /// independent of this code).
    /// Cofactor inversion lost every digit here (Δx_c = (−0.012, 0.005, −0.046)) and the
    /// cloth blew up.
    #[test]
    fn a_star_dominated_by_a_pinned_spoke_keeps_the_other_spokes_digits() {
        let v = DVec3::new;
        let star = [
            (
                v(
                    -0.4981858148841626,
                    -0.4217530739792999,
                    0.26774451755946477,
                ),
                v(
                    -0.4990430164418995,
                    -0.42697748331735996,
                    0.26042121008748575,
                ),
                0.0,
                std::f64::consts::FRAC_1_SQRT_2,
            ),
            (
                v(
                    0.0018141896220369436,
                    -0.4222526780502167,
                    0.26777135191045687,
                ),
                v(
                    0.00020088393195177856,
                    -0.427550074533775,
                    0.2605544252211906,
                ),
                1.0,
                0.5,
            ),
            (
                v(
                    -0.5000020746829205,
                    0.00032990583733605305,
                    -0.0002911366463195231,
                ),
                v(
                    -0.49984778939393,
                    0.00020437508080273226,
                    -0.0009409360369215802,
                ),
                1.0,
                0.5,
            ),
            (
                v(
                    0.5000152644785206,
                    0.0011682436355294201,
                    -0.0015093024314367653,
                ),
                v(
                    0.499644184751606,
                    -0.0006201100607234888,
                    -0.0004646609658717771,
                ),
                1.0,
                0.5,
            ),
            (
                v(
                    0.0005018912594215719,
                    0.49875207418445827,
                    -0.033052481842206716,
                ),
                v(
                    0.0005911630594877537,
                    0.49871446069376635,
                    -0.030444316369724278,
                ),
                1.0,
                0.5,
            ),
            (
                v(0.501041297342791, 0.4988360753449264, -0.032973977041309055),
                v(
                    0.5005911346099979,
                    0.49848463543289956,
                    -0.030357605181922653,
                ),
                1.0,
                std::f64::consts::FRAC_1_SQRT_2,
            ),
        ];
        let mut spokes: Vec<Spoke> = star
            .iter()
            .map(|&(x, x0, w, rest)| Spoke::new(x, x0, w, rest, 0.0))
            .collect();
        let terms = EdgeMaterial::HARD.terms(1.0 / 600.0);
        let dxc = project_star(DVec3::ZERO, DVec3::ZERO, 1.0, &mut spokes, &terms);
        // The solution (0.0010501655157, 0.0006742478600, −0.0011774129139) moves the centre
        // 1.72 mm, beyond the trust region (the largest violation, 1.59 mm): scaled by 0.9276.
        let expected = v(0.0009740887446, 0.0006254035594, -0.0010921180043);
        assert!((dxc - expected).length() < 1e-9, "{dxc:?}");
        // The scaled Newton step leaves 7.2 % of each violation, and second-order terms.
        for s in &spokes {
            let before = s.x.length() - s.rest;
            let after = (s.x + s.dx - dxc).length() - s.rest;
            assert!(
                after.abs() < 0.073 * before.abs() + 3e-6,
                "{after:e} from {before:e}"
            );
        }
    }

    #[test]
    fn solve3_is_accurate_on_ill_conditioned_systems() {
        let mut rng = Rng(5);
        for case in 0..200 {
            // I + big · u nᵀ + a random O(1) part, as a star with a floored spoke builds.
            let (u, n) = (rng.unit(), rng.unit());
            let big = [1.0, 1e3, 1e6, 1e9][case % 4];
            let mut m = DMat3::IDENTITY * 2.0
                + DMat3::from_cols(u * n.x, u * n.y, u * n.z) * big
                + DMat3::from_cols(rng.vec3(0.3), rng.vec3(0.3), rng.vec3(0.3));
            if case % 7 == 0 {
                m = m.transpose();
            }
            let x = rng.vec3(1.0);
            let got = solve3(m, m * x).expect("a regular system");
            // Backward stable: the error is bounded by the condition number times ε.
            let cond = m.inverse().abs().to_cols_array().iter().sum::<f64>()
                * m.abs().to_cols_array().iter().sum::<f64>();
            assert!(
                (got - x).length() <= 1e-15 * cond.max(1.0) * 10.0,
                "case {case}"
            );
        }
        assert_eq!(solve3(DMat3::ZERO, DVec3::X), None);
        assert_eq!(
            solve3(DMat3::from_cols(DVec3::X, DVec3::X, DVec3::Z), DVec3::X),
            None
        );
        assert_eq!(solve3(DMat3::IDENTITY * f64::NAN, DVec3::X), None);
    }

    fn edges_of(ids: &[[u32; 2]], particles: usize) -> Edges {
        Edges {
            ids: ids.to_vec(),
            rest: vec![1.0; ids.len()],
            max_index: ids.iter().map(|e| e[0].max(e[1])).max(),
            particles,
        }
    }

    #[test]
    fn every_dynamic_particle_with_an_edge_is_a_centre() {
        // A chain 0 - 1 - 2 - 3, 3 pinned, and a lone particle 4.
        let edges = edges_of(&[[0, 1], [1, 2], [2, 3]], 5);
        assert_eq!(centres(&edges, &[1.0, 1e6, 1.0, 0.0, 1.0]), vec![0, 1, 2]);
    }

    #[test]
    fn stars_of_one_colour_write_no_common_particle() {
        // A 6 × 6 grid with one diagonal per quad, stars everywhere.
        let n = 6u32;
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
        let edges = edges_of(&ids, (n * n) as usize);
        let w = vec![1.0; (n * n) as usize];
        let centres = centres(&edges, &w);
        let group = StarGroup::from_edges(&StretchParams::default(), edges, &centres);
        assert_eq!(group.stars(), 36);
        let written = |s: usize| {
            let spokes = group.first[s] as usize..group.first[s + 1] as usize;
            let mut p: Vec<u32> = group.other[spokes].to_vec();
            p.push(group.centre[s]);
            p
        };
        for (range, independent) in &group.batches {
            assert!(independent);
            for a in range.clone() {
                for b in range.clone().filter(|&b| b != a) {
                    let (wa, wb) = (written(a), written(b));
                    assert!(!wa.iter().any(|p| wb.contains(p)), "stars {a} and {b}");
                }
            }
        }
        // Every edge lies in the stars of both its ends.
        assert_eq!(group.other.len(), 2 * ids.len());
        assert!(group.colours() <= 19, "{}", group.colours());
    }
}
