//! Shapesmith's native core: pure functions from a face rig (plain arrays) to results.
//!
//! Three methods share one set of parts:
//! - [`packing`]: expression packing (Carrigan et al. 2020), a 0/1 program per expression.
//! - [`landmarks`]: compact landmark layouts (Zell & McDonnell 2022), a weighted set cover.
//! - [`transfer`]: deformation transfer with virtual edges (Sumner & Popovic 2004; Li et al. 2023)
//!   and example-based personalisation (Li, Weise & Pauly 2010).
//! - [`wrap`]: the template fitted onto a character of any topology (Umeyama 1991; Amberg,
//!   Romdhani & Vetter 2007) and shapes carried onto the character's own mesh.
//! - [`performance`]: the head's pose and the shape weights per frame from tracked landmarks.
//!
//! Shared parts: [`rig`] (the borrowed rig and its validation), [`bounded`] (box-constrained
//! least squares), [`geometry`] (mirror map,
//! symmetric and antagonist shape pairs, k-d tree neighbours, closest points, the penetration metric), [`sparse`] (sparse Cholesky), [`ilp`] (HiGHS through good_lp),
//! [`settings`] (each tool's settings as one JSON object onto its `*Params`).
//! No Blender notion enters this crate; the `python` feature adds the thin pyo3 layer in `py`.

pub mod analysis;
pub mod bounded;
pub mod error;
pub mod geometry;
pub mod ilp;
pub mod landmarks;
pub mod packing;
pub mod performance;
pub mod progress;
pub mod rig;
pub mod settings;
pub mod sparse;
pub mod transfer;
pub mod wrap;

#[cfg(feature = "python")]
mod py;

pub use error::{ShapesmithError, ShapesmithResult};
pub use progress::{NoProgress, Progress};
pub use rig::RigView;
