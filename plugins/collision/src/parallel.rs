//! Work split over the host's thread team so that the results are the same bits on any
//! number of threads: every value is computed alone and written where its index says, never
//! summed or appended in the order the threads happen to finish.

use nucleus_sdk::team::TeamRef;

/// From this many vertices (or edges, or candidates) up, the broad phase's queries and the
/// separations taken ahead of a pass are split over the thread team. Chosen, not tuned: a
/// query costs about a microsecond, the team's hand-off about as much as one.
pub(crate) const PARALLEL_MIN_QUERIES: usize = 512;

/// From this many items up, the per-candidate and per-primitive maps (the candidates'
/// particles, the carried separations, the primitives' boxes) are split over the thread team.
/// Each item costs a few nanoseconds, the team's hand-off about a microsecond.
pub(crate) const PARALLEL_MIN_ITEMS: usize = 16384;

/// How many chunks a job split over the team claims per part ([`claim_chunks`]): enough that
/// a part whose chunks cost more (the edge–edge pairs sort after the vertex–face ones, and
/// their exact distances cost more) is helped by the others, few enough that a chunk's
/// hand-off stays small against its work.
pub(crate) const CHUNKS_PER_PART: usize = 8;

/// `out[i] = f(i)` for every `i`, the indices split over the team in contiguous ranges from
/// [`PARALLEL_MIN_ITEMS`] on: each value is computed alone, so the array is the same on any
/// number of threads.
pub(crate) fn fill_over_team<T: Send>(
    team: TeamRef<'_>,
    out: &mut [T],
    f: impl Fn(usize) -> T + Sync,
) {
    team.for_ranges_mut(out, PARALLEL_MIN_ITEMS, &|r, out| {
        for (o, i) in out.iter_mut().zip(r) {
            *o = f(i);
        }
    });
}

/// Runs `f(part, chunk)` for every chunk `0..chunks` on the team, each chunk once, claimed by
/// the parts in turn as they come free (a part that finds its chunks cheap takes more), with
/// the claiming part's index. Whoever runs a chunk, it must write only what the chunk owns:
/// the results are then the same on any number of threads.
pub(crate) fn claim_chunks(team: TeamRef<'_>, chunks: usize, f: &(dyn Fn(usize, usize) + Sync)) {
    let next = std::sync::atomic::AtomicUsize::new(0);
    team.run(&|part| loop {
        // Relaxed: the counter only hands out chunk numbers; what the chunks write is published
        // by the end of the team's job.
        let c = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if c >= chunks {
            break;
        }
        f(part, c);
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use nucleus_sdk::team::span;

    #[test]
    fn every_chunk_runs_once_whatever_the_team_and_the_chunks_cover_the_range() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let teams = [0, 1, 2, 4].map(nucleus_sdk::team::Team::new);
        for team in &teams {
            let team = TeamRef::new(team);
            for (n, chunks) in [(1, 1), (7, 7), (513, 16), (100_003, 32)] {
                let runs: Vec<AtomicUsize> = (0..chunks).map(|_| AtomicUsize::new(0)).collect();
                let covered: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
                let parts = team.parts();
                claim_chunks(team, chunks, &|part, c| {
                    assert!(part < parts, "a part index out of the team");
                    runs[c].fetch_add(1, Ordering::Relaxed);
                    for i in span(c, chunks, n) {
                        covered[i].fetch_add(1, Ordering::Relaxed);
                    }
                });
                let parts = team.parts();
                assert!(
                    runs.iter().all(|r| r.load(Ordering::Relaxed) == 1),
                    "{parts} parts, {chunks} chunks"
                );
                assert!(
                    covered.iter().all(|c| c.load(Ordering::Relaxed) == 1),
                    "{parts} parts, n = {n}"
                );
            }
        }
    }
}
