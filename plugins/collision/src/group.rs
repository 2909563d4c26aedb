//! The `collision` group: the state of each stage of the pipeline, and the stages run in
//! order at each step of the core's substep (see the [crate docs](crate) for the algorithm).
//!
//! * `begin_substep`: predicted positions kept, colliders posed over the substep, candidates
//!   found (a full broad phase, a refresh, or the last ones kept), objects impaled on a
//!   capsule found;
//! * `project`, each pass: refresh, then one detection and resolution pass; the last pass
//!   adds friction, a refresh, the final projections out of the colliders' features and out
//!   of the colliders, the fail-safe, and the push-outs' record;
//! * `end_substep`: the deepest penetration, the push-outs' velocity taken off, restitution.

use nucleus_sdk::prelude::*;
use nucleus_sdk::team::TeamRef;

use crate::broad_phase::refresh::Refreshed;
use crate::broad_phase::BroadPhase;
use crate::candidates::{Candidate, Candidates};
use crate::colliders::motion::Pose;
use crate::colliders::Colliders;
use crate::narrow_phase::{distance, Pass};
use crate::params::CollisionParams;
use crate::primitives::{Geometry, Primitives};
use crate::response::contact::{Contact, PairKind};
use crate::response::{leaving, Response};

#[cfg(test)]
mod tests;

/// Counters of one frame, for the stats.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Frame they belong to.
    pub frame: u64,
    /// Largest number of contacts in a substep.
    pub contacts: usize,
    /// Largest number of candidate pairs in a substep.
    pub candidates: usize,
    /// Full broad phases run: when a collider left its box or a mass changed, and when more
    /// than an eighth of the primitives left their boxes (at a substep's start or during
    /// the passes).
    pub broad_phases: usize,
    /// Partial broad phases: only the primitives that left their boxes looked for new pairs.
    pub refreshes: usize,
    /// Vertices frozen by the fail-safe.
    pub frozen: usize,
    /// Crossing pairs the fail-safe could not resolve (0 unless two colliders squeeze a
    /// vertex, or a deforming kinematic mesh sweeps through a frozen one).
    pub unresolved: usize,
    /// Deepest violation of the thickness at the end of a substep (m).
    pub max_penetration: f64,
}

/// All the collisions of one group: the state of each stage.
pub struct CollisionGroup {
    /// What collides: the target objects' vertices, edges and faces (built once).
    prims: Primitives,
    /// The analytic colliders, posed over the substep.
    colliders: Colliders,
    /// The swept boxes, trees and grid that find the candidates.
    broad: BroadPhase,
    /// The candidate pairs of the substep, with what proves them apart.
    cands: Candidates,
    /// The contacts of the substep.
    contacts: Vec<Contact>,
    /// Friction, restitution, push-out and fail-safe.
    response: Response,
    /// Whether any pair can ever collide (else the group is empty and never scheduled).
    active: bool,
    stats: FrameStats,
}

impl CollisionGroup {
    /// Builds the group: collects the vertices, edges and faces of the target objects (only
    /// the surface of tetrahedral solids), their settings and the colliders.
    pub fn new(params: &CollisionParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate_numbers()?;
        let n = scene.rest_positions().len().min(scene.inv_mass.len());
        let targets = scene.unique_targets()?;
        let names: Vec<&str> = targets.iter().map(|(_, o)| o.name.as_str()).collect();
        let settings = params.object_settings(&names)?;
        let excluded = params.excluded_pairs(&names)?;
        let colliders = params.colliders()?;
        let names = names.iter().map(|n| n.to_string()).collect();
        let prims = Primitives::build(scene, names, settings, excluded)?;
        let colliders = Colliders::new(colliders, prims.settings.len());
        Ok(Self {
            active: prims.any_pair(&colliders),
            broad: BroadPhase::new(&prims, n, params.max_candidates),
            cands: Candidates::new(n, 4 * prims.len()),
            contacts: Vec::with_capacity(prims.len()),
            response: Response::new(params, n),
            prims,
            colliders,
            stats: FrameStats::default(),
        })
    }

