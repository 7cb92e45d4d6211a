//! Friction cones, primitive wrenches and object wrenches (DESIGN.md section 3).
//!
//! Conventions, shared with the Python reference `bench/reference_qhull.py`:
//! - a wrench is `w = [f; (p - c) x f / rho]` in R^6, `c` the centre of mass and `rho`
//!   the torque normalisation length, so forces and torques are comparable;
//! - the contact force of cone edge `j` at a point with outward unit normal `n` is
//!   `f_j = -n + mu (cos(2 pi j / s) t1 + sin(2 pi j / s) t2)` (not normalised: its normal
//!   component is one), with the tangent basis of [`tangent_basis_about`] (`t1 = axis x n`
//!   normalised, the frame's tangent axis `+z` unless set);
//! - the tangent basis belongs to the object: for an object at orientation `R` it is `R` times
//!   the basis of the body-frame normal `R^T n`, so a rigid motion of the object with its
//!   contacts leaves every wrench's geometry, and alpha*, unchanged;
//! - the object wrench of facet `k` is `o_k = [n_k; (l_k - c) x n_k / rho]`;
//! - the planar space is the projection of R^6 onto `(f_x, f_y, tau_z / rho)`, for the
//!   primitive and the object wrenches alike (so `s` keeps its meaning in the plane: with an
//!   even `s` the projected cone's extreme edges are exactly `-n +- mu t1`).

use crate::math::{Real, UnitQuaternion, Vec3};

/// The wrench space a grasp is analysed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Space {
    /// The reduced space `(f_x, f_y, tau_z / rho)` of a hand moving in a horizontal plane.
    Planar,
    /// The full space `(f, tau / rho)` in R^6.
    Spatial,
}

impl Space {
    /// Dimension of the wrench space.
    pub const fn dim(self) -> usize {
        match self {
            Space::Planar => 3,
            Space::Spatial => 6,
        }
    }

    /// Components of the 6D wrench kept by this space.
    pub const fn components(self) -> &'static [usize] {
        match self {
            Space::Planar => &[0, 1, 5],
            Space::Spatial => &[0, 1, 2, 3, 4, 5],
        }
    }

    /// The name used in configs and JSON output.
    pub const fn name(self) -> &'static str {
        match self {
            Space::Planar => "planar",
            Space::Spatial => "spatial",
        }
    }
}

/// Errors in the parameters of a contact model or wrench frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum WrenchError {
    /// The friction coefficient is negative or not finite.
    #[error("friction coefficient must be finite and >= 0, got {mu}")]
    Friction {
        /// The value given.
        mu: Real,
    },
    /// Too few or too many edges to linearise a friction cone.
    #[error("a linearised friction cone needs 3 to {MAX_CONE_EDGES} edges, got {edges}")]
    ConeEdges {
        /// The value given.
        edges: usize,
    },
    /// The tangent rule's axis is not a finite, non-zero vector.
    #[error("the friction cones' tangent axis must be a finite, non-zero vector, got {axis:?}")]
    TangentAxis {
        /// The value given.
        axis: [Real; 3],
    },
    /// The torque normalisation length is not positive and finite.
    #[error("torque normalisation length rho must be finite and > 0, got {rho}")]
    Rho {
        /// The value given.
        rho: Real,
    },
}

/// Most edges a linearised friction cone may have: beyond this the pyramid is within 0.1% of
/// the cone, and hull sizes grow with no gain.
pub const MAX_CONE_EDGES: usize = 64;

/// Point contact with Coulomb friction, the cone linearised with `edges` edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactModel {
    mu: Real,
    edges: usize,
}

impl ContactModel {
    /// A validated contact model.
    pub fn new(mu: Real, edges: usize) -> Result<Self, WrenchError> {
        if !mu.is_finite() || mu < 0.0 {
            return Err(WrenchError::Friction { mu });
        }
        if !(3..=MAX_CONE_EDGES).contains(&edges) {
            return Err(WrenchError::ConeEdges { edges });
        }
        Ok(Self { mu, edges })
    }

    /// Friction coefficient.
    pub fn mu(&self) -> Real {
        self.mu
    }

    /// Number of cone edges `s`.
    pub fn edges(&self) -> usize {
        self.edges
    }
}

/// Below this `|axis x n|` a normal counts as at a pole of the tangent rule
/// ([`tangent_basis_about`]).
pub const POLE: Real = 1e-6;

/// Tangent basis `(t1, t2)` at a point with outward unit normal `n` for the tangent axis `+z`
/// ([`tangent_basis_about`]): for a normal in the horizontal plane `t1` is the in-plane
/// tangent, counter-clockwise seen from +z.
pub fn tangent_basis(n: &Vec3) -> (Vec3, Vec3) {
    tangent_basis_about(&Vec3::z(), n)
}

