//! Geometry shared by the tools.

pub mod bvh;
pub mod wide_bvh;
pub mod closest_point;
pub mod contact;
pub mod front;
pub mod mat3;
pub mod mesh_faults;
pub mod mirror;
pub mod neighbours;
pub mod penetration;
pub mod similarity;
pub mod topology;
pub mod weld;
