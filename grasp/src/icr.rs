//! Independent contact regions with a quality margin alpha (paper II-B, III-B; DESIGN.md).
//!
//! For a force-closure grasp with hull `H(GWS) = {w : a_f . w <= b_f}` and OWS support
//! `h_f`, the search hyperplane of facet `f` is `a_f . w = alpha h_f`, with positive side
//! `H_f+ = {w : a_f . w >= alpha h_f}`. Every hull vertex `omega` that is a primitive wrench
//! of contact `i` has a search zone `Z_omega`, the intersection of `H_f+` over the facets `f`
//! that have `omega` as a vertex. A candidate point `q` satisfies contact `i`'s zone rule when
//! every zone of contact `i` holds at least one of `q`'s primitive wrenches (up to the
//! absolute tolerance of the evaluation). `ICR_i` is the connected set of such candidates
//! containing the contact, grown breadth-first over the neighbourhood graph, so only points
//! near the contact are ever tested.
//!
//! Why the rule keeps the margin: every direction `u` lies in the normal cone of some vertex
//! `omega`, `u = sum lambda_f a_f` over the facets at `omega` with `lambda_f >= 0`. A new
//! contact with a wrench `w'` in `Z_omega` gives `u . w' >= alpha sum lambda_f h_f >=
//! alpha h(u)` (the support function is sublinear), so the new grasp's support is at least
//! alpha times the OWS support in every direction, i.e. `alpha OWS` lies inside the new
//! `H(GWS)`: any pick of one point per region has quality >= alpha.

use std::collections::VecDeque;

use crate::hull::Hull;
use crate::math::Real;
use crate::quality::{Evaluation, GraspProblem};
use crate::support::SupportScratch;

/// Why no regions were computed. These are grasp outcomes the caller branches on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IcrError {
    /// The grasp is not force closure, so there is no margin to keep.
    #[error("the grasp is not force closure")]
    NotForceClosure,
    /// The margin asked for exceeds the grasp's own quality.
    #[error("the margin alpha = {alpha} exceeds the grasp's quality alpha* = {quality}")]
    MarginAboveQuality {
        /// The margin asked for.
        alpha: Real,
        /// The grasp's quality.
        quality: Real,
    },
    /// The margin is negative or not finite.
    #[error("the margin alpha must be finite and >= 0, got {alpha}")]
    BadMargin {
        /// The value given.
        alpha: Real,
    },
    /// The evaluation does not belong to these contacts.
    #[error(
        "the evaluation has {wrenches} wrenches, but {contacts} contacts of {edges} edges were given"
    )]
    Mismatch {
        /// Wrenches in the evaluation.
        wrenches: usize,
        /// Contacts given.
        contacts: usize,
        /// Cone edges.
        edges: usize,
    },
}

/// The independent contact region of one contact.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// The contact's candidate index.
    pub contact: usize,
    /// Candidate indices in the region, ascending (the contact included).
    pub members: Vec<u32>,
    /// Number of search zones of the contact (its primitive wrenches that are hull vertices).
    pub zones: usize,
}

/// One search zone: the facets at a hull vertex, and the cone edge of that vertex.
struct Zone {
    /// Cone edge index `j` of the vertex `omega = w_ij`.
    edge: usize,
    /// Facets whose half-spaces `H_f+` intersect to the zone.
    facets: Vec<u32>,
    /// Their normals in blocks of [`LANES`] facets, coordinate-major within a block
    /// (`normals[(block * dim + k) * LANES + lane]`), so that a wrench is tested against
    /// several facets at once; the last block is padded with zero normals.
    normals: Vec<Real>,
    /// Their sure limits (`Limits::sure`) in the same blocks, padded with `-inf`.
    sure: Vec<Real>,
}

/// Facets tested together.
const LANES: usize = 4;