    /// The contacts of the current substep.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The candidate pairs of the current substep.
    pub fn candidates(&self) -> &[Candidate] {
        &self.cands.list
    }

    /// The counters of the last frame.
    pub fn frame_stats(&self) -> FrameStats {
        self.stats
    }

    /// Number of vertex, edge and face primitives.
    pub fn primitive_counts(&self) -> [usize; 3] {
        self.prims.counts()
    }

    /// The primitives and the colliders.
    fn geometry(&self) -> Geometry<'_> {
        Geometry {
            prims: &self.prims,
            colliders: &self.colliders,
        }
    }

    /// The working view of a pass over the candidates, and the response, borrowed apart.
    fn pass(&mut self) -> (Pass<'_>, &mut Response) {
        let push = self.response.push_out();
        let pass = Pass {
            geo: Geometry {
                prims: &self.prims,
                colliders: &self.colliders,
            },
            boxes: &self.broad.boxes,
            cands: &mut self.cands,
            contacts: &mut self.contacts,
            push,
        };
        (pass, &mut self.response)
    }

    /// The candidates of a new substep: a full broad phase when a collider left the box it
    /// was found with or a mass changed, else a refresh of the primitives that left their
    /// boxes, else the last candidates, their passes' state restarted.
    fn find_candidates(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64], team: TeamRef<'_>) {
        // A new substep, new tracks: no separation carries over from the last one.
        self.cands.within_substep = false;
        if !self
            .broad
            .colliders_and_masses_hold(self.geometry(), inv_mass)
        {
            self.broad_phase(x0, x, inv_mass, team);
        } else if !self.refresh(x0, x, inv_mass, team) {
            self.cands.restart(x, &self.contacts);
        }
        self.cands.within_substep = true;
    }

    /// A full broad phase over `[x0, x]`, its candidates handed over.
    fn broad_phase(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64], team: TeamRef<'_>) {
        let geo = Geometry {
            prims: &self.prims,
            colliders: &self.colliders,
        };
        self.broad.find_all(geo, x0, x, inv_mass, team);
        self.stats.broad_phases += 1;
        self.hand_over(x, team);
    }

    /// The refresh of the primitives that left their boxes ([`BroadPhase::refresh`]), its
    /// candidates handed over; whether the candidates were found again (the passes' state
    /// then restarted).
    fn refresh(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64], team: TeamRef<'_>) -> bool {
        let geo = Geometry {
            prims: &self.prims,
            colliders: &self.colliders,
        };
        match self.broad.refresh(geo, &self.cands, x0, x, inv_mass, team) {
            Refreshed::Nothing => return false,
            Refreshed::Full => self.stats.broad_phases += 1,
            Refreshed::Partial => self.stats.refreshes += 1,
        }
        self.hand_over(x, team);
        true
    }

    /// Hands the candidates just found to the passes.
    fn hand_over(&mut self, x: &[DVec3], team: TeamRef<'_>) {
        self.broad
            .hand_over(&mut self.cands, &self.prims, &self.contacts, x, team);
        self.stats.candidates = self.stats.candidates.max(self.cands.list.len());
    }

    /// The fail-safe ([`crate::response::fail_safe`]): while some pair still crosses over
    /// `[x0, x]`, its dynamic particles are frozen, the candidates refreshed before each
    /// round. The start of the substep is crossing-free, so every round either resolves the
    /// remaining crossings or freezes a new particle: at most one round per particle. Returns
    /// the pairs left crossing.
    fn fail_safe(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) -> usize {
        loop {
            self.refresh(x0, x, inv_mass, team);
            let (mut pass, response) = self.pass();
            let (crossing, froze) = response.fail_safe.round(&mut pass, x0, x, inv_mass);
            self.stats.frozen += froze;
            if crossing == 0 || froze == 0 {
                return crossing;
            }
        }
    }

    /// One detection and resolution pass over the candidates ([`Pass::resolve`]).
    fn resolve_pass(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
        team: TeamRef<'_>,
    ) {
        self.pass().0.resolve(x0, x, inv_mass, pushes, team);
    }

    /// The final projections: faces and edges out of the colliders' features, then vertices
    /// out of the colliders ([`crate::response::push_out`]).
    fn project_out_of_colliders(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) {
        let (mut pass, _) = self.pass();
        pass.project_features_out(x0, x, inv_mass, pushes);
        pass.project_out_of_colliders(x0, x, inv_mass, pushes);
    }

    /// Follows the push-out of what started the substep inside a collider
    /// ([`Response::record_push_outs`]).
    fn record_push_outs(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64]) {
        let (mut pass, response) = self.pass();
        response.record_push_outs(&mut pass, x0, x, inv_mass);
    }

    fn check_state(&self, len: usize) -> Result<(), PluginError> {
        let n = self.response.x_pred.len();
        if len < n {
            return Err(PluginError::failed(format!(
                "the group was built for {n} particles but the state has {len}"
            )));
        }
        Ok(())
    }

    /// Deepest thickness violation (m) at positions `x`, with the colliders at `poses`: over
    /// the contacts between particles, and over every candidate pair with a collider (its
    /// vertices by the exact signed distance, its features by their distance to the faces and
    /// edges near them). With `at_substep_end` (`x` the substep's end positions, the
    /// certificates' motion current and `poses` its end poses) the pairs certainly beyond
    /// their reach, which add nothing, are skipped.
    fn penetration(&self, x: &[DVec3], poses: &[Pose], at_substep_end: bool) -> f64 {
        let geo = self.geometry();
        let mut worst: f64 = 0.0;
        for c in &self.contacts {
            if c.kind != PairKind::Collider && !c.kind.is_feature() {
                worst = worst.max(c.offset - current_distance_squared(c, x).sqrt());
            }
        }
        for (k, cand) in self.cands.list.iter().enumerate() {
            let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
            if cand.kind != PairKind::Collider && !cand.kind.is_feature() {
                continue;
            }
            if at_substep_end && self.cands.certainly_beyond_reach(k, geo) {
                continue;
            }
            let dist = match cand.kind {
                PairKind::Collider => {
                    let p = self.prims.verts[b] as usize;
                    let col = &self.colliders.list[a];
                    let (phi, _) = col.shape.signed_distance(poses[a].inverse_apply(x[p]));
                    phi
                }
                kind if kind.is_feature() => {
                    let c = self.colliders.feature_collider(*cand) as usize;
                    geo.feature_distance(*cand, x, poses[c])
                }
                _ => continue,
            };
            worst = worst.max(self.cands.reach[k] - dist);
        }
        worst
    }
}

