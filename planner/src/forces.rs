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
//! contacts cannot balance the load inside their cones) is a status the caller acts on
//! ([`ForceError::Infeasible`]), not a crash.

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

/// Why no forces were found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ForceError {
    /// The contacts cannot balance the load inside their friction cones with the minimum
    /// normal force.
    #[error("no balancing contact forces exist (solver status {status})")]
    Infeasible {
        /// The solver's status.
        status: String,
    },
    /// Bad input: no contacts, non-finite values, a zero normal, negative friction or force.
    #[error("bad force problem: {0}")]
    Input(String),
}

/// Solves for the fingertip forces (one per contact, in the contacts' frame) that balance
/// the external wrench `(force, torque)` about `centre`, inside cones of friction `mu`, each
/// with a normal component of at least `min_normal`.
pub fn balance(
    contacts: &[ForceContact],
    centre: &Vec3,
    mu: Real,
    min_normal: Real,
    external_force: &Vec3,
    external_torque: &Vec3,
) -> Result<Vec<Vec3>, ForceError> {
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
    if !finite(centre) || !finite(external_force) || !finite(external_torque) {
        return Err(ForceError::Input(
            "non-finite centre or external wrench".into(),
        ));
    }
    let mut inward = Vec::with_capacity(n);
    for (i, c) in contacts.iter().enumerate() {
        if !finite(&c.point) || !finite(&c.normal) || c.normal.norm() < 1e-9 {
            return Err(ForceError::Input(format!(
                "contact {i}: non-finite point or zero normal"
            )));
        }
        inward.push(-c.normal.normalize());
    }
    let nv = 3 * n;
    // Rows: 6 equilibrium (zero cone), n minimum-normal (nonnegative), 3n friction (SOC).
    let rows = 6 + n + 3 * n;
    let mut dense = vec![vec![0.0; nv]; rows];
    let mut b = vec![0.0; rows];
    for (i, c) in contacts.iter().enumerate() {
        let r = c.point - centre;
        for k in 0..3 {
            // Force balance: sum f = -F_ext.
            dense[k][3 * i + k] = 1.0;
            // Torque balance: sum r x f = -tau_ext; (r x f)_k = sum_j [r]x_{kj} f_j.
            let e = Vec3::ith(k, 1.0);
            let col = r.cross(&e); // r x e_k: column k of [r]x
            for (j, v) in col.iter().enumerate() {
                dense[3 + j][3 * i + k] = *v;
            }
        }
    }
    for k in 0..3 {
        b[k] = -external_force[k];
        b[3 + k] = -external_torque[k];
    }
    for (i, n_in) in inward.iter().enumerate() {
        // s = n_in . f - f_min >= 0  <=>  -n_in . f + s = -f_min.
        let row = 6 + i;
        for k in 0..3 {
            dense[row][3 * i + k] = -n_in[k];
        }
        b[row] = -min_normal;
        // s = (mu n_in . f, t1 . f, t2 . f) in SOC.
        let (t1, t2) = tangent_basis(&(-n_in));
        let base = 6 + n + 3 * i;
        for k in 0..3 {
            dense[base][3 * i + k] = -mu * n_in[k];
            dense[base + 1][3 * i + k] = -t1[k];
            dense[base + 2][3 * i + k] = -t2[k];
        }
    }
    let mut colptr = Vec::with_capacity(nv + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for col in 0..nv {
        for (r, row) in dense.iter().enumerate() {
            if row[col] != 0.0 {
                rowval.push(r);
                nzval.push(row[col]);
            }
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(rows, nv, colptr, rowval, nzval);
    // P = I (upper triangle), q = 0.
    let p = CscMatrix::new(nv, nv, (0..=nv).collect(), (0..nv).collect(), vec![1.0; nv]);
    let q = vec![0.0; nv];
    let mut cones = vec![
        SupportedConeT::ZeroConeT(6),
        SupportedConeT::NonnegativeConeT(n),
    ];
    cones.extend(std::iter::repeat_n(SupportedConeT::SecondOrderConeT(3), n));
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(100)
        .build()
        .map_err(|e| ForceError::Input(format!("solver settings: {e}")))?;
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
        .map_err(|e| ForceError::Input(format!("solver setup: {e}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(solver
            .solution
            .x
            .chunks_exact(3)
            .map(|f| Vec3::new(f[0], f[1], f[2]))
            .collect()),
        status => Err(ForceError::Infeasible {
            status: format!("{status:?}"),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let f = balance(&body, &zero, 0.3, 1.0, &zero, &zero).unwrap();
        for angle in [0.4_f64, 2.0, -1.3] {
            let rot = nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), angle);
            let turned: Vec<ForceContact> = body
                .iter()
                .map(|c| ForceContact {
                    point: rot * c.point,
                    normal: rot * c.normal,
                })
                .collect();
            let g = balance(&turned, &zero, 0.3, 1.0, &zero, &zero).unwrap();
            for (a, b) in f.iter().zip(&g) {
                assert!((rot * a - b).norm() < 1e-6, "{angle}: {a} turned vs {b}");
            }
        }
    }

    #[test]
    fn the_paper_grasp_balances_with_forces_inside_the_cones() {
        let c = ring(&[30.0, -30.0, 140.0], 0.0475);
        let (mu, fmin) = (0.3, 1.0);
        let f = balance(&c, &Vec3::zeros(), mu, fmin, &Vec3::zeros(), &Vec3::zeros()).unwrap();
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
        let e = balance(&c, &Vec3::zeros(), 0.3, 1.0, &Vec3::zeros(), &Vec3::zeros()).unwrap_err();
        assert!(matches!(e, ForceError::Infeasible { .. }), "{e}");
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

    #[test]
    fn gravity_is_carried_by_friction() {
        // Four contacts around the equator hold a 1 N weight with mu = 0.5.
        let c = ring(&[0.0, 90.0, 180.0, 270.0], 0.05);
        let weight = Vec3::new(0.0, 0.0, -1.0);
        let f = balance(&c, &Vec3::zeros(), 0.5, 0.1, &weight, &Vec3::zeros()).unwrap();
        let total: Vec3 = f.iter().sum::<Vec3>() + weight;
        assert!(total.norm() < 1e-6, "net force {total}");
        // Without friction nothing can carry a vertical load with horizontal contacts.
        assert!(matches!(
            balance(&c, &Vec3::zeros(), 0.0, 0.1, &weight, &Vec3::zeros()),
            Err(ForceError::Infeasible { .. })
        ));
    }
}
