//! Worst-case visibility measured on demand ([`cover::Visibilities`]): the neutral pose's
//! visibility bounds every candidate's worst case from above (`l[n] = min_k L_k[n] <=
//! L_0[n]`, Eq. 4), and the cover measures through every pose only the vertices whose cost
//! decides a coverage set ([`cover::settle`]). Most candidates share their coverage set with
//! dozens of neighbours of which the reduction keeps one, so most are never traced beyond the
//! neutral: the layout is the one every candidate measured would give.

use std::time::Instant;

use crate::error::ShapesmithResult;
use crate::progress::Progress;
use crate::rig::RigView;

use super::cover::Visibilities;
use super::design::Screen;
use super::visibility::{Need, Sampling, Scene, Seen};
use super::Stage;

/// Progress of the neutral bound, then of the first measurement; later ones (few vertices)
/// report the end of that span.
const BOUND_SPAN: f64 = 0.1;

pub struct OnDemand<'a> {
    scene: Scene<'a>,
    sampling: &'a Sampling<'a>,
    reuse: bool,
    partners: Option<&'a [Option<u32>]>,
    /// `l[n]` where measured, the neutral's `L_0[n]` where only bounded, NaN elsewhere.
    level: Vec<f64>,
    exact: Vec<bool>,
    /// Threshold answers (the design's pool).
    seen: Vec<Option<Seen>>,
    /// Threshold questions for the next pass over the poses.
    pending: Vec<(u32, f64)>,
    /// Vertices traced through the poses (exactly or against a threshold).
    traced: Vec<bool>,
    pub rays_cast: u64,
    pub rays_reused: u64,
    pub seconds: f64,
    measurements: usize,
    progress: &'a dyn Progress,
}

impl<'a> OnDemand<'a> {
    /// Bounds `bounded` (and their mirror partners) by their neutral visibility; with
    /// `exhaustive`, measures them through every pose at once instead (to time the saving).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        rig: &'a RigView<'a>,
        shapes: &'a [usize],
        sampling: &'a Sampling<'a>,
        reuse: bool,
        partners: Option<&'a [Option<u32>]>,
        bounded: &[u32],
        exhaustive: bool,
        progress: &'a dyn Progress,
    ) -> ShapesmithResult<Self> {
        let n = rig.n_vertices();
        let mut this = Self {
            scene: Scene::new(rig, shapes),
            sampling,
            reuse,
            partners,
            level: vec![f64::NAN; n],
            exact: vec![false; n],
            seen: vec![None; n],
            pending: Vec::new(),
            traced: vec![false; n],
            rays_cast: 0,
            rays_reused: 0,
            seconds: 0.0,
            measurements: 0,
            progress,
        };
        let vertices = this.with_partners(bounded.iter().copied());
        if exhaustive {
            this.measure(&vertices)?;
        } else {
            let started = Instant::now();
            let stage = Stage { inner: progress, start: 0.0, span: BOUND_SPAN };
            let needs = vec![Need::Exact; vertices.len()];
            let neutral = this.scene.measure(&vertices, &needs, sampling, reuse, false, &stage)?;
            this.rays_cast += neutral.rays_cast;
            for (&v, seen) in vertices.iter().zip(&neutral.worst) {
                this.level[v as usize] = seen.exact().unwrap_or(f64::NAN);
            }
            this.seconds += started.elapsed().as_secs_f64();
        }
        Ok(this)
    }

    /// `vertices` and their mirror partners, ascending, once each.
    fn with_partners(&self, vertices: impl Iterator<Item = u32>) -> Vec<u32> {
        let mut all: Vec<u32> = vertices.flat_map(|v| std::iter::once(v).chain(self.partners.and_then(|p| p[v as usize]))).collect();
        all.sort_unstable();
        all.dedup();
        all
    }

    /// Asks whether each of `vertices` (and partner) reaches `threshold` along with the next
    /// measurement: one pass over the poses for both (a pass prepares every pose again, which
    /// on a 25k head costs more than the threshold rays of the whole pool).
    pub fn ask_at_least(&mut self, vertices: &[u32], threshold: f64) {
        let all = self.with_partners(vertices.iter().copied());
        self.pending.extend(all.into_iter().filter(|&v| !self.exact[v as usize]).map(|v| (v, threshold)));
    }

    /// `l[n]` when measured.
    pub fn exact_level(&self, n: usize) -> Option<f64> {
        self.exact[n].then_some(self.level[n])
    }

    /// Whether `l[n] >= threshold`, when measured, asked, or below it already at rest.
    pub fn at_least(&self, n: usize, threshold: f64) -> Option<bool> {
        match self.exact_level(n) {
            Some(l) => Some(l >= threshold),
            None if self.level[n] < threshold => Some(false),
            None => self.seen[n].and_then(|s| s.at_least(threshold)),
        }
    }

    /// Vertices traced through the poses, exactly or against a threshold.
    pub fn traced(&self) -> usize {
        self.traced.iter().filter(|&&t| t).count()
    }
}