/// The squared distance between a mesh contact's two primitives at `x`.
fn current_distance_squared(c: &Contact, x: &[DVec3]) -> f64 {
    let g = |k: usize| x[c.ids[k] as usize];
    match c.kind {
        PairKind::VertexFace => distance::point_triangle_closest(g(0), g(1), g(2), g(3)).1,
        PairKind::EdgeEdge => distance::segment_segment_closest(g(0), g(1), g(2), g(3)).2,
        PairKind::VertexEdge => distance::point_segment_closest(g(0), g(2), g(3)).1,
        PairKind::VertexVertex => g(0).distance_squared(g(1)),
        _ => f64::INFINITY,
    }
}

impl ConstraintGroup for CollisionGroup {
    fn stages(&self) -> Stages {
        Stages::BEGIN_SUBSTEP
            | Stages::PROJECT
            | Stages::END_SUBSTEP
            | Stages::REPORT
            | Stages::GIVES_PUSHES
    }

    /// The number of collision primitives (vertices, edges, faces and colliders), or 0 when
    /// no pair can ever collide: then the core never schedules the group.
    fn len(&self) -> usize {
        if self.active {
            self.prims.len() + self.colliders.list.len()
        } else {
            0
        }
    }

    /// Keeps the predicted positions, poses the colliders at both ends of the substep, finds
    /// the candidate pairs over the swept primitives and the objects impaled on a capsule.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        if ctx.frame != self.stats.frame {
            self.stats = FrameStats {
                frame: ctx.frame,
                ..FrameStats::default()
            };
        }
        let (h, time, team) = (ctx.substep_length()?, ctx.time, ctx.team);
        let p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        self.response.begin(p.x, h);
        self.broad.boxes.follow(&self.prims, p.x0, p.x, p.inv_mass);
        let (shift, max_thickness) = (self.broad.boxes.shift, self.prims.max_thickness);
        self.colliders.pose(time, h, shift, max_thickness);
        self.contacts.clear();
        self.find_candidates(p.x0, p.x, p.inv_mass, team);
        leaving::find_impaled(&mut self.colliders, &self.prims, &self.cands, p.x0);
        self.broad.over_budget_error(&self.prims, p.x0, p.x, h)
    }

    /// One pass of detection and resolution; the last pass of the substep also applies
    /// friction, projects out of the analytic colliders and runs the fail-safe.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (last, team) = (ctx.pass + 1 >= ctx.passes, ctx.team);
        let p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        let (x0, x, w, pushes) = (p.x0, p.x, p.inv_mass, p.pushes);
        self.refresh(x0, x, w, team);
        self.resolve_pass(x0, x, w, pushes, team);
        if last {
            self.response.friction(&mut self.contacts, x0, x, w, pushes);
            // Friction and the sweeps moved particles: the final projections must see every
            // pair near a collider now, not only those of the pass's candidates.
            self.refresh(x0, x, w, team);
            self.project_out_of_colliders(x0, x, w, pushes);
            let unresolved = self.fail_safe(x0, x, w, team);
            self.record_push_outs(x0, x, w);
            self.stats.unresolved += unresolved;
            self.stats.contacts = self.stats.contacts.max(self.contacts.len());
        }
        self.broad
            .over_budget_error(&self.prims, x0, x, self.response.h)
    }

    /// The deepest penetration of the substep, then, at the velocity level, the push-outs'
    /// velocity taken off and restitution: contacts that worked this substep and were
    /// approaching faster than `2|g|h` leave with `−e` times their approach speed.
    fn end_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.h;
        let threshold = 2.0 * ctx.gravity().length() * h;
        let mut p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        self.cands.certs.update_moved(p.x);
        let pen = self.penetration(p.x, &self.colliders.pose1, true);
        self.stats.max_penetration = self.stats.max_penetration.max(pen);
        self.response.drop_push_out_velocity(p.v);
        self.response
            .restitution(&mut self.contacts, &mut p, h, threshold);
        Ok(())
    }

    /// The deepest violation of the thickness (m) over the contacts of the last substep and
    /// the vertices near colliders, at the current positions.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        if x.len() < self.response.x_pred.len() {
            return Residual::default();
        }
        let poses: Vec<Pose> = (self.colliders.list.iter())
            .map(|c| c.motion.pose(ctx.time))
            .collect();
        let max = self.penetration(x, &poses, false);
        Residual {
            count: self.contacts.len() as u64,
            max,
            rms: max,
            energy: 0.0,
        }
    }

    fn report(&self, _ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let s = self.stats;
        out.push(("contacts".into(), s.contacts as f64));
        out.push(("candidates".into(), s.candidates as f64));
        out.push(("broad_phases".into(), s.broad_phases as f64));
        out.push(("refreshes".into(), s.refreshes as f64));
        out.push(("frozen".into(), s.frozen as f64));
        out.push(("unresolved".into(), s.unresolved as f64));
        out.push(("max_penetration".into(), s.max_penetration));
    }
}

/// The factory of the `collision` kind.
pub(crate) fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params = CollisionParams::parse(params_json)?;
    Ok(Box::new(CollisionGroup::new(&params, scene)?))
}
