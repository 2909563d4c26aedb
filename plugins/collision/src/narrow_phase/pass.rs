//! One detection and resolution pass over the candidates (Gauss-Seidel): the contacts found so
//! far are projected again, then the continuous test runs on every candidate from `x0` to the
//! *current* `x`, and each new contact is projected at once. Nothing is ever moved back to a
//! time of impact, and there is no event loop: the work per substep is bounded by the passes
//! (the group's importance gives their number).

use glam::DVec3;
use nucleus_sdk::team::TeamRef;

use super::Pass;
use crate::candidates::NO_CONTACT;
use crate::parallel::PARALLEL_MIN_QUERIES;
use crate::response::recorded;

impl Pass<'_> {
    /// One Gauss-Seidel pass: re-project the contacts found so far, then run the continuous
    /// test on every candidate and project each new contact at once, its displacement
    /// recorded in `pushes` when it is against something immovable. The pass after the
    /// candidates were found takes their separations ahead over the team, where it has more
    /// than one thread and enough candidates
    /// ([`crate::candidates::Candidates::take_separations_ahead`]).
    pub fn resolve(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
        team: TeamRef<'_>,
    ) {
        for c in self.contacts.iter_mut() {
            recorded(c, x, inv_mass, pushes, |c, x| {
                c.project(x, inv_mass);
            });
        }
        self.cands.certs.update_moved(x);
        if std::mem::take(&mut self.cands.certs.unknown)
            && team.parts() > 1
            && self.cands.list.len() >= PARALLEL_MIN_QUERIES
        {
            self.cands.take_separations_ahead(self.geo, x0, x, team);
            self.cands.certs.begin_ahead();
        }
        for k in 0..self.cands.list.len() {
            let cand = self.cands.list[k];
            let d = self.cands.reach[k];
            if self.cands.skip(k, d) || !self.boxes.overlap(self.geo, cand, x0, x) {
                continue;
            }
            // A pair tested for the first time since the broad phase: its separation, kept for
            // the next passes, may settle it here (the verdict its test's prefilter would give)
            // and otherwise serves the test. One taken ahead that proves nothing is taken
            // again: the positions may have moved since.
            let mut known = None;
            let certs = &self.cands.certs;
            let exact = certs.ahead_exact
                && certs.taken_ahead[k]
                && !self.cands.ids[k].iter().any(|&i| certs.touched[i as usize]);
            if exact || certs.separation[k].d0.is_nan() || certs.taken_ahead[k] {
                self.cands.certs.taken_ahead[k] = false;
                known = if exact {
                    Some(self.cands.certs.separation[k])
                } else {
                    self.cands.take_separation(k, self.geo, x0, x)
                };
                if known.is_some_and(|s| s.certainly_apart(0.0, d)) {
                    continue;
                }
            }
            let Some(mut contact) = self.detect(k, x0, x, 1.0, known) else {
                continue;
            };
            let ids = contact.ids;
            let slot = self.cands.contact_of[k];
            if slot != NO_CONTACT {
                contact.dn = self.contacts[slot as usize].dn;
            }
            recorded(&mut contact, x, inv_mass, pushes, |c, x| {
                c.project(x, inv_mass);
            });
            if slot == NO_CONTACT {
                self.cands.contact_of[k] = self.contacts.len() as u32;
                self.contacts.push(contact);
            } else {
                self.contacts[slot as usize] = contact;
            }
            self.cands.certs.update_moved_of(&ids, x);
        }
        self.cands.certs.ahead_exact = false;
    }
}
