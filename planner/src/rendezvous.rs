//! Rendezvous regions for finger switching (paper III-C, eq. 8; DESIGN.md section 3).
//!
//! Finger `k` of a grasp reaches its limit and a free finger must take over: where may the
//! free finger touch so that, with the remaining contacts, the grasp keeps the margin alpha?
//! Three answers are computed, all over every candidate point:
//!
//! - **exact** (brute force): the candidates `q` whose grasp with the remaining contacts has
//!   quality >= alpha, each evaluated from scratch. This is the ground truth, and the planner
//!   chooses the rendezvous point from it.
//! - **ICR** (zone rule): `q` can replace contact `k` by the zone rule of the ICRs (every
//!   search zone of `k` holds a wrench of `q`), i.e. `k`'s ICR without the connectivity
//!   requirement. Proven inside the exact region (`icrflow_grasp::icr`).
//! - **LP** (eq. 8): the zone rule with each search hyperplane replaced by the hyperplane of
//!   eq. 8: through the wrenches of the remaining contacts on the hull facet (`h . w_jr + d
//!   = 0`), tangent to the alpha-scaled OWS with every object wrench on the origin's side
//!   (`h . (alpha o_i) + d <= 0`, `d <= 0`), found by linear programming (clarabel). Eq. 8
//!   as printed is invariant under scaling `(h, d)`; we fix the scale by `h . a_f = 1`
//!   (`a_f` the facet's outward unit normal, so the hyperplane is the facet *pivoted* about
//!   the remaining contacts' wrenches) and, instead of the degenerate `max d`, pivot as far as
//!   the OWS allows away from contact `k`: maximise `t` with `h . w + d >= t` for every wrench
//!   `w` of contact `k` on the facet (a max-min over them: pivoting for one vertex alone
//!   recovers less, 28 % against 70 % of the exact region on random planar grasps in our
//!   prototype). A facet with no wrench of a remaining contact keeps its zone-rule
//!   hyperplane. The OWS constraints are added by cutting planes: solve with the few
//!   violated ones, scan every object wrench for the most violated, repeat.
//!
//! The LP region is not proven to lie inside the exact region; the tests check that it does
//! on every switch of the shipped scenarios and report how much of the exact region each
//! rule recovers. The planner never relies on it: its choice is from the exact region and is
//! verified again before the finger attaches.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use icrflow_grasp::hull::Hull;
use icrflow_grasp::math::Real;
use icrflow_grasp::quality::{GraspError, GraspProblem};
use rayon::prelude::*;

use crate::planner::QUALITY_SLACK;

/// The three rendezvous regions of one switch (candidate indices, ascending).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Regions {
    /// Brute force: quality with the remaining contacts >= alpha.
    pub exact: Vec<usize>,
    /// The zone rule of the ICRs.
    pub icr: Vec<usize>,
    /// The eq. (8) hyperplanes in the zone rule.
    pub lp: Vec<usize>,
    /// Linear programs solved (cutting-plane rounds included).
    pub lp_solves: usize,
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A half-space `h . w >= c`.
#[derive(Debug, Clone)]
struct Half {
    h: Vec<Real>,
    c: Real,
}