impl Zone {
    /// The zone of the vertex of cone edge `edge` with these facets, tested in the order of
    /// their offsets: the vertex lies on each facet, so a nearby wrench's slack
    /// `a_f . w - sure_f` is about `b_f (1 - alpha / alpha*)`, smallest for the smallest
    /// offset, and a failing wrench is usually rejected by the first facet tested (the
    /// answer does not depend on the order, only the cost).
    fn new(edge: usize, facets: &[u32], hull: &Hull, sure: &[Real]) -> Self {
        let d = hull.dim();
        let mut facets = facets.to_vec();
        facets.sort_by(|&f, &g| {
            let offsets = hull.offsets();
            offsets[f as usize]
                .total_cmp(&offsets[g as usize])
                .then(f.cmp(&g))
        });
        let blocks = facets.len().div_ceil(LANES);
        let mut normals = vec![0.0; blocks * d * LANES];
        let mut limits = vec![Real::NEG_INFINITY; blocks * LANES];
        for (t, &f) in facets.iter().enumerate() {
            let (block, lane) = (t / LANES, t % LANES);
            for (k, &x) in hull.normal(f as usize).iter().enumerate() {
                normals[(block * d + k) * LANES + lane] = x;
            }
            limits[t] = sure[f as usize];
        }
        Self {
            edge,
            facets,
            normals,
            sure: limits,
        }
    }

    /// Whether `w` is in the zone: `a_f . w >= alpha h_f - tol` for each of its facets, by
    /// the sure limit where it suffices, else by `limits`. Stops at the first failure.
    fn holds(&self, w: &[Real], problem: &GraspProblem, hull: &Hull, limits: &mut Limits) -> bool {
        let d = w.len();
        for (block, (normals, sure)) in self
            .normals
            .chunks_exact(d * LANES)
            .zip(self.sure.chunks_exact(LANES))
            .enumerate()
        {
            let v = lane_dots(normals, w);
            for lane in 0..LANES {
                if v[lane] >= sure[lane] {
                    continue;
                }
                let f = self.facets[block * LANES + lane] as usize;
                if !limits.passes(problem, f, hull.normal(f), v[lane]) {
                    return false;
                }
            }
        }
        true
    }
}

/// `a_l . w` for the [`LANES`] normals of a block (coordinate-major), each rounded exactly as
/// [`crate::hull::dot`] rounds it (same products, same order of the sums).
#[inline(always)]
fn lane_dots(normals: &[Real], w: &[Real]) -> [Real; LANES] {
    let p = |k: usize| -> [Real; LANES] {
        let a = &normals[k * LANES..(k + 1) * LANES];
        std::array::from_fn(|l| a[l] * w[k])
    };
    match w.len() {
        6 => {
            let (p0, p1, p2, p3, p4, p5) = (p(0), p(1), p(2), p(3), p(4), p(5));
            std::array::from_fn(|l| (p0[l] + p1[l]) + (p2[l] + p3[l]) + (p4[l] + p5[l]))
        }
        3 => {
            let (p0, p1, p2) = (p(0), p(1), p(2));
            std::array::from_fn(|l| p0[l] + p1[l] + p2[l])
        }
        d => std::array::from_fn(|l| (0..d).map(|k| normals[k * LANES + l] * w[k]).sum::<Real>()),
    }
}

