//! The simulation: what it holds (settings, objects, particles, the groups built by plugins,
//! the schedule), the one place the core builds a group's [`SolveContext`], and what it
//! answers between steps (residuals, reports, energies). Built in [`crate::build`], stepped in
//! [`crate::step`].

use std::path::PathBuf;

use abi_stable::std_types::{RResult, RSlice, RSliceMut};
use glam::DVec3;
use nucleus_sdk::team::TeamRef;
use nucleus_sdk::{GroupBox, PluginError, Residual, SolveContext, Stage, Stages};

use crate::error::StepError;
use crate::object::{MovingPins, ObjectData};
use crate::particles::Particles;
use crate::scene::SolverSettings;
use crate::schedule::{schedule, Call, Slot};

/// A constraint group as the core holds it.
pub struct Group {
    /// Group name.
    pub name: String,
    /// Kind.
    pub kind: String,
    /// Plugin name.
    pub plugin: String,
    /// Plugin library.
    pub path: PathBuf,
    /// The group object.
    pub group: GroupBox,
    /// Stages it implements.
    pub stages: Stages,
    /// Order.
    pub order: i32,
    /// Importance (before the `iterations` multiplier).
    pub importance: u32,
    /// Number of constraints.
    pub len: u64,
    /// Residual unit.
    pub residual_unit: String,
}

impl Group {
    /// Whether the step calls this group's `stage`: it implements the stage and holds at
    /// least one constraint (an empty group is never scheduled).
    pub fn runs(&self, stage: Stage) -> bool {
        self.declares(stage.flag())
    }

    /// Whether the group holds at least one constraint and declares every flag of `flags`.
    pub fn declares(&self, flags: Stages) -> bool {
        self.len > 0 && self.stages.contains(flags)
    }

    /// The error for this group's `error` in `stage` at `frame`, `substep`.
    pub(crate) fn error(
        &self,
        stage: Stage,
        frame: u64,
        substep: u32,
        error: PluginError,
    ) -> StepError {
        StepError::Plugin {
            plugin: self.plugin.clone(),
            path: self.path.clone(),
            group: self.name.clone(),
            stage,
            frame,
            substep,
            error: Box::new(error),
        }
    }
}

/// The whole simulation.
pub struct Simulation {
    /// Solver settings.
    pub settings: SolverSettings,
    /// Objects.
    pub objects: Vec<ObjectData>,
    /// Particle state.
    pub particles: Particles,
    /// Groups, in scene order.
    pub groups: Vec<Group>,
    /// The call sequence of one substep.
    pub calls: Vec<Call>,
    /// Groups with a force stage, begin stage, end stage.
    pub(crate) force_groups: Vec<usize>,
    pub(crate) begin_groups: Vec<usize>,
    pub(crate) end_groups: Vec<usize>,
    /// The moving pins and where they go.
    pub(crate) pins: MovingPins,
    /// Simulated time (s).
    pub time: f64,
    /// Frames done.
    pub frame: u64,
    /// Threads of the step's team (`RAYON_NUM_THREADS`, default the machine's cores; see
    /// [`nucleus_sdk::team`]), read when the simulation is built.
    pub threads: usize,
}

/// Where a group call falls in the step: its substep of the frame, and which of the group's
/// passes in that substep it is.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CallAt {
    pub substep: u32,
    pub pass: u32,
    pub passes: u32,
}

impl CallAt {
    /// A stage called once in substep `substep` (everything but `project`).
    pub(crate) const fn once(substep: u32) -> CallAt {
        CallAt {
            substep,
            pass: 0,
            passes: 1,
        }
    }
}

impl Simulation {
    /// Recomputes the call sequence and stage lists (after changing settings or importances).
    pub fn reschedule(&mut self) {
        let slots: Vec<Slot> = self
            .groups
            .iter()
            .map(|g| Slot {
                order: g.order,
                importance: if g.runs(Stage::Project) {
                    g.importance.saturating_mul(self.settings.iterations)
                } else {
                    0
                },
            })
            .collect();
        self.calls = schedule(&slots, self.settings.schedule);
        let pick = |s: Stage| -> Vec<usize> {
            (0..self.groups.len())
                .filter(|&i| self.groups[i].runs(s))
                .collect()
        };
        self.force_groups = pick(Stage::Force);
        self.begin_groups = pick(Stage::BeginSubstep);
        self.end_groups = pick(Stage::EndSubstep);
        // The pushes exist only for a scene with a group that reads them and one that writes
        // them: elsewhere they are empty slices, which writers and readers skip.
        let any = |flag: Stages| self.groups.iter().any(|g| g.declares(flag));
        let used = any(Stages::TAKES_PUSHES) && any(Stages::GIVES_PUSHES);
        let n = if used { self.particles.x.len() } else { 0 };
        let p = &mut self.particles;
        for a in [&mut p.pushes, &mut p.kicks] {
            a.clear();
            a.resize(n, [0.0; 3]);
        }
    }

