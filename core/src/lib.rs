//! Nucleus core: knows no constraint type.

pub mod complex;
pub mod schedule;
