//! The group's stages driven one by one over a crumpling cloth: the refresh keeps every pair a
//! full broad phase finds, the shift keeps every pair that comes within reach, and what a
//! refresh carries over (separations, starts) gives the bits of what it would take afresh.

use super::*;
use crate::broad_phase::bvh::Aabb;
use crate::broad_phase::swept::shared_displacement;
use crate::candidates::starts::{start_slot, StartOf};
use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::testing::Rng;

/// The stages as the tests call them.
impl CollisionGroup {
    fn pose_colliders(&mut self, time: f64, h: f64) {
        let (shift, max_thickness) = (self.broad.boxes.shift, self.prims.max_thickness);
        self.colliders.pose(time, h, shift, max_thickness);
    }

    fn start_of(&mut self, k: usize, x0: &[DVec3]) -> StartOf {
        let geo = Geometry {
            prims: &self.prims,
            colliders: &self.colliders,
        };
        self.cands.start_of(k, geo, x0)
    }

    fn colliders_and_masses_hold(&self, inv_mass: &[f64]) -> bool {
        self.broad
            .colliders_and_masses_hold(self.geometry(), inv_mass)
    }

    fn vert_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        self.broad.boxes.vert_box(&self.prims, i, x0, x)
    }

    fn edge_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        self.broad.boxes.edge_box(&self.prims, i, x0, x)
    }

    fn face_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        self.broad.boxes.face_box(&self.prims, i, x0, x)
    }
}

/// Rest positions, edges and triangles of a mesh.
type Mesh = (Vec<[f64; 3]>, Vec<[u32; 2]>, Vec<[u32; 3]>);

/// A flat `n × n` cloth of side 0.5 m in the plane z = 0, two triangles per quad.
fn cloth(n: u32) -> Mesh {
    let s = 0.5 / (n - 1) as f64;
    let rest = (0..n * n)
        .map(|k| [(k % n) as f64 * s, (k / n) as f64 * s, 0.0])
        .collect();
    let mut tris = Vec::new();
    for r in 0..n - 1 {
        for c in 0..n - 1 {
            let a = r * n + c;
            tris.push([a, a + 1, a + n + 1]);
            tris.push([a, a + n + 1, a + n]);
        }
    }
    let mut edges: Vec<[u32; 2]> = tris
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    (rest, edges, tris)
}

/// Two identical groups over the cloth: self-collision, a sphere and a box (whose corners
/// and edges are features).
fn groups(rest: &[[f64; 3]], edges: &[[u32; 2]], tris: &[[u32; 3]]) -> [CollisionGroup; 2] {
    let inv_mass = vec![1.0; rest.len()];
    let objects = [ObjectView {
        edges: RSlice::from_slice(edges),
        triangles: RSlice::from_slice(tris),
        ..ObjectView::new("cloth", 0, rest.len() as u32)
    }];
    let scene = SceneView::new(&objects, &[0], rest, &inv_mass);
    let infos: Vec<_> = CollisionParams::specs().iter().map(|s| s.info()).collect();
    let json = nucleus_sdk::params::validate_json(
        r#"{"thickness": 0.01, "colliders": [
            {"type": "sphere", "center": [0.25, 0.25, -0.2], "radius": 0.15},
            {"type": "box", "center": [0.1, 0.1, 0.05], "half_extents": [0.05, 0.05, 0.05]}
        ]}"#,
        &infos,
    )
    .expect("valid parameters");
    let params = CollisionParams::parse(&json).expect("params");
    let make = || CollisionGroup::new(&params, &scene).expect("group");
    let mut pair = [make(), make()];
    for g in &mut pair {
        g.pose_colliders(0.0, 0.0);
        let features = (g.colliders.feat_points.len(), g.colliders.feat_edges.len());
        assert!(features.0 > 0 && features.1 > 0, "the box has features");
    }
    pair
}

