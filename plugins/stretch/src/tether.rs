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

/// The `tether` group: SoA batch of (particle, pin, length), ordered by particle.
pub struct TetherGroup {
    particle: Vec<u32>,
    pin: Vec<u32>,
    length: Vec<f64>,
    lambda: Vec<f64>,
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
            compliance: p.compliance,
            max_index: None,
        };
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
                for &(pin, dist) in list {
                    if dist > 0.0 {
                        g.particle.push(i);
                        g.pin.push(first + pin);
                        g.length.push(p.scale * dist);
                    }
                }
            }
        }
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

    /// One pass over the tethers in order. A tether moves only its particle (a pin has
    /// infinite mass), and a particle's tethers are consecutive, so from `PARALLEL_MIN_TETHERS`
    /// (2,048) tethers up the batch is split at particle boundaries over the host's thread
    /// team (`ctx.team`, see [`nucleus_sdk::team`]): each particle's tethers run in the same
    /// order on one thread, so the result is bit-identical whatever the thread count.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (h, team) = (ctx.substep_length()?, ctx.team);
        ctx.check_holds(self.max_index)?;
        let p = ctx.particles();
        let w = p.inv_mass;
        let x = SharedArray::new(p.x);
        let lambda = SharedArray::new(&mut self.lambda);
        let (particle, pin, length) = (&self.particle[..], &self.pin[..], &self.length[..]);
        let compliance = self.compliance;
        let n = particle.len();
        // The part of the batch that `part` of `parts` projects: equal shares, each boundary
        // moved forward to the start of a particle's run of tethers.
        let span = |part: usize, parts: usize| {
            let boundary = |b: usize| {
                let mut b = b * n / parts;
                while b > 0 && b < n && particle[b] == particle[b - 1] {
                    b += 1;
                }
                b
            };
            boundary(part)..boundary(part + 1)
        };
        let job = |part: usize, parts: usize| {
            for k in span(part, parts) {
                let (i, pin) = (particle[k] as usize, pin[k] as usize);
                // SAFETY: `i` and `pin` are below `len` (checked above, against the state of
                // this call). Particle `i` is written only by the part that owns its run of
                // tethers; a pin is only read, and never written, since tethers of a particle
                // with infinite mass are not built and `project_tether` moves no such particle.
                // `lambda[k]` belongs to this part's span alone.
                unsafe {
                    let xi = *x.at(i);
                    let xp = *x.at(pin);
                    let l = lambda.at(k);
                    if let Some((dx, dl)) =
                        project_tether(xi, w[i], xp, length[k], compliance, *l, h)
                    {
                        *x.at(i) = xi + dx;
                        *l += dl;
                    }
                }
            }
        };
        let parts = team.parts();
        if parts > 1 && n >= PARALLEL_MIN_TETHERS {
            team.run(&|part| job(part, parts));
        } else {
            job(0, 1);
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
