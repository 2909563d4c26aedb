//! The analytic colliders: their shapes and how they move.

pub mod motion;
pub mod shapes;
