//! What a shape adds to its neutral's intersection curve, and what the template's own shape
//! allows it: SPEC 3's criterion ([`TemplateCurve::allowed`], [`AddedCurve::excess`]) and the
//! template's contacts the pass leaves alone ([`TemplateContacts::near`]).

use std::collections::{HashMap, HashSet};

use super::guard::SideMemo;
use super::{Attempt, CollisionGuard};
use crate::geometry::penetration::{crossings, AddedCurve, TemplateCurve};
use crate::transfer::deformation::DeformationTransfer;
use crate::transfer::gradients::{add, to_f64, Vec3};

impl DeformationTransfer {
    /// The template shape's own crossing pairs (one sweep of its moved triangles, plus its
    /// neutral's unmoved ones), computed once per shape that has candidate pairs.
    pub(super) fn template_contacts(&self, guard: &CollisionGuard, delta: &[[f32; 3]], moved: &[bool]) -> TemplateContacts {
        let points: Vec<Vec3> = self.source_neutral.iter().zip(delta).map(|(p, d)| add(*p, to_f64(d))).collect();
        let bvh = guard.template_bvh.refitted(&points, &self.triangles);
        let swept = crossings(&points, &self.triangles, &bvh, Some(moved));
        let unmoved = guard.template_rest_pairs.iter().copied().filter(|&(a, b, _)| !moved[a as usize] && !moved[b as usize]);
        let all: Vec<(u32, u32, f64)> = swept.into_iter().chain(unmoved).collect();
        // The artist's own contacts are the pairs the shape crosses and its neutral does not:
        // a pair crossing at the template's rest (skin resting in its teeth) says nothing
        // about what the shape may add around it.
        let mut partners: HashMap<u32, Vec<u32>> = HashMap::new();
        let at_rest = |a: u32, b: u32| guard.template_rest_pairs.binary_search_by_key(&(a, b), |p| (p.0, p.1)).is_ok();
        for &(a, b, _) in all.iter().filter(|&&(a, b, _)| !at_rest(a, b)) {
            partners.entry(a).or_default().push(b);
            partners.entry(b).or_default().push(a);
        }
        // Template and target share the topology, hence the pieces.
        let piece_of = |t: u32| self.triangle_piece(t);
        let rest = AddedCurve::of(guard.template_rest_pairs.iter().copied(), piece_of, AddedCurve::default());
        // The template's lengths, at the target's size where they are compared with its.
        let noise = 0.5 * super::JUDGE_TOLERANCE * guard.diagonal / self.template_to_target;
        let adding = pieces_grown(all.iter().copied(), guard.template_rest_pairs.iter().copied(), piece_of, noise);
        let template = TemplateCurve {
            added: AddedCurve::of(all.iter().copied(), piece_of, rest),
            crossing: AddedCurve::of(all.into_iter(), piece_of, AddedCurve::default()),
        };
        let allowed = template.scaled(self.template_to_target).allowed(&AddedCurve::crossing(&guard.rest_penetration));
        TemplateContacts { partners, allowed, positions: points, adding, sides: SideMemo::default() }
    }
}

/// The template shape's crossing pairs, per triangle its partners, the curve the criterion
/// allows the target's shape to add to the target's neutral, and the template shape's
/// positions (what the holds compare the target's sides with).
pub(super) struct TemplateContacts {
    partners: HashMap<u32, Vec<u32>>,
    pub(super) allowed: AddedCurve,
    pub(super) positions: Vec<Vec3>,
    /// The pairs of pieces ([`piece_key`]) between which the shape's curve is longer than at
    /// the template's rest (beyond the judging noise).
    adding: HashSet<(u32, u32)>,
    /// Per `(vertex, static piece)`, the side of the piece's surface the shape has the vertex
    /// on ([`TemplateContacts::side`]): the same for every round and attempt of the shape
    /// that asks, so each is found once per shape.
    sides: SideMemo,
}

impl TemplateContacts {
    /// The side of static piece `piece` the template's shape has vertex `u` on, `find`
    /// computing it the first time it is asked.
    pub(super) fn side(&self, u: usize, piece: u32, find: impl FnOnce() -> Option<f64>) -> Option<f64> {
        self.sides.get_or(u, piece, find)
    }

    /// Whether the template's shape adds no curve between pieces `p` and `q` (it keeps or
    /// removes what its neutral has there): the criterion then allows the target none.
    pub(super) fn adds_none(&self, p: u32, q: u32) -> bool {
        !self.adding.contains(&piece_key(p, q))
    }

    /// Whether `attempt` acts on the crossing pair `(a, b)` of pieces `pieces`: a pair away from
    /// the template's own contacts, or any pair for the attempts that do not follow the
    /// template or that act beside its contacts. The rest attempt also acts near the template's
    /// contacts against a piece it adds no curve to: there its contacts only slide along what
    /// its neutral has. The piece test goes first: the contact test reads two one-rings a pair,
    /// for the tens of thousands of pairs that moving lashes carry.
    pub(super) fn acts_on(&self, guard: &CollisionGuard, attempt: &Attempt, (a, b): (u32, u32), (p, q): (u32, u32)) -> bool {
        attempt.follow || attempt.clear || attempt.contacts || attempt.along_path || (attempt.rest && p != q && self.adds_none(p, q)) || !self.near(guard, a, b)
    }

