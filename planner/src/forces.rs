//! Fingertip forces that balance the grasp (DESIGN.md section 3, "Grasp forces"): a small
//! second-order-cone program solved with clarabel.
//!
//! Unknowns: the force `f_i` each fingertip applies to the object (pushing in). Constraints:
//! - equilibrium: `sum f_i + F_ext = 0` and `sum (p_i - c) x f_i + tau_ext = 0`;
//! - the exact Coulomb cones `||f_i - (f_i . n_i) n_i|| <= mu (f_i . n_i)` with `n_i` the
//!   inward normal at contact `i` (second-order cones, which clarabel solves natively);
//! - a minimum normal force `f_i . n_i >= f_min`, so the object is squeezed.
//!
//! Objective: the least total squared force `sum ||f_i||^2`. An infeasible problem (the
//! contacts cannot balance the load inside their cones) is an outcome the caller acts on
//! ([`Balance::Infeasible`]), not an error and not a crash; [`ForceError`] is bad input.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use icrflow_grasp::math::{Real, Vec3};
use icrflow_grasp::wrench::tangent_basis;

/// One contact: where, and the object's outward normal there (any frame, the same for all).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceContact {
    /// Contact point.
    pub point: Vec3,
    /// Outward unit normal of the object.
    pub normal: Vec3,
}

/// What a force solve found: forces, or that none exist. Either is an expected outcome.
#[derive(Debug, Clone, PartialEq)]
pub enum Balance<T> {
    /// The balancing forces (for [`ForceSolver::solve`], `()`: they are in its buffer).
    Balanced(T),
    /// The contacts cannot balance the load inside their friction cones with the minimum
    /// normal force.
    Infeasible {
        /// The solver's status.
        status: String,
    },
}

impl<T> Balance<T> {
    /// The forces, if they exist.
    pub fn balanced(self) -> Option<T> {
        match self {
            Balance::Balanced(t) => Some(t),
            Balance::Infeasible { .. } => None,
        }
    }
}

impl<T> std::fmt::Display for Balance<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Balance::Balanced(_) => write!(f, "balanced"),
            Balance::Infeasible { status } => {
                write!(
                    f,
                    "no balancing contact forces exist (solver status {status})"
                )
            }
        }
    }
}

/// Why a force problem could not be posed: bad input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ForceError {
    /// Bad input: no contacts, non-finite values, a zero normal, negative friction or force.
    #[error("bad force problem: {0}")]
    Input(String),
}

/// Solves for the fingertip forces (one per contact, in the contacts' frame) that balance
/// the external wrench `(force, torque)` about `centre`, inside cones of friction `mu`, each
/// with a normal component of at least `min_normal`.
///
/// A one-off solve: a caller that solves again and again keeps a [`ForceSolver`], which
/// allocates only the first time it meets a number of contacts.
pub fn balance(
    contacts: &[ForceContact],
    centre: &Vec3,
    mu: Real,
    min_normal: Real,
    external_force: &Vec3,
    external_torque: &Vec3,
) -> Result<Balance<Vec<Vec3>>, ForceError> {
    let mut forces = Vec::with_capacity(contacts.len());
    let found = ForceSolver::new().solve(
        contacts,
        &Load {
            centre: *centre,
            force: *external_force,
            torque: *external_torque,
        },
        mu,
        min_normal,
        &mut forces,
    )?;
    Ok(match found {
        Balance::Balanced(()) => Balance::Balanced(forces),
        Balance::Infeasible { status } => Balance::Infeasible { status },
    })
}

/// The external load on the object: a force and a torque about `centre`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Load {
    /// The point torques are taken about (the contacts' frame).
    pub centre: Vec3,
    /// External force on the object.
    pub force: Vec3,
    /// External torque about `centre`.
    pub torque: Vec3,
}

impl Load {
    /// No load, torques about the origin.
    pub fn none() -> Self {
        Self {
            centre: Vec3::zeros(),
            force: Vec3::zeros(),
            torque: Vec3::zeros(),
        }
    }
}

/// Nonzeros per column of the constraint matrix: one force-balance row, two torque rows, the
/// minimum-normal row and the three rows of the friction cone.
const COLUMN_NONZEROS: usize = 7;

