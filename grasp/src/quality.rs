//! Force closure, the quality margin alpha* (paper eq. 6) and the Ferrari-Canny epsilon.
//!
//! A [`GraspProblem`] holds everything that depends only on the object and the contact model,
//! computed once: the object wrenches `o_k` of every facet (the OWS generators) and the `s`
//! primitive wrenches of every candidate contact point, all in the object's body frame. A
//! rigid motion of the object moves its grasp wrench space and its object wrench space
//! together, so alpha* is evaluated in the body frame.
//!
//! [`GraspProblem::evaluate`] builds `H(GWS)` (the hull of the contacts' primitive wrenches,
//! [`Hull::of_contacts`]: facet enumeration for three contacts in 6D, beneath-beyond
//! otherwise) and reports:
//! - force closure: the hull is full-dimensional and the origin is strictly inside it, i.e.
//!   every facet offset `b_f > tol` with `tol = 1e-9 * max |w|`;
//! - epsilon (Ferrari-Canny, the L1 / "sum of forces <= 1" variant): `min_f b_f`, the radius
//!   of the largest ball about the origin inside the hull; reported as 0 when the origin is on
//!   the boundary within `tol`, negative when it is outside, and 0 for a degenerate hull, so
//!   that `epsilon > 0` exactly when the grasp is force closure;
//! - alpha*: `min_f b_f / h_f` over the facets with `h_f > 0`, where `h_f = max_k a_f . o_k` is
//!   the support function of the OWS (never its hull). By convention alpha* = 0 for a grasp
//!   that is not force closure: the literal eq. 6 can be positive for such a grasp when the
//!   OWS is degenerate (a sphere's OWS has no torque), but a grasp that cannot resist some
//!   wrench has no margin.
//!
//! alpha* never needs the whole support function: with `g_f = a_f / b_f`, alpha* is
//! `1 / max_{f,k} g_f . o_k`, a search over a tree of the OWS points (bounding ellipsoids) built once per object
//! ([`crate::support::SupportTree::max_over`]) that skips clusters of points and whole facets
//! by bounds. The full support function (every facet, needed by the ICRs) uses the same tree
//! per facet; the plain dense product `A O^T` through faer, blocked over the OWS, is kept as
//! the reference ([`GraspProblem::support_function_dense`]).

use faer::{Accum, MatMut, MatRef, Par};

use crate::hull::{Hull, HullError, HullScratch};
use crate::math::{Real, Vec3};
use crate::object::{NearestPoints, SurfaceSamples};
use crate::progress::{Progress, Silent, Stage, tick};
use crate::support::SupportTree;
use crate::wrench::{ContactModel, Space, WrenchFrame};

/// Relative tolerance of the force-closure and ICR membership tests.
pub const RELATIVE_TOLERANCE: Real = 1e-9;

/// OWS points per block of the support-function product.
const BLOCK: usize = 256;

/// Errors building or querying a grasp problem (bad input; not grasp outcomes).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GraspError {
    /// A contact index does not name a candidate.
    #[error("contact {contact} is candidate {index}, but there are only {count} candidates")]
    ContactIndex {
        /// Position of the contact in the list.
        contact: usize,
        /// The index given.
        index: usize,
        /// Number of candidates.
        count: usize,
    },
    /// No contacts were given.
    #[error("a grasp needs at least one contact")]
    NoContacts,
    /// The object has no facets to build the OWS from, or no candidates.
    #[error("the object has no {what}")]
    Empty {
        /// What is missing.
        what: &'static str,
    },
    /// No hull could be built for the contacts' wrenches (not a degenerate grasp: both hull
    /// implementations failed).
    #[error("no hull for the grasp wrenches: {0}")]
    Hull(HullError),
    /// A facet or candidate gives a non-finite wrench (a non-finite point or normal).
    #[error("{what} {index} gives a non-finite wrench (check its point and normal)")]
    NonFinite {
        /// "facet" or "candidate".
        what: &'static str,
        /// Its index.
        index: usize,
    },
    /// Candidate data of different lengths.
    #[error(
        "candidate data disagree: {points} points, {normals} normals, {adjacency} adjacency lists"
    )]
    CandidateLengths {
        /// Points.
        points: usize,
        /// Normals.
        normals: usize,
        /// Adjacency lists.
        adjacency: usize,
    },
}

