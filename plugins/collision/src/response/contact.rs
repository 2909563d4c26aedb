//! One contact as pure functions: the non-penetration constraint, its projection, friction
//! at the position level and restitution at the velocity level.
//!
//! Every contact — vertex–face, edge–edge, vertex–vertex, vertex–edge, vertex–collider — is
//! the same inequality on up to four particles. With the weights `wₖ` of the closest points at
//! the time of impact (for vertex–face `p − (β₀a + β₁b + β₂c)`: `w = [1, −β₀, −β₁, −β₂]`; for
//! edge–edge `(1−s)a + s b − (1−t)c − t d`: `w = [1−s, s, −(1−t), −t]`), the separation
//! vector is `s(x) = Σₖ wₖ xₖ`, and with the contact normal `n` (unit, fixed at the time of
//! impact) and the target distance `d` (the sum of the thicknesses):
//!
//! ```text
//! C(x) = n · Σₖ wₖ xₖ − offset ≥ 0          (offset = d; for a collider, n·q + d)
//! ∇ₖC = wₖ n,   W = Σₖ mₖ⁻¹ wₖ²
//! Δλ = −C / W  (only when C < 0),   Δxₖ = mₖ⁻¹ wₖ n Δλ
//! ```
//!
//! the PBD projection of a hard inequality. The corrections are weighted by inverse masses and
//! sum to zero momentum (`Σ mₖ Δxₖ = n Δλ Σ wₖ = 0`, since the weights of each side sum to
//! ±1); a kinematic particle (`m⁻¹ = 0`) never moves, and a contact whose particles are all
//! kinematic is skipped. `dn` accumulates the normal correction `−C` of the substep (m): the
//! normal "impulse" `dn/h` (m/s) that bounds friction.
//!
//! **Friction** (Coulomb, position level, once per substep, after Macklin et al. 2014): the
//! relative tangential displacement of the substep, `Δt = (I − n nᵀ)(Σ wₖ (xₖ − x0ₖ) − u)`
//! (`u` the collider's own displacement at the contact), is removed completely when
//! `|Δt| ≤ μs dn` (static: sticks), else by `μd dn` (dynamic: slides). For a particle on a
//! plane inclined at `θ`, gravity gives `dn = h² g cos θ` and `Δt = h vₜ + h² g sin θ`
//! per substep: it sticks exactly when `tan θ ≤ μs`, and otherwise accelerates at exactly
//! `g (sin θ − μd cos θ)`.
//!
//! **Restitution** (velocity level, after `v = (x − x0)/h`): with the relative normal velocity
//! before the solve `v̄ₙ` (from the predicted positions) and after it `vₙ`, a contact that
//! worked this substep (`dn > 0`) and was approaching faster than the threshold (`v̄ₙ <
//! −2|g|h`, two substeps' worth of gravity, so resting contacts never bounce) gets
//! `vₙ ← −e v̄ₙ`, shared like the position correction. Below the threshold the contact is
//! inelastic, which is how a bouncing ball comes to rest in finitely many steps.

use glam::DVec3;

/// What touches what.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum PairKind {
    /// A vertex and an analytic collider (`a` = collider, `b` = vertex primitive).
    Collider = 0,
    /// Two unconnected particles.
    VertexVertex = 1,
    /// An unconnected particle and a curve edge.
    VertexEdge = 2,
    /// A vertex and a triangle.
    VertexFace = 3,
    /// Two edges.
    EdgeEdge = 4,
    /// A vertex of an analytic collider's core (a box corner, a sphere's centre, a capsule's
    /// end) and a triangle (`a` = feature point, `b` = face).
    FeatureFace = 5,
    /// A vertex of an analytic collider's core and an edge (`a` = feature point, `b` = edge).
    FeaturePointEdge = 6,
    /// An edge of an analytic collider's core (a box edge, a capsule's axis) and an edge
    /// (`a` = feature edge, `b` = edge).
    FeatureEdgeEdge = 7,
}

impl PairKind {
    /// Whether one side is a sharp feature of an analytic collider.
    #[inline]
    pub fn is_feature(self) -> bool {
        matches!(
            self,
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge
        )
    }
}

