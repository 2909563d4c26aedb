//! The scheduler: a pure function from each constraint group's order and importance to the
//! sequence of `project` calls made in one substep (paper, Figures 9–13).
//!
//! Every group has an **order** `O` (smaller runs earlier) and an **importance** `I` (how many
//! times per substep it is projected). Importance 0 means the group is never called.
//!
//! * [`ScheduleMode::Sequential`]: groups sorted by `O` (ties by group index), each called
//!   `I` times in a row.
//! * [`ScheduleMode::Interleaved`] (the default): the `I` calls of every group are spread
//!   evenly over `M = max(I)` columns; each column runs its groups sorted by `O` (ties by
//!   group index). Group `g` is called in column `c` (0-based) iff
//!   `⌊(c+1)·I/M⌋ > ⌊c·I/M⌋`. The left side telescopes, so a group gets exactly `I` calls,
//!   at most one per column (`I ≤ M`), and always one in the last column `M − 1`
//!   (`I − ⌊(M−1)·I/M⌋ = ⌈I/M⌉ ≥ 1`): every group has the last word in the substep.
//!
//! Each [`Call`] also says which pass of its group it is (`0..I`, in call order), so a group
//! can tell its first projection of the substep from its last.

use serde::{Deserialize, Serialize};

/// How the calls of the constraint groups are arranged within a substep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ScheduleMode {
    /// Spread every group's calls evenly over `max(importance)` columns (paper, Figure 12).
    #[default]
    Interleaved,
    /// Call each group `importance` times in a row, groups in order (paper, Figure 10).
    Sequential,
}

/// The scheduling data of one constraint group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// Position in the sequence: smaller runs earlier; ties keep the group index order.
    pub order: i32,
    /// How many times per substep the group is projected; 0 = never.
    pub importance: u32,
}

/// One call of the sequence: which group, and which of its passes this is (0-based) out of
/// its importance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Call {
    /// Index of the group in the slice given to [`schedule`].
    pub group: u32,
    /// `0..importance`, in call order.
    pub pass: u32,
}

/// The sequence of `project` calls for one substep.
pub fn schedule(slots: &[Slot], mode: ScheduleMode) -> Vec<Call> {
    match mode {
        ScheduleMode::Sequential => by_order(slots)
            .into_iter()
            .flat_map(|group| {
                (0..slots[group as usize].importance).map(move |pass| Call { group, pass })
            })
            .collect(),
        ScheduleMode::Interleaved => {
            let mut passes = vec![0u32; slots.len()];
            columns(slots)
                .into_iter()
                .flatten()
                .map(|group| {
                    let pass = &mut passes[group as usize];
                    *pass += 1;
                    Call {
                        group,
                        pass: *pass - 1,
                    }
                })
                .collect()
        }
    }
}

/// The interleaved layout as columns (`max(importance)` of them), each listing the groups it
/// calls in execution order — for tests and for printing (`nucleus run --verbose`).
pub fn columns(slots: &[Slot]) -> Vec<Vec<u32>> {
    let ordered = by_order(slots);
    let m = slots.iter().map(|s| s.importance).max().unwrap_or(0);
    (0..m)
        .map(|c| {
            ordered
                .iter()
                .copied()
                .filter(|&g| in_column(slots[g as usize].importance, c, m))
                .collect()
        })
        .collect()
}

