//! The stages of a group by name.
//!
//! [`Stages`] is the set of optional stages a group implements, as it crosses the boundary;
//! [`Stage`] is one of them: what the host names when it calls a group for one stage, and in
//! its error messages. Plain Rust, outside the ABI.

use crate::abi::Stages;

/// One stage of a group, in the order a substep calls them (see [`ConstraintGroup`]);
/// `Report` stands for the once-per-frame `residual` and `report`.
///
/// [`ConstraintGroup`]: crate::ConstraintGroup
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stage {
    /// `force`: velocity level, before the prediction.
    Force,
    /// `begin_substep`: after the prediction, before the first projection.
    BeginSubstep,
    /// `project`: one pass, scheduled `importance` times per substep.
    Project,
    /// `end_substep`: velocity level, after the velocity update.
    EndSubstep,
    /// `residual` and `report`: once per frame, for the stats.
    Report,
}

impl Stage {
    /// The stage's bit in [`Stages`].
    pub const fn flag(self) -> Stages {
        match self {
            Stage::Force => Stages::FORCE,
            Stage::BeginSubstep => Stages::BEGIN_SUBSTEP,
            Stage::Project => Stages::PROJECT,
            Stage::EndSubstep => Stages::END_SUBSTEP,
            Stage::Report => Stages::REPORT,
        }
    }

    /// The name of the group's method for the stage (`begin_substep`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Force => "force",
            Stage::BeginSubstep => "begin_substep",
            Stage::Project => "project",
            Stage::EndSubstep => "end_substep",
            Stage::Report => "report",
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::Stage;
    use crate::abi::Stages;

    #[test]
    fn each_stage_has_its_own_bit_and_no_stage_has_the_pushes_bits() {
        let all = [
            Stage::Force,
            Stage::BeginSubstep,
            Stage::Project,
            Stage::EndSubstep,
            Stage::Report,
        ];
        for (i, a) in all.iter().enumerate() {
            assert_eq!(a.flag().0.count_ones(), 1, "{a}");
            assert!(!a.flag().contains(Stages::TAKES_PUSHES), "{a}");
            assert!(!a.flag().contains(Stages::GIVES_PUSHES), "{a}");
            for b in &all[i + 1..] {
                assert!(!a.flag().contains(b.flag()), "{a} and {b}");
                assert_ne!(a.name(), b.name());
            }
        }
    }
}