/// Where the origin lies with respect to the hull of the contacts' primitive wrenches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Closure {
    /// Strictly inside: force closure.
    ForceClosure,
    /// On the boundary within the tolerance: not force closure.
    OriginOnBoundary,
    /// Outside: not force closure.
    OriginOutside,
    /// The wrenches span only a subspace of dimension `rank`: not force closure.
    Degenerate {
        /// Dimension of the wrenches' affine hull.
        rank: usize,
    },
}

/// The result of evaluating one grasp.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Force-closure status.
    pub closure: Closure,
    /// alpha* (paper eq. 6); 0 unless force closure.
    pub quality: Real,
    /// Ferrari-Canny epsilon (L1); positive exactly when force closure.
    pub epsilon: Real,
    /// The grasp wrench space hull, when full-dimensional.
    pub hull: Option<Hull>,
    /// The contacts' primitive wrenches, contact-major (`contacts x s x dim`).
    pub wrenches: Vec<Real>,
    /// The facet attaining alpha*, if force closure.
    pub limiting_facet: Option<usize>,
    /// Absolute tolerance used for the closure test.
    pub tolerance: Real,
}

/// An evaluation of no grasp (not force closure, no hull, no wrenches): where
/// [`GraspProblem::evaluate_in`] evaluates into.
impl Default for Evaluation {
    fn default() -> Self {
        Self::without_hull(Closure::OriginOutside, Vec::new(), 0.0)
    }
}

/// The buffers of [`GraspProblem::evaluate_in`], kept between evaluations.
#[derive(Default)]
pub struct EvaluationScratch {
    hull: HullScratch,
    /// A hull's buffers while the evaluation has none (degenerate).
    spare: Option<Hull>,
    /// The facets' directions `a_f / b_f` of alpha*.
    directions: Vec<Real>,
    order: Vec<(Real, u32)>,
    stack: Vec<(Real, u32)>,
}

impl std::fmt::Debug for EvaluationScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EvaluationScratch").finish_non_exhaustive()
    }
}

impl Evaluation {
    /// Whether the grasp is force closure.
    pub fn force_closure(&self) -> bool {
        self.closure == Closure::ForceClosure
    }
}

/// Per-object, per-contact-model data for grasp evaluation, computed once.
pub struct GraspProblem {
    frame: WrenchFrame,
    model: ContactModel,
    /// Object wrenches, `dim x m`, column-major (one column per facet).
    ows: Vec<Real>,
    ows_count: usize,
    tree: SupportTree,
    candidates: SurfaceSamples,
    /// The candidates' points, indexed for nearest-point queries.
    nearest: NearestPoints,
    /// Primitive wrenches of every candidate, `candidates x s x dim`.
    candidate_wrenches: Vec<Real>,
}

impl GraspProblem {
    /// Builds the problem from the object's facets (the OWS generators: every facet centre
    /// `l_k` with its outward normal `n_k`; their adjacency guides the support search) and the
    /// candidate contact points.
    pub fn new(
        facets: &SurfaceSamples,
        candidates: SurfaceSamples,
        frame: WrenchFrame,
        model: ContactModel,
    ) -> Result<Self, GraspError> {
        Self::new_with(facets, candidates, frame, model, &mut Silent)
    }