impl Visibilities for OnDemand<'_> {
    /// The worse of the two mirror vertices for symmetric layouts (both become landmarks).
    fn level(&self, n: usize) -> f64 {
        match self.partners.and_then(|p| p[n]) {
            Some(m) => self.level[n].min(self.level[m as usize]),
            None => self.level[n],
        }
    }

    fn is_exact(&self, n: usize) -> bool {
        self.exact[n] && self.partners.and_then(|p| p[n]).is_none_or(|m| self.exact[m as usize])
    }

    /// Measures `vertices` and their partners exactly, and answers the pending threshold
    /// questions, in one pass over the poses.
    fn measure(&mut self, vertices: &[u32]) -> ShapesmithResult<()> {
        let started = Instant::now();
        let exact = self.with_partners(vertices.iter().copied());
        let mut asked: Vec<(u32, Need)> =
            exact.iter().filter(|&&v| !self.exact[v as usize]).map(|&v| (v, Need::Exact)).collect();
        for (v, t) in std::mem::take(&mut self.pending) {
            if !self.exact[v as usize] && exact.binary_search(&v).is_err() {
                asked.push((v, Need::AtLeast(t)));
            }
        }
        asked.sort_by_key(|a| a.0);
        asked.dedup_by_key(|a| a.0);
        let (list, needs): (Vec<u32>, Vec<Need>) = asked.into_iter().unzip();
        let start = if self.measurements == 0 { BOUND_SPAN } else { 0.8 };
        let stage = Stage { inner: self.progress, start, span: 0.8 - start };
        let measured = self.scene.measure(&list, &needs, self.sampling, self.reuse, true, &stage)?;
        self.measurements += 1;
        self.rays_cast += measured.rays_cast;
        self.rays_reused += measured.rays_reused;
        for (&v, seen) in list.iter().zip(&measured.worst) {
            self.traced[v as usize] = true;
            match seen.exact() {
                Some(l) => {
                    self.level[v as usize] = l;
                    self.exact[v as usize] = true;
                }
                None => self.seen[v as usize] = Some(*seen),
            }
        }
        self.seconds += started.elapsed().as_secs_f64();
        Ok(())
    }
}

/// The design's pool rule on [`OnDemand`]: a unit (a vertex, or a mirror pair) passes when
/// each of its vertices is seen at least `threshold` in its worst pose.
pub struct PoolScreen<'v, 'a> {
    pub visibility: &'v mut OnDemand<'a>,
    pub units: &'v [Vec<u32>],
    pub threshold: f64,
}

impl Screen for PoolScreen<'_, '_> {
    fn known(&self, unit: usize) -> Option<bool> {
        let answers: Vec<Option<bool>> = self.units[unit].iter().map(|&v| self.visibility.at_least(v as usize, self.threshold)).collect();
        if answers.contains(&Some(false)) {
            Some(false)
        } else if answers.iter().all(|a| *a == Some(true)) {
            Some(true)
        } else {
            None
        }
    }

    fn trace(&mut self, units: &[usize]) -> ShapesmithResult<()> {
        let vertices: Vec<u32> = units.iter().flat_map(|&u| self.units[u].iter().copied()).collect();
        self.visibility.ask_at_least(&vertices, self.threshold);
        self.visibility.measure(&[])
    }
}