/// A contact: which pair, the constraint's geometry fixed at the time of impact, and what it
/// did this substep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Kind of the pair.
    pub kind: PairKind,
    /// The pair's primitives (see [`PairKind`]); with `kind`, the key of the contact.
    pub pair: [u32; 2],
    /// Particles (global indices); unused slots have weight 0.
    pub ids: [u32; 4],
    /// Weights of the separation vector `Σ wₖ xₖ`.
    pub w: [f64; 4],
    /// Unit contact normal (from the second side towards the first).
    pub n: DVec3,
    /// `C = n·Σ wₖ xₖ − offset` (m).
    pub offset: f64,
    /// The collider's displacement at the contact over the substep (m); 0 for mesh pairs.
    pub collider_disp: DVec3,
    /// Normal correction accumulated this substep (m).
    pub dn: f64,
}

impl Contact {
    /// `Σ wₖ xₖ`.
    #[inline]
    pub fn separation_vector(&self, x: &[DVec3]) -> DVec3 {
        let mut s = DVec3::ZERO;
        for k in 0..4 {
            if self.w[k] != 0.0 {
                s += self.w[k] * x[self.ids[k] as usize];
            }
        }
        s
    }

    /// The constraint value `C` (m): negative when penetrating.
    #[inline]
    pub fn value(&self, x: &[DVec3]) -> f64 {
        self.n.dot(self.separation_vector(x)) - self.offset
    }

    /// `W = Σ mₖ⁻¹ wₖ²`.
    #[inline]
    pub fn inverse_mass(&self, inv_mass: &[f64]) -> f64 {
        let mut s = 0.0;
        for k in 0..4 {
            if self.w[k] != 0.0 {
                s += inv_mass[self.ids[k] as usize] * self.w[k] * self.w[k];
            }
        }
        s
    }

    /// Moves the particles along the generalised direction `dir` of the separation vector:
    /// `Δxₖ = mₖ⁻¹ wₖ dir / W`, so `Σ wₖ Δxₖ = dir`.
    #[inline]
    fn apply(&self, x: &mut [DVec3], inv_mass: &[f64], w_total: f64, dir: DVec3) {
        for k in 0..4 {
            let i = self.ids[k] as usize;
            if self.w[k] != 0.0 && inv_mass[i] > 0.0 {
                x[i] += inv_mass[i] * self.w[k] / w_total * dir;
            }
        }
    }

    /// What the contact is about to move, to record as pushes ([`Moves`]): `None` unless
    /// `record` and the contact moves one side only — the other is a collider's or
    /// kinematic particles (inverse mass 0), which do not move back. What it moves a particle
    /// by is then all it wants, whatever the particle's mass, and a group that holds the
    /// particle as part of a body answers it with the body's mass
    /// ([`SolveContext::pushes`](nucleus_sdk::SolveContext::pushes)).
    #[inline]
    pub fn moves_if(&self, record: bool, x: &[DVec3], inv_mass: &[f64]) -> Option<Moves> {
        if !record {
            return None;
        }
        let mut moves = Moves {
            ids: self.ids,
            used: [false; 4],
            before: [DVec3::ZERO; 4],
        };
        let (mut plus, mut minus) = (false, false);
        for k in 0..4 {
            let i = self.ids[k] as usize;
            if self.w[k] != 0.0 && inv_mass[i] > 0.0 {
                plus |= self.w[k] > 0.0;
                minus |= self.w[k] < 0.0;
                moves.used[k] = true;
                moves.before[k] = x[i];
            }
        }
        (plus != minus).then_some(moves)
    }

    /// Projects the constraint `C ≥ 0`; returns the correction `−C` applied (0 if satisfied or
    /// if nothing can move).
    #[inline]
    pub fn project(&mut self, x: &mut [DVec3], inv_mass: &[f64]) -> f64 {
        let c = self.value(x);
        if c >= 0.0 {
            return 0.0;
        }
        let w = self.inverse_mass(inv_mass);
        if w <= 0.0 || !w.is_finite() {
            return 0.0;
        }
        self.apply(x, inv_mass, w, -c * self.n);
        self.dn += -c;
        -c
    }

