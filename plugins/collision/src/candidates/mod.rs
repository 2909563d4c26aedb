//! The candidate pairs of the substep: the pairs of primitives whose swept boxes overlap
//! (`Candidates`), kept sorted with their contact distances and particles; which pairs may
//! be candidates at all ([`filter`], [`rest_pairs`]); the proofs that a pair is apart, which
//! let a pass skip it ([`certificates`]); and what each collider pair was at the substep's
//! start ([`starts`]).
//!
//! The list is found by the broad phase ([`crate::broad_phase`]) and handed over whole
//! (`Candidates::adopt`): in sorted order — kinds in [`PairKind`] order, the first
//! primitive ascending, the second ascending — so it is the same on any number of threads,
//! and the passes meet the pairs in the same order.

pub mod certificates;
pub mod filter;
pub mod rest_pairs;
pub mod starts;

use glam::DVec3;
use nucleus_sdk::team::{SharedArray, TeamRef};

use crate::narrow_phase::pairs::Separation;
use crate::parallel::{fill_over_team, PARALLEL_MIN_ITEMS};
use crate::primitives::Primitives;
use crate::response::contact::{Contact, PairKind};
use certificates::Certificates;
use starts::{start_slot, Starts};

/// A pair of primitives whose swept boxes overlap this substep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Candidate {
    /// What the two primitives are.
    pub kind: PairKind,
    /// The primitives (indices into the group's lists; see [`PairKind`]).
    pub pair: [u32; 2],
}

/// No contact for this candidate ([`Candidates::contact_of`]).
pub(crate) const NO_CONTACT: u32 = u32::MAX;

/// The candidate pairs of the substep and what the passes know of each.
#[derive(Default)]
pub(crate) struct Candidates {
    /// The pairs, sorted.
    pub list: Vec<Candidate>,
    /// Contact distance of each candidate (m): the sum of the two radii, or less for a pair
    /// of one object that is close in the rest shape ([`rest_pairs::rest_reach`]).
    pub reach: Vec<f64>,
    /// The particles of each candidate (unused slots repeat one of them;
    /// [`candidate_ids`]).
    pub ids: Vec<[u32; 4]>,
    /// Contact of each candidate ([`NO_CONTACT`] if none).
    pub contact_of: Vec<u32>,
    /// What proves each candidate apart, and how far the particles have moved since.
    pub certs: Certificates,
    /// Each collider or feature candidate's primitive at the substep's start.
    pub starts: Starts,
    /// Whether the candidates' separations are over this substep's tracks: set once the
    /// substep's first broad phase, refresh or restart is done. A refresh within the substep
    /// then carries the separations of the candidates it keeps ([`Self::carry_separations`]).
    pub within_substep: bool,
    /// Scratch of [`Self::adopt`]: the list before a refresh, with its certificates and starts.
    old: Carried,
}

/// The candidates before a refresh, with what was known of them, and how far each particle
/// has moved from their `x_ref` ([`Candidates::carry_separations`]).
#[derive(Default)]
struct Carried {
    list: Vec<Candidate>,
    separation: Vec<Separation>,
    separation_moved: Vec<f64>,
    starts: Starts,
    moved: Vec<f64>,
}

impl Candidates {
    /// Candidates for a group of `n` particles, with room for `capacity` of them.
    pub fn new(n: usize, capacity: usize) -> Self {
        Self {
            list: Vec::with_capacity(capacity),
            reach: Vec::with_capacity(capacity),
            contact_of: Vec::with_capacity(capacity),
            certs: Certificates::new(n),
            ..Self::default()
        }
    }

    /// Makes `pending` (sorted, with their contact distances) the candidates, with their
    /// particles, and restarts the passes' state, keeping the slots of the `contacts` found
    /// so far. Within a substep, the candidates found again keep their separations and starts
    /// ([`Self::carry_separations`]).
    pub fn adopt(
        &mut self,
        pending: &[(Candidate, f64)],
        x: &[DVec3],
        prims: &Primitives,
        contacts: &[Contact],
        team: TeamRef<'_>,
    ) {
        debug_assert!(
            pending.windows(2).all(|w| w[0].0 < w[1].0),
            "candidates out of order"
        );
        let carry = self.within_substep;
        if carry {
            let (old, certs) = (&mut self.old, &mut self.certs);
            std::mem::swap(&mut self.list, &mut old.list);
            std::mem::swap(&mut certs.separation, &mut old.separation);
            std::mem::swap(&mut certs.separation_moved, &mut old.separation_moved);
            std::mem::swap(&mut self.starts, &mut old.starts);
            old.moved.clear();
            old.moved
                .extend(certs.x_ref.iter().zip(x).map(|(&r, &p)| (p - r).length()));
        }
        self.list.clear();
        self.list.extend(pending.iter().map(|&(c, _)| c));
        self.reach.clear();
        self.reach.extend(pending.iter().map(|&(_, d)| d));
        let (list, ids) = (&self.list, &mut self.ids);
        ids.clear();
        ids.resize(list.len(), [0; 4]);
        fill_over_team(team, ids, |k| candidate_ids(prims, list[k]));
        self.restart(x, contacts);
        if carry {
            self.carry_separations(team);
        }
    }

