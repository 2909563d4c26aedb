//! The narrow phase: whether and when a candidate pair comes within its contact distance.

pub mod ccd;
pub mod distance;
pub mod pairs;