    /// [`GraspProblem::new`], reporting its stages to `progress` ([`Stage::Wrenches`],
    /// [`Stage::SupportTree`]).
    pub fn new_with(
        facets: &SurfaceSamples,
        candidates: SurfaceSamples,
        frame: WrenchFrame,
        model: ContactModel,
        progress: &mut dyn Progress,
    ) -> Result<Self, GraspError> {
        let (ows_points, ows_normals) = (&facets.points, &facets.normals);
        if ows_points.is_empty() || ows_points.len() != ows_normals.len() {
            return Err(GraspError::Empty { what: "facets" });
        }
        let n = candidates.points.len();
        if n == 0 {
            return Err(GraspError::Empty {
                what: "candidate contact points",
            });
        }
        if candidates.normals.len() != n || candidates.adjacency.len() != n {
            return Err(GraspError::CandidateLengths {
                points: n,
                normals: candidates.normals.len(),
                adjacency: candidates.adjacency.len(),
            });
        }
        let d = frame.dim();
        let m = ows_points.len();
        let total = m + n;
        progress.report(Stage::Wrenches, 0, total);
        let mut ows = vec![0.0; d * m];
        for (k, ((l, nk), col)) in ows_points
            .iter()
            .zip(ows_normals)
            .zip(ows.chunks_exact_mut(d))
            .enumerate()
        {
            tick(progress, Stage::Wrenches, k, total);
            frame.object_wrench(l, nk, col);
        }
        let s = model.edges();
        let mut candidate_wrenches = vec![0.0; n * s * d];
        for (i, ((p, nq), out)) in candidates
            .points
            .iter()
            .zip(&candidates.normals)
            .zip(candidate_wrenches.chunks_exact_mut(s * d))
            .enumerate()
        {
            tick(progress, Stage::Wrenches, m + i, total);
            frame.primitive_wrenches(p, nq, &model, out);
        }
        progress.report(Stage::Wrenches, total, total);
        if let Some(k) = ows.iter().position(|x| !x.is_finite()) {
            return Err(GraspError::NonFinite {
                what: "facet",
                index: k / d,
            });
        }
        if let Some(k) = candidate_wrenches.iter().position(|x| !x.is_finite()) {
            return Err(GraspError::NonFinite {
                what: "candidate",
                index: k / (s * d),
            });
        }
        let tree = SupportTree::new_with(&ows, d, |i| facets.adjacency.neighbours(i), progress);
        Ok(Self {
            frame,
            model,
            ows,
            ows_count: ows_points.len(),
            tree,
            nearest: NearestPoints::new(&candidates.points),
            candidates,
            candidate_wrenches,
        })
    }

    /// The wrench frame (centre, rho, space).
    pub fn frame(&self) -> &WrenchFrame {
        &self.frame
    }

    /// The contact model.
    pub fn model(&self) -> &ContactModel {
        &self.model
    }

    /// The wrench space.
    pub fn space(&self) -> Space {
        self.frame.space()
    }

    /// Dimension of the wrench space.
    pub fn dim(&self) -> usize {
        self.frame.dim()
    }

    /// The bounding-ellipsoid tree over the object wrenches.
    pub fn support_tree(&self) -> &SupportTree {
        &self.tree
    }

    /// The candidate contact points.
    pub fn candidates(&self) -> &SurfaceSamples {
        &self.candidates
    }

    /// The candidate nearest to `p` and its distance (as [`SurfaceSamples::nearest`], through
    /// a k-d tree: [`NearestPoints`]); `None` without candidates or if `p` is not finite.
    pub fn nearest_candidate(&self, p: &Vec3) -> Option<(usize, Real)> {
        self.nearest.nearest(p)
    }

    /// Number of OWS generators.
    pub fn ows_count(&self) -> usize {
        self.ows_count
    }

    /// OWS generator `k` (object wrench of facet `k`).
    pub fn ows_wrench(&self, k: usize) -> &[Real] {
        let d = self.dim();
        &self.ows[k * d..(k + 1) * d]
    }

    /// The `s` primitive wrenches of candidate `i` (`s x dim`, row-major).
    pub fn candidate_wrenches(&self, i: usize) -> &[Real] {
        let w = self.model.edges() * self.dim();
        &self.candidate_wrenches[i * w..(i + 1) * w]
    }