/// A picture of the schedule like the paper's figures: one line per group in execution order,
/// one character per column (interleaved) or per call (sequential), `x` where the group is
/// called and `.` elsewhere, e.g. `stretch  xxxx  (order 10, importance 4)`. Groups without a
/// name in `names` are called `group <index>`.
pub fn describe(names: &[&str], slots: &[Slot], mode: ScheduleMode) -> String {
    let name = |g: usize| {
        names
            .get(g)
            .map_or_else(|| format!("group {g}"), |n| (*n).to_string())
    };
    let width = (0..slots.len())
        .map(|g| name(g).chars().count())
        .max()
        .unwrap_or(0);
    // The position of every call on the time axis, per group.
    let mut marks = vec![Vec::new(); slots.len()];
    let length = match mode {
        ScheduleMode::Interleaved => {
            let cols = columns(slots);
            for (c, col) in cols.iter().enumerate() {
                for &g in col {
                    marks[g as usize].push(c);
                }
            }
            cols.len()
        }
        ScheduleMode::Sequential => {
            let calls = schedule(slots, mode);
            for (t, call) in calls.iter().enumerate() {
                marks[call.group as usize].push(t);
            }
            calls.len()
        }
    };
    let mut out = String::new();
    for g in by_order(slots) {
        let g = g as usize;
        let line: String = (0..length)
            .map(|t| if marks[g].contains(&t) { 'x' } else { '.' })
            .collect();
        let Slot { order, importance } = slots[g];
        out.push_str(&format!(
            "{:width$}  {line}  (order {order}, importance {importance})\n",
            name(g)
        ));
    }
    out
}

/// Group indices sorted by order, ties by index (a stable sort of `0..n`).
fn by_order(slots: &[Slot]) -> Vec<u32> {
    let mut groups: Vec<u32> = (0..slots.len() as u32).collect();
    groups.sort_by_key(|&g| slots[g as usize].order);
    groups
}