/// Whether candidate `c`'s primitives can touch now: their tight boxes (swept over the
/// substep and grown by their radii, no margin) overlap, or for a collider feature, lie
/// within the collider's radius.
fn touching(g: &CollisionGroup, c: Candidate, x0: &[DVec3], x: &[DVec3]) -> bool {
    let [a, b] = c.pair.map(|k| k as usize);
    let feature = |tight: Aabb, collider: u32, other: Aabb| {
        let rc = g.colliders.radius[collider as usize];
        tight.distance_squared(&other) <= rc * rc
    };
    match c.kind {
        PairKind::Collider => g.vert_box(b, x0, x).overlaps(&g.colliders.boxes[a]),
        PairKind::VertexFace => g.vert_box(a, x0, x).overlaps(&g.face_box(b, x0, x)),
        PairKind::EdgeEdge => g.edge_box(a, x0, x).overlaps(&g.edge_box(b, x0, x)),
        PairKind::FeatureFace => feature(
            g.colliders.feat_point_boxes[a],
            g.colliders.feat_points[a].0,
            g.face_box(b, x0, x),
        ),
        PairKind::FeaturePointEdge => feature(
            g.colliders.feat_point_boxes[a],
            g.colliders.feat_points[a].0,
            g.edge_box(b, x0, x),
        ),
        PairKind::FeatureEdgeEdge => feature(
            g.colliders.feat_edge_boxes[a],
            g.colliders.feat_edges[a].0,
            g.edge_box(b, x0, x),
        ),
        PairKind::VertexVertex | PairKind::VertexEdge => true,
    }
}

/// After primitives leave their boxes, the partial refresh keeps every pair a full broad
/// phase finds that can touch now, with the same contact distance, in sorted order — over
/// rounds of random crumpling in which a few or most vertices move. (A full broad phase
/// also lists pairs within a fresh margin of each other; the refresh keeps the older
/// boxes of the primitives that stayed in theirs, and lists the pairs within those.)
#[test]
fn a_refresh_keeps_every_pair_a_full_broad_phase_finds() {
    let (rest, edges, tris) = cloth(14);
    let [mut partial, mut full] = groups(&rest, &edges, &tris);
    let inv_mass = vec![1.0; rest.len()];
    let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    let mut x = x0.clone();
    let mut rng = Rng(3);
    partial.broad_phase(&x0, &x, &inv_mass, TeamRef::serial());
    let (mut refreshed, mut fallbacks) = (0, 0);
    for round in 0..60 {
        // A few vertices (or, one round in ten, most) jump by up to 3 cm; the cloth folds.
        let share = if round % 10 == 9 { 0.6 } else { 0.05 };
        for p in x.iter_mut() {
            if rng.next_f64() < share {
                *p += rng.vec3(0.03);
            }
        }
        let before = partial.stats;
        partial.refresh(&x0, &x, &inv_mass, TeamRef::serial());
        refreshed += partial.stats.refreshes - before.refreshes;
        fallbacks += partial.stats.broad_phases - before.broad_phases;
        full.broad_phase(&x0, &x, &inv_mass, TeamRef::serial());
        assert!(partial.cands.list.windows(2).all(|w| w[0] < w[1]));
        let mut checked = 0;
        for (c, d) in full.cands.list.iter().zip(&full.cands.reach) {
            if !touching(&full, *c, &x0, &x) {
                continue;
            }
            checked += 1;
            let at = partial.cands.list.binary_search(c);
            let at = at.unwrap_or_else(|_| panic!("round {round}: {c:?} missing"));
            assert_eq!(
                partial.cands.reach[at].to_bits(),
                d.to_bits(),
                "round {round}: {c:?}"
            );
        }
        assert_eq!(partial.cands.ids.len(), partial.cands.list.len());
        assert!(checked > 0, "round {round}: no pair can touch");
    }
    assert!(
        refreshed > 30 && fallbacks >= 3,
        "{refreshed} refreshes, {fallbacks} full"
    );
    let kinds: Vec<PairKind> = full.cands.list.iter().map(|c| c.kind).collect();
    for kind in [PairKind::VertexFace, PairKind::EdgeEdge, PairKind::Collider] {
        assert!(
            kinds.contains(&kind),
            "no {kind:?} pair: the test would not test it"
        );
    }
}

/// The tight boxes a broad phase or a refresh takes from the particle boxes are, to the
/// bit, the boxes of the primitives' own coordinates ([`CollisionGroup::vert_box`],
/// [`CollisionGroup::edge_box`], [`CollisionGroup::face_box`]), with a shift and crumpled
/// positions.
#[test]
fn tight_boxes_from_particle_boxes_are_the_primitives_own() {
    let (rest, edges, tris) = cloth(9);
    let [mut g, _] = groups(&rest, &edges, &tris);
    let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    let mut rng = Rng(17);
    for round in 0..20 {
        let x: Vec<DVec3> = x0.iter().map(|&p| p + rng.vec3(0.05)).collect();
        g.broad.boxes.shift = if round % 2 == 0 {
            DVec3::ZERO
        } else {
            rng.vec3(0.02)
        };
        g.broad.boxes.fill_particle_boxes(&x0, &x);
        let bits = |b: Aabb| {
            (
                b.min.to_array().map(f64::to_bits),
                b.max.to_array().map(f64::to_bits),
            )
        };
        for i in 0..g.prims.verts.len() {
            assert_eq!(
                bits(g.broad.boxes.tight_box(&g.prims, 0, i).0),
                bits(g.vert_box(i, &x0, &x))
            );
        }
        for i in 0..g.prims.edges.len() {
            assert_eq!(
                bits(g.broad.boxes.tight_box(&g.prims, 1, i).0),
                bits(g.edge_box(i, &x0, &x))
            );
        }
        for i in 0..g.prims.faces.len() {
            assert_eq!(
                bits(g.broad.boxes.tight_box(&g.prims, 2, i).0),
                bits(g.face_box(i, &x0, &x))
            );
        }
        assert!(!g.prims.faces.is_empty() && !g.prims.edges.is_empty());
    }
}