    /// Substep length (s).
    pub fn h(&self) -> f64 {
        1.0 / (self.settings.frame_rate * self.settings.substeps as f64)
    }

    /// The groups, and the context a group call at `at` receives on `team`: every particle
    /// slice, the step's clock and the call's place. The one place the core builds a
    /// [`SolveContext`]; the groups come borrowed apart from the particles the context lends.
    pub(crate) fn groups_and_context<'a>(
        &'a mut self,
        at: CallAt,
        team: TeamRef<'a>,
    ) -> (&'a mut [Group], SolveContext<'a>) {
        let h = self.h();
        let p = &mut self.particles;
        let ctx = SolveContext {
            x: RSliceMut::from_mut_slice(&mut p.x),
            v: RSliceMut::from_mut_slice(&mut p.v),
            x0: RSlice::from_slice(&p.x0),
            inv_mass: RSlice::from_slice(&p.inv_mass),
            object: RSlice::from_slice(&p.object),
            flags: RSlice::from_slice(&p.flags),
            attributes: RSlice::from_slice(&[]),
            h,
            time: self.time,
            gravity: self.settings.gravity,
            frame: self.frame,
            substep: at.substep,
            substeps: self.settings.substeps,
            pass: at.pass,
            passes: at.passes,
            team,
            pushes: RSliceMut::from_mut_slice(&mut p.pushes),
            kicks: RSliceMut::from_mut_slice(&mut p.kicks),
        };
        (&mut self.groups, ctx)
    }

    /// Every group's residual at the current positions.
    pub fn residuals(&mut self) -> Result<Vec<Residual>, StepError> {
        self.ask_groups(|g, ctx| g.group.residual(ctx))
    }

    /// Named values each group reports (prefixed `group.`).
    pub fn reports(&mut self) -> Result<Vec<(String, f64)>, StepError> {
        let per_group = self.ask_groups(|g, ctx| {
            if !g.stages.contains(Stages::REPORT) {
                return RResult::ROk(Vec::new());
            }
            g.group.report(ctx).map(|stats| {
                let named = stats
                    .iter()
                    .map(|s| (format!("{}.{}", g.name, s.name), s.value));
                named.collect()
            })
        })?;
        Ok(per_group.into_iter().flatten().collect())
    }

    /// `ask(group, ctx)` of every group in scene order, with the context of the current state
    /// (substep 0, one pass, no team); the first error stops and names its group.
    fn ask_groups<T>(
        &mut self,
        ask: impl Fn(&Group, &SolveContext<'_>) -> RResult<T, PluginError>,
    ) -> Result<Vec<T>, StepError> {
        let frame = self.frame;
        let (groups, ctx) = self.groups_and_context(CallAt::once(0), TeamRef::serial());
        let answers = groups.iter().map(|g| {
            let answer = ask(g, &ctx).into_result();
            answer.map_err(|e| g.error(Stage::Report, frame, 0, e))
        });
        answers.collect()
    }

    /// Kinetic energy of the dynamic particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.particles.kinetic_energy()
    }

    /// Gravitational potential energy of the dynamic particles relative to the origin (J).
    pub fn gravity_energy(&self) -> f64 {
        self.particles.gravity_energy(self.settings.gravity)
    }

    /// Positions as glam vectors.
    pub fn positions(&self) -> &[DVec3] {
        nucleus_sdk::view::as_dvec3(&self.particles.x)
    }

    /// Velocities as glam vectors.
    pub fn velocities(&self) -> &[DVec3] {
        nucleus_sdk::view::as_dvec3(&self.particles.v)
    }

    /// The object named `name`.
    pub fn object(&self, name: &str) -> Option<&ObjectData> {
        self.objects.iter().find(|o| o.name == name)
    }
}
