//! Graph colouring of constraints for Gauss-Seidel passes that split over the host's thread
//! team ([`crate::team`]) and still give the same bits on any thread count.
//!
//! A constraint *writes* the particles it moves. Colour the constraints so that no two of one
//! colour write a common particle, list them colour by colour, and a pass over that order is
//! plain sequential Gauss-Seidel; yet the constraints of one colour may run in any order, or
//! in parallel parts, with the same result, since none reads what another writes. Split each
//! colour into the team's parts ([`crate::team::span`]) and the bits do not depend on the
//! thread count. Consecutive constraints of one colour also do not wait for each other's
//! position writes, which helps a single thread too.
//!
//! ```
//! use nucleus_sdk::colour::{colour_batches, greedy_colours, independent_sets_order};
//!
//! // A chain of four edges over five particles: edges 0 and 2 share none, nor 1 and 3.
//! let edges = [[0u32, 1], [1, 2], [2, 3], [3, 4]];
//! let colours = greedy_colours(edges.len(), 5, |k| edges[k].into_iter().map(|p| p as usize));
//! assert_eq!(colours, [0, 1, 0, 1]);
//! let order = independent_sets_order(&colours);
//! assert_eq!(order, [0, 2, 1, 3]);
//! assert_eq!(colour_batches(&colours, &order), [(0..2, true), (2..4, true)]);
//! ```

use std::ops::Range;

/// The colour of a constraint one of whose particles is already written by constraints of
/// all 64 colours: the last colour, whose constraints may share particles (so its batch must
/// run in order, on one thread).
pub const OVERFLOW_COLOUR: usize = 64;

/// Greedy colouring of `count` constraints in their given order, constraint `k` writing the
/// particles `written(k)` (each below `particles`): each takes the smallest colour that no
/// constraint writing one of its particles has yet, so the constraints of one colour (below
/// [`OVERFLOW_COLOUR`]) write no common particle. A constraint all of whose colours are taken
/// gets [`OVERFLOW_COLOUR`]. Deterministic.
///
/// # Panics
/// If `written` yields a particle index not below `particles`.
pub fn greedy_colours<I: Iterator<Item = usize>>(
    count: usize,
    particles: usize,
    written: impl Fn(usize) -> I,
) -> Vec<usize> {
    let mut used = vec![0u64; particles];
    (0..count)
        .map(|k| {
            let taken = written(k).fold(0u64, |acc, p| acc | used[p]);
            if taken == u64::MAX {
                return OVERFLOW_COLOUR;
            }
            let colour = (!taken).trailing_zeros() as usize;
            written(k).for_each(|p| used[p] |= 1 << colour);
            colour
        })
        .collect()
}

/// The order that lists the constraints colour by colour, each colour in the given order (a
/// stable sort by colour). Deterministic.
pub fn independent_sets_order(colours: &[usize]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..colours.len()).collect();
    order.sort_by_key(|&k| colours[k]); // stable: the given order within a colour
    order
}

/// The consecutive ranges of `order` (from [`independent_sets_order`]) of one colour each,
/// flagged `true` when that colour is a real one (its constraints write no common particle)
/// and so may be split over threads; `false` for [`OVERFLOW_COLOUR`].
pub fn colour_batches(colours: &[usize], order: &[usize]) -> Vec<(Range<usize>, bool)> {
    let mut batches = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let colour = colours[order[start]];
        let end = start + order[start..].partition_point(|&k| colours[k] == colour);
        batches.push((start..end, colour < OVERFLOW_COLOUR));
        start = end;
    }
    batches
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every particle touched by 70 triangles' worth of constraints around one centre: the
    /// constraints of one real colour share no particle, the overflow takes the rest, and the
    /// batches cover the order exactly, each of one colour.
    #[test]
    fn colours_of_a_crowded_particle_share_no_particle_and_batches_tile_the_order() {
        // 70 triangles (0, 2k + 1, 2k + 2) sharing particle 0, plus a chain 141–150.
        let mut ids: Vec<Vec<usize>> = (0..70).map(|k| vec![0, 2 * k + 1, 2 * k + 2]).collect();
        ids.extend((141..150).map(|p| vec![p, p + 1]));
        let colours = greedy_colours(ids.len(), 151, |k| ids[k].clone().into_iter());
        assert_eq!(colours.iter().filter(|&&c| c == OVERFLOW_COLOUR).count(), 6);
        for c in 0..OVERFLOW_COLOUR {
            let mut seen = [false; 151];
            for (k, _) in colours.iter().enumerate().filter(|(_, &x)| x == c) {
                for &p in &ids[k] {
                    assert!(!seen[p], "colour {c} writes particle {p} twice");
                    seen[p] = true;
                }
            }
        }
        let order = independent_sets_order(&colours);
        let batches = colour_batches(&colours, &order);
        let mut next = 0;
        for (range, independent) in &batches {
            assert_eq!(range.start, next);
            let colour = colours[order[range.start]];
            assert!(order[range.clone()].iter().all(|&k| colours[k] == colour));
            assert!(order[range.clone()].windows(2).all(|w| w[0] < w[1]));
            assert_eq!(*independent, colour < OVERFLOW_COLOUR);
            next = range.end;
        }
        assert_eq!(next, ids.len());
        assert!(!batches.last().unwrap().1, "the overflow comes last");
    }
}
