//! Blendshape transfer: deformation transfer (Sumner & Popovic 2004, in the gradient form of
//! Botsch et al. 2006) with virtual-edge constraints against penetration (Li, Shen & Liu 2023,
//! paper 004) and example-based personalisation (Li, Weise & Pauly 2010). Method, section 3.
//!
//! [`DeformationTransfer::new`] does everything that depends only on the two neutrals (the
//! target's gradient operators, the normal matrix, the virtual edges, the pieces);
//! [`DeformationTransfer::transfer`] then solves all shapes, rayon across shapes, and
//! [`DeformationTransfer::personalise`] refits them to training expressions of the target.
//! [`measure_penetration`] scores the results; [`find_virtual_edges`] feeds the preview;
//! [`transfer_shapes`] runs it all and writes the report.
//!
//! | paper symbol | identifier |
//! |---|---|
//! | `V0`, `D_k` (template neutral, shape deltas) | `source_neutral`, `source_deltas` |
//! | `B0`, `B_k - B0` (target neutral, target deltas) | `target_neutral`, [`TransferResult::deltas`] |
//! | `V = [v2-v1, v3-v1, v4-v1]` (S&P Eq. 3) | `gradients::edge_frame` |
//! | `S_kt = V~ V^{-1}` (S&P Eq. 1), stored as `S_kt - I` | `gradients::delta_gradient` |
//! | `G_t` (gradient operator of the target rest triangle) | `gradients::HatGradients` |
//! | `sum_t area_t G_t^T G_t` (+ virtual-edge springs) | `system::NormalMatrix` |
//! | `tau_d`, `tau_r` (paper 004, section 4) | [`VirtualEdgeParams`] |
//! | `w_ve` (virtual-edge weight) | [`TransferParams::edge_weight`] |
//! | `A_ij` (rest-to-rest gradient at the ends of a virtual edge; replaces `S_ij`) | `DeformationTransfer::edge_rest_maps` |
//! | `alpha_jk` (EBFR blend weights of example `j`) | `weights` of [`DeformationTransfer::personalise`] |
//! | `beta` (EBFR regulariser; here the inverse square of the transfer's relative error) | [`PersonaliseParams`] |
//!
//! # Deviations (each a decision in docs/design_transfer.md, with its numbers)
//! - **Static vertices by elimination**: each shape removes its static vertices
//!   (`|D_k[n]| < 1e-4 max_n |D_k[n]|`) from the system (Dirichlet) and factorises only the
//!   principal submatrix on its moving vertices, in one AMD order computed once; static
//!   vertices are exact zeros, a triangle with only static corners gets a zero gradient.
//! - **Pieces that move as a whole** are pinned at one vertex, solved, and translated so the
//!   mean of their deltas is the source piece's scaled by the ratio of the pieces' RMS radii
//!   (the gradient energy is translation invariant per piece, so the shift keeps the minimiser).
//! - **Rotation alignment** ([`TransferParams::align_rotation`]): deformation transfer copies
//!   world-space gradients, so a rotated target is turned onto the source (Kabsch) for the
//!   solve and its deltas turned back.
//! - **Virtual edges** join vertices of one piece only ([`find_virtual_edges`]).
//! - **Virtual-edge target** `f_k = A_ij e_k + rho (f_0 - A_ij e_0)` instead of the method's
//!   `S_ij (B0_i - B0_j)`: `e_0`, `e_k` the source pair's vector at rest and in shape k,
//!   `f_0 = B0_i - B0_j`, `A_ij` the mean rest-to-rest gradient `E_target E_source^{-1}` around
//!   i and j, `rho = (1 - min(1, |e_k - e_0| / |e_0|))^2` (`DeformationTransfer::edge_change`).
//!   A pair that moves a lot ends where the source pair ends, mapped into the target; one that
//!   barely moves keeps the target's rest vector; self-transfer is exact (`A = I`, `f_0 = e_0`).
//! - **A key's contacts are virtual edges of its own solve** (`key_contacts.rs`): the
//!   pairs the template's key brings to touch from beyond `tau_d` (the lids of a blink) join
//!   that key's matrix and aim by the same `f_k`, so `rho -> 0` and they meet on a target
//!   whose eyes are larger; every other key's solve is as before, to the bit.
//! - **`w_ve = 3`**: the springs hold the template's final gap, so they need more pull than 1
//!   against the gradient term (the two-layer lip test in `tests.rs`).
//! - **Contact as one solve** ([`ContactParams`], `contact.rs`; method, section 3, beyond paper
//!   004), when asked for: a shape adding a crossing beyond its neutral's and the template
//!   shape's own contacts is solved again with the IPC barrier around the added crossings;
//!   every other shape comes out bit for bit as without it.
//! - **Personalisation** follows EBFR in the gradient domain as a Gaussian MAP fit per
//!   triangle (equations and deviations in `personalise.rs`).
//!
mod alignment;
mod contact;
mod deformation;
mod gradients;
mod key_contacts;
mod personalise;
mod report;
mod system;
mod virtual_edges;