    /// Whether the pair `(a, b)` is the artist's own: some triangle sharing a corner with `a`
    /// crosses some triangle sharing a corner with `b` in the template's shape (the target's
    /// contact may sit a triangle away from the template's). Lips the template presses into
    /// each other stay as the template has them.
    pub(super) fn near(&self, guard: &CollisionGuard, a: u32, b: u32) -> bool {
        let near_b = guard.around(b);
        guard.around(a).iter().any(|x| {
            self.partners.get(x).is_some_and(|ys| ys.iter().any(|y| near_b.binary_search(y).is_ok()))
        })
    }
}

/// The pairs of pieces `(p, q)`, `p <= q` (`p == q`: inside one piece), whose crossing curve
/// in `pairs` is longer than in `rest` by more than `noise`.
pub(super) fn pieces_grown(
    pairs: impl Iterator<Item = (u32, u32, f64)>,
    rest: impl Iterator<Item = (u32, u32, f64)>,
    piece_of: impl Fn(u32) -> u32,
    noise: f64,
) -> HashSet<(u32, u32)> {
    let mut curve: HashMap<(u32, u32), f64> = HashMap::new();
    for (a, b, l) in pairs {
        *curve.entry(piece_key(piece_of(a), piece_of(b))).or_default() += l;
    }
    for (a, b, l) in rest {
        *curve.entry(piece_key(piece_of(a), piece_of(b))).or_default() -= l;
    }
    curve.into_iter().filter(|&(_, grown)| grown > noise).map(|(key, _)| key).collect()
}

pub(super) fn piece_key(p: u32, q: u32) -> (u32, u32) {
    (p.min(q), p.max(q))
}

#[cfg(test)]
mod tests {
    use super::{pieces_grown, AddedCurve, TemplateCurve};

    #[test]
    fn pieces_grown_names_the_pairs_of_pieces_whose_own_curve_grew() {
        // Triangles 0, 1 in piece 0; 2 in piece 1; 3 in piece 2. Skin (0) slides out of the
        // teeth (1) it rests in and into the eyeball (2): between pieces grows by 0.125 in
        // all, yet only the skin-eyeball pair grew; inside the skin nothing changed.
        let piece = |t: u32| [0, 0, 1, 2][t as usize];
        let rest = [(0, 1, 0.25), (0, 2, 0.5), (1, 3, 0.125)];
        let shape = [(0, 1, 0.25), (0, 2, 0.25), (2, 1, 0.125), (1, 3, 0.375)];
        let grown = pieces_grown(shape.into_iter(), rest.into_iter(), piece, 1e-9);
        assert_eq!(grown.into_iter().collect::<Vec<_>>(), vec![(0, 2)]);
        // Below the noise, nothing grew.
        assert!(pieces_grown(shape.into_iter(), rest.into_iter(), piece, 0.5).is_empty());
    }

    #[test]
    fn added_curve_splits_by_piece_and_judges_each_part_against_the_templates_allowance() {
        // Triangles 0, 1 in piece 0; 2 in piece 1. Rest: inside 0.5, between 0.25.
        let piece = |t: u32| u32::from(t == 2);
        let rest = AddedCurve::of([(0, 1, 0.5), (1, 2, 0.25)].into_iter(), piece, AddedCurve::default());
        assert_eq!(rest, AddedCurve { inside: 0.5, between: 0.25 });
        let added = AddedCurve::of([(0, 1, 0.75), (0, 2, 0.125)].into_iter(), piece, rest);
        assert_eq!(added, AddedCurve { inside: 0.25, between: -0.125 });
        // A template whose own shape crosses nowhere: only its added curve allows.
        let allowed = |added: AddedCurve| TemplateCurve { added, crossing: AddedCurve::default() }.allowed(&rest);
        // A template adding more inside and anything between: met.
        assert_eq!(added.excess(&allowed(AddedCurve { inside: 0.5, between: -1.0 })), 0.0);
        // Removing between does not pay for adding inside: the template adds none inside.
        assert_eq!(added.excess(&allowed(AddedCurve { inside: -0.5, between: 1.0 })), 0.25);
        // Where the template removes, the target need only add none (not remove as much).
        let removes = allowed(AddedCurve { inside: -0.25, between: -0.5 });
        assert_eq!(AddedCurve { inside: 0.0, between: -0.125 }.excess(&removes), 0.0);
        assert_eq!(AddedCurve { inside: 0.125, between: 0.25 }.excess(&removes), 0.375);
        // A template shape crossing 1.0 inside (its neutral more, so it removes): the target's
        // shape may cross as much, 0.5 beyond the target's own rest inside.
        let crossing = TemplateCurve { added: AddedCurve { inside: -0.25, between: 0.0 }, crossing: AddedCurve { inside: 1.0, between: 0.0 } };
        assert_eq!(crossing.allowed(&rest), AddedCurve { inside: 0.5, between: 0.0 });
        assert_eq!(AddedCurve { inside: 0.5, between: 0.0 }.excess(&crossing.allowed(&rest)), 0.0);
        assert_eq!(AddedCurve { inside: 0.75, between: 0.0 }.excess(&crossing.allowed(&rest)), 0.25);
    }
}