    /// Coulomb friction on the substep's relative tangential displacement (see the module
    /// docs); returns the tangential correction's length (m).
    pub fn friction(
        &self,
        x: &mut [DVec3],
        x0: &[DVec3],
        inv_mass: &[f64],
        mu_static: f64,
        mu_dynamic: f64,
    ) -> f64 {
        if self.dn <= 0.0 {
            return 0.0;
        }
        let w = self.inverse_mass(inv_mass);
        if w <= 0.0 || !w.is_finite() {
            return 0.0;
        }
        let rel = self.separation_vector(x) - self.separation_vector(x0) - self.collider_disp;
        let t = rel - self.n.dot(rel) * self.n;
        let len = t.length();
        if len <= 0.0 {
            return 0.0;
        }
        let remove = if len <= mu_static * self.dn {
            len
        } else {
            (mu_dynamic * self.dn).min(len)
        };
        self.apply(x, inv_mass, w, -t * (remove / len));
        remove
    }

    /// Restitution at the velocity level (see the module docs). `v_pre` are the velocities
    /// before the solve, `collider_v` the collider's velocity at the contact, `threshold`
    /// the approach speed (m/s) below which the contact is inelastic.
    pub fn restitution(
        &self,
        v: &mut [DVec3],
        v_pre: &[DVec3],
        inv_mass: &[f64],
        restitution: f64,
        threshold: f64,
        collider_v: DVec3,
    ) {
        if self.dn <= 0.0 || restitution <= 0.0 {
            return;
        }
        let w = self.inverse_mass(inv_mass);
        if w <= 0.0 || !w.is_finite() {
            return;
        }
        let vn_pre = self.n.dot(self.separation_vector(v_pre) - collider_v);
        if vn_pre >= -threshold {
            return;
        }
        let vn = self.n.dot(self.separation_vector(v) - collider_v);
        let target = -restitution * vn_pre;
        if vn < target {
            self.apply(v, inv_mass, w, (target - vn) * self.n);
        }
    }
}

/// The particles a contact against something immovable is about to move, with their values
/// before ([`Contact::moves_if`]).
#[derive(Clone, Copy, Debug)]
pub struct Moves {
    ids: [u32; 4],
    used: [bool; 4],
    before: [DVec3; 4],
}