    fn check_contacts(&self, contacts: &[usize]) -> Result<(), GraspError> {
        if contacts.is_empty() {
            return Err(GraspError::NoContacts);
        }
        let count = self.candidates.points.len();
        match contacts.iter().enumerate().find(|(_, i)| **i >= count) {
            Some((contact, &index)) => Err(GraspError::ContactIndex {
                contact,
                index,
                count,
            }),
            None => Ok(()),
        }
    }

    /// Evaluates the grasp with one contact at each of the given candidates.
    pub fn evaluate(&self, contacts: &[usize]) -> Result<Evaluation, GraspError> {
        let mut e = Evaluation::default();
        self.evaluate_in(contacts, &mut e, &mut EvaluationScratch::default())?;
        Ok(e)
    }

    /// [`Self::evaluate`] into `e` (replaced; unspecified after an error), reusing its
    /// buffers and `scratch`'s: for a caller that evaluates grasp after grasp (the
    /// wrench-space node, once per contact set). Once they have met a grasp of the size, an
    /// evaluation allocates nothing (unless its hull falls back to Qhull; see
    /// [`Hull::of_contacts_in`]).
    pub fn evaluate_in(
        &self,
        contacts: &[usize],
        e: &mut Evaluation,
        scratch: &mut EvaluationScratch,
    ) -> Result<(), GraspError> {
        self.check_contacts(contacts)?;
        e.wrenches.clear();
        e.wrenches
            .reserve(contacts.len() * self.candidate_wrenches(0).len());
        for &c in contacts {
            e.wrenches.extend_from_slice(self.candidate_wrenches(c));
        }
        self.grade(e, scratch)
    }

    /// Evaluates the grasp with one contact at each of the given points (body frame) with
    /// the outward unit normal given beside it: the contacts where they are, not at a
    /// candidate (the cones built by the problem's frame and contact model, as a candidate's
    /// are). Errors as [`Self::evaluate_wrenches`], and [`GraspError::NoContacts`].
    pub fn evaluate_at(&self, contacts: &[(Vec3, Vec3)]) -> Result<Evaluation, GraspError> {
        let mut e = Evaluation::default();
        self.evaluate_at_in(contacts, &mut e, &mut EvaluationScratch::default())?;
        Ok(e)
    }

    /// [`Self::evaluate_at`] into `e` (replaced; unspecified after an error), reusing its
    /// buffers and `scratch`'s, as [`Self::evaluate_in`]: once they have met a grasp of the
    /// size, an evaluation allocates nothing (unless its hull falls back to Qhull).
    pub fn evaluate_at_in(
        &self,
        contacts: &[(Vec3, Vec3)],
        e: &mut Evaluation,
        scratch: &mut EvaluationScratch,
    ) -> Result<(), GraspError> {
        if contacts.is_empty() {
            return Err(GraspError::NoContacts);
        }
        let w = self.model.edges() * self.dim();
        e.wrenches.clear();
        e.wrenches.resize(contacts.len() * w, 0.0);
        for ((p, n), out) in contacts.iter().zip(e.wrenches.chunks_exact_mut(w)) {
            self.frame.primitive_wrenches(p, n, &self.model, out);
        }
        if let Some(k) = e.wrenches.iter().position(|x| !x.is_finite()) {
            return Err(GraspError::NonFinite {
                what: "contact",
                index: k / w,
            });
        }
        self.grade(e, scratch)
    }

    /// Evaluates the grasp whose primitive wrenches are given (row-major, `dim` per wrench).
    ///
    /// Errors: only when no hull can be built for a reason other than degeneracy (both hull
    /// implementations failed, or non-finite wrenches): that is not a grasp outcome, and no
    /// quality is reported for it.
    pub fn evaluate_wrenches(&self, wrenches: Vec<Real>) -> Result<Evaluation, GraspError> {
        let mut e = Evaluation::without_hull(Closure::OriginOutside, wrenches, 0.0);
        self.grade(&mut e, &mut EvaluationScratch::default())?;
        Ok(e)
    }