/// Computes the three regions for replacing contact `k` of the grasp `contacts` (candidate
/// indices) with margin `alpha`. Candidates already in use by the other contacts are left
/// out.
pub fn regions(
    problem: &GraspProblem,
    contacts: &[usize],
    k: usize,
    alpha: Real,
) -> Result<Regions, GraspError> {
    let n = problem.candidates().points.len();
    let occupied = |q: usize| contacts.iter().enumerate().any(|(i, &c)| i != k && c == q);
    let mut out = Regions::default();
    // Exact, by brute force: every candidate's grasp on every core (rayon), in order.
    let keeps: Vec<Result<bool, GraspError>> = (0..n)
        .into_par_iter()
        .filter(|&q| !occupied(q))
        .map_init(
            || contacts.to_vec(),
            |trial, q| {
                trial[k] = q;
                let e = problem.evaluate(trial)?;
                Ok(e.force_closure() && e.quality >= alpha * (1.0 - QUALITY_SLACK))
            },
        )
        .collect();
    for (q, keep) in (0..n).filter(|&q| !occupied(q)).zip(keeps) {
        if keep? {
            out.exact.push(q);
        }
    }
    let eval = problem.evaluate(contacts)?;
    let Some(hull) = eval.hull.as_ref().filter(|_| eval.force_closure()) else {
        return Ok(out);
    };
    if eval.quality < alpha {
        return Ok(out);
    }
    let (d, s) = (problem.dim(), problem.model().edges());
    let mut support = vec![0.0; hull.facet_count()];
    problem.support_function(hull.normals(), &mut support);
    let vertex_facets = hull.vertex_facets(contacts.len() * s);
    let own = k * s..(k + 1) * s;
    let wrench = |v: usize| &eval.wrenches[v * d..(v + 1) * d];
    // The pivoted hyperplane of each facet, computed once.
    let mut pivots: Vec<Option<Half>> = vec![None; hull.facet_count()];
    let mut zones: Vec<Vec<Half>> = Vec::new();
    let mut pivoted: Vec<Vec<Half>> = Vec::new();
    for facets in vertex_facets[own.clone()].iter().filter(|f| !f.is_empty()) {
        let mut zone = Vec::with_capacity(facets.len());
        let mut piv = Vec::with_capacity(facets.len());
        for &f in facets {
            let f = f as usize;
            let parallel = Half {
                h: hull.normal(f).to_vec(),
                c: alpha * support[f],
            };
            if pivots[f].is_none() {
                let (mine, remaining): (Vec<usize>, Vec<usize>) = hull
                    .facet_vertices(f)
                    .iter()
                    .map(|&v| v as usize)
                    .partition(|v| own.contains(v));
                let mine: Vec<&[Real]> = mine.into_iter().map(wrench).collect();
                let remaining: Vec<&[Real]> = remaining.into_iter().map(wrench).collect();
                pivots[f] = Some(if remaining.is_empty() {
                    parallel.clone()
                } else {
                    pivot(
                        problem,
                        hull,
                        f,
                        &mine,
                        &remaining,
                        alpha,
                        &mut out.lp_solves,
                    )
                    .unwrap_or_else(|| parallel.clone())
                });
            }
            #[expect(clippy::expect_used, reason = "pivots[f] is computed above")]
            piv.push(pivots[f].clone().expect("computed above"));
            zone.push(parallel);
        }
        zones.push(zone);
        pivoted.push(piv);
    }
    let inside = |q: usize, zones: &[Vec<Half>]| {
        let w = problem.candidate_wrenches(q);
        zones.iter().all(|zone| {
            (0..s).any(|j| {
                let wj = &w[j * d..(j + 1) * d];
                zone.iter()
                    .all(|half| dot(&half.h, wj) >= half.c - eval.tolerance)
            })
        })
    };
    for q in (0..n).filter(|&q| !occupied(q)) {
        if inside(q, &zones) {
            out.icr.push(q);
        }
        if inside(q, &pivoted) {
            out.lp.push(q);
        }
    }
    Ok(out)
}

