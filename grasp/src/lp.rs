//! An independent second method for alpha*: ray shooting by linear programming (clarabel).
//!
//! alpha* = min_k t_k with `t_k = max { t : t o_k in H(GWS) }`, where
//! `H(GWS) = conv({0} U {w_ij})` is written through its generators, not its facets:
//! `t o_k = sum_j lambda_j w_j`, `lambda >= 0`, `sum_j lambda_j <= 1`. No convex hull is
//! involved, so agreement with [`crate::quality`] checks the hull, the facet formula and the
//! support function together. One small LP per OWS generator: meant for tests, not hot paths.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};

use crate::math::Real;

/// Why the LP method gave no answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LpError {
    /// The solver could not be set up (its message is kept).
    #[error("clarabel setup failed: {message}")]
    Setup {
        /// The solver's message.
        message: String,
    },
    /// The solver stopped without an optimal solution.
    #[error("clarabel stopped with status {status} on OWS generator {index}")]
    NotSolved {
        /// The generator whose ray was being shot.
        index: usize,
        /// The solver's status.
        status: String,
    },
}

/// alpha* by ray shooting: `min_k max { t : t o_k in conv({0} U wrenches) }`.
///
/// `wrenches` and `ows` are row-major with `dim` coordinates per wrench. Generators with a
/// zero wrench are skipped (their ray never leaves the hull). Returns `+inf` when no
/// generator is nonzero.
pub fn quality_by_lp(wrenches: &[Real], ows: &[Real], dim: usize) -> Result<Real, LpError> {
    let n = wrenches.len() / dim;
    // Variables x = [t, lambda_1..lambda_n]; minimise -t.
    // Rows: dim equalities  t o_k - W lambda = 0             (zero cone)
    //       1 row           sum lambda <= 1                  (nonnegative cone)
    //       n + 1 rows      -lambda_j <= 0, -t <= 0           (nonnegative cone)
    let rows = dim + 1 + n + 1;
    let q: Vec<Real> = std::iter::once(-1.0)
        .chain(std::iter::repeat_n(0.0, n))
        .collect();
    let mut b = vec![0.0; rows];
    b[dim] = 1.0;
    let cones = [
        SupportedConeT::ZeroConeT(dim),
        SupportedConeT::NonnegativeConeT(n + 2),
    ];
    let p = CscMatrix::new(n + 1, n + 1, vec![0; n + 2], Vec::new(), Vec::new());
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        // Where clarabel stops short of 1e-12 (its `AlmostSolved`), 1e-9 is still three orders
        // finer than any comparison made with this reference; taken as a solution.
        .reduced_tol_gap_abs(1e-9)
        .reduced_tol_gap_rel(1e-9)
        .reduced_tol_feas(1e-9)
        .max_iter(200)
        .build()
        .map_err(|e| LpError::Setup {
            message: e.to_string(),
        })?;
    let mut best = Real::INFINITY;
    for (index, o) in ows.chunks_exact(dim).enumerate() {
        if o.iter().all(|x| *x == 0.0) {
            continue;
        }
        // Column-major A: column 0 is t, column 1 + j is lambda_j.
        let mut colptr = Vec::with_capacity(n + 2);
        let mut rowval = Vec::new();
        let mut nzval = Vec::new();
        colptr.push(0);
        for (r, &x) in o.iter().enumerate() {
            if x != 0.0 {
                rowval.push(r);
                nzval.push(x);
            }
        }
        rowval.push(dim + 1 + n);
        nzval.push(-1.0);
        colptr.push(rowval.len());
        for (j, w) in wrenches.chunks_exact(dim).enumerate() {
            for (r, &x) in w.iter().enumerate() {
                if x != 0.0 {
                    rowval.push(r);
                    nzval.push(-x);
                }
            }
            rowval.push(dim);
            nzval.push(1.0);
            rowval.push(dim + 1 + j);
            nzval.push(-1.0);
            colptr.push(rowval.len());
        }
        let a = CscMatrix::new(rows, n + 1, colptr, rowval, nzval);
        let mut solver =
            DefaultSolver::new(&p, &q, &a, &b, &cones, settings.clone()).map_err(|e| {
                LpError::Setup {
                    message: e.to_string(),
                }
            })?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                best = best.min(solver.solution.x[0])
            }
            status => {
                return Err(LpError::NotSolved {
                    index,
                    status: format!("{status:?}"),
                });
            }
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_cross_polytope_against_a_box() {
        // Wrenches: +-e_i in R^3 (the cross-polytope |x|_1 <= 1). Ray along (1,1,1)/3 leaves
        // it at t = 1; along e_1 at t = 1.
        let w = [
            1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
            -1.0,
        ];
        let t = quality_by_lp(&w, &[1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 3).unwrap();
        assert!((t - 1.0).abs() < 1e-8, "{t}");
        let t = quality_by_lp(&w, &[0.5, 0.0, 0.0, 0.0, 0.0, 0.25], 3).unwrap();
        assert!((t - 2.0).abs() < 1e-8, "{t}");
    }

    #[test]
    fn agrees_with_the_hull_on_the_paper_grasp() {
        let p = crate::quality::tests::planar_sphere_problem(0.3);
        let e = p.evaluate(&[6, 66, 28]).unwrap();
        let ows: Vec<Real> = (0..p.ows_count())
            .flat_map(|k| p.ows_wrench(k).to_vec())
            .collect();
        let t = quality_by_lp(&e.wrenches, &ows, 3).unwrap();
        assert!(
            (t - e.quality).abs() <= 1e-6 * e.quality,
            "lp {t} hull {}",
            e.quality
        );
    }
}