    /// Everything of `e` but its wrenches, from its wrenches.
    fn grade(&self, e: &mut Evaluation, scratch: &mut EvaluationScratch) -> Result<(), GraspError> {
        let d = self.dim();
        let scale = e.wrenches.iter().fold(0.0, |m: Real, x| m.max(x.abs()));
        e.tolerance = RELATIVE_TOLERANCE * scale.max(Real::MIN_POSITIVE);
        (e.quality, e.epsilon, e.limiting_facet) = (0.0, 0.0, None);
        let mut hull = e
            .hull
            .take()
            .or_else(|| scratch.spare.take())
            .unwrap_or_else(Hull::empty);
        match hull.of_contacts_in(&e.wrenches, d, self.model.edges(), &mut scratch.hull) {
            Ok(()) => {}
            Err(HullError::Degenerate { rank, .. }) => {
                scratch.spare = Some(hull);
                e.closure = Closure::Degenerate { rank };
                return Ok(());
            }
            Err(err) => {
                scratch.spare = Some(hull);
                return Err(GraspError::Hull(err));
            }
        }
        let b_min = hull
            .offsets()
            .iter()
            .copied()
            .fold(Real::INFINITY, Real::min);
        let tolerance = e.tolerance;
        (e.closure, e.epsilon) = if b_min > tolerance {
            (Closure::ForceClosure, b_min)
        } else if b_min >= -tolerance {
            (Closure::OriginOnBoundary, 0.0)
        } else {
            (Closure::OriginOutside, b_min)
        };
        if e.closure == Closure::ForceClosure {
            // alpha* = min_f b_f / h_f = 1 / max_{f,k} (a_f / b_f) . o_k.
            let g = &mut scratch.directions;
            g.clear();
            for (a, &b) in hull.normals().chunks_exact(d).zip(hull.offsets()) {
                let inv = 1.0 / b;
                g.extend(a.iter().map(|x| x * inv));
            }
            match self
                .tree
                .max_over(g, 0.0, &mut scratch.order, &mut scratch.stack)
            {
                Some((f, best)) => {
                    e.quality = 1.0 / best;
                    e.limiting_facet = Some(f);
                }
                // No facet direction reaches any object wrench: nothing limits the scale.
                None => e.quality = Real::INFINITY,
            }
        }
        e.hull = Some(hull);
        Ok(())
    }

    /// OWS support function `out[f] = max_k a_f . o_k` for the row-major directions `normals`
    /// (`out.len()` rows of `dim`), exact, by branch and bound over the OWS tree.
    pub fn support_function(&self, normals: &[Real], out: &mut [Real]) {
        self.tree
            .support_many(normals, out, &mut crate::support::SupportScratch::default());
    }

    /// The same support function as one blocked dense product `A O^T` through faer: every
    /// facet against every OWS point. The reference for [`Self::support_function`].
    pub fn support_function_dense(&self, normals: &[Real], out: &mut [Real]) {
        let d = self.dim();
        let rows = out.len();
        out.fill(Real::NEG_INFINITY);
        if rows == 0 {
            return;
        }
        let a = MatRef::from_row_major_slice(normals, rows, d);
        let mut scratch = vec![0.0; rows * BLOCK];
        let mut start = 0;
        while start < self.ows_count {
            let len = BLOCK.min(self.ows_count - start);
            let o =
                MatRef::from_column_major_slice(&self.ows[start * d..(start + len) * d], d, len);
            let dst = MatMut::from_column_major_slice_mut(&mut scratch[..rows * len], rows, len);
            faer::linalg::matmul::matmul(dst, Accum::Replace, a, o, 1.0, Par::Seq);
            for col in scratch[..rows * len].chunks_exact(rows) {
                for (m, &x) in out.iter_mut().zip(col) {
                    if x > *m {
                        *m = x;
                    }
                }
            }
            start += len;
        }
    }
}