impl Moves {
    /// Adds to `out` what each of the particles moved by since: `x` now minus before (a
    /// displacement, or with velocities for `x` a velocity change).
    #[inline]
    pub fn add_to(&self, x: &[DVec3], out: &mut [DVec3]) {
        for k in 0..4 {
            if self.used[k] {
                let i = self.ids[k] as usize;
                out[i] += x[i] - self.before[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vf_contact(beta: [f64; 3], n: DVec3, d: f64) -> Contact {
        Contact {
            kind: PairKind::VertexFace,
            pair: [0, 0],
            ids: [0, 1, 2, 3],
            w: [1.0, -beta[0], -beta[1], -beta[2]],
            n,
            offset: d,
            collider_disp: DVec3::ZERO,
            dn: 0.0,
        }
    }

    fn momentum(x: &[DVec3], inv_mass: &[f64]) -> DVec3 {
        x.iter()
            .zip(inv_mass)
            .filter(|(_, &w)| w > 0.0)
            .map(|(p, &w)| *p / w)
            .sum()
    }

    #[test]
    fn only_contacts_against_something_immovable_record_their_pushes() {
        let beta = [0.2, 0.3, 0.5];
        let x0 = vec![
            DVec3::new(0.3, 0.3, -0.004),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.001),
            DVec3::new(0.0, 1.0, -0.002),
        ];
        let pushed = |inv_mass: [f64; 4], record: bool| {
            let (mut c, mut x) = (vf_contact(beta, DVec3::Z, 0.01), x0.clone());
            let mut out = vec![DVec3::ZERO; 4];
            let moves = c.moves_if(record, &x, &inv_mass);
            c.project(&mut x, &inv_mass);
            if let Some(m) = moves {
                m.add_to(&x, &mut out);
            }
            (out, x)
        };
        // The face kinematic (a mesh collider): the vertex's whole displacement is recorded.
        let (out, x) = pushed([1.0, 0.0, 0.0, 0.0], true);
        assert!(out[0].z > 0.0 && out[0] == x[0] - x0[0], "{out:?}");
        assert_eq!(&out[1..], &[DVec3::ZERO; 3]);
        // The vertex kinematic, the face moving: the face's displacements.
        let (out, x) = pushed([0.0, 1.0, 2.0, 0.5], true);
        assert_eq!(out[0], DVec3::ZERO);
        for k in 1..4 {
            assert!(out[k] == x[k] - x0[k] && out[k].z < 0.0, "{out:?}");
        }
        // Both sides moving: momentum is shared between them, nothing is recorded; nor when
        // no group reads the pushes.
        assert_eq!(pushed([2.0, 1.0, 0.5, 1.5], true).0, vec![DVec3::ZERO; 4]);
        assert_eq!(pushed([1.0, 0.0, 0.0, 0.0], false).0, vec![DVec3::ZERO; 4]);
        // A collider contact: one particle, always recorded.
        let c = particle_on_ground(0.0);
        assert!(c.moves_if(true, &x0, &[1.0]).is_some());
        assert!(
            c.moves_if(true, &x0, &[0.0]).is_none(),
            "a pinned particle is not pushed"
        );
    }

    #[test]
    fn projection_reaches_the_target_distance_and_conserves_momentum() {
        let beta = [0.2, 0.3, 0.5];
        let mut c = vf_contact(beta, DVec3::Z, 0.01);
        let mut x = vec![
            DVec3::new(0.3, 0.3, -0.004),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.001),
            DVec3::new(0.0, 1.0, -0.002),
        ];
        let inv_mass = [2.0, 1.0, 0.5, 1.5];
        let before = momentum(&x, &inv_mass);
        assert!(c.value(&x) < 0.0);
        let corr = c.project(&mut x, &inv_mass);
        assert!(corr > 0.0);
        assert!(c.value(&x).abs() < 1e-15, "{}", c.value(&x));
        assert!((momentum(&x, &inv_mass) - before).length() < 1e-15);
        assert!((c.dn - corr).abs() < 1e-18);
        // Satisfied up to rounding: a second projection does (next to) nothing.
        assert!(c.project(&mut x, &inv_mass) < 1e-15);
    }

    #[test]
    fn gradient_of_the_constraint_matches_finite_differences() {
        let c = vf_contact([0.1, 0.6, 0.3], DVec3::new(0.3, 0.4, 1.0).normalize(), 0.02);
        let x = vec![
            DVec3::new(0.3, 0.3, 0.1),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.2),
            DVec3::new(0.0, 1.0, -0.1),
        ];
        let e = 1e-7;
        for k in 0..4 {
            for axis in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[k][axis] += e;
                xm[k][axis] -= e;
                let fd = (c.value(&xp) - c.value(&xm)) / (2.0 * e);
                let analytic = c.w[k] * c.n[axis];
                assert!(
                    (fd - analytic).abs() < 1e-8,
                    "{k} {axis}: {fd} vs {analytic}"
                );
            }
        }
    }

    #[test]
    fn kinematic_particles_never_move() {
        let mut c = vf_contact([0.3, 0.3, 0.4], DVec3::Y, 0.01);
        let mut x = vec![DVec3::new(0.2, -0.1, 0.2), DVec3::ZERO, DVec3::X, DVec3::Z];
        let tri = [x[1], x[2], x[3]];
        c.project(&mut x, &[1.0, 0.0, 0.0, 0.0]);
        assert_eq!([x[1], x[2], x[3]], tri);
        assert!((x[0].y - 0.01).abs() < 1e-15);
        // All kinematic: nothing moves, no NaN.
        let mut c = vf_contact([0.3, 0.3, 0.4], DVec3::Y, 0.01);
        let before = x.clone();
        x[0].y = -1.0;
        let mut y = x.clone();
        assert_eq!(c.project(&mut y, &[0.0; 4]), 0.0);
        assert_eq!(y, x);
        let _ = before;
    }

