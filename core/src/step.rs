//! The step. [`Simulation::substep`], first below, is the solver's whole loop: the stages of
//! one substep of length `h`, in order. The particle loops they run are in
//! [`crate::particles`], the order of the `project` calls in [`crate::schedule`].

use abi_stable::std_types::RResult;
use glam::DVec3;
use nucleus_sdk::team::{self, TeamRef};
use nucleus_sdk::Stage;

use crate::error::StepError;
use crate::particles::{NonFinite, PARALLEL_MIN_PARTICLES};
use crate::simulation::{CallAt, Simulation};

impl Simulation {
    /// Runs one substep: the paper's implicit-velocity / explicit-position scheme (symplectic
    /// Euler), stage by stage. Only the stages a group implements are called, and empty groups
    /// never; every group call is followed by a check that the state is finite (unless the
    /// scene turns it off). The step allocates nothing.
    ///
    /// The substep holds the process's thread team ([`nucleus_sdk::team`]): the particle loops
    /// and every group's passes run on it. When another simulation holds it (two stepping at
    /// once), this one runs on its own thread, with the same results.
    pub fn substep(&mut self, substep: u32) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let h = self.h();
        let t1 = self.time + h;
        // kinematic: where each object's pinned and animated particles go at `t + h`.
        self.kinematic(t1);
        // forces: `v += h g` for the free particles, then every group's `force`.
        let gravity = self.gravity(h, team);
        self.call_each(Stage::Force, substep, team)?;
        // predict: `x0 = x; x = x0 + h v`, the moving pins to their targets.
        self.predict(h, gravity, team);
        // begin: every group's `begin_substep`.
        self.call_each(Stage::BeginSubstep, substep, team)?;
        // solve: the schedule, each group's `project` `importance × iterations` times,
        // interleaved by order (paper, Figures 9–13).
        let last = self.solve(substep, team)?;
        // velocities: `v = (x − x0) / h`.
        self.update_velocities(h, substep, last, team)?;
        // end: the kicks zeroed (the last substep's, read by this one's passes), every group's
        // `end_substep` (restitution, friction), then global damping.
        self.particles.kicks.fill([0.0; 3]);
        self.call_each(Stage::EndSubstep, substep, team)?;
        self.damp(h, team);
        self.time = t1;
        Ok(())
    }

    /// Runs one frame (all its substeps).
    pub fn step_frame(&mut self) -> Result<(), StepError> {
        for s in 0..self.settings.substeps {
            self.substep(s)?;
        }
        self.frame += 1;
        Ok(())
    }

    /// Sets the moving pins' targets to time `t`.
    fn kinematic(&mut self, t: f64) {
        self.pins.update(&self.objects, t, self.settings.frame_rate);
    }

    /// Gravity's velocity change over `h`: applied now when force groups follow; otherwise
    /// returned, for the prediction's loop to apply (the same arithmetic, one pass fewer).
    fn gravity(&mut self, h: f64, team: TeamRef<'_>) -> Option<[f64; 3]> {
        let g = (DVec3::from_array(self.settings.gravity) * h).to_array();
        if self.force_groups.is_empty() {
            return Some(g);
        }
        self.particles.apply_gravity(g, team);
        None
    }

    /// The prediction (after `v += g` when `gravity` is given), then the pushes zeroed: the
    /// substep's own are recorded from here on (nothing when no group takes them).
    fn predict(&mut self, h: f64, gravity: Option<[f64; 3]>, team: TeamRef<'_>) {
        let p = &mut self.particles;
        p.predict(h, gravity, &self.pins, &self.objects, team);
        p.pushes.fill([0.0; 3]);
    }

    /// The schedule's `project` calls; the group called last, whose finite check the velocity
    /// update makes (it reads the same positions anyway).
    fn solve(&mut self, substep: u32, team: TeamRef<'_>) -> Result<Option<usize>, StepError> {
        for k in 0..self.calls.len() {
            let call = self.calls[k];
            let g = call.group as usize;
            let at = CallAt {
                substep,
                pass: call.pass,
                passes: self.passes(g),
            };
            let check = k + 1 < self.calls.len();
            self.call_group(g, Stage::Project, at, team, check)?;
        }
        Ok(self.calls.last().map(|call| call.group as usize))
    }

    /// `v = (x − x0) / h`, with the finite check of group `last`'s last `project` call.
    fn update_velocities(
        &mut self,
        h: f64,
        substep: u32,
        last: Option<usize>,
        team: TeamRef<'_>,
    ) -> Result<(), StepError> {
        let check = self.settings.check_finite && last.is_some();
        let found = self.particles.update_velocities(h, team, check);
        match last {
            Some(g) => self.non_finite_error(g, Stage::Project, substep, found),
            None => Ok(()),
        }
    }

    /// Global damping: `v *= exp(−damping h)`.
    fn damp(&mut self, h: f64, team: TeamRef<'_>) {
        if self.settings.damping > 0.0 {
            let k = (-self.settings.damping * h).exp();
            self.particles.damp(k, team);
        }
    }

    /// Group `g`'s passes in a substep: its importance times the iterations.
    fn passes(&self, g: usize) -> u32 {
        self.groups[g]
            .importance
            .saturating_mul(self.settings.iterations)
    }

    /// The groups whose `stage` runs once a substep, in scene order (none for `project`,
    /// which the schedule orders, nor for the once-a-frame report).
    fn once_groups(&self, stage: Stage) -> &[usize] {
        match stage {
            Stage::Force => &self.force_groups,
            Stage::BeginSubstep => &self.begin_groups,
            Stage::EndSubstep => &self.end_groups,
            Stage::Project | Stage::Report => &[],
        }
    }

    /// Calls `stage` of every group that runs it once a substep, in scene order.
    fn call_each(
        &mut self,
        stage: Stage,
        substep: u32,
        team: TeamRef<'_>,
    ) -> Result<(), StepError> {
        for k in 0..self.once_groups(stage).len() {
            let g = self.once_groups(stage)[k];
            self.call_group(g, stage, CallAt::once(substep), team, true)?;
        }
        Ok(())
    }

    /// Calls group `g`'s `stage`, then checks that every position and velocity is finite
    /// (unless the scene turned the check off, or `check` is false: the caller checks).
    fn call_group(
        &mut self,
        g: usize,
        stage: Stage,
        at: CallAt,
        team: TeamRef<'_>,
        check: bool,
    ) -> Result<(), StepError> {
        let (groups, mut ctx) = self.groups_and_context(at, team);
        let group = &mut groups[g].group;
        let result = match stage {
            Stage::Force => group.force(&mut ctx),
            Stage::BeginSubstep => group.begin_substep(&mut ctx),
            Stage::Project => group.project(&mut ctx),
            Stage::EndSubstep => group.end_substep(&mut ctx),
            Stage::Report => RResult::ROk(()),
        };
        if let RResult::RErr(error) = result {
            return Err(self.groups[g].error(stage, self.frame, at.substep, error));
        }
        if check && self.settings.check_finite {
            let found = self.particles.check_finite(team);
            self.non_finite_error(g, stage, at.substep, found)?;
        }
        Ok(())
    }

    /// The error naming group `g` and its `stage` if `found` saw a non-finite position (first)
    /// or velocity.
    fn non_finite_error(
        &self,
        g: usize,
        stage: Stage,
        substep: u32,
        found: NonFinite,
    ) -> Result<(), StepError> {
        let Some(what) = found.what() else {
            return Ok(());
        };
        let group = &self.groups[g];
        Err(StepError::NonFinite {
            plugin: group.plugin.clone(),
            path: group.path.clone(),
            group: group.name.clone(),
            stage,
            frame: self.frame,
            substep,
            what,
        })
    }

    /// The process's thread team for one substep, if this simulation uses more than one
    /// thread and another simulation does not hold the team: a scene without groups and too
    /// small to split its own loops does not ask for it.
    fn team_guard(&self) -> Option<TeamGuard> {
        let wanted = !self.groups.is_empty() || self.particles.len() >= PARALLEL_MIN_PARTICLES;
        if self.threads > 1 && wanted {
            team::shared(self.threads)
        } else {
            None
        }
    }

    /// For benchmarks and tests that time or inspect one group's stages: the first stages of
    /// substep `substep` exactly as [`Simulation::substep`] runs them (pins, gravity, force
    /// groups, the prediction `x0 = x`, `x += h v`), stopping before any group's
    /// `begin_substep`. The time does not advance. Follow it with [`Simulation::run_stage`].
    pub fn predict_substep(&mut self, substep: u32) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let h = self.h();
        self.kinematic(self.time + h);
        let gravity = self.gravity(h, team);
        self.call_each(Stage::Force, substep, team)?;
        self.predict(h, gravity, team);
        Ok(())
    }

    /// For benchmarks and tests: calls group `group`'s `stage` as [`Simulation::substep`]
    /// does — the same context (its passes are the group's importance times the iterations),
    /// the same thread team and the same finite check — as pass `pass` of substep `substep`.
    /// The core's own stages between the groups' (the velocity update, damping) are not run.
    pub fn run_stage(
        &mut self,
        group: usize,
        stage: Stage,
        substep: u32,
        pass: u32,
    ) -> Result<(), StepError> {
        let guard = self.team_guard();
        let team = team_ref(&guard);
        let passes = match stage {
            Stage::Project => self.passes(group),
            _ => 1,
        };
        let at = CallAt {
            substep,
            pass,
            passes,
        };
        self.call_group(group, stage, at, team, true)
    }
}

/// The process's thread team while a substep holds it ([`team::shared`]).
type TeamGuard = std::sync::MutexGuard<'static, Option<team::Team>>;

/// The team a held guard lends, or the serial team when none is held.
fn team_ref(guard: &Option<TeamGuard>) -> TeamRef<'_> {
    guard
        .as_ref()
        .and_then(|g| g.as_ref())
        .map_or(TeamRef::serial(), TeamRef::new)
}
