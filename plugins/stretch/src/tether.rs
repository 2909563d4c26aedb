//! The `tether` kind: long-range attachments (Kim, Chentanez, Müller 2012, "Long Range
//! Attachments — A Method to Simulate Inextensible Clothing in Computer Games").
//!
//! A cloth hanging from pins can be no farther from each pin than the shortest path between
//! them along the cloth at rest. Each dynamic particle `i` is tethered to its `k` nearest
//! pinned particles `p` (nearest along the mesh, by Dijkstra over the rest edge lengths), with
//! the *unilateral* constraint
//!
//! ```text
//! C = |xᵢ − xₚ| − s·gᵢₚ ≤ 0          (gᵢₚ the geodesic rest distance, s = `scale`)
//! ```
//!
//! projected only when violated (`C > 0`): `xᵢ ← xᵢ − n·C` for the hard tether (`α = 0`),
//! or by the XPBD step with compliance `α` otherwise (the pin has inverse mass 0, so only
//! the particle moves). Plain Gauss-Seidel needs O(N) passes to carry a pin's pull through an
//! N-edge cloth; a tether carries it in one, so the stretch of the edges next to the pins —
//! where the whole weight hangs — stops growing with the resolution. Tethers never resist
//! compression or bending: the cloth stays free to fold.
//!
//! Pins move with the scene (the tether reads the pin's current position), and a particle
//! that cannot reach any pin along the mesh gets no tether.
//!
//! A pass runs the batch in rounds (every particle's first tether, then every particle's
//! second, …), four tethers of a round at a time in AVX2's lanes, with the bits of one tether
//! at a time particle after particle: tethers of different particles never touch the same
//! particle, and a pin is only read (the crate docs' "Cost").

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::SharedArray;
use serde::Deserialize;

/// The parameters of the `tether` kind.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TetherParams {
    /// Pins per particle: each particle is tethered to its `pins_per_particle` nearest pins.
    pub pins_per_particle: i64,
    /// Slack: the tether's length is `scale` × the geodesic rest distance.
    pub scale: f64,
    /// Compliance of the tether when taut (m/N); 0 is hard.
    pub compliance: f64,
}

impl TetherParams {
    /// The parameter descriptions.
    pub fn specs() -> Vec<ParamSpec> {
        vec![
            ParamSpec::integer("pins_per_particle", 2)
                .doc("each particle is tethered to this many nearest pins (along the cloth)")
                .range(1.0, 64.0),
            ParamSpec::number("scale", 1.0)
                .doc("tether length as a multiple of the geodesic rest distance (slack > 1)")
                .range(1.0, 10.0),
            ParamSpec::number("compliance", 0.0)
                .unit("m/N")
                .doc("compliance of a taut tether; 0 is hard")
                .range(0.0, f64::INFINITY),
        ]
    }
}

/// One search state of the k-nearest-sources Dijkstra.
#[derive(Clone, Copy, PartialEq)]
struct Item {
    dist: f64,
    node: u32,
    source: u32,
}

impl Eq for Item {}

impl Ord for Item {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on distance; ties broken by node then source, so the result is
        // deterministic.
        other
            .dist
            .total_cmp(&self.dist)
            .then_with(|| other.node.cmp(&self.node))
            .then_with(|| other.source.cmp(&self.source))
    }
}

impl PartialOrd for Item {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// For every node, up to `k` nearest sources and their distances along the graph, by a
/// multi-source Dijkstra that settles each node once per source, at most `k` times:
/// `O(k·E·log)`. `adjacency[v]` lists `(neighbour, length)`. Results are sorted by distance.
pub fn k_nearest_sources(
    adjacency: &[Vec<(u32, f64)>],
    sources: &[u32],
    k: usize,
) -> Vec<Vec<(u32, f64)>> {
    let mut found: Vec<Vec<(u32, f64)>> = vec![Vec::new(); adjacency.len()];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        heap.push(Item {
            dist: 0.0,
            node: s,
            source: s,
        });
    }
    while let Some(Item { dist, node, source }) = heap.pop() {
        let settled = &mut found[node as usize];
        if settled.len() >= k || settled.iter().any(|&(s, _)| s == source) {
            continue;
        }
        settled.push((source, dist));
        for &(next, len) in &adjacency[node as usize] {
            let f = &found[next as usize];
            if f.len() < k && !f.iter().any(|&(s, _)| s == source) {
                heap.push(Item {
                    dist: dist + len,
                    node: next,
                    source,
                });
            }
        }
    }
    found
}

