//! # Nucleus core
//!
//! The simplicial complex, particle state, integrator, scheduler, plugin loading, scenes and
//! output. The core never names a constraint type: everything it knows about a constraint
//! group is its order, its importance, and which optional stages it implements.

pub mod complex;
pub mod error;
pub mod obj;
pub mod output;
pub mod plugins;
pub mod scene;
pub mod schedule;
pub mod shapes;
pub mod world;

pub use plugins::Registry;
pub use scene::Scene;
pub use world::Simulation;
