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
//! ## Layout
//!
//! The group ([`group`]) runs the stages of its pipeline in order; each stage is a room with
//! its own state and its own theory in its module docs:
//!
//! * [`primitives`] — what collides: the target objects' vertices, edges, faces, settings;
//! * [`colliders`] — the analytic colliders: shapes, motion, sharp features, posed per substep;
//! * [`broad_phase`] — swept boxes, trees, hash grid: the candidate pairs, found and refreshed;
//! * [`candidates`] — the pairs kept, which pairs may be kept, the proofs that pairs are apart;
//! * [`narrow_phase`] — the continuous tests (ccd, distance), a pair's contact, the pass;
//! * [`response`] — projection, friction, restitution, push-out, fail-safe;
//! * [`params`] — the kind's parameters and their validation.
//!
//! ## Thickness (Maya's model)
//!
//! Each object has a thickness `r` (m): its vertices are spheres, its edges cylinders and its
//! faces slabs of radius `r`, i.e. the points within `r` of the simplex. Two simplices of
//! objects `A` and `B` are kept `d = r_A + r_B` apart (`2r` within one object). The default
//! is 5 mm; Maya's default nCloth thickness is 0.1 scene units, 1 mm in Maya's default
//! centimetres. Per-object flags choose which simplices collide (`vertex`, `edge`, `face`).
//! A self-colliding dynamic object may be at most [`primitives::MAX_THICKNESS_PER_EDGE`] (4)
//! times as thick as its mean rest edge length: thicker, every vertex touches its own surface
//! at rest, and the build refuses it with the limit and the ways out (a smaller thickness, or
//! `self_collision = false` for that object).
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
//!   tests of [`narrow_phase::ccd`], the feature moving rigidly with its collider
//!   ([`shapes::Shape::features`]). A thin capsule or a box edge sweeping through the middle
//!   of a coarse triangle is stopped by the triangle, not only by its vertices. The plane
//!   needs no feature: a half-space's distance to a triangle is attained at a vertex.
//!
//! Which pairs are never tested, and the distance a pair of one object that is close at
//! rest is kept at, are [`candidates::filter`]'s and [`candidates::rest_pairs`]'. A group in
//! which no pair can ever collide reports no constraint, so the core never schedules it: a
//! scene without colliding objects pays nothing.
//!
//! ## The substep
//!
//! 1. **Broad phase** (`begin_substep`, and before every pass): the candidate pairs, every
//!    pair whose swept boxes overlap, in sorted order, the same on any number of threads
//!    ([`broad_phase`]); only the primitives that left their boxes look for new pairs
//!    ([`broad_phase::refresh`]).
//! 2. **Passes** (`project`; the group's importance gives their number, the "max collision
//!    iterations", default 4): the contacts found so far are projected again, then the
//!    continuous test runs on every candidate from `x0` to the *current* `x`, and each new
//!    contact is projected at once (Gauss-Seidel, [`narrow_phase::pass`]). A pair a
//!    certificate proves apart is skipped with the verdict its test would give
//!    ([`candidates::certificates`]). Nothing is ever moved back to a time of impact, and
//!    there is no event loop: the work per substep is bounded by the passes.
//! 3. **Last pass**: friction, the final projections out of the analytic colliders and the
//!    push-out of what started inside them, and the fail-safe, after which no simplex ends
//!    the substep crossing another ([`response`]).
//! 4. **Velocity level** (`end_substep`): restitution, and the velocity the push-outs gave
//!    taken off. Only `v` changes here; positions are final after the last pass.
//!
//! ## Residual and stats
//!
//! Residual (m): the deepest thickness violation at the end of the frame over the contacts of
//! its last substep, the vertices near colliders and the colliders' features near faces and
//! edges. Reported each frame: `contacts`, `candidates` (largest per substep),
//! `broad_phases` (full), `refreshes` (partial), `frozen`, `unresolved`, `max_penetration`
//! (deepest violation at the end of any substep of the frame, m).
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