impl Evaluation {
    fn without_hull(closure: Closure, wrenches: Vec<Real>, tolerance: Real) -> Self {
        Self {
            closure,
            quality: 0.0,
            epsilon: 0.0,
            hull: None,
            wrenches,
            limiting_facet: None,
            tolerance,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::object::Adjacency;

    /// Quasi-uniform points on a sphere (Fibonacci lattice), with their radial normals.
    pub(crate) fn fibonacci_sphere(count: usize, radius: Real) -> (Vec<Vec3>, Vec<Vec3>) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let normals: Vec<Vec3> = (0..count)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as Real + 0.5) / count as Real;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as Real;
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        (normals.iter().map(|n| n * radius).collect(), normals)
    }

    /// Samples with no neighbourhood graph.
    pub(crate) fn unconnected(points: Vec<Vec3>, normals: Vec<Vec3>) -> SurfaceSamples {
        let n = points.len();
        SurfaceSamples {
            points,
            normals,
            areas: vec![1.0; n],
            adjacency: Adjacency::from_lists(&vec![Vec::new(); n]),
        }
    }

    /// An equator ring of `count` points on a sphere, ring adjacency.
    pub(crate) fn ring(count: usize, radius: Real) -> SurfaceSamples {
        let normals: Vec<Vec3> = (0..count)
            .map(|k| {
                let t = std::f64::consts::TAU * k as Real / count as Real;
                Vec3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        let lists: Vec<Vec<u32>> = (0..count)
            .map(|k| vec![((k + count - 1) % count) as u32, ((k + 1) % count) as u32])
            .collect();
        SurfaceSamples {
            points: normals.iter().map(|n| n * radius).collect(),
            normals,
            areas: vec![std::f64::consts::TAU * radius / count as Real; count],
            adjacency: Adjacency::from_lists(&lists),
        }
    }

    pub(crate) fn planar_sphere_problem(mu: Real) -> GraspProblem {
        let r = 0.0475;
        let (pts, nrm) = fibonacci_sphere(2000, r);
        let frame = WrenchFrame::new(Vec3::zeros(), r, Space::Planar).unwrap();
        GraspProblem::new(
            &unconnected(pts, nrm),
            ring(72, r),
            frame,
            ContactModel::new(mu, 8).unwrap(),
        )
        .unwrap()
    }

    #[test]
    fn paper_grasp_is_not_force_closure_with_mu_003_but_is_with_mu_03() {
        // Contacts at 30, -30 and 140 degrees on the 72-point equator ring.
        let contacts = [6, 66, 28];
        let low = planar_sphere_problem(0.03).evaluate(&contacts).unwrap();
        assert!(!low.force_closure(), "{:?}", low.closure);
        assert_eq!(low.quality, 0.0);
        assert!(low.epsilon <= 0.0);
        let high = planar_sphere_problem(0.3).evaluate(&contacts).unwrap();
        assert!(high.force_closure());
        assert!(high.epsilon > 0.0);
        assert!(
            high.quality > 0.1 && high.quality < 1.0,
            "alpha* = {}",
            high.quality
        );
    }

    #[test]
    fn a_grasp_evaluated_at_its_candidates_points_is_the_candidates_grasp() {
        let p = planar_sphere_problem(0.3);
        let c = p.candidates();
        for contacts in [[6, 66, 28], [0, 24, 48], [1, 2, 3]] {
            let at: Vec<(Vec3, Vec3)> = contacts
                .iter()
                .map(|&i| (c.points[i], c.normals[i]))
                .collect();
            let (grid, exact) = (p.evaluate(&contacts).unwrap(), p.evaluate_at(&at).unwrap());
            assert_eq!(grid.closure, exact.closure, "{contacts:?}");
            assert_eq!(grid.quality, exact.quality, "{contacts:?}");
        }
        // Off the candidates: the first contact turned 2.3 deg along the equator.
        let turned = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), 0.04);
        let at = [
            (turned * c.points[6], turned * c.normals[6]),
            (c.points[66], c.normals[66]),
            (c.points[28], c.normals[28]),
        ];
        let (grid, exact) = (
            p.evaluate(&[6, 66, 28]).unwrap(),
            p.evaluate_at(&at).unwrap(),
        );
        assert!(exact.force_closure());
        assert_ne!(grid.quality, exact.quality);
        assert!(matches!(p.evaluate_at(&[]), Err(GraspError::NoContacts)));
    }

