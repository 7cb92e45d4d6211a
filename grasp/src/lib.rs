//! # icrflow-grasp: the grasp-analysis core
//!
//! Pure mathematics for in-hand rolling with independent contact regions (ICRs) and a
//! guaranteed quality margin (the paper in `shared/paper/icr-inhand-rolling.md`, DESIGN.md
//! section 3). No IPC, no visualisation, no async runtime: the pipeline's nodes and the CLI
//! build on it.
//!
//! | module | what |
//! |---|---|
//! | [`object`] | objects: primitives and STL/OBJ meshes, validated; candidate points, normals, areas, neighbourhood graph, centre of mass, planar section |
//! | [`wrench`] | friction cones, primitive wrenches, object wrenches, planar and spatial spaces |
//! | [`hull`] | convex hulls in 3 and 6 dimensions (facet enumeration for three contacts in 6D; beneath-beyond; Qhull as fallback and reference), degenerate input as a status |
//! | [`quality`] | force closure, the quality alpha* (paper eq. 6) and the Ferrari-Canny epsilon |
//! | [`support`] | the OWS support function by branch and bound over a tree of bounding ellipsoids |
//! | [`lp`] | alpha* by ray-shooting linear programs (clarabel): the independent check |
//! | [`icr`] | independent contact regions with margin alpha (search zones + region growing) |
//! | [`progress`] | progress reports of the long operations on large meshes (loading, validation, problem building), for the caller to show |
//!
//! ## Conventions
//! - Units are SI. Everything is expressed in the object's body frame unless stated.
//! - Normals point **out** of the object. A contact force pushes in: cone edge `j` of `s` at
//!   a point with outward normal `n` is `f_j = -n + mu (cos(2 pi j/s) t1 + sin(2 pi j/s) t2)`
//!   (normal component one; tangent basis in [`wrench::tangent_basis`], fixed to the body).
//! - Wrenches are `w = [f; (p - c) x f / rho]`, `c` the centre of mass and `rho` the torque
//!   normalisation length, by default the object's largest distance from `c`
//!   ([`object::Object::max_radius`]). Planar problems use `(f_x, f_y, tau_z / rho)`, the
//!   projection of the 6D wrench, for grasp and object wrenches alike.
//! - The object wrench of facet `k` is `o_k = [n_k; (l_k - c) x n_k / rho]`; the OWS is
//!   `conv({0} U {o_k})`, used only through its support function, never as a hull.
//! - `H(GWS)` is the hull of the contacts' primitive wrenches; a hull facet is
//!   `a_f . w <= b_f` with `a_f` a unit outward normal. Force closure: full-dimensional and
//!   `min_f b_f > tol`. alpha* = `min_f b_f / h_f` over facets with `h_f > 0`, 0 unless
//!   force closure. epsilon = `min_f b_f` (0 on the boundary, negative outside).
//! - Tolerances: `tol = 1e-9 * max |w|` (component-wise maximum over the contacts'
//!   wrenches), used for the force-closure test and, subtracted from each threshold, for ICR
//!   membership ([`quality::RELATIVE_TOLERANCE`]). Hull and LP values of alpha* agree to
//!   1e-6 relative (tested); the ICR margin holds to 1e-9 relative (tested by sampling).

#![warn(missing_docs)]

pub mod hull;
pub mod icr;
pub mod lp;
pub mod math;
pub mod object;
pub mod progress;
pub mod quality;
pub mod support;
pub mod wrench;