/// With every box of a substep shifted by the displacement its vertices share
/// ([`CollisionGroup::shift`]), the broad phase still pairs every pair that comes within
/// reach over the substep — every pair in which the narrow phase's continuous test finds
/// a contact — over rounds of random crumpling carried by a common motion of up to 20 cm
/// (ten times the contact distance), each a new substep with its own shift. The shifted
/// lists are shorter than the unshifted ones (else the test would not test the shift).
#[test]
fn a_shifted_broad_phase_keeps_every_pair_that_comes_within_reach() {
    let (rest, edges, tris) = cloth(14);
    let [mut shifted, mut plain] = groups(&rest, &edges, &tris);
    let inv_mass = vec![1.0; rest.len()];
    let mut x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    let mut rng = Rng(5);
    let team = TeamRef::serial();
    let (mut checked, mut fewer) = (0, 0);
    for round in 0..40 {
        let common = rng.vec3(0.2);
        let x: Vec<DVec3> = x0
            .iter()
            .map(|&p| {
                let own = if rng.next_f64() < 0.3 {
                    rng.vec3(0.02)
                } else {
                    DVec3::ZERO
                };
                p + common + own
            })
            .collect();
        // A substep long enough that no push-out limit applies.
        for g in [&mut shifted, &mut plain] {
            g.response.h = 1e3;
        }
        shifted.broad.boxes.shift = shared_displacement(&shifted.prims, &x0, &x, &inv_mass);
        shifted.pose_colliders(0.0, 0.0);
        shifted.broad_phase(&x0, &x, &inv_mass, team);
        plain.broad_phase(&x0, &x, &inv_mass, team);
        for k in 0..plain.cands.list.len() {
            if plain.pass().0.detect(k, &x0, &x, 1.0, None).is_none() {
                continue;
            }
            let (c, d) = (&plain.cands.list[k], &plain.cands.reach[k]);
            checked += 1;
            let at = shifted.cands.list.binary_search(c);
            let at = at.unwrap_or_else(|_| panic!("round {round}: {c:?} missing"));
            assert_eq!(shifted.cands.reach[at].to_bits(), d.to_bits());
        }
        fewer += usize::from(shifted.cands.list.len() < plain.cands.list.len());
        x0 = x;
    }
    assert!(checked > 100, "only {checked} pairs came within reach");
    assert!(fewer > 30, "the shift made {fewer} of 40 lists shorter");
}

/// A refresh within a substep keeps the separations of the pairs it keeps, with the motion
/// since they were taken added ([`CollisionGroup::carry_separations`]): over rounds of
/// random crumpling, each followed by a refresh and a pass, the contacts and positions are
/// the bits of a group whose refreshes forget every separation, as before the carry. Fails
/// if the motion since the old `x_ref` is left out of a carried certificate.
#[test]
fn separations_carried_over_a_refresh_give_the_contacts_of_forgotten_ones() {
    let (rest, edges, tris) = cloth(14);
    let [mut carried, mut forgotten] = groups(&rest, &edges, &tris);
    let inv_mass = vec![1.0; rest.len()];
    let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    let (mut xa, mut xb) = (x0.clone(), x0.clone());
    let team = TeamRef::serial();
    for (g, x) in [(&mut carried, &xa), (&mut forgotten, &xb)] {
        g.broad_phase(&x0, x, &inv_mass, team);
    }
    carried.cands.within_substep = true;
    let mut rng = Rng(11);
    let (mut carries, mut contacts) = (0, 0);
    for round in 0..80 {
        // A few vertices (one round in ten, most) move by up to 1.5 cm, as far as the
        // cloth's contact distance (2 cm): pairs come into contact after their separation
        // was taken.
        let share = if round % 10 == 9 { 0.6 } else { 0.08 };
        for k in 0..xa.len() {
            if rng.next_f64() < share {
                let dx = rng.vec3(0.015);
                xa[k] += dx;
                xb[k] += dx;
            }
        }
        let kept = carried
            .cands
            .certs
            .separation
            .iter()
            .filter(|s| !s.d0.is_nan())
            .count();
        let refreshed = carried.refresh(&x0, &xa, &inv_mass, team);
        forgotten.refresh(&x0, &xb, &inv_mass, team);
        if refreshed && kept > 0 {
            carries += carried
                .cands
                .certs
                .separation
                .iter()
                .filter(|s| !s.d0.is_nan())
                .count();
        }
        carried
            .pass()
            .0
            .resolve(&x0, &mut xa, &inv_mass, &mut [], team);
        forgotten
            .pass()
            .0
            .resolve(&x0, &mut xb, &inv_mass, &mut [], team);
        assert_eq!(carried.cands.list, forgotten.cands.list, "round {round}");
        assert_eq!(
            carried.contacts.len(),
            forgotten.contacts.len(),
            "round {round}"
        );
        contacts += carried.contacts.len();
        for (k, (a, b)) in xa.iter().zip(&xb).enumerate() {
            assert_eq!(
                a.to_array().map(f64::to_bits),
                b.to_array().map(f64::to_bits),
                "round {round}: particle {k}"
            );
        }
    }
    assert!(carries > 1000, "only {carries} separations carried over");
    assert!(
        contacts > 100,
        "only {contacts} contacts: nothing to get wrong"
    );
}