impl GraspProblem {
    /// The ICRs of `contacts` (candidate indices, one per finger) with margin `alpha`, given
    /// the evaluation of that grasp from [`GraspProblem::evaluate`].
    pub fn icrs(
        &self,
        contacts: &[usize],
        eval: &Evaluation,
        alpha: Real,
    ) -> Result<Vec<Region>, IcrError> {
        if !alpha.is_finite() || alpha < 0.0 {
            return Err(IcrError::BadMargin { alpha });
        }
        let s = self.model().edges();
        let d = self.dim();
        if eval.wrenches.len() != contacts.len() * s * d {
            return Err(IcrError::Mismatch {
                wrenches: eval.wrenches.len() / d,
                contacts: contacts.len(),
                edges: s,
            });
        }
        let Some(hull) = eval.hull.as_ref().filter(|_| eval.force_closure()) else {
            return Err(IcrError::NotForceClosure);
        };
        if alpha > eval.quality {
            return Err(IcrError::MarginAboveQuality {
                alpha,
                quality: eval.quality,
            });
        }
        // Membership: a_f . w >= alpha h_f - tol. The exact OWS support h_f is computed only
        // for the facets where it matters: alpha* <= b_f / h_f gives h_f <= b_f / alpha*, so a
        // wrench with a_f . w >= alpha b_f / alpha* - tol passes without it; elsewhere the
        // support is computed only as far as the test needs (`Limits::passes`).
        let mut limits = Limits {
            sure: hull
                .offsets()
                .iter()
                .map(|b| alpha * (b / eval.quality) - eval.tolerance)
                .collect(),
            exact: vec![Real::NAN; hull.facet_count()],
            upper: vec![Real::INFINITY; hull.facet_count()],
            alpha,
            tolerance: eval.tolerance,
            scratch: SupportScratch::default(),
        };
        let vertex_facets = hull.vertex_facets(contacts.len() * s);
        let mut visited = vec![u32::MAX; self.candidates().points.len()];
        let mut regions = Vec::with_capacity(contacts.len());
        for (i, &contact) in contacts.iter().enumerate() {
            let zones: Vec<Zone> = vertex_facets[i * s..(i + 1) * s]
                .iter()
                .enumerate()
                .filter(|(_, f)| !f.is_empty())
                .map(|(edge, facets)| Zone::new(edge, facets, hull, &limits.sure))
                .collect();
            let mut members = Vec::new();
            let mut queue = VecDeque::from([contact]);
            visited[contact] = i as u32;
            while let Some(q) = queue.pop_front() {
                if !self.satisfies(q, &zones, hull, &mut limits) {
                    continue;
                }
                members.push(q as u32);
                for &nb in self.candidates().adjacency.neighbours(q) {
                    if visited[nb as usize] != i as u32 {
                        visited[nb as usize] = i as u32;
                        queue.push_back(nb as usize);
                    }
                }
            }
            members.sort_unstable();
            regions.push(Region {
                contact,
                members,
                zones: zones.len(),
            });
        }
        Ok(regions)
    }

    /// Whether candidate `q` has a primitive wrench in every zone. Each zone tries first the
    /// wrench of the same cone edge as its vertex (a neighbouring point's cone is nearly the
    /// same, so that is almost always the one inside), and every facet test stops at the
    /// first failure.
    fn satisfies(&self, q: usize, zones: &[Zone], hull: &Hull, limits: &mut Limits) -> bool {
        let d = self.dim();
        let wrenches = self.candidate_wrenches(q);
        let s = wrenches.len() / d;
        let mut inside =
            |j: usize, z: &Zone| z.holds(&wrenches[j * d..(j + 1) * d], self, hull, limits);
        zones
            .iter()
            .all(|z| inside(z.edge, z) || (0..s).any(|j| j != z.edge && inside(j, z)))
    }
}

/// Membership limits per facet: a sufficient one from alpha*, and the exact test
/// `a_f . w >= alpha h_f - tol` decided with as little of the OWS support as it needs.
struct Limits {
    /// `alpha b_f / alpha* - tol >= alpha h_f - tol`.
    sure: Vec<Real>,
    /// `alpha h_f - tol`, NaN until the exact support `h_f` is computed.
    exact: Vec<Real>,
    /// A proven upper bound on `h_f` (`+inf` until one is known).
    upper: Vec<Real>,
    alpha: Real,
    tolerance: Real,
    scratch: SupportScratch,
}

impl Limits {
    /// Whether `v >= alpha h_f - tol` (with exactly that floating-point evaluation).
    ///
    /// The test is monotone in `h_f`: it holds exactly when `h_f <= t`, `t` the largest double
    /// that passes. So `h_f` is only needed up to the answer: a bound `h_f <= t` proven by a
    /// pruned tree search (cheap when `h_f` is well below `t`) settles a pass, and a point
    /// above `t` makes the search continue to the exact `h_f`, kept for later tests.
    fn passes(&mut self, problem: &GraspProblem, f: usize, a: &[Real], v: Real) -> bool {
        if !self.exact[f].is_nan() {
            return v >= self.exact[f];
        }
        let (alpha, tol) = (self.alpha, self.tolerance);
        let pass = |h: Real| alpha * h - tol <= v;
        let Some(t) = largest_passing(pass, (v + tol) / alpha) else {
            let h = problem.support_tree().support_warm(a, &mut self.scratch);
            self.exact[f] = alpha * h - tol;
            return v >= self.exact[f];
        };
        if t >= self.upper[f] {
            return true;
        }
        match problem
            .support_tree()
            .support_above(a, t, &mut self.scratch.stack)
        {
            None => {
                self.upper[f] = t;
                true
            }
            Some(h) => {
                self.exact[f] = alpha * h - tol;
                v >= self.exact[f]
            }
        }
    }
}

