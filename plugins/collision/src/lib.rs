//! # `collision` — space-time collisions with thickness (the paper's Section 7)
//!
//! One kind, `collision`, applied to the objects a scene names: every vertex, edge and face of
//! those objects collides with every other one, of any object and of the same object
//! (self-collision), and with the analytic colliders listed in its parameters. Points,
//! curves, cloth and the surfaces of tetrahedral solids mix freely. Triangle-mesh colliders
//! are ordinary objects whose vertices are all kinematic (`pins = ["all"]`, moved by the
//! core's `pin_motion` or an OBJ sequence): their real motion over the substep is in
//! `[x0, x]`, so they take part in the space-time test like everything else, and their
//! inverse mass 0 keeps them out of the response.
//!
//! ## Thickness (Maya's model)
//!
//! Each object has a thickness `r` (m): its vertices are spheres, its edges cylinders and its
//! faces slabs of radius `r`, i.e. the points within `r` of the simplex. Two simplices of
//! objects `A` and `B` are kept `d = r_A + r_B` apart (`2r` within one object). The default
//! is 5 mm; Maya's default nCloth thickness is 0.1 scene units, 1 mm in Maya's default
//! centimetres. Per-object flags choose which simplices collide (`vertex`, `edge`, `face`).
//! A self-colliding dynamic object may be at most [`group::MAX_THICKNESS_PER_EDGE`] (4) times
//! as thick as its mean rest edge length: thicker, every vertex touches its own surface at
//! rest (a 0.5 m thickness on a 64 × 64, 1 m cloth kept 30 million pairs, 30 s to build and
//! minutes a substep), and the build refuses it with the limit and the ways out (a smaller
//! thickness, or `self_collision = false` for that object).
//!
//! ## Which pairs are tested
//!
//! * vertex–face (every vertex against every triangle) and edge–edge (every edge against
//!   every edge): together they find the first contact of any two simplicial surfaces or
//!   curves, since the distance between two moving simplices first reaches `d` at a
//!   vertex–face or an edge–edge pair;
//! * for unconnected particles, which have no edge: particle–particle (a hash grid) and
//!   particle–curve edge;
//! * each analytic collider (plane, sphere, box, capsule) against vertices, edges and faces
//!   alike. A collider is the set of points within a radius of a convex *core* — a sphere's
//!   centre, a capsule's axis, a box itself (radius 0); the plane is a half-space — so the
//!   distance from a triangle (or a segment) to it is the distance to the core minus the
//!   radius, and the distance between two convex polytopes is attained at a vertex of one
//!   against the other or at an edge of each. Hence three tests, together exact:
//!   **vertex–collider** (every vertex against the collider's exact signed distance,
//!   [`shapes::first_contact`]), **feature point–face** (every vertex of the core — box
//!   corners, capsule ends, the sphere's centre — against every face, and against curve
//!   edges) and **feature edge–edge** (every edge of the core — box edges, the capsule's axis
//!   — against every edge), the last two with the ordinary point–triangle and edge–edge
//!   tests of [`ccd`](narrow_phase::ccd), the feature moving rigidly with its collider
//!   ([`shapes::Shape::features`]). A thin capsule or a box edge sweeping through the middle
//!   of a coarse triangle is stopped by the triangle, not only by its vertices. The plane
//!   needs no feature: a half-space's distance to a triangle is attained at a vertex.
//!
//! Never tested: pairs sharing a vertex (neighbours); pairs of one object when its
//! `self_collision` is off; pairs of two objects, or of an object and a collider, whose
//! collision `layers` (bitmasks) share no bit; excluded object pairs (`exclude`); pairs whose
//! particles are all kinematic; a primitive whose flag (`vertex`, `edge`, `face`) is off.
//! A pair of one object that does not share a vertex but is closer than `d` in the rest shape
//! (a fine mesh whose non-adjacent vertices are closer than twice its thickness, or the
//! front and back of a garment modelled close together) is **kept**, at a reduced distance:
//! half its rest distance ([`group::rest_reach`]) — pushing it to `d` would fight the
//! object's own shape, and dropping it would let it pass through itself once folded. Only a
//! pair that touches in the rest shape (an unwelded seam) is dropped, like neighbours.
//! A group in which no pair can ever collide reports no constraint, so the core never
//! schedules it: a scene without colliding objects pays nothing.
//!
//! ## Broad phase ([`bvh`](broad_phase::bvh))
//!
//! Axis-aligned bounding box trees over the swept edges and faces — each primitive's box
//! covers its particles at `x0` and `x − s`, grown by its thickness and a margin
//! (`0.3 r + 0.1 mm`), with `s` the displacement the group's vertices share (every box of the
//! substep takes the same `s`, which keeps every pair that can touch; a slow group keeps
//! `s = 0`) — built once over the rest shape and **refit** every substep, and a
//! spatial hash grid over the unconnected particles. The candidate pairs are collected once
//! per substep (`begin_substep`), in sorted order: deterministic. The vertex–face and
//! edge–edge queries (one per vertex, one per edge) are split over the host's thread team in
//! contiguous ranges whose hits are joined in order, so the list is the same on any number of
//! threads. The solve moves positions; before every pass, and at the start of the next substep,
//! each primitive's tight swept box is checked against the box its candidates were found with.
//! Only the primitives that left their boxes get new boxes and look for new pairs (a
//! *refresh*: a query per vertex, face or edge that left, then a merge into the sorted list);
//! every other candidate is kept. More than an eighth of the primitives out, a collider out of
//! its box, or a changed mass (a pin released) takes a full broad phase instead. The contact set
//! may grow, but no pair is ever skipped: the list holds every pair whose boxes overlap (a
//! property test checks it against full broad phases over rounds of random crumpling).
//! A full broad phase would also list the pairs within a fresh margin of a primitive that stayed
//! in its older box; such a pair can only come within reach by leaving the boxes, and is then
//! tested from the next pass. The frames were the same bits over 60 frames of `cloth_heap` and
//! `cloth_on_sphere` (2 threads) and 20 of `soccer_net` and `collision_sweep`.
//!
//! Most candidates of a cloth never touch: a flat 64 × 64 sheet has 27,000 edge pairs whose
//! boxes overlap and none within the thickness. A pass tests a pair the first time in full,
//! keeping its start and end distances and relative motion ([`pairs::Separation`](narrow_phase::pairs::Separation)); until the
//! next broad phase it skips the pair while that separation, less twice the most any of its
//! particles has moved since, still proves it apart ([`pairs::Separation::certainly_apart`](narrow_phase::pairs::Separation::certainly_apart)) —
//! the verdict the full test would give, so the contacts and positions are the same bits.
//! A collider's feature against a face or an edge keeps the separation of the mesh test it
//! runs on the feature's track, and a vertex against a plane or a sphere its signed distances
//! at the ends of its track and the track's length ([`pairs::collider_separation`](narrow_phase::pairs::collider_separation)); the final
//! projections and the penetration statistic skip on them too. The separations' distances are
//! taken by [`distance::segment_segment_distance_squared`](narrow_phase::distance::segment_segment_distance_squared) and
//! [`distance::point_triangle_distance_squared`](narrow_phase::distance::point_triangle_distance_squared), the robust ones' to rounding.
//!
//! Measured back to back (2026-11-23, the 2-core VM, the first 40 frames, mean ms per frame,
//! before = commit 7d55671, after = the skip, the split and the `0.3 r` margin):
//!
//! | scene | 1 thread before → after | 2 threads before → after |
//! |---|---:|---:|
//! | `soccer_net` | 104.8 → 86.2 | 106.0 → **65.5** |
//! | `cloth_on_sphere` | 967 → 636 | 998 → **573** |
//! | `cloth_heap` (mostly pairs in contact) | 1,319 → 1,154 | 1,340 → **924** |
//! | `collision_sweep` | 10.0 → 9.2 | 11.9 → 10.5 |
//!
//! The skip alone gives the same bits (every OBJ frame of the first three scenes compared);
//! the margin changes when the broad phase reruns, and with it the order of the contacts.
//! Command: `RAYON_NUM_THREADS=T target/release/nucleus run scenes/SCENE.toml --frames 40`.
//!
//! Then the refresh (2026-11-23, the same 40 frames, before = commit 6184ccd, full broad
//! phases at every substep and whenever a primitive left its box; every OBJ frame of the four
//! scenes the same bits on 1 and on 2 threads):
//!
//! | scene | full / partial broad phases | 1 thread before → after | 2 threads before → after |
//! |---|---|---:|---:|
//! | `soccer_net` | 531 / 0 → 251 / 278 | 92.7 → 67.4 | 70.5 → **61.8** |
//! | `cloth_on_sphere` | 549 / 0 → 295 / 336 | 646 → 560 | 559 → **523** |
//! | `cloth_heap` | 1,010 / 0 → 407 / 704 | 1,252 → 1,063 | 937 → **771** |
//! | `collision_sweep` | 633 / 0 → 345 / 235 | 8.1 → 6.9 | 8.1 → 7.6 |
//!
//! ## Narrow phase ([`ccd`](narrow_phase::ccd), [`distance`](narrow_phase::distance))
//!
//! Vertex–face and edge–edge (and the colliders' features, on their rigid tracks): the
//! conservative continuous tests of [`ccd`](narrow_phase::ccd) (no false negative), giving the earliest
//! `t ∈ [0, 1]` at which the pair comes within `d` — for every pair that moves farther over
//! the substep than it is apart, the only pairs that can pass through each other. A pair
//! that moves less than its start distance cannot cross: its end state decides (a contact at
//! `t = 1` if it ends within `d`), which spares the bisection the grazing and resting
//! contacts ([`pairs`](narrow_phase::pairs), the prefilter). Particle–particle: a quadratic in closed form
//! ([`pairs::point_point_toi`](narrow_phase::pairs::point_point_toi)). Vertex–collider: the same question against the collider's
//! exact signed distance, in the collider's frame ([`shapes::first_contact`]). The closest
//! points at `t` fix the contact's weights and normal for the rest of the substep
//! ([`pairs`](narrow_phase::pairs)); a collider's feature is folded into the contact's offset and its motion into
//! the contact's collider displacement ([`pairs::fold_kinematic`](narrow_phase::pairs::fold_kinematic)), so friction and
//! restitution see the motion relative to the collider.
//!
//! ## Response ([`contact`](response::contact))
//!
//! Each contact is the inequality `C(x) = n · Σₖ wₖ xₖ − d ≥ 0` on the end-of-substep
//! positions, projected by inverse masses (momentum-conserving; kinematic particles never
//! move). **Resolved sequentially at the fixed time step**: each `project` pass (the group's
//! importance gives the number of passes per substep, the "max collision iterations";
//! default 4) re-projects the contacts found so far, then runs the continuous test on every
//! candidate from `x0` to the *current* `x` and projects each new contact at once
//! (Gauss-Seidel). Nothing is ever moved back to a time of impact, and there is no event
//! loop: the work per substep is bounded by the passes.
//!
//! In the **last pass** of the substep, in this order:
//!
//! 1. **friction** (Coulomb at the position level, once per substep): each contact that
//!    pushed (`dn > 0`) removes its relative tangential displacement entirely if it is at
//!    most `μs dn` (sticking), else `μd dn` of it (sliding); the collider's own motion is
//!    subtracted, so animated colliders drag and carry correctly;
//! 2. every face and edge near an analytic collider's feature is **pushed out** to its
//!    contact distance along the current separating direction (a few Gauss-Seidel sweeps;
//!    contacts keep the plane of their time of impact, which drifts when cloth slides around a
//!    curved core), then every vertex is **projected out of the analytic colliders** (exact
//!    signed-distance projection to `r` from the surface at the end pose): no vertex ends
//!    inside one. A primitive that *started* the substep deeper than its contact distance
//!    (a cloth placed through a collider) is moved out by at most `push_out_speed · h`
//!    instead, here and in the contacts (`group::push_out_reach`): it leaves over several
//!    substeps, its neighbours carried along by the stretch constraints, instead of being
//!    thrown out in one jump that tears the cloth; once out, the outward speed the pushes
//!    gave it is taken off its velocity at the substep's end (`group::without_push_velocity`).
//!    A box's corners and edges are its surface: an edge or face that starts the substep in
//!    the box, or whose closest point to a corner or edge is inside it, is pushed out
//!    *through* that feature (and has no contact or fail-safe test against it, both of which
//!    would hold it inside), so a cloth started through a box is untangled; a cloth a
//!    capsule's axis pierces (impaled) slides along the axis over its nearer end, every part of
//!    it inside the capsule with it (`push_off_axis`, `slide_off_axis`);
//! 3. the **fail-safe**: the continuous test is run once more with zero thickness on every
//!    candidate (for a collider's feature: reaching the collider's core — a face crossing a
//!    box corner or a capsule's axis); while a pair still crosses, its dynamic particles are
//!    *frozen*: put back at their start-of-substep position (a state free of crossings),
//!    carried by the rigid motion of a fully kinematic object or an analytic collider they
//!    hit (a moving collider pushes them along).
//!    Each round freezes at least one more particle or ends, so it terminates, and no
//!    simplex ends the substep crossing another. A frozen particle's velocity becomes, through
//!    the core's `v = (x − x0)/h`, zero or its carrier's: a local, perfectly inelastic
//!    "impact zone". `frozen` in the stats counts them; `unresolved` counts what the
//!    fail-safe cannot fix (a particle squeezed between two differently moving colliders, or
//!    a deforming kinematic mesh sweeping into a frozen one), 0 in every scene we ship.
//!    With importance 1 and a stack of contacts one pass cannot separate, the fail-safe is
//!    what keeps the cloth whole (the in-crate test
//!    `the_fail_safe_leaves_no_crossing_when_one_pass_per_substep_cannot_resolve_a_stack`).
//!
//! ## Velocity level (`end_substep`)
//!
//! Restitution: a contact that pushed this substep and was approaching faster than
//! `2|g|h` before the solve (its relative normal velocity from the predicted positions
//! saved in `begin_substep`) leaves with `−e` times that velocity; slower contacts are
//! inelastic, which is what brings a bouncing ball to rest in finitely many steps without
//! jitter. Only `v` changes here; positions are final after the last pass.
//!
//! ## Candidate budget
//!
//! A group holds at most `max_candidates` candidate pairs (automatic by default,
//! `group::candidate_budget`: 64 per primitive, or 8 per same-object pair within reach at
//! rest, at least 2²⁰; the shipped scenes peak at about 8 per primitive). Beyond it, the substep fails with an error naming the object whose vertex
//! moved farthest and how far, instead of holding tens of millions of pairs for minutes (a
//! gravity of −2e9 m/s² on `cloth_on_sphere`: 54 million, 76 s a substep).
//!
//! ## Residual and stats
//!
//! Residual (m): the deepest thickness violation at the end of the frame over the contacts of
//! its last substep, the vertices near colliders and the colliders' features near faces and
//! edges. Reported each frame: `contacts`,
//! `candidates` (largest per substep), `broad_phases` (full), `refreshes` (partial), `frozen`, `unresolved`,
//! `max_penetration` (deepest violation at the end of any substep of the frame, m).
//!
//! ## Scheduling defaults
//!
//! Order 100: collisions run after the structural kinds in every column, so they have the
//! last word on positions. Importance 4: four detection/resolution passes per substep.

pub mod broad_phase;
pub mod candidates;
pub mod colliders;
pub mod group;
pub mod narrow_phase;
mod parallel;
pub mod params;
pub mod primitives;
pub mod response;

#[cfg(test)]
mod tests;

pub use candidates::Candidate;
pub use colliders::shapes;
pub use group::{CollisionGroup, FrameStats};
pub use params::CollisionParams;
pub use response::contact::{Contact, PairKind};

use nucleus_sdk::KindSpec;

/// The kinds this plugin provides: `collision`.
pub fn kinds() -> Vec<KindSpec> {
    vec![KindSpec {
        name: "collision",
        doc: "Space-time collisions with thickness between every vertex, edge and face of the \
              target objects (self-collision included) and with analytic colliders (plane, \
              sphere, box, capsule); continuous detection with no missed collision, \
              sequential resolution with friction and restitution, and a fail-safe so no \
              simplex ends a substep crossing another.",
        default_order: 100,
        default_importance: 4,
        residual_unit: "m",
        params: CollisionParams::specs(),
        factory: group::build,
    }]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "collision",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