    fn particle_on_ground(dn: f64) -> Contact {
        Contact {
            kind: PairKind::Collider,
            pair: [0, 0],
            ids: [0, 0, 0, 0],
            w: [1.0, 0.0, 0.0, 0.0],
            n: DVec3::Y,
            offset: 0.0,
            collider_disp: DVec3::ZERO,
            dn,
        }
    }

    #[test]
    fn friction_sticks_below_the_static_cone_and_slides_by_mu_dynamic_above() {
        let x0 = [DVec3::ZERO];
        // Tangential displacement 0.3 with normal correction 1: sticks for μs ≥ 0.3.
        let c = particle_on_ground(1.0);
        let mut x = [DVec3::new(0.3, 0.0, 0.0)];
        c.friction(&mut x, &x0, &[1.0], 0.4, 0.2);
        assert!(x[0].length() < 1e-15);
        let mut x = [DVec3::new(0.3, 0.0, 0.0)];
        c.friction(&mut x, &x0, &[1.0], 0.25, 0.2);
        assert!((x[0].x - 0.1).abs() < 1e-15, "{}", x[0]);
        // No normal correction, no friction.
        let mut x = [DVec3::new(0.3, 0.0, 0.0)];
        particle_on_ground(0.0).friction(&mut x, &x0, &[1.0], 10.0, 10.0);
        assert_eq!(x[0].x, 0.3);
    }

    #[test]
    fn friction_acts_on_the_motion_relative_to_a_moving_collider() {
        // The ground moved by 0.3 in x; the particle moved with it: nothing to remove.
        let mut c = particle_on_ground(1.0);
        c.collider_disp = DVec3::new(0.3, 0.0, 0.0);
        let mut x = [DVec3::new(0.3, 0.0, 0.0)];
        c.friction(&mut x, &[DVec3::ZERO], &[1.0], 0.5, 0.5);
        assert_eq!(x[0].x, 0.3);
        // The particle stayed put while the ground moved: static friction drags it along.
        let mut x = [DVec3::ZERO];
        c.friction(&mut x, &[DVec3::ZERO], &[1.0], 0.5, 0.5);
        assert!((x[0].x - 0.3).abs() < 1e-15);
    }

    #[test]
    fn restitution_reverses_the_approach_speed_scaled_by_e() {
        let c = particle_on_ground(0.01);
        let mut v = [DVec3::new(1.0, 0.0, 0.0)];
        let pre = [DVec3::new(1.0, -4.0, 0.0)];
        c.restitution(&mut v, &pre, &[1.0], 0.5, 0.1, DVec3::ZERO);
        assert!((v[0] - DVec3::new(1.0, 2.0, 0.0)).length() < 1e-15);
        // Slow approach: inelastic.
        let mut v = [DVec3::ZERO];
        c.restitution(
            &mut v,
            &[DVec3::new(0.0, -0.05, 0.0)],
            &[1.0],
            0.5,
            0.1,
            DVec3::ZERO,
        );
        assert_eq!(v[0], DVec3::ZERO);
    }

    #[test]
    fn restitution_between_two_particles_conserves_momentum() {
        let c = Contact {
            kind: PairKind::VertexVertex,
            pair: [0, 1],
            ids: [0, 1, 0, 0],
            w: [1.0, -1.0, 0.0, 0.0],
            n: DVec3::X,
            offset: 0.1,
            collider_disp: DVec3::ZERO,
            dn: 0.01,
        };
        let inv_mass = [1.0, 0.25];
        let pre = [DVec3::new(-3.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0)];
        let mut v = [DVec3::new(-0.2, 0.0, 0.0), DVec3::new(-0.2, 0.0, 0.0)];
        let p0 = v[0] / inv_mass[0] + v[1] / inv_mass[1];
        c.restitution(&mut v, &pre, &inv_mass, 1.0, 0.0, DVec3::ZERO);
        let p1 = v[0] / inv_mass[0] + v[1] / inv_mass[1];
        assert!((p1 - p0).length() < 1e-14);
        // Relative normal velocity: −(−4) = 4.
        assert!(((v[0] - v[1]).x - 4.0).abs() < 1e-14);
    }
}
