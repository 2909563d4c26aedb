//! The response: what the contacts do to the particles.
//!
//! Each contact is the inequality `C(x) = n · Σₖ wₖ xₖ − d ≥ 0` on the end-of-substep
//! positions, projected by inverse masses ([`contact`]; momentum-conserving, kinematic
//! particles never move), in every pass (the narrow phase's
//! `Pass::resolve`). In the last pass of the substep, in this order:
//! **friction** (Coulomb at the position level, once per substep, then one more normal
//! sweep: `Response::friction`), the **final projections** out of the analytic colliders
//! and the **push-out** of what started inside them ([`push_out`], [`leaving`]), and the
//! **fail-safe** ([`fail_safe`]). At the velocity level, after the substep:
//! **restitution** (`Response::restitution`) and the velocity the push-outs gave taken off
//! (`Response::drop_push_out_velocity`).

pub mod contact;
pub mod fail_safe;
pub mod leaving;
pub mod push_out;

use glam::DVec3;
use nucleus_sdk::prelude::Particles;

use crate::params::CollisionParams;
use contact::Contact;
use fail_safe::FailSafe;
use push_out::PushOuts;

/// The response's parameters and its state over a substep.
pub(crate) struct Response {
    restitution: f64,
    mu_static: f64,
    mu_dynamic: f64,
    /// Depenetration speed limit (m/s): see [`push_out::push_out_reach`].
    pub push_out_speed: f64,
    /// The substep's length (s).
    pub h: f64,
    /// Positions after prediction, before the solve.
    pub x_pred: Vec<DVec3>,
    /// Velocities before the solve (restitution's scratch).
    v_pre: Vec<DVec3>,
    /// The push-out each particle got ([`Self::record_push_outs`]).
    push_outs: PushOuts,
    /// The particles the fail-safe froze this substep.
    pub fail_safe: FailSafe,
}

impl Response {
    /// The response of a group of `n` particles.
    pub fn new(params: &CollisionParams, n: usize) -> Self {
        Self {
            restitution: params.restitution,
            mu_static: params.friction_static,
            mu_dynamic: params.friction_dynamic,
            push_out_speed: params.push_out_speed,
            h: 0.0,
            x_pred: vec![DVec3::ZERO; n],
            v_pre: vec![DVec3::ZERO; n],
            push_outs: PushOuts::new(n),
            fail_safe: FailSafe::new(n),
        }
    }

    /// Starts a substep of length `h` from the predicted positions `x`.
    pub fn begin(&mut self, x: &[DVec3], h: f64) {
        let n = self.x_pred.len();
        self.x_pred.copy_from_slice(&x[..n]);
        self.h = h;
        self.fail_safe.begin();
    }

    /// How far (m) a primitive that starts the substep inside a collider may leave it by in
    /// this substep: `push_out_speed · h` ([`push_out::push_out_reach`]).
    #[inline]
    pub fn push_out(&self) -> f64 {
        self.push_out_speed * self.h
    }

    /// Friction on every contact (Coulomb at the position level: [`Contact::friction`]), then
    /// one more normal sweep, since friction moved particles tangentially; the moves against
    /// something immovable recorded in `pushes`.
    pub fn friction(
        &self,
        contacts: &mut [Contact],
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) {
        let (mu_static, mu_dynamic) = (self.mu_static, self.mu_dynamic);
        for c in contacts.iter_mut() {
            recorded(c, x, inv_mass, pushes, |c, x| {
                c.friction(x, x0, inv_mass, mu_static, mu_dynamic);
            });
        }
        for c in contacts.iter_mut() {
            recorded(c, x, inv_mass, pushes, |c, x| {
                c.project(x, inv_mass);
            });
        }
    }

    /// Restitution on the velocities of `p` after a substep of length `h`: the contacts that
    /// worked this substep and were approaching faster than `threshold` (m/s) before the
    /// solve (from the predicted positions) leave with `−e` times their approach speed
    /// ([`Contact::restitution`]); the velocity changes against something immovable are
    /// recorded in its kicks.
    pub fn restitution(
        &mut self,
        contacts: &mut [Contact],
        p: &mut Particles<'_>,
        h: f64,
        threshold: f64,
    ) {
        if self.restitution <= 0.0 || contacts.is_empty() || h <= 0.0 {
            return;
        }
        for (vp, (&xp, &x0)) in self.v_pre.iter_mut().zip(self.x_pred.iter().zip(p.x0)) {
            *vp = (xp - x0) / h;
        }
        for c in contacts.iter_mut() {
            let collider_v = c.collider_disp / h;
            recorded(c, p.v, p.inv_mass, p.kicks, |c, v| {
                c.restitution(
                    v,
                    &self.v_pre,
                    p.inv_mass,
                    self.restitution,
                    threshold,
                    collider_v,
                );
            });
        }
    }
}

/// Runs `act` on contact `c` and, when `out` is being recorded (not empty), adds to it what
/// `act` moved the contact's particles by if the contact is against something immovable
/// ([`Contact::moves_if`]): displacements with positions for `x`, velocity changes with
/// velocities.
#[inline]
pub(crate) fn recorded(
    c: &mut Contact,
    x: &mut [DVec3],
    inv_mass: &[f64],
    out: &mut [DVec3],
    act: impl FnOnce(&mut Contact, &mut [DVec3]),
) {
    let moves = c.moves_if(!out.is_empty(), x, inv_mass);
    act(c, x);
    if let Some(m) = moves {
        m.add_to(x, out);
    }
}