    #[test]
    fn alpha_star_with_a_round_ows_is_the_offset_over_the_force_norm() {
        // A sphere's planar OWS is (nearly) the unit disc in (f_x, f_y) with no torque, whose
        // support is |a_xy|: alpha* = min_f b_f / |a_f,xy| for three contacts 120 deg apart.
        let p = planar_sphere_problem(0.3);
        let e = p.evaluate(&[0, 24, 48]).unwrap();
        assert!(e.force_closure());
        let hull = e.hull.as_ref().unwrap();
        let expected = (0..hull.facet_count())
            .map(|f| {
                let a = hull.normal(f);
                hull.offsets()[f] / a[0].hypot(a[1])
            })
            .fold(Real::INFINITY, Real::min);
        // The Fibonacci OWS approximates the circle to within its sampling.
        assert!(
            (e.quality - expected).abs() / expected < 2e-3,
            "{} vs {}",
            e.quality,
            expected
        );
        // The reported limiting facet attains alpha*.
        let f = e.limiting_facet.unwrap();
        let mut h = [0.0];
        p.support_function(hull.normal(f), &mut h);
        assert!((hull.offsets()[f] / h[0] - e.quality).abs() <= 1e-12 * e.quality);
    }

    #[test]
    fn support_function_equals_brute_force() {
        let p = planar_sphere_problem(0.3);
        let dirs = [1.0, 0.0, 0.0, 0.0, -2.0, 0.5, 0.3, 0.3, 0.3];
        let (mut tree, mut dense) = ([0.0; 3], [0.0; 3]);
        p.support_function(&dirs, &mut tree);
        p.support_function_dense(&dirs, &mut dense);
        for (f, a) in dirs.chunks_exact(3).enumerate() {
            let brute = (0..p.ows_count())
                .map(|k| crate::hull::dot(a, p.ows_wrench(k)))
                .fold(Real::NEG_INFINITY, Real::max);
            assert!((tree[f] - brute).abs() < 1e-12);
            assert!((dense[f] - brute).abs() < 1e-12);
        }
    }

    #[test]
    fn alpha_star_by_the_tree_equals_the_dense_facet_formula() {
        for mu in [0.3, 0.8] {
            let p = planar_sphere_problem(mu);
            for contacts in [[6, 66, 28], [0, 24, 48], [3, 30, 50]] {
                let e = p.evaluate(&contacts).unwrap();
                let hull = e.hull.as_ref().unwrap();
                let mut h = vec![0.0; hull.facet_count()];
                p.support_function_dense(hull.normals(), &mut h);
                let dense = hull
                    .offsets()
                    .iter()
                    .zip(&h)
                    .filter(|(_, h)| **h > 0.0)
                    .map(|(b, h)| b / h)
                    .fold(Real::INFINITY, Real::min);
                let dense = if e.force_closure() { dense } else { 0.0 };
                assert!(
                    (e.quality - dense).abs() <= 1e-12 * dense.max(1.0),
                    "{} vs {dense}",
                    e.quality
                );
            }
        }
    }