    /// Sets the passes' state up for the current candidates: no separation known yet, no
    /// start taken ([`Self::start_of`]), and the `contacts` found so far in their slots.
    pub fn restart(&mut self, x: &[DVec3], contacts: &[Contact]) {
        self.certs.restart(x, self.list.len());
        self.starts.restart(&self.list);

        // Existing contacts keep their slot.
        self.contact_of.clear();
        self.contact_of.resize(self.list.len(), NO_CONTACT);
        for (k, c) in contacts.iter().enumerate() {
            let key = Candidate {
                kind: c.kind,
                pair: c.pair,
            };
            if let Ok(at) = self.list.binary_search(&key) {
                self.contact_of[at] = k as u32;
            }
        }
    }

    /// Gives every candidate that was a candidate before the last [`Self::adopt`] its start
    /// ([`Self::start_of`], the same substep's), and its separation from then, as a
    /// certificate only: taken when its particles had moved at most `m0` from the old
    /// `x_ref`, which they have now left by at most `m1` (`old.moved`), so they have moved
    /// at most `m0 + m1` since, and the new `x_ref` is where they are now. A refresh after a
    /// few primitives left their boxes then costs the exact distances of the new pairs only,
    /// not those of every pair again; the skips stay the verdicts of the full tests
    /// ([`Self::skip`]), so the same contacts and bits.
    ///
    /// The new list is split over the team in contiguous ranges, each merged with the part of
    /// the old list from its first candidate on (both lists are sorted): every candidate's
    /// values come from its own old twin alone, so the same on any number of threads.
    fn carry_separations(&mut self, team: TeamRef<'_>) {
        let mut start = std::mem::take(&mut self.starts.slots);
        let mut separation = std::mem::take(&mut self.certs.separation);
        let mut moved = std::mem::take(&mut self.certs.separation_moved);
        let n = self.list.len();
        {
            let this = &*self;
            let old = &this.old;
            let (start_n, split) = (start.len(), self.starts.split);
            let (st, sep, mov) = (
                SharedArray::new(&mut start),
                SharedArray::new(&mut separation),
                SharedArray::new(&mut moved),
            );
            team.for_ranges(n, PARALLEL_MIN_ITEMS, &|r| {
                // SAFETY: the ranges of `for_ranges` are disjoint and inside `0..n`, the length
                // of the two separation arrays; a candidate's start slot is a strictly
                // increasing function of its index within `0..start_n` ([`start_slot`]), so
                // the ranges' slots are disjoint too. The three arrays are exclusively
                // borrowed for this block.
                let (sep, mov) =
                    unsafe { (sep.slice(r.start, r.len()), mov.slice(r.start, r.len())) };
                let (old_list, new) = (&old.list, &this.list[r.clone()]);
                let Some(first) = new.first() else {
                    return;
                };
                let mut i = old_list.partition_point(|c| c < first);
                let mut j = 0;
                while i < old_list.len() && j < new.len() {
                    match old_list[i].cmp(&new[j]) {
                        std::cmp::Ordering::Less => i += 1,
                        std::cmp::Ordering::Greater => j += 1,
                        std::cmp::Ordering::Equal => {
                            let k = r.start + j;
                            let (from, to) =
                                (start_slot(old.starts.split, i), start_slot(split, k));
                            if let (Some(from), Some(to)) = (from, to) {
                                debug_assert!(to < start_n);
                                // SAFETY: `to` is this candidate's own slot (above).
                                unsafe { *st.at(to) = old.starts.slots[from] };
                            }
                            let s = old.separation[i];
                            if !s.d0.is_nan() {
                                let m1 = this.ids[k]
                                    .iter()
                                    .fold(0.0f64, |m, &p| m.max(old.moved[p as usize]));
                                sep[j] = s;
                                mov[j] = old.separation_moved[i] + m1;
                            }
                            i += 1;
                            j += 1;
                        }
                    }
                }
            });
        }
        self.starts.slots = start;
        self.certs.separation = separation;
        self.certs.separation_moved = moved;
    }
}

/// The particles of a candidate of a kind with a prefilter (vertex–face, edge–edge,
/// vertex–edge), in the slots its test uses; the vertex's for a vertex–collider pair, the
/// primitive's first in a feature's slots, and zeros for a particle pair.
pub(crate) fn candidate_ids(prims: &Primitives, cand: Candidate) -> [u32; 4] {
    let [a, b] = cand.pair;
    let (a, b) = (a as usize, b as usize);
    match cand.kind {
        PairKind::VertexFace => {
            let (p, t) = (prims.verts[a], prims.faces[b]);
            [p, t[0], t[1], t[2]]
        }
        PairKind::EdgeEdge => {
            let (e, f) = (prims.edges[a], prims.edges[b]);
            [e[0], e[1], f[0], f[1]]
        }
        PairKind::VertexEdge => {
            let (p, f) = (prims.verts[a], prims.edges[b]);
            [p, p, f[0], f[1]]
        }
        PairKind::VertexVertex => [0; 4],
        PairKind::Collider => [prims.verts[b]; 4],
        // The feature's slots hold no particle: the primitive's first stands in.
        PairKind::FeatureFace => {
            let t = prims.faces[b];
            [t[0], t[0], t[1], t[2]]
        }
        PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
            let e = prims.edges[b];
            [e[0], e[0], e[0], e[1]]
        }
    }
}