/// Tangent basis `(t1, t2)` at a point with outward unit normal `n`, for the unit tangent axis
/// `axis`: `t1 = axis x n` normalised, `t2 = n x t1`; at the poles of the rule (`|axis x n| <
/// POLE`, the normal along the axis) `t1 = r x n` normalised, `r` the coordinate axis least
/// aligned with `axis` (for `+z`, `ex`).
///
/// The basis turns smoothly with the normal everywhere but at the two poles. For an object
/// turned about `axis`, a rolling contact circles the poles and never crosses them, so its
/// linearised cone turns smoothly along its path. (Until session 18 the rule was `ez x n`
/// below `|n_z| = 0.9` and `ex x n` above: at that seam a contact's cone turned abruptly, and
/// a grasp's alpha* jumped, up to 7 times between the two bases in an independent check. The
/// cones are inscribed in the exact ones in any basis, so the seam cost smoothness and region
/// size, not safety.)
pub fn tangent_basis_about(axis: &Vec3, n: &Vec3) -> (Vec3, Vec3) {
    let t = axis.cross(n);
    let t1 = if t.norm() >= POLE {
        t.normalize()
    } else {
        let (x, y, z) = (axis.x.abs(), axis.y.abs(), axis.z.abs());
        let r = if x <= y && x <= z {
            Vec3::x()
        } else if y <= z {
            Vec3::y()
        } else {
            Vec3::z()
        };
        r.cross(n).normalize()
    };
    let t2 = n.cross(&t1);
    (t1, t2)
}

/// The frame wrenches are expressed in: centre of mass, torque normalisation, space, and the
/// body-frame axis of the cones' tangent rule ([`tangent_basis_about`]; `+z` unless
/// [`WrenchFrame::with_tangent_axis`] says).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrenchFrame {
    centre: Vec3,
    rho: Real,
    space: Space,
    orientation: UnitQuaternion,
    tangent_axis: Vec3,
}

impl WrenchFrame {
    /// A validated frame.
    pub fn new(centre: Vec3, rho: Real, space: Space) -> Result<Self, WrenchError> {
        if !rho.is_finite() || rho <= 0.0 {
            return Err(WrenchError::Rho { rho });
        }
        Ok(Self {
            centre,
            rho,
            space,
            orientation: UnitQuaternion::identity(),
            tangent_axis: Vec3::z(),
        })
    }

    /// The same frame with the cones' tangent rule about `axis` (body frame, normalised): the
    /// axis the object is turned about, so that rolling contacts' cones turn smoothly.
    pub fn with_tangent_axis(mut self, axis: Vec3) -> Result<Self, WrenchError> {
        let norm = axis.norm();
        if !norm.is_finite() || norm < POLE {
            return Err(WrenchError::TangentAxis {
                axis: [axis.x, axis.y, axis.z],
            });
        }
        self.tangent_axis = axis / norm;
        Ok(self)
    }

    /// The body-frame axis of the cones' tangent rule.
    pub fn tangent_axis(&self) -> Vec3 {
        self.tangent_axis
    }

    /// The same frame for an object at `orientation` (body to this frame): cone tangents are
    /// taken in the body frame and rotated with it.
    pub fn with_orientation(mut self, orientation: UnitQuaternion) -> Self {
        self.orientation = orientation;
        self
    }

    /// The object's orientation in this frame.
    pub fn orientation(&self) -> UnitQuaternion {
        self.orientation
    }

    /// Centre of mass the torques are taken about.
    pub fn centre(&self) -> Vec3 {
        self.centre
    }

    /// Torque normalisation length.
    pub fn rho(&self) -> Real {
        self.rho
    }

    /// The wrench space.
    pub fn space(&self) -> Space {
        self.space
    }

    /// Dimension of the wrench space.
    pub fn dim(&self) -> usize {
        self.space.dim()
    }

    /// Writes the wrench of force `f` applied at `p` into `out` (length [`Self::dim`]).
    pub fn wrench(&self, p: &Vec3, f: &Vec3, out: &mut [Real]) {
        let tau = (p - self.centre).cross(f) / self.rho;
        let full = [f.x, f.y, f.z, tau.x, tau.y, tau.z];
        for (o, &c) in out.iter_mut().zip(self.space.components()) {
            *o = full[c];
        }
    }

    /// Writes the `s` primitive wrenches of a contact at `p` with outward normal `n` into
    /// `out` (length `s * dim`, edge-major).
    pub fn primitive_wrenches(&self, p: &Vec3, n: &Vec3, model: &ContactModel, out: &mut [Real]) {
        let d = self.dim();
        let s = model.edges;
        let (t1, t2) = tangent_basis_about(&self.tangent_axis, &(self.orientation.inverse() * n));
        let (t1, t2) = (self.orientation * t1, self.orientation * t2);
        for (j, row) in out.chunks_exact_mut(d).take(s).enumerate() {
            let phi = std::f64::consts::TAU * j as Real / s as Real;
            let f = -n + model.mu * (phi.cos() * t1 + phi.sin() * t2);
            self.wrench(p, &f, row);
        }
    }