/// Whether a group of importance `i` is called in column `c` of `m`.
fn in_column(i: u32, c: u32, m: u32) -> bool {
    let (i, c, m) = (u64::from(i), u64::from(c), u64::from(m));
    (c + 1) * i / m > c * i / m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slots(list: &[(i32, u32)]) -> Vec<Slot> {
        list.iter()
            .map(|&(order, importance)| Slot { order, importance })
            .collect()
    }

    fn groups(calls: &[Call]) -> Vec<u32> {
        calls.iter().map(|c| c.group).collect()
    }

    const MODES: [ScheduleMode; 2] = [ScheduleMode::Interleaved, ScheduleMode::Sequential];

    #[test]
    fn empty_input_gives_empty_output() {
        for mode in MODES {
            assert!(schedule(&[], mode).is_empty());
        }
        assert!(columns(&[]).is_empty());
        assert_eq!(describe(&[], &[], ScheduleMode::Interleaved), "");
    }

    #[test]
    fn equal_orders_keep_index_order() {
        let s = slots(&[(5, 1), (5, 1), (5, 1), (0, 1)]);
        for mode in MODES {
            assert_eq!(groups(&schedule(&s, mode)), [3, 0, 1, 2]);
        }
    }

    #[test]
    fn importance_one_runs_only_in_the_last_of_ten_columns() {
        let s = slots(&[(0, 1), (1, 10)]);
        let cols = columns(&s);
        assert_eq!(cols.len(), 10);
        for col in &cols[..9] {
            assert_eq!(col, &[1]);
        }
        assert_eq!(cols[9], [0, 1]);
    }

    #[test]
    fn every_group_is_in_the_last_column() {
        let s = slots(&[(3, 1), (-2, 7), (0, 3), (9, 5), (1, 0), (4, 2)]);
        let cols = columns(&s);
        assert_eq!(cols.len(), 7);
        assert_eq!(cols[6], [1, 2, 0, 5, 3]);
    }

    #[test]
    fn each_group_is_called_importance_times_in_both_modes() {
        let s = slots(&[(3, 1), (-2, 7), (0, 3), (9, 5), (1, 0), (4, 2), (0, 13)]);
        for mode in MODES {
            let calls = schedule(&s, mode);
            for (g, slot) in s.iter().enumerate() {
                let n = calls.iter().filter(|c| c.group as usize == g).count();
                assert_eq!(n, slot.importance as usize, "group {g} in {mode:?}");
            }
        }
    }

    #[test]
    fn passes_are_numbered_in_call_order() {
        let s = slots(&[(1, 3), (0, 4), (2, 2)]);
        for mode in MODES {
            let calls = schedule(&s, mode);
            for g in 0..s.len() as u32 {
                let passes: Vec<u32> = calls
                    .iter()
                    .filter(|c| c.group == g)
                    .map(|c| c.pass)
                    .collect();
                let expected: Vec<u32> = (0..s[g as usize].importance).collect();
                assert_eq!(passes, expected);
            }
        }
    }

    #[test]
    fn sequential_order_respects_order_field() {
        let s = slots(&[(10, 2), (-1, 1), (3, 3)]);
        let calls = schedule(&s, ScheduleMode::Sequential);
        assert_eq!(groups(&calls), [1, 2, 2, 2, 0, 0]);
    }

    #[test]
    fn columns_run_in_order_field() {
        let s = slots(&[(10, 2), (-1, 2), (3, 2)]);
        assert_eq!(columns(&s), [vec![1, 2, 0], vec![1, 2, 0]]);
    }

    #[test]
    fn importance_zero_is_never_called() {
        let s = slots(&[(0, 0), (1, 3), (2, 0)]);
        for mode in MODES {
            assert!(schedule(&s, mode).iter().all(|c| c.group == 1));
        }
        assert!(columns(&slots(&[(0, 0), (1, 0)])).is_empty());
    }

    #[test]
    fn calls_are_spread_evenly() {
        // I = 3 over M = 6 columns: every other column, ending in the last.
        let s = slots(&[(0, 3), (1, 6)]);
        let with_group_0: Vec<usize> = columns(&s)
            .iter()
            .enumerate()
            .filter(|(_, col)| col.contains(&0))
            .map(|(c, _)| c)
            .collect();
        assert_eq!(with_group_0, [1, 3, 5]);
    }

    /// A rubber band: stretch (importance 4), bend (2) and collisions (1), with collisions
    /// ordered first. Written out by hand from the column rule.
    #[test]
    fn rubber_band_example_matches_hand_written_sequence() {
        const STRETCH: u32 = 0;
        const BEND: u32 = 1;
        const COLLIDE: u32 = 2;
        let s = slots(&[(10, 4), (20, 2), (0, 1)]);
        let call = |group, pass| Call { group, pass };

        assert_eq!(
            columns(&s),
            [
                vec![STRETCH],
                vec![STRETCH, BEND],
                vec![STRETCH],
                vec![COLLIDE, STRETCH, BEND],
            ]
        );
        assert_eq!(
            schedule(&s, ScheduleMode::Interleaved),
            [
                call(STRETCH, 0),
                call(STRETCH, 1),
                call(BEND, 0),
                call(STRETCH, 2),
                call(COLLIDE, 0),
                call(STRETCH, 3),
                call(BEND, 1),
            ]
        );
        assert_eq!(
            schedule(&s, ScheduleMode::Sequential),
            [
                call(COLLIDE, 0),
                call(STRETCH, 0),
                call(STRETCH, 1),
                call(STRETCH, 2),
                call(STRETCH, 3),
                call(BEND, 0),
                call(BEND, 1),
            ]
        );
        assert_eq!(
            describe(
                &["stretch", "bend", "collide"],
                &s,
                ScheduleMode::Interleaved
            ),
            "collide  ...x  (order 0, importance 1)\n\
             stretch  xxxx  (order 10, importance 4)\n\
             bend     .x.x  (order 20, importance 2)\n"
        );
        assert_eq!(
            describe(&["stretch", "bend"], &s, ScheduleMode::Sequential),
            "group 2  x......  (order 0, importance 1)\n\
             stretch  .xxxx..  (order 10, importance 4)\n\
             bend     .....xx  (order 20, importance 2)\n"
        );
    }

    #[test]
    fn large_importances_do_not_overflow() {
        let s = slots(&[(0, 1), (0, 100_000)]);
        let cols = columns(&s);
        assert_eq!(cols.len(), 100_000);
        assert_eq!(cols.iter().filter(|c| c.contains(&0)).count(), 1);
        assert_eq!(cols[99_999], [0, 1]);
    }

    #[test]
    fn mode_reads_lowercase() {
        let mode: ScheduleMode = serde_json::from_str("\"sequential\"").unwrap();
        assert_eq!(mode, ScheduleMode::Sequential);
        assert_eq!(
            serde_json::to_string(&ScheduleMode::Interleaved).unwrap(),
            "\"interleaved\""
        );
        assert_eq!(ScheduleMode::default(), ScheduleMode::Interleaved);
    }
}