pub use crate::geometry::penetration::{AddedCurve, TemplateCurve};
pub use contact::{ContactOutcome, ContactParams};
pub use deformation::{DeformationTransfer, MAX_CONTACT_DISTANCE};
pub use crate::geometry::penetration::{measure_penetration, Penetration, PenetrationBaseline};
pub use personalise::{PersonaliseParams, Personalisation};
pub use report::{
    measure_rig_penetration, transfer_shapes, transfer_weld, RigPenetration, ShapePenetration, StageSeconds, TrainingExpressions, TransferReport,
    TransferShapesParams,
};
pub use virtual_edges::{find_virtual_edges, VirtualEdgeParams};

/// Knobs of [`DeformationTransfer::new`], defaults from method, section 3.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TransferParams {
    /// Virtual edges against penetration; `None` is plain deformation transfer.
    pub virtual_edges: Option<VirtualEdgeParams>,
    /// `w_ve`, the weight of each virtual-edge spring relative to the gradient energy (the method: 1;
    /// 3 here, see Deviations).
    pub edge_weight: f64,
    /// A vertex moving less than this fraction of a shape's largest displacement is static.
    pub static_fraction: f64,
    /// Solve in the source's orientation (Kabsch) so that a rotated target gets rotated shapes.
    pub align_rotation: bool,
    /// The contact solve after each shape's solve; `None` (the default) leaves the solve as it
    /// is: on the bench heads the solve costs hundreds of times the transfer (docs/design_transfer.md).
    pub contact: Option<ContactParams>,
}

impl Default for TransferParams {
    fn default() -> Self {
        Self {
            virtual_edges: Some(VirtualEdgeParams::default()),
            edge_weight: 3.0,
            static_fraction: 1e-5,
            align_rotation: true,
            contact: None,
        }
    }
}

/// Transferred shapes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TransferResult {
    /// K x N target deltas `B_k - B0`, shape-major like the input.
    pub deltas: Vec<[f32; 3]>,
    /// Shapes that do not move in the source (their deltas are zero).
    pub inert: Vec<String>,
    /// Wall-clock seconds of the per-shape solves (the contact solves' share excluded).
    pub seconds: f64,
    /// Per shape, what the contact solve did; `None` when contact is off.
    pub contact: Option<Vec<ContactOutcome>>,
    /// Per shape, K entries: the deltas (N rows) before the contact solve, for the shapes it
    /// changed.
    #[serde(skip)]
    pub before_contact: Vec<Option<Vec<[f32; 3]>>>,
    /// Wall-clock seconds of the contact solves (their share of the shapes' solves, plus the
    /// setup on the two neutrals).
    pub contact_seconds: f64,
}

#[cfg(test)]
mod contact_tests;
#[cfg(test)]
mod tests;