/// The largest finite double `t` with `pass(t)`, searched from the estimate `t0` by steps of
/// one ulp, for a monotone (non-increasing in `t`) test; `None` when the estimate is not
/// within a few ulps (or not finite), and the caller decides by the exact value instead.
fn largest_passing(pass: impl Fn(Real) -> bool, t0: Real) -> Option<Real> {
    if !t0.is_finite() {
        return None;
    }
    let mut t = t0;
    for _ in 0..8 {
        if pass(t) {
            let up = t.next_up();
            if up.is_finite() && pass(up) {
                t = up;
            } else {
                return Some(t);
            }
        } else {
            t = t.next_down();
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::tests::planar_sphere_problem;

    #[test]
    fn paper_grasp_regions_contain_their_contacts_and_keep_the_margin() {
        let p = planar_sphere_problem(0.3);
        let contacts = [6, 66, 28];
        let e = p.evaluate(&contacts).unwrap();
        let alpha = 0.1;
        let regions = p.icrs(&contacts, &e, alpha).unwrap();
        assert_eq!(regions.len(), 3);
        for (r, &c) in regions.iter().zip(&contacts) {
            assert!(r.members.contains(&(c as u32)));
            assert!(r.members.len() > 1, "region of {c} is only the contact");
            assert!(r.members.len() < 72);
        }
        // Every combination keeps the margin (exhaustive on the 72-point ring).
        let mut worst = Real::INFINITY;
        for &a in &regions[0].members {
            for &b in &regions[1].members {
                for &c in &regions[2].members {
                    let q = p
                        .evaluate(&[a as usize, b as usize, c as usize])
                        .unwrap()
                        .quality;
                    worst = worst.min(q);
                }
            }
        }
        assert!(worst >= alpha - 1e-9, "worst pick has quality {worst}");
    }

    #[test]
    fn largest_passing_finds_the_boundary_double() {
        let (alpha, tol, v) = (0.3, 1e-12, 0.123456789);
        let pass = |h: Real| alpha * h - tol <= v;
        for t0 in [(v + tol) / alpha, ((v + tol) / alpha).next_up().next_up()] {
            let t = largest_passing(pass, t0).unwrap();
            assert!(pass(t) && !pass(t.next_up()));
        }
        assert_eq!(largest_passing(pass, Real::INFINITY), None);
        assert_eq!(
            largest_passing(pass, 1.0),
            None,
            "too far from the boundary"
        );
    }

    #[test]
    fn margin_above_quality_and_non_closure_are_statuses() {
        let p = planar_sphere_problem(0.3);
        let e = p.evaluate(&[6, 66, 28]).unwrap();
        assert!(matches!(
            p.icrs(&[6, 66, 28], &e, e.quality * 1.01),
            Err(IcrError::MarginAboveQuality { .. })
        ));
        let low = planar_sphere_problem(0.03);
        let e = low.evaluate(&[6, 66, 28]).unwrap();
        assert_eq!(
            low.icrs(&[6, 66, 28], &e, 0.01),
            Err(IcrError::NotForceClosure)
        );
        assert!(matches!(
            p.icrs(&[6, 66], &e, 0.1),
            Err(IcrError::Mismatch { .. })
        ));
    }

    #[test]
    fn zero_margin_regions_are_at_least_as_large() {
        let p = planar_sphere_problem(0.3);
        let contacts = [6, 66, 28];
        let e = p.evaluate(&contacts).unwrap();
        let tight = p.icrs(&contacts, &e, 0.9 * e.quality).unwrap();
        let loose = p.icrs(&contacts, &e, 0.0).unwrap();
        for (t, l) in tight.iter().zip(&loose) {
            assert!(t.members.iter().all(|m| l.members.contains(m)));
            assert!(l.members.len() >= t.members.len());
        }
    }
}
