//! # Nucleus core
//!
//! The simplicial complex, particle state, integrator, scheduler, plugin loading, scenes and
//! output. The core never names a constraint type: everything it knows about a constraint
//! group is its order, its importance, and which optional stages it implements.
//!
//! **The solver loop is [`Simulation::substep`], the first function in [`step`]
//! (`core/src/step.rs`):** one substep as a list of named stages.
//!
//! ## The rooms, in the order a scene passes through them
//!
//! * [`scene`] — a scene file read, overridden (`--set`) and validated; each object's geometry,
//!   pins and masses.
//! * [`shapes`], [`obj`] — the generated shapes and OBJ meshes objects are made of.
//! * [`complex`] — an object's simplicial complex: simplices, adjacency, pairs, boundary.
//! * [`plugins`] — the plugin libraries found, loaded, and the kinds they provide.
//! * [`build`] — scene to [`Simulation`]: objects, particles, one group per constraint entry
//!   (its parameters checked against the kind's).
//! * [`simulation`] — what a simulation holds; the one place a group's context is built;
//!   residuals, reports and energies between steps.
//! * [`schedule`] — the order of the `project` calls in a substep.
//! * [`step`] — the substep loop and its stages.
//! * [`particles`] — the particle state and the flat loops the stages run over it.
//! * [`object`] — an object's topology as plugins see it, and where its moving pins go.
//! * [`output`] — OBJ frames and the stats CSV, written so a failed run leaves no false file.
//! * [`error`] — every error the core returns.

pub mod build;
pub mod complex;
pub mod error;
pub mod obj;
pub mod object;
pub mod output;
pub mod particles;
pub mod plugins;
pub mod scene;
pub mod schedule;
pub mod shapes;
pub mod simulation;
pub mod step;

pub use plugins::Registry;
pub use scene::Scene;
pub use simulation::Simulation;