/// `|x − p|² < len² (1 − 1e-9)`: the tether is slack, whatever the rounding of `|x − p| − len`.
const SLACK_BY_MARGIN: f64 = 1.0 - 1e-9;

/// One tether projection: particle `x` (inverse mass `w`) toward pin `p`, length `len`.
/// Returns the particle's displacement and `Δλ`, or `None` when the tether is slack, the
/// particle sits on the pin, or the particle cannot move.
#[inline]
pub fn project_tether(
    x: DVec3,
    w: f64,
    p: DVec3,
    len: f64,
    alpha: f64,
    lambda: f64,
    h: f64,
) -> Option<(DVec3, f64)> {
    let d = x - p;
    // Slack by a margin a million times the rounding of the test below, which would say so too:
    // the common case decided without a square root, with the same results.
    if d.length_squared() < len * len * SLACK_BY_MARGIN {
        return None;
    }
    let dist = d.length();
    let c = dist - len;
    if c <= 0.0 || w <= 0.0 || dist.is_nan() || dist <= 1e-12 {
        return None;
    }
    let n = d / dist;
    let dl = nucleus_sdk::xpbd::delta_lambda(c, w, alpha, lambda, h);
    Some((n * (w * dl), dl))
}

/// Projects the tethers `particle[k]` → `pin[k]` of one round (distinct particles), each as
/// [`project_tether`] does, four at a time in AVX2's lanes where the processor has them, with
/// the same bits (every operation of the scalar code, in its order, no fused multiply-add).
/// Most tethers of a hanging cloth are slack: four of them are dismissed by one comparison.
///
/// # Safety
/// `x` holds every particle and pin index, valid for the call; no two tethers move the same
/// particle; no other thread touches these particles meanwhile, nor writes the pins.
unsafe fn project_tethers(
    x: SharedArray<DVec3>,
    w: &[f64],
    mut round: Round<'_>,
    compliance: f64,
    h: f64,
) {
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if nucleus_sdk::lanes::avx2_available() {
        // SAFETY: AVX2 is present; the rest is the caller's guarantee.
        done = unsafe { avx2::project_fours(x, w, &mut round, compliance, h) };
    }
    let Round {
        particle,
        pin,
        length,
        lambda,
    } = round;
    for k in done..particle.len() {
        let (i, pin) = (particle[k] as usize, pin[k] as usize);
        // SAFETY: the caller's guarantee.
        unsafe {
            let xi = *x.at(i);
            let xp = *x.at(pin);
            if let Some((dx, dl)) =
                project_tether(xi, w[i], xp, length[k], compliance, lambda[k], h)
            {
                *x.at(i) = xi + dx;
                lambda[k] += dl;
            }
        }
    }
}

