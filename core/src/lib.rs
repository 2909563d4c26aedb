//! # Nucleus core
//!
//! The simplicial complex, particle state, integrator, scheduler, plugin loading, scenes and
//! output. The core never names a constraint type: everything it knows about a constraint
//! group is its order, its importance, and which optional stages it implements.

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