    #[test]
    fn bad_contact_indices_are_errors() {
        let p = planar_sphere_problem(0.3);
        assert!(matches!(
            p.evaluate(&[0, 99]),
            Err(GraspError::ContactIndex {
                contact: 1,
                index: 99,
                count: 72
            })
        ));
        assert!(matches!(p.evaluate(&[]), Err(GraspError::NoContacts)));
    }

    #[test]
    fn two_contacts_in_6d_are_not_force_closure() {
        let r = 0.05;
        let (pts, nrm) = fibonacci_sphere(500, r);
        let cand = unconnected(pts, nrm);
        let frame = WrenchFrame::new(Vec3::zeros(), r, Space::Spatial).unwrap();
        let p = GraspProblem::new(
            &cand,
            cand.clone(),
            frame,
            ContactModel::new(0.5, 8).unwrap(),
        )
        .unwrap();
        let e = p.evaluate(&[0, 499]).unwrap();
        assert!(!e.force_closure());
        assert_eq!(e.quality, 0.0);
        assert!(e.epsilon <= 0.0);
    }

    /// Evaluating grasp after grasp in kept buffers (`evaluate_in`, as the wrench-space node
    /// does) gives, bit for bit, what a fresh evaluation gives: planar and spatial grasps of
    /// 1 to 9 contacts in random order (three contacts in 6D take the facet enumeration, more
    /// than 64 wrenches a builder of their own, one contact is degenerate), and bad input.
    #[test]
    fn evaluating_in_kept_buffers_gives_what_a_fresh_evaluation_gives() {
        let r = 0.05;
        let (pts, nrm) = fibonacci_sphere(400, r);
        let cand = unconnected(pts, nrm);
        let spatial = GraspProblem::new(
            &cand,
            cand.clone(),
            WrenchFrame::new(Vec3::zeros(), r, Space::Spatial).unwrap(),
            ContactModel::new(0.5, 8).unwrap(),
        )
        .unwrap();
        let planar = planar_sphere_problem(0.3);
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: usize| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % n as u64) as usize
        };
        for p in [&planar, &spatial] {
            let n = p.candidates().points.len();
            let mut kept = Evaluation::default();
            let mut scratch = EvaluationScratch::default();
            let mut closures = std::collections::BTreeSet::new();
            for round in 0..300 {
                let count = [3, 3, 3, 2, 4, 1, 9][round % 7];
                let contacts: Vec<usize> = (0..count).map(|_| next(n)).collect();
                let fresh = p.evaluate(&contacts).unwrap();
                p.evaluate_in(&contacts, &mut kept, &mut scratch).unwrap();
                let what = format!("round {round}, contacts {contacts:?}");
                assert_eq!(kept.closure, fresh.closure, "{what}");
                assert_eq!(kept.quality.to_bits(), fresh.quality.to_bits(), "{what}");
                assert_eq!(kept.epsilon.to_bits(), fresh.epsilon.to_bits(), "{what}");
                assert_eq!(
                    kept.tolerance.to_bits(),
                    fresh.tolerance.to_bits(),
                    "{what}"
                );
                assert_eq!(kept.limiting_facet, fresh.limiting_facet, "{what}");
                assert_eq!(kept.wrenches, fresh.wrenches, "{what}");
                assert_eq!(kept.hull, fresh.hull, "{what}");
                closures.insert(
                    format!("{:?}", fresh.closure)
                        .chars()
                        .take(8)
                        .collect::<String>(),
                );
            }
            // Each kind of outcome was met.
            assert!(closures.len() >= 3, "{closures:?}");
            assert!(matches!(
                p.evaluate_in(&[0, n], &mut kept, &mut scratch),
                Err(GraspError::ContactIndex { index, .. }) if index == n
            ));
            p.evaluate_in(&[0, n / 3, 2 * n / 3], &mut kept, &mut scratch)
                .unwrap();
            let fresh = p.evaluate(&[0, n / 3, 2 * n / 3]).unwrap();
            assert_eq!(kept.hull, fresh.hull);
        }
    }
}