/// The tethers of one round a part projects: particle, pin, length and multiplier of each.
struct Round<'a> {
    particle: &'a [u32],
    pin: &'a [u32],
    length: &'a [f64],
    lambda: &'a mut [f64],
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use nucleus_sdk::lanes::avx2::{dot, load, moved, neg, scale, store, sub, Lanes3};

    use super::*;

    /// [`project_tethers`]'s groups of four; returns how many tethers it projected (a multiple
    /// of four: the rest are the caller's).
    ///
    /// # Safety
    /// As [`project_tethers`], and AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        round: &mut Round<'_>,
        compliance: f64,
        h: f64,
    ) -> usize {
        let (particle, pin, length) = (round.particle, round.pin, round.length);
        let lambda = &mut *round.lambda;
        let n = particle.len() / 4 * 4;
        let p = x.at(0);
        // `delta_lambda`'s `α̃ = α / h²`, and its guard on the denominator.
        let alpha_tilde = compliance / (h * h);
        let at = _mm256_set1_pd(alpha_tilde);
        let (zero, tiny, infinity) = (
            _mm256_setzero_pd(),
            _mm256_set1_pd(1e-12),
            _mm256_set1_pd(f64::INFINITY),
        );
        let slack_by_margin = _mm256_set1_pd(SLACK_BY_MARGIN);
        let min_positive = _mm256_set1_pd(f64::MIN_POSITIVE);
        let abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(i64::MAX));
        for k in (0..n).step_by(4) {
            let ki = [0, 1, 2, 3].map(|l| particle[k + l] as usize);
            let kp = [0, 1, 2, 3].map(|l| pin[k + l] as usize);
            // SAFETY: the caller's guarantee (indices in bounds, particles owned, pins read).
            let (xi, xp) = unsafe { (load(p, ki), load(p, kp)) };
            let d = sub(&xi, &xp);
            let d2 = dot(&d, &d);
            // SAFETY: `k + 3 < n <= length.len()`.
            let len = unsafe { _mm256_loadu_pd(length.as_ptr().add(k)) };
            // Not slack: `!(|d|² < len² (1 − 1e-9))` (NaN goes on, as in the scalar code).
            let taut = _mm256_cmp_pd::<_CMP_NLT_UQ>(
                d2,
                _mm256_mul_pd(_mm256_mul_pd(len, len), slack_by_margin),
            );
            if _mm256_movemask_pd(taut) == 0 {
                continue;
            }
            let dist = _mm256_sqrt_pd(d2);
            let c = _mm256_sub_pd(dist, len);
            let wi = _mm256_setr_pd(w[ki[0]], w[ki[1]], w[ki[2]], w[ki[3]]);
            // `!(c <= 0 || w <= 0 || dist is NaN || dist <= 1e-12)`.
            let moves = _mm256_and_pd(
                _mm256_and_pd(taut, _mm256_cmp_pd::<_CMP_NLE_UQ>(c, zero)),
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_NLE_UQ>(wi, zero),
                    _mm256_and_pd(
                        _mm256_cmp_pd::<_CMP_ORD_Q>(dist, dist),
                        _mm256_cmp_pd::<_CMP_NLE_UQ>(dist, tiny),
                    ),
                ),
            );
            if _mm256_movemask_pd(moves) == 0 {
                continue;
            }
            // SAFETY: `k + 3 < n <= lambda.len()`.
            let l = unsafe { _mm256_loadu_pd(lambda.as_ptr().add(k)) };
            // `delta_lambda(c, w, α, λ, h)`: 0 unless `MIN_POSITIVE < w + α̃ < ∞`.
            let denom = _mm256_add_pd(wi, at);
            let usable = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_NLE_UQ>(denom, min_positive),
                _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_and_pd(denom, abs_mask), infinity),
            );
            let dl = _mm256_blendv_pd(
                zero,
                _mm256_div_pd(_mm256_sub_pd(neg(c), _mm256_mul_pd(at, l)), denom),
                usable,
            );
            // `n = d / |d|`, moved by `n (w Δλ)`.
            let unit = Lanes3 {
                x: _mm256_div_pd(d.x, dist),
                y: _mm256_div_pd(d.y, dist),
                z: _mm256_div_pd(d.z, dist),
            };
            let dx = scale(&unit, _mm256_mul_pd(wi, dl));
            // SAFETY: as the load above; lanes that do not move write their own bits back.
            unsafe {
                store(p, ki, &moved(&xi, &dx, moves));
                _mm256_storeu_pd(
                    lambda.as_mut_ptr().add(k),
                    _mm256_blendv_pd(l, _mm256_add_pd(l, dl), moves),
                );
            }
        }
        n
    }
}

/// The `tether` group: SoA batch of (particle, pin, length) in rounds: round `r` holds the
/// `r`-th tether of every particle that has more than `r`, ordered by particle. A round's
/// tethers move distinct particles, four of which a pass projects at once (`project_tethers`),
/// and each particle's tethers still run in its own order, round after round.
pub struct TetherGroup {
    particle: Vec<u32>,
    pin: Vec<u32>,
    length: Vec<f64>,
    lambda: Vec<f64>,
    /// Where each round starts in the batch, and the batch's end.
    rounds: Vec<usize>,
    compliance: f64,
    /// The largest particle index of the batch (`None` when it is empty).
    max_index: Option<u32>,
}

