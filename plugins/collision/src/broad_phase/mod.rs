//! The broad phase: the pairs of primitives whose swept boxes overlap.

pub mod bvh;