/// [`balance`] for a caller that solves repeatedly, as the hand command node does once per
/// contact set: it keeps one clarabel solver per number of contacts, built on the first
/// problem of that size, and afterwards only overwrites the constraint values (whose
/// sparsity pattern depends on the number of contacts alone) before solving. Solving again
/// then allocates once, inside clarabel 0.11 (its `solve` resets its timers, rebuilding one
/// map), where a fresh solver allocates about 130 times (`nodes/tests/alloc.rs` counts it).
///
/// The solver's equilibration (its diagonal scaling) stays that of the first problem of each
/// size: it only conditions the problem, the solution is that of the new data (the tests
/// compare it with a fresh solve).
#[derive(Default)]
pub struct ForceSolver {
    /// One solver per number of contacts, in the order they were first met.
    solvers: Vec<(usize, DefaultSolver<Real>)>,
    /// Scratch: the constraint matrix's values, column by column, and its right-hand side.
    values: Vec<Real>,
    rhs: Vec<Real>,
}

impl std::fmt::Debug for ForceSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ForceSolver")
            .field(
                "contact_counts",
                &self.solvers.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
            )
            .finish()
    }
}

impl ForceSolver {
    /// A solver with nothing built yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Solves the problem of [`balance`] and writes the forces, one per contact, into
    /// `forces` (cleared first; left empty unless balanced).
    pub fn solve(
        &mut self,
        contacts: &[ForceContact],
        load: &Load,
        mu: Real,
        min_normal: Real,
        forces: &mut Vec<Vec3>,
    ) -> Result<Balance<()>, ForceError> {
        forces.clear();
        let n = contacts.len();
        if n == 0 {
            return Err(ForceError::Input("no contacts".into()));
        }
        if !(mu.is_finite() && mu >= 0.0 && min_normal.is_finite() && min_normal >= 0.0) {
            return Err(ForceError::Input(format!(
                "friction {mu} and minimum normal force {min_normal} must be finite and >= 0"
            )));
        }
        let finite = |v: &Vec3| v.iter().all(|x| x.is_finite());
        if !finite(&load.centre) || !finite(&load.force) || !finite(&load.torque) {
            return Err(ForceError::Input(
                "non-finite centre or external wrench".into(),
            ));
        }
        for (i, c) in contacts.iter().enumerate() {
            if !finite(&c.point) || !finite(&c.normal) || c.normal.norm() < 1e-9 {
                return Err(ForceError::Input(format!(
                    "contact {i}: non-finite point or zero normal"
                )));
            }
        }
        self.fill(contacts, load, mu, min_normal);
        let solver = match self.solvers.iter().position(|(m, _)| *m == n) {
            Some(k) => {
                let solver = &mut self.solvers[k].1;
                solver
                    .update_A(&self.values)
                    .and_then(|()| solver.update_b(&self.rhs))
                    .map_err(|e| ForceError::Input(format!("solver update: {e}")))?;
                solver
            }
            None => {
                let solver = self.build(n)?;
                let k = self.solvers.len();
                self.solvers.push((n, solver));
                &mut self.solvers[k].1
            }
        };
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                forces.extend(
                    solver
                        .solution
                        .x
                        .chunks_exact(3)
                        .map(|f| Vec3::new(f[0], f[1], f[2])),
                );
                Ok(Balance::Balanced(()))
            }
            status => Ok(Balance::Infeasible {
                status: format!("{status:?}"),
            }),
        }
    }

    /// Writes the constraint matrix's values (column by column, rows ascending, the pattern
    /// of [`Self::build`]) and the right-hand side for these contacts.
    ///
    /// Rows: 6 equilibrium (zero cone), `n` minimum-normal (nonnegative), `3n` friction
    /// (second-order cones); column `3i + k` is component `k` of contact `i`'s force.
    fn fill(&mut self, contacts: &[ForceContact], load: &Load, mu: Real, min_normal: Real) {
        let n = contacts.len();
        self.values.clear();
        self.rhs.clear();
        self.rhs.resize(6 + 4 * n, 0.0);
        for k in 0..3 {
            // Force balance: sum f = -F_ext; torque balance: sum r x f = -tau_ext.
            self.rhs[k] = -load.force[k];
            self.rhs[3 + k] = -load.torque[k];
        }
        for (i, c) in contacts.iter().enumerate() {
            let n_in = -c.normal.normalize();
            let r = c.point - load.centre;
            // s = (mu n_in . f, t1 . f, t2 . f) in the second-order cone.
            let (t1, t2) = tangent_basis(&(-n_in));
            for k in 0..3 {
                self.values.push(1.0);
                // (r x f)_j = sum_k [r]x_{jk} f_k; column k of [r]x is r x e_k, whose k-th
                // entry is zero: the two rows j != k.
                let col = r.cross(&Vec3::ith(k, 1.0));
                for j in (0..3).filter(|&j| j != k) {
                    self.values.push(col[j]);
                }
                // s = n_in . f - f_min >= 0  <=>  -n_in . f + s = -f_min.
                self.values.push(-n_in[k]);
                self.values.push(-mu * n_in[k]);
                self.values.push(-t1[k]);
                self.values.push(-t2[k]);
            }
            self.rhs[6 + i] = -min_normal;
        }
    }

    /// A solver for `n` contacts on the values [`Self::fill`] just wrote.
    fn build(&self, n: usize) -> Result<DefaultSolver<Real>, ForceError> {
        let nv = 3 * n;
        let rows = 6 + 4 * n;
        let mut rowval = Vec::with_capacity(COLUMN_NONZEROS * nv);
        for i in 0..n {
            for k in 0..3 {
                rowval.push(k);
                rowval.extend((0..3).filter(|&j| j != k).map(|j| 3 + j));
                rowval.push(6 + i);
                rowval.extend([6 + n + 3 * i, 6 + n + 3 * i + 1, 6 + n + 3 * i + 2]);
            }
        }
        let colptr = (0..=nv).map(|c| COLUMN_NONZEROS * c).collect();
        let a = CscMatrix::new(rows, nv, colptr, rowval, self.values.clone());
        // P = I (upper triangle), q = 0.
        let p = CscMatrix::new(nv, nv, (0..=nv).collect(), (0..nv).collect(), vec![1.0; nv]);
        let q = vec![0.0; nv];
        let mut cones = vec![
            SupportedConeT::ZeroConeT(6),
            SupportedConeT::NonnegativeConeT(n),
        ];
        cones.extend(std::iter::repeat_n(SupportedConeT::SecondOrderConeT(3), n));
        // Presolve off and structural zeros kept: the data may then be overwritten.
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(100)
            .presolve_enable(false)
            .input_sparse_dropzeros(false)
            .build()
            .map_err(|e| ForceError::Input(format!("solver settings: {e}")))?;
        DefaultSolver::new(&p, &q, &a, &self.rhs, &cones, settings)
            .map_err(|e| ForceError::Input(format!("solver setup: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The forces of a solve that must balance.
    fn forces(found: Result<Balance<Vec<Vec3>>, ForceError>) -> Vec<Vec3> {
        match found {
            Ok(Balance::Balanced(f)) => f,
            other => panic!("expected forces: {other:?}"),
        }
    }

    fn ring(angles_deg: &[Real], r: Real) -> Vec<ForceContact> {
        angles_deg
            .iter()
            .map(|a| {
                let a = a.to_radians();
                let n = Vec3::new(a.cos(), a.sin(), 0.0);
                ForceContact {
                    point: r * n,
                    normal: n,
                }
            })
            .collect()
    }

    /// With no external load the forces turn with the grasp: the hand command node solves
    /// once per contact set in the object's frame and rotates the result.
    #[test]
    fn without_a_load_the_forces_rotate_with_the_contacts() {
        let body = ring(&[30.0, -30.0, 140.0], 0.0475);
        let zero = Vec3::zeros();
        let f = forces(balance(&body, &zero, 0.3, 1.0, &zero, &zero));
        for angle in [0.4_f64, 2.0, -1.3] {
            let rot = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), angle);
            let turned: Vec<ForceContact> = body
                .iter()
                .map(|c| ForceContact {
                    point: rot * c.point,
                    normal: rot * c.normal,
                })
                .collect();
            let g = forces(balance(&turned, &zero, 0.3, 1.0, &zero, &zero));
            for (a, b) in f.iter().zip(&g) {
                assert!((rot * a - b).norm() < 1e-6, "{angle}: {a} turned vs {b}");
            }
        }
    }

    #[test]
    fn the_paper_grasp_balances_with_forces_inside_the_cones() {
        let c = ring(&[30.0, -30.0, 140.0], 0.0475);
        let (mu, fmin) = (0.3, 1.0);
        let f = forces(balance(
            &c,
            &Vec3::zeros(),
            mu,
            fmin,
            &Vec3::zeros(),
            &Vec3::zeros(),
        ));
        let total: Vec3 = f.iter().sum();
        assert!(total.norm() < 1e-6, "net force {total}");
        let torque: Vec3 = c.iter().zip(&f).map(|(c, f)| c.point.cross(f)).sum();
        assert!(torque.norm() < 1e-7, "net torque {torque}");
        for (c, f) in c.iter().zip(&f) {
            let n_in = -c.normal;
            let fn_ = f.dot(&n_in);
            assert!(fn_ >= fmin - 1e-6, "normal force {fn_}");
            let ft = (f - fn_ * n_in).norm();
            assert!(ft <= mu * fn_ + 1e-6, "tangential {ft} > mu {}", mu * fn_);
        }
    }

    #[test]
    fn a_grasp_that_cannot_balance_is_infeasible_not_a_crash() {
        // Two contacts on the same side cannot squeeze the object.
        let c = ring(&[10.0, -10.0], 0.05);
        let e = balance(&c, &Vec3::zeros(), 0.3, 1.0, &Vec3::zeros(), &Vec3::zeros()).unwrap();
        assert!(matches!(e, Balance::Infeasible { .. }), "{e}");
        let e = balance(
            &[],
            &Vec3::zeros(),
            0.3,
            1.0,
            &Vec3::zeros(),
            &Vec3::zeros(),
        )
        .unwrap_err();
        assert!(matches!(e, ForceError::Input(_)));
        let mut bad = ring(&[0.0, 180.0], 0.05);
        bad[0].point.x = Real::NAN;
        assert!(matches!(
            balance(
                &bad,
                &Vec3::zeros(),
                0.3,
                1.0,
                &Vec3::zeros(),
                &Vec3::zeros()
            ),
            Err(ForceError::Input(_))
        ));
    }

    /// A kept solver, fed contact sets of changing sizes (one infeasible among them), finds
    /// what a fresh solve finds: overwriting the data keeps the first problem's scaling only.
    #[test]
    fn a_kept_solver_solves_each_new_contact_set_like_a_fresh_one() {
        let mut kept = ForceSolver::new();
        let mut forces = Vec::new();
        let sets: [&[Real]; 7] = [
            &[30.0, -30.0, 140.0],
            &[0.0, 90.0, 180.0, 270.0],
            &[35.0, -25.0, 150.0],
            &[10.0, -10.0], // one-sided: infeasible
            &[50.0, -80.0, 170.0],
            &[0.0, 180.0],
            &[20.0, 110.0, 200.0, 290.0],
        ];
        for (k, angles) in sets.iter().enumerate() {
            // The load and the minimum force change too: both are on the right-hand side.
            let weight = Vec3::new(0.0, 0.0, -0.3 - 0.1 * k as Real);
            let min_normal = 0.3 + 0.05 * k as Real;
            // Off-centre, tilted contacts so every structural entry is nonzero in some set.
            let tilt = nalgebra::Rotation3::from_euler_angles(0.1 * k as Real, -0.2, 0.05);
            let c: Vec<ForceContact> = ring(angles, 0.04 + 0.002 * k as Real)
                .into_iter()
                .map(|c| ForceContact {
                    point: tilt * c.point + Vec3::new(0.001, -0.002, 0.003),
                    normal: tilt * c.normal,
                })
                .collect();
            let load = Load {
                centre: Vec3::new(0.001, -0.002, 0.003),
                force: weight,
                torque: Vec3::new(0.0, 0.001, 0.0),
            };
            let fresh = balance(&c, &load.centre, 0.5, min_normal, &load.force, &load.torque);
            let again = kept.solve(&c, &load, 0.5, min_normal, &mut forces);
            match fresh.unwrap() {
                Balance::Balanced(f) => {
                    let again = again.unwrap_or_else(|e| panic!("set {k}: kept solver: {e}"));
                    assert_eq!(again, Balance::Balanced(()), "set {k}");
                    assert_eq!(forces.len(), f.len());
                    for (a, b) in f.iter().zip(&forces) {
                        assert!((a - b).norm() < 1e-6, "set {k}: fresh {a} vs kept {b}");
                    }
                }
                infeasible => {
                    assert!(
                        matches!(infeasible, Balance::Infeasible { .. }),
                        "set {k}: {infeasible}"
                    );
                    assert!(
                        matches!(again, Ok(Balance::Infeasible { .. })),
                        "set {k}: kept solver {again:?}"
                    );
                    assert!(forces.is_empty());
                }
            }
        }
        assert_eq!(
            format!("{kept:?}"),
            "ForceSolver { contact_counts: [3, 4, 2] }"
        );
    }

    #[test]
    fn gravity_is_carried_by_friction() {
        // Four contacts around the equator hold a 1 N weight with mu = 0.5.
        let c = ring(&[0.0, 90.0, 180.0, 270.0], 0.05);
        let weight = Vec3::new(0.0, 0.0, -1.0);
        let f = forces(balance(
            &c,
            &Vec3::zeros(),
            0.5,
            0.1,
            &weight,
            &Vec3::zeros(),
        ));
        let total: Vec3 = f.iter().sum::<Vec3>() + weight;
        assert!(total.norm() < 1e-6, "net force {total}");
        // Without friction nothing can carry a vertical load with horizontal contacts.
        assert!(matches!(
            balance(&c, &Vec3::zeros(), 0.0, 0.1, &weight, &Vec3::zeros()),
            Ok(Balance::Infeasible { .. })
        ));
    }
}