    /// Writes the object wrench `o = [n; (l - c) x n / rho]` of a unit push along the outward
    /// normal `n` at `l` into `out` (length [`Self::dim`]).
    pub fn object_wrench(&self, l: &Vec3, n: &Vec3, out: &mut [Real]) {
        self.wrench(l, n, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangent_basis_is_orthonormal_and_right_handed() {
        for n in [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.3, -0.4, 0.866).normalize(),
            Vec3::new(0.0, 0.0, -1.0),
        ] {
            let (t1, t2) = tangent_basis(&n);
            assert!((t1.norm() - 1.0).abs() < 1e-12);
            assert!((t2.norm() - 1.0).abs() < 1e-12);
            assert!(t1.dot(&n).abs() < 1e-12 && t2.dot(&n).abs() < 1e-12);
            assert!((t1.cross(&t2) - n).norm() < 1e-12);
        }
    }

    /// About any axis: orthonormal and right-handed everywhere, the poles included; `t1` is
    /// along `axis x n` off the poles; about `+z` at the poles it is `ex x n` (the old rule's
    /// there, so axis-aligned faces keep their cones); a zero axis is refused.
    #[test]
    fn the_basis_about_an_axis_is_orthonormal_and_follows_the_axis() {
        let axes = [
            Vec3::z(),
            Vec3::new(-0.5, 0.866, 0.0).normalize(),
            Vec3::new(0.2, -0.3, 0.93).normalize(),
        ];
        for axis in axes {
            for n in [
                axis,
                -axis,
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.3, -0.4, 0.866).normalize(),
                (axis + Vec3::new(1e-8, 0.0, 0.0)).normalize(),
            ] {
                let (t1, t2) = tangent_basis_about(&axis, &n);
                assert!((t1.norm() - 1.0).abs() < 1e-9 && (t2.norm() - 1.0).abs() < 1e-9);
                assert!(t1.dot(&n).abs() < 1e-9 && t2.dot(&n).abs() < 1e-9);
                assert!((t1.cross(&t2) - n).norm() < 1e-9);
                let t = axis.cross(&n);
                if t.norm() >= POLE {
                    assert!((t1 - t.normalize()).norm() < 1e-12);
                }
            }
        }
        let (t1, _) = tangent_basis(&Vec3::z());
        assert!((t1 - Vec3::x().cross(&Vec3::z())).norm() < 1e-12);
        let frame = WrenchFrame::new(Vec3::zeros(), 1.0, Space::Spatial).unwrap();
        assert_eq!(frame.tangent_axis(), Vec3::z());
        let e = frame
            .with_tangent_axis(Vec3::zeros())
            .unwrap_err()
            .to_string();
        assert!(e.contains("tangent axis"), "{e}");
        let turned = frame.with_tangent_axis(Vec3::new(0.0, 2.0, 0.0)).unwrap();
        assert_eq!(turned.tangent_axis(), Vec3::y());
    }

    #[test]
    fn cone_edges_make_the_friction_angle_with_the_inward_normal() {
        let frame = WrenchFrame::new(Vec3::zeros(), 1.0, Space::Spatial).unwrap();
        let model = ContactModel::new(0.3, 8).unwrap();
        let n = Vec3::new(0.0, 1.0, 0.0);
        let mut w = vec![0.0; 8 * 6];
        frame.primitive_wrenches(&Vec3::new(0.0, 2.0, 0.0), &n, &model, &mut w);
        for row in w.chunks_exact(6) {
            let f = Vec3::new(row[0], row[1], row[2]);
            // Normal component pushes into the object, tangential part has length mu.
            assert!((f.dot(&-n) - 1.0).abs() < 1e-12);
            assert!(((f + n).norm() - 0.3).abs() < 1e-12);
            // Torque about the centre is p x f.
            let tau = Vec3::new(0.0, 2.0, 0.0).cross(&f);
            assert!((Vec3::new(row[3], row[4], row[5]) - tau).norm() < 1e-12);
        }
    }

    #[test]
    fn planar_projection_keeps_fx_fy_tauz() {
        let frame = WrenchFrame::new(Vec3::zeros(), 0.5, Space::Planar).unwrap();
        let mut w = [0.0; 3];
        frame.wrench(&Vec3::new(1.0, 0.0, 0.0), &Vec3::new(0.0, 2.0, 7.0), &mut w);
        // tau = (1,0,0) x (0,2,7) = (0,-7,2); tau_z / rho = 4.
        assert_eq!(w, [0.0, 2.0, 4.0]);
    }

    #[test]
    fn bad_parameters_are_named() {
        assert_eq!(
            ContactModel::new(-0.1, 8),
            Err(WrenchError::Friction { mu: -0.1 })
        );
        assert_eq!(
            ContactModel::new(0.3, 2),
            Err(WrenchError::ConeEdges { edges: 2 })
        );
        assert!(ContactModel::new(Real::NAN, 8).is_err());
        assert!(WrenchFrame::new(Vec3::zeros(), 0.0, Space::Planar).is_err());
    }
}