/// What the passes keep of a collider or feature pair's start (its distance from the
/// collider or feature, and how it leaves) is what it would take afresh, after refreshes
/// within the substep move the pairs to new places in the list: over rounds of random
/// crumpling, every kept start is checked against one taken again, bit for bit.
#[test]
fn the_starts_kept_over_refreshes_are_those_taken_afresh() {
    let (rest, edges, tris) = cloth(14);
    let [mut g, _] = groups(&rest, &edges, &tris);
    let inv_mass = vec![1.0; rest.len()];
    let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    let mut x = x0.clone();
    let team = TeamRef::serial();
    g.response.h = 1e-2;
    g.broad_phase(&x0, &x, &inv_mass, team);
    g.cands.within_substep = true;
    let mut rng = Rng(5);
    let (mut carried, mut checked) = (0, 0);
    for round in 0..40 {
        let share = if round % 10 == 9 { 0.6 } else { 0.08 };
        for p in x.iter_mut() {
            if rng.next_f64() < share {
                *p += rng.vec3(0.015);
            }
        }
        if g.refresh(&x0, &x, &inv_mass, team) {
            carried += g
                .cands
                .starts
                .slots
                .iter()
                .filter(|s| !s.distance.is_nan())
                .count();
        }
        g.resolve_pass(&x0, &mut x, &inv_mass, &mut [], team);
        for k in 0..g.cands.list.len() {
            let kind = g.cands.list[k].kind;
            let Some(slot) = start_slot(g.cands.starts.split, k) else {
                assert!(kind != PairKind::Collider && !kind.is_feature(), "{kind:?}");
                continue;
            };
            assert!(kind == PairKind::Collider || kind.is_feature(), "{kind:?}");
            let kept = g.cands.starts.slots[slot];
            if kept.distance.is_nan() {
                continue;
            }
            g.cands.starts.slots[slot] = StartOf::UNKNOWN;
            let fresh = g.start_of(k, &x0);
            assert_eq!(
                (kept.distance.to_bits(), kept.leaves),
                (fresh.distance.to_bits(), fresh.leaves),
                "round {round}: candidate {k} ({kind:?})"
            );
            checked += 1;
        }
    }
    assert!(
        carried > 100,
        "only {carried} starts carried over a refresh"
    );
    assert!(checked > 1000, "only {checked} starts checked");
}

#[test]
fn a_changed_mass_or_a_moved_collider_takes_a_full_broad_phase() {
    let (rest, edges, tris) = cloth(6);
    let [mut g, _] = groups(&rest, &edges, &tris);
    let mut inv_mass = vec![1.0; rest.len()];
    let x: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
    assert!(!g.colliders_and_masses_hold(&inv_mass), "nothing found yet");
    g.broad_phase(&x, &x, &inv_mass, TeamRef::serial());
    assert!(g.colliders_and_masses_hold(&inv_mass));
    inv_mass[3] = 0.0;
    assert!(!g.colliders_and_masses_hold(&inv_mass), "a pinned vertex");
    inv_mass[3] = 1.0;
    g.colliders.boxes[0] = g.colliders.boxes[0].grow(1e-3);
    assert!(
        !g.colliders_and_masses_hold(&inv_mass),
        "a collider left its box"
    );
}