/// From this many tethers a pass is shared by the host's thread team (`ctx.team`): a pass of 2,048
/// tethers takes about 10 µs, a few times the team's hand-off. Chosen, not tuned.
const PARALLEL_MIN_TETHERS: usize = 2048;

impl TetherGroup {
    /// Builds the tethers of the target objects.
    pub fn new(p: &TetherParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        let rest = scene.rest_positions();
        let w = scene.inv_mass.as_slice();
        let mut g = TetherGroup {
            particle: Vec::new(),
            pin: Vec::new(),
            length: Vec::new(),
            lambda: Vec::new(),
            rounds: vec![0],
            compliance: p.compliance,
            max_index: None,
        };
        // (round, particle, pin, length): a particle's tethers, nearest pin first.
        let mut tethers: Vec<(usize, u32, u32, f64)> = Vec::new();
        for (_, object) in scene.unique_targets()? {
            let range = object.particles();
            let first = object.first;
            let mut adjacency = vec![Vec::new(); range.len()];
            for &[i, j] in object.edges.as_slice() {
                if !range.contains(&(i as usize)) || !range.contains(&(j as usize)) {
                    return Err(PluginError::bad_object(
                        object.name.as_str(),
                        format!("edge ({i}, {j}) is outside the object"),
                    ));
                }
                let len = (rest[j as usize] - rest[i as usize]).length();
                adjacency[(i - first) as usize].push((j - first, len));
                adjacency[(j - first) as usize].push((i - first, len));
            }
            let pins: Vec<u32> = range
                .clone()
                .filter(|&i| w[i] == 0.0)
                .map(|i| i as u32 - first)
                .collect();
            if pins.is_empty() {
                continue;
            }
            let nearest = k_nearest_sources(&adjacency, &pins, p.pins_per_particle as usize);
            for (local, list) in nearest.iter().enumerate() {
                let i = first + local as u32;
                if w[i as usize] == 0.0 {
                    continue;
                }
                let reachable = list.iter().filter(|&&(_, dist)| dist > 0.0);
                for (round, &(pin, dist)) in reachable.enumerate() {
                    tethers.push((round, i, first + pin, p.scale * dist));
                }
            }
        }
        // Round by round, each by particle (the objects' particles are disjoint ranges).
        tethers.sort_by_key(|&(round, i, _, _)| (round, i));
        for (k, &(round, i, pin, length)) in tethers.iter().enumerate() {
            if round == g.rounds.len() {
                g.rounds.push(k);
            }
            g.particle.push(i);
            g.pin.push(pin);
            g.length.push(length);
        }
        g.rounds.push(tethers.len());
        g.lambda = vec![0.0; g.particle.len()];
        g.max_index = g.particle.iter().chain(&g.pin).copied().max();
        Ok(g)
    }
}

impl ConstraintGroup for TetherGroup {
    fn stages(&self) -> Stages {
        if self.compliance > 0.0 {
            Stages::PROJECT | Stages::BEGIN_SUBSTEP
        } else {
            Stages::PROJECT
        }
    }

    fn len(&self) -> usize {
        self.particle.len()
    }

    fn begin_substep(&mut self, _ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        self.lambda.fill(0.0);
        Ok(())
    }

