//! Geometry shared by the three tools.

pub mod bvh;
pub mod mirror;
pub mod neighbours;
pub mod topology;