/// The eq. (8) hyperplane of facet `f`: pivoted about the remaining contacts' wrenches on it,
/// away from contact `k`'s wrenches `mine` on it, until it touches the alpha-scaled OWS.
/// `None` if the LP fails or is unbounded.
fn pivot(
    problem: &GraspProblem,
    hull: &Hull,
    f: usize,
    mine: &[&[Real]],
    remaining: &[&[Real]],
    alpha: Real,
    solves: &mut usize,
) -> Option<Half> {
    const BOUND: Real = 1e6;
    const ROUNDS: usize = 60;
    let d = problem.dim();
    let a = hull.normal(f);
    let m = problem.ows_count();
    #[expect(clippy::expect_used, reason = "a grasp problem has object wrenches")]
    let scan = |h: &[Real]| {
        (0..m)
            .map(|i| (i, alpha * dot(h, problem.ows_wrench(i))))
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .expect("the OWS is not empty")
    };
    // Start with the object wrench that supports the facet's own normal.
    let mut active = vec![scan(a).0];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .max_iter(200)
        .build()
        .ok()?;
    for _ in 0..ROUNDS {
        // Variables x = [h_1..h_d, c, t] (c = -d of eq. 8). Maximise t.
        let nv = d + 2;
        let mut rows: Vec<Vec<Real>> = Vec::new();
        let mut b = Vec::new();
        // Zero cone: h . r - c = 0 for the remaining wrenches; h . a_f = 1.
        for r in remaining {
            let mut row: Vec<Real> = r.to_vec();
            row.extend([-1.0, 0.0]);
            rows.push(row);
            b.push(0.0);
        }
        let mut row = a.to_vec();
        row.extend([0.0, 0.0]);
        rows.push(row);
        b.push(1.0);
        let zeros = rows.len();
        // Nonnegative cone (s = b - A x >= 0): alpha h . o_i - c <= 0; t - h . w + c <= 0
        // for k's wrenches w on the facet; -c <= 0; -BOUND <= h_j <= BOUND.
        for &i in &active {
            let mut row: Vec<Real> = problem.ows_wrench(i).iter().map(|x| alpha * x).collect();
            row.extend([-1.0, 0.0]);
            rows.push(row);
            b.push(0.0);
        }
        for w in mine {
            let mut row: Vec<Real> = w.iter().map(|x| -x).collect();
            row.extend([1.0, 1.0]);
            rows.push(row);
            b.push(0.0);
        }
        let mut row = vec![0.0; nv];
        row[d] = -1.0;
        rows.push(row);
        b.push(0.0);
        for j in 0..d {
            for sign in [1.0, -1.0] {
                let mut row = vec![0.0; nv];
                row[j] = sign;
                rows.push(row);
                b.push(BOUND);
            }
        }
        let total = rows.len();
        // Column-major sparse A.
        let mut colptr = Vec::with_capacity(nv + 1);
        let mut rowval = Vec::new();
        let mut nzval = Vec::new();
        colptr.push(0);
        for col in 0..nv {
            for (r, row) in rows.iter().enumerate() {
                if row[col] != 0.0 {
                    rowval.push(r);
                    nzval.push(row[col]);
                }
            }
            colptr.push(rowval.len());
        }
        let amat = CscMatrix::new(total, nv, colptr, rowval, nzval);
        let p = CscMatrix::new(nv, nv, vec![0; nv + 1], Vec::new(), Vec::new());
        let mut q = vec![0.0; nv];
        q[d + 1] = -1.0;
        let cones = [
            SupportedConeT::ZeroConeT(zeros),
            SupportedConeT::NonnegativeConeT(total - zeros),
        ];
        let mut solver = DefaultSolver::new(&p, &q, &amat, &b, &cones, settings.clone()).ok()?;
        solver.solve();
        *solves += 1;
        if solver.solution.status != SolverStatus::Solved {
            return None;
        }
        let x = &solver.solution.x;
        let h = x[..d].to_vec();
        let c = x[d];
        if h.iter().any(|v| v.abs() > 0.5 * BOUND) {
            return None;
        }
        let (worst, value) = scan(&h);
        let scale = h.iter().fold(0.0, |m: Real, v| m.max(v.abs())).max(1.0);
        if value <= c + 1e-10 * scale {
            // Every object wrench is on the origin's side: the hyperplane of eq. 8. Any
            // remaining violation below the tolerance is absorbed by raising c to the true
            // support, which only shrinks the region.
            return Some(Half { h, c: c.max(value) });
        }
        if active.contains(&worst) {
            return None;
        }
        active.push(worst);
    }
    None
}