    /// One pass over the tethers, round by round. A tether moves only its particle (a pin has
    /// infinite mass), so from `PARALLEL_MIN_TETHERS` (2,048) tethers up the particles are
    /// split into equal shares of the first round over the host's thread team (`ctx.team`, see
    /// [`nucleus_sdk::team`]): each part runs its particles' tethers of every round, each
    /// particle's in the same order on one thread, so the result is bit-identical whatever the
    /// thread count — and the same as one tether at a time in the order particle by particle.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (h, team) = (ctx.substep_length()?, ctx.team);
        ctx.check_holds(self.max_index)?;
        let p = ctx.particles();
        let w = p.inv_mass;
        let x = SharedArray::new(p.x);
        let lambda = SharedArray::new(&mut self.lambda);
        let (particle, pin, length) = (&self.particle[..], &self.pin[..], &self.length[..]);
        let (rounds, compliance) = (&self.rounds[..], self.compliance);
        let n = particle.len();
        let parts = if team.parts() > 1 && n >= PARALLEL_MIN_TETHERS {
            team.parts()
        } else {
            1
        };
        // The particles part `part` owns: from the first particle of its share of round 0 on.
        let first_round = &particle[..rounds.get(1).copied().unwrap_or(0)];
        let owned_from = |part: usize| match part {
            0 => 0,
            _ if part >= parts => u32::MAX,
            _ => first_round
                .get(part * first_round.len() / parts)
                .copied()
                .unwrap_or(u32::MAX),
        };
        let job = |part: usize| {
            let (from, to) = (owned_from(part), owned_from(part + 1));
            for r in rounds.windows(2) {
                let round = &particle[r[0]..r[1]];
                let start = r[0] + round.partition_point(|&i| i < from);
                let end = r[0] + round.partition_point(|&i| i < to);
                // SAFETY: every index is below the state's length (checked above, against the
                // state of this call). The tethers `start..end` of a round move distinct
                // particles, which this part alone owns (those in `from..to`); a pin is only
                // read, and never written, since tethers of a particle with infinite mass are
                // not built and `project_tether` moves no such particle. `lambda[start..end]`
                // belongs to this part alone.
                unsafe {
                    let round = Round {
                        particle: &particle[start..end],
                        pin: &pin[start..end],
                        length: &length[start..end],
                        lambda: lambda.slice(start, end - start),
                    };
                    project_tethers(x, w, round, compliance, h);
                }
            }
        };
        if parts > 1 {
            team.run(&job);
        } else {
            job(0);
        }
        Ok(())
    }

    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let (mut max, mut sq, mut energy) = (0.0f64, 0.0, 0.0);
        for k in 0..self.particle.len() {
            let (i, pin) = (self.particle[k] as usize, self.pin[k] as usize);
            let (Some(xi), Some(xp)) = (x.get(i), x.get(pin)) else {
                continue;
            };
            let c = ((*xi - *xp).length() - self.length[k]).max(0.0);
            let r = c / self.length[k];
            max = max.max(r);
            sq += r * r;
            if self.compliance > 0.0 {
                energy += 0.5 * c * c / self.compliance;
            }
        }
        let n = self.particle.len();
        Residual {
            count: n as u64,
            max,
            rms: if n > 0 { (sq / n as f64).sqrt() } else { 0.0 },
            energy,
        }
    }
}

