//! Contact as one solve: Incremental Potential Contact (Li, Ferguson, Schneider, Langlois,
//! Zorin, Panozzo, Jiang, Kaufman 2020) on a quadratic shape energy: every iterate free of
//! intersection by construction (method, section 3).
//!
//! | paper | here |
//! |---|---|
//! | unsigned distance `d(x)` of point-triangle and edge-edge pairs, by distance type | [`distance`] |
//! | barrier `b(d, d_hat) = -(d - d_hat)^2 ln(d / d_hat)` (on squared distances) | [`barrier::barrier`] |
//! | edge-edge mollifier `m(x)`, `eps_x = 1e-3 |e_a|^2 |e_b|^2` at rest | [`barrier::mollifier`] |
//! | projected Newton, per-pair Hessians projected to PSD | [`newton::solve`], [`barrier::project_pair_psd`] |
//! | broad phase on swept boxes grown by `d_hat` (here half of it each) | [`broad`], [`newton::SolveBroadPhase`] |
//! | additive CCD (Li, Kaufman, Jiang 2021), the line search's largest safe step | [`ccd::additive_ccd`] |
//! | `kappa` (barrier stiffness) | the energy's mean diagonal over the region / `d_hat^2` |
//! | an intersection-free start | the solved shape untangled (Volino and Magnenat-Thalmann 2006's contour minimisation), [`untangle`] |
//!
//! Deviations from the paper: a static solve (no inertia term); `kappa` is fixed per solve
//! from the energy's own scale instead of adapted (the CCD keeps every iterate apart whatever
//! `kappa` is; it only sets how close pressed surfaces end); pairs are not deduplicated by
//! distance type (a point closest to a shared edge has a barrier from each triangle: a
//! stiffer contact, the same guarantee); exempt pairs carry no barrier at all.

pub mod barrier;
pub mod broad;
pub mod ccd;
pub mod distance;
pub mod dual;
pub mod exemptions;
pub mod newton;
pub mod shape;
pub mod untangle;

pub use exemptions::{Crossed, Exemptions, TemplatePose, Topology};
pub use newton::{solve, ContactMesh, NewtonParams, NewtonResult, Pair, SolveBroadPhase};
pub use shape::{ContactScene, Resolved, TemplateShape};