/// The factory of the `tether` kind.
pub fn build(json: &str, scene: &SceneView<'_>) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let p: TetherParams = params::parse(json)?;
    Ok(Box::new(TetherGroup::new(&p, scene)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn k_nearest_sources_on_a_path_are_the_graph_distances() {
        // 0 - 1 - 2 - 3 - 4 with unit edges; sources 0 and 4.
        let mut adj = vec![Vec::new(); 5];
        for i in 0..4u32 {
            adj[i as usize].push((i + 1, 1.0));
            adj[i as usize + 1].push((i, 1.0));
        }
        let near = k_nearest_sources(&adj, &[0, 4], 2);
        assert_eq!(near[1], vec![(0, 1.0), (4, 3.0)]);
        assert_eq!(near[2], vec![(0, 2.0), (4, 2.0)]);
        let near1 = k_nearest_sources(&adj, &[0, 4], 1);
        assert_eq!(near1[3], vec![(4, 1.0)]);
    }

    /// A coordinate: mostly ordinary, sometimes a value that breaks arithmetic (signed zeros,
    /// infinities, NaN, subnormal, huge).
    fn coordinate(rng: &mut nucleus_sdk::testing::Rng) -> f64 {
        const SPECIAL: [f64; 8] = [
            0.0,
            -0.0,
            f64::INFINITY,
            -1e300,
            f64::NAN,
            1e-310,
            1e300,
            1.0,
        ];
        if rng.next_f64() < 0.05 {
            SPECIAL[rng.pick(SPECIAL.len())]
        } else {
            rng.range(-2.0, 2.0)
        }
    }

    #[test]
    fn four_lanes_give_the_bits_of_one_tether_at_a_time() {
        if !nucleus_sdk::lanes::avx2_available() {
            eprintln!("this processor has no AVX2: the four-lane tether kernel is not exercised");
        }
        let mut rng = nucleus_sdk::testing::Rng(0x7e7e);
        for case in 0..400 {
            // 64 particles (the first 8 pins), a round of up to 43 tethers on distinct ones.
            let n = 64;
            let x: Vec<DVec3> = (0..n)
                .map(|_| {
                    DVec3::new(
                        coordinate(&mut rng),
                        coordinate(&mut rng),
                        coordinate(&mut rng),
                    )
                })
                .collect();
            let w: Vec<f64> = (0..n)
                .map(|i| match (i < 8, rng.pick(10)) {
                    (true, _) => 0.0,
                    (false, 0) => 0.0,
                    (false, 1) => 1e-300,
                    _ => rng.range(0.1, 50.0),
                })
                .collect();
            let mut free: Vec<u32> = (8..n as u32).collect();
            for k in (1..free.len()).rev() {
                free.swap(k, rng.pick(k + 1));
            }
            let count = rng.pick(44);
            let particle = &free[..count];
            let pin: Vec<u32> = (0..count).map(|_| rng.pick(8) as u32).collect();
            let length: Vec<f64> = (0..count)
                .map(|_| match rng.pick(8) {
                    0 => 0.0,
                    1 => 1e-13,
                    _ => rng.range(0.0, 3.0),
                })
                .collect();
            let lambda0: Vec<f64> = (0..count).map(|_| rng.range(-1e-3, 1e-3)).collect();
            let compliance = [0.0, 1e-6, 1.0][case % 3];
            let h = 1.0 / 600.0;

            let mut x_lanes = x.clone();
            let mut lambda_lanes = lambda0.clone();
            // SAFETY: every index is inside `x_lanes`, the particles are distinct, and no pin
            // is among them.
            unsafe {
                let round = Round {
                    particle,
                    pin: &pin,
                    length: &length,
                    lambda: &mut lambda_lanes,
                };
                project_tethers(SharedArray::new(&mut x_lanes), &w, round, compliance, h);
            }
            let (mut x_one, mut lambda_one) = (x.clone(), lambda0.clone());
            for k in 0..count {
                let (i, p) = (particle[k] as usize, pin[k] as usize);
                if let Some((dx, dl)) = project_tether(
                    x_one[i],
                    w[i],
                    x_one[p],
                    length[k],
                    compliance,
                    lambda_one[k],
                    h,
                ) {
                    x_one[i] += dx;
                    lambda_one[k] += dl;
                }
            }
            let bits = |v: &[DVec3]| -> Vec<[u64; 3]> {
                v.iter().map(|p| p.to_array().map(f64::to_bits)).collect()
            };
            assert_eq!(bits(&x_lanes), bits(&x_one), "positions, case {case}");
            let lbits = |v: &[f64]| -> Vec<u64> { v.iter().map(|l| l.to_bits()).collect() };
            assert_eq!(
                lbits(&lambda_lanes),
                lbits(&lambda_one),
                "multipliers, case {case}"
            );
        }
    }

    #[test]
    fn a_pass_in_rounds_gives_the_bits_of_one_particle_after_another() {
        use crate::tests::{Mesh, State, Steps};
        // A 40 x 40 grid hung from four pins, three tethers a particle (4,900, enough to split
        // a pass over a team), crumpled at random.
        let mut mesh = Mesh::grid(40, 1.0);
        for pin in [0, 17, 40, 1200] {
            mesh.inv_mass[pin] = 0.0;
        }
        let mut rng = nucleus_sdk::testing::Rng(31);
        let x: Vec<[f64; 3]> = mesh
            .rest
            .iter()
            .map(|r| (DVec3::from_array(*r) * 1.6 + rng.vec3(0.3)).to_array())
            .collect();
        let params = TetherParams {
            pins_per_particle: 3,
            scale: 1.0,
            compliance: 1e-7,
        };
        let mut group = mesh
            .with_scene(&[0], |scene| TetherGroup::new(&params, scene))
            .unwrap();
        assert_eq!(group.rounds.len(), 4, "three rounds: {:?}", group.rounds);
        // Each round by particle; every particle's tethers nearest pin first.
        for r in group.rounds.windows(2) {
            assert!(group.particle[r[0]..r[1]].windows(2).all(|p| p[0] < p[1]));
        }
        assert!(group.particle.len() >= PARALLEL_MIN_TETHERS);
        // The reference: particle after particle, each one's tethers in its own order.
        let mut order: Vec<usize> = (0..group.particle.len()).collect();
        order.sort_by_key(|&k| (group.particle[k], k));
        let mut state = State::new(&mesh, x.clone());
        // Passes split over teams of one, two and three parts, in turn.
        let teams = [0, 1, 2].map(nucleus_sdk::team::Team::new);
        let mut reference: Vec<DVec3> = x.iter().map(|p| DVec3::from_array(*p)).collect();
        let mut lambda = vec![0.0; order.len()];
        for pass in 0..6 {
            for &k in &order {
                let (i, p) = (group.particle[k] as usize, group.pin[k] as usize);
                if let Some((dx, dl)) = project_tether(
                    reference[i],
                    mesh.inv_mass[i],
                    reference[p],
                    group.length[k],
                    params.compliance,
                    lambda[k],
                    state.h,
                ) {
                    reference[i] += dx;
                    lambda[k] += dl;
                }
            }
            let team = &teams[pass % 3];
            let mut ctx = state.ctx();
            ctx.team = nucleus_sdk::team::TeamRef::new(team);
            group.project(&mut ctx).unwrap();
            let got: Vec<[u64; 3]> = state.x.iter().map(|p| p.map(f64::to_bits)).collect();
            let want: Vec<[u64; 3]> = reference
                .iter()
                .map(|p| p.to_array().map(f64::to_bits))
                .collect();
            assert_eq!(got, want, "pass {pass}, {} parts", team.parts());
            assert!(state.x.iter().zip(&x).any(|(a, b)| a != b), "nothing moved");
        }
    }

    #[test]
    fn slack_tether_does_nothing_and_taut_one_pulls_back_exactly() {
        let p = DVec3::ZERO;
        assert!(project_tether(DVec3::new(0.5, 0.0, 0.0), 1.0, p, 1.0, 0.0, 0.0, 0.01).is_none());
        let x = DVec3::new(0.0, -2.0, 0.0);
        let (dx, _) = project_tether(x, 1.0, p, 1.5, 0.0, 0.0, 0.01).unwrap();
        assert!(((x + dx).length() - 1.5).abs() < 1e-15);
        // A particle with infinite mass never moves.
        assert!(project_tether(x, 0.0, p, 1.5, 0.0, 0.0, 0.01).is_none());
        // On the pin: no direction, no NaN.
        assert!(project_tether(p, 1.0, p, 0.0, 0.0, 0.0, 0.01).is_none());
    }

    /// The tether step as it was before the slack test on squared lengths: the reference that
    /// test must not change.
    fn without_square_test(x: DVec3, w: f64, p: DVec3, len: f64) -> Option<(DVec3, f64)> {
        let d = x - p;
        let dist = d.length();
        let c = dist - len;
        if c <= 0.0 || w <= 0.0 || dist.is_nan() || dist <= 1e-12 {
            return None;
        }
        let dl = nucleus_sdk::xpbd::delta_lambda(c, w, 1e-7, 0.0, 0.01);
        Some((d / dist * (w * dl), dl))
    }

    #[test]
    fn the_slack_test_on_squares_changes_no_bit() {
        let mut rng = nucleus_sdk::testing::Rng(3);
        let p = DVec3::new(0.1, -0.2, 0.3);
        for k in 0..100_000 {
            let x = p + rng.unit() * rng.range(0.5, 2.0);
            let dist = (x - p).length();
            // Lengths within a few roundings of the distance, and farther off either way.
            let len = match k % 4 {
                0 => dist,
                1 => dist * (1.0 + rng.int(8) as f64 * f64::EPSILON),
                2 => dist * (1.0 + rng.range(-1e-8, 1e-8)),
                _ => dist * rng.range(0.5, 1.5),
            };
            let got = project_tether(x, 1.0, p, len, 1e-7, 0.0, 0.01);
            let want = without_square_test(x, 1.0, p, len);
            let bits = |r: Option<(DVec3, f64)>| {
                r.map(|(d, l)| [d.x.to_bits(), d.y.to_bits(), d.z.to_bits(), l.to_bits()])
            };
            assert_eq!(bits(got), bits(want), "x {x}, len {len}");
        }
    }
}
