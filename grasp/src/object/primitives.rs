//! Analytic primitives, discretised into closed polygon meshes with analytic sections.

use std::f64::consts::TAU;

use super::Object;
use super::error::ObjectError;
use super::samples::{Section, SurfaceSamples, loop_adjacency, polar_angle, wrap_angle};
use super::validate::assemble;
use crate::math::{Real, Vec3};

/// The largest number of faces a primitive may have.
const MAX_FACES: usize = 1 << 24;

impl Object {
    /// A UV sphere of `radius` centred at the origin, with exactly
    /// `longitude_segments x latitude_segments` faces (the paper's is 72 x 72 = 5184).
    ///
    /// Latitude bands are equally spaced in polar angle between the poles; each band has
    /// `longitude_segments` faces, triangles in the two pole bands and planar quads elsewhere.
    /// Longitude 0 is at +x and increases counter-clockwise seen from +z, so with an even
    /// `latitude_segments` the equator is a ring of vertices at longitudes
    /// `2 pi k / longitude_segments`.
    ///
    /// Section: the `longitude_segments` points of the equator circle at angles exactly
    /// `2 pi k / n` (the stored `angles` are these values), radius `radius`, radial normals,
    /// each standing for an arc of `2 pi radius / n`. With an even `latitude_segments` these
    /// are mesh vertices; with an odd one they lie on the exact sphere, just outside the mesh
    /// (whose equator is then mid-band). The centre of mass is exactly the
    /// origin (the mesh is symmetric); the volume is the mesh's.
    ///
    /// Errors: `radius` not positive and finite, `longitude_segments < 3`,
    /// `latitude_segments < 2`, or more than 2^24 faces.
    pub fn sphere(
        radius: Real,
        longitude_segments: usize,
        latitude_segments: usize,
    ) -> Result<Object, ObjectError> {
        check_dimension("radius", radius)?;
        uv_ellipsoid(
            "sphere",
            Vec3::repeat(radius),
            longitude_segments,
            latitude_segments,
        )
    }

    /// An ellipsoid with semi-axes `semi_axes` along x, y, z, centred at the origin: the
    /// [`Object::sphere`] mesh of radius 1 scaled by the semi-axes. A linear map keeps planar
    /// polygons planar, so its quads are planar too (up to rounding); facet normals still use
    /// Newell's method and centroids are area-weighted.
    ///
    /// Section: the points `(a cos t, b sin t, 0)` at `t = 2 pi k / n`, normals proportional to
    /// `(cos t / a, sin t / b, 0)`, each standing for the arc length `|dP/dt| 2 pi / n`; the
    /// angles are the points' polar angles (equal to `t` only when `a == b`).
    ///
    /// Errors: a semi-axis not positive and finite, or as for [`Object::sphere`].
    pub fn ellipsoid(
        semi_axes: Vec3,
        longitude_segments: usize,
        latitude_segments: usize,
    ) -> Result<Object, ObjectError> {
        for (name, value) in ["semi_axes.x", "semi_axes.y", "semi_axes.z"]
            .into_iter()
            .zip(semi_axes.iter())
        {
            check_dimension(name, *value)?;
        }
        uv_ellipsoid(
            "ellipsoid",
            semi_axes,
            longitude_segments,
            latitude_segments,
        )
    }

    /// A box `[-h.x, h.x] x [-h.y, h.y] x [-h.z, h.z]` (`h = half_extents`), each of its six
    /// faces split into `segments_per_edge x segments_per_edge` equal quads.
    ///
    /// Section: the rectangle's perimeter in the plane z = 0, one sample at the middle of each
    /// grid cell along each side (`4 segments_per_edge` samples, one loop counter-clockwise
    /// seen from +z starting at the -y side), with the side's normal and the cell width as
    /// arc length. Corners are never samples (their normal is undefined). With an odd
    /// `segments_per_edge` the samples are the facet centres of the middle row of side quads.
    ///
    /// Errors: a half extent not positive and finite, `segments_per_edge < 1`, or more than
    /// 2^24 faces.
    pub fn cuboid(half_extents: Vec3, segments_per_edge: usize) -> Result<Object, ObjectError> {
        for (name, value) in ["half_extents.x", "half_extents.y", "half_extents.z"]
            .into_iter()
            .zip(half_extents.iter())
        {
            check_dimension(name, *value)?;
        }
        let s = segments_per_edge;
        check_segments("segments_per_edge", s, 1)?;
        check_faces("cuboid", [6, s, s])?;
        let h = half_extents;
        let grid = |axis: usize, i: usize| h[axis] * grid_fraction(2 * i, s);
        let mut index = std::collections::HashMap::new();
        let mut vertices = Vec::new();
        let mut faces = Vec::with_capacity(6 * s * s);
        for axis in 0..3 {
            for side in [0, s] {
                // (u, v, axis) is right-handed; swapped on the negative side to face outward.
                let (mut u, mut v) = ((axis + 1) % 3, (axis + 2) % 3);
                if side == 0 {
                    std::mem::swap(&mut u, &mut v);
                }
                let mut vertex = |p: usize, q: usize| {
                    let mut lattice = [0; 3];
                    lattice[axis] = side;
                    lattice[u] = p;
                    lattice[v] = q;
                    *index.entry(lattice).or_insert_with(|| {
                        vertices.push(Vec3::from_fn(|c, _| grid(c, lattice[c])));
                        (vertices.len() - 1) as u32
                    })
                };
                for p in 0..s {
                    for q in 0..s {
                        faces.push(vec![
                            vertex(p, q),
                            vertex(p + 1, q),
                            vertex(p + 1, q + 1),
                            vertex(p, q + 1),
                        ]);
                    }
                }
            }
        }
        let mut object = assemble("cuboid", vertices, faces)?;
        object.centre_of_mass = Vec3::zeros();
        object.section = rectangle_section(h.x, h.y, s);
        Ok(object)
    }

    /// A cylinder of `radius` with axis z, from `z = -height / 2` to `height / 2`:
    /// `segments` quads around times `height_segments` along the side, and each cap a fan of
    /// `segments` triangles around a centre vertex.
    ///
    /// Section: the circle of `segments` points at angles exactly `2 pi k / segments` in the
    /// plane z = 0 (the mesh's vertex longitudes), radial normals, each standing for an arc of
    /// `2 pi radius / segments`.
    ///
    /// Errors: `radius` or `height` not positive and finite, `segments < 3`,
    /// `height_segments < 1`, or more than 2^24 faces.
    pub fn cylinder(
        radius: Real,
        height: Real,
        segments: usize,
        height_segments: usize,
    ) -> Result<Object, ObjectError> {
        check_dimension("radius", radius)?;
        check_dimension("height", height)?;
        check_segments("segments", segments, 3)?;
        check_segments("height_segments", height_segments, 1)?;
        check_faces("cylinder", [segments, height_segments.saturating_add(2)])?;
        let (n, m) = (segments, height_segments);
        let mut vertices = Vec::with_capacity((m + 1) * n + 2);
        for j in 0..=m {
            let z = height / 2.0 * grid_fraction(2 * j, m);
            for k in 0..n {
                let (c, s) = circle_point(k, n);
                vertices.push(Vec3::new(radius * c, radius * s, z));
            }
        }
        let ring = |j: usize, k: usize| (j * n + k % n) as u32;
        let (bottom, top) = (vertices.len() as u32, vertices.len() as u32 + 1);
        vertices.push(Vec3::new(0.0, 0.0, -height / 2.0));
        vertices.push(Vec3::new(0.0, 0.0, height / 2.0));
        let mut faces = Vec::with_capacity(n * (m + 2));
        for k in 0..n {
            faces.push(vec![bottom, ring(0, k + 1), ring(0, k)]);
            for j in 0..m {
                faces.push(vec![
                    ring(j, k),
                    ring(j, k + 1),
                    ring(j + 1, k + 1),
                    ring(j + 1, k),
                ]);
            }
            faces.push(vec![top, ring(m, k), ring(m, k + 1)]);
        }
        let mut object = assemble("cylinder", vertices, faces)?;
        object.centre_of_mass = Vec3::zeros();
        object.section = ellipse_section(radius, radius, n);
        Ok(object)
    }
}

fn check_dimension(name: &'static str, value: Real) -> Result<(), ObjectError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ObjectError::InvalidDimension { name, value })
    }
}

fn check_segments(name: &'static str, value: usize, min: usize) -> Result<(), ObjectError> {
    if value >= min {
        Ok(())
    } else {
        Err(ObjectError::TooFewSegments { name, value, min })
    }
}

fn check_faces<const N: usize>(name: &'static str, factors: [usize; N]) -> Result<(), ObjectError> {
    let count = factors
        .iter()
        .try_fold(1usize, |acc, &f| acc.checked_mul(f));
    match count {
        Some(c) if c <= MAX_FACES => Ok(()),
        _ => Err(ObjectError::TooManyFaces {
            name,
            max: MAX_FACES,
        }),
    }
}

/// `(i - s) / s` for `i` in `0..=2 s`: -1 at 0, exactly 0 at `s`, 1 at `2 s`, and exactly
/// antisymmetric about `s`.
fn grid_fraction(i: usize, s: usize) -> Real {
    (i as Real - s as Real) / s as Real
}

/// `(cos, sin)` of `2 pi k / n`, exact at quarter turns.
fn circle_point(k: usize, n: usize) -> (Real, Real) {
    let k = k % n;
    if (4 * k).is_multiple_of(n) {
        match 4 * k / n {
            0 => (1.0, 0.0),
            1 => (0.0, 1.0),
            2 => (-1.0, 0.0),
            _ => (0.0, -1.0),
        }
    } else {
        let (s, c) = (TAU * k as Real / n as Real).sin_cos();
        (c, s)
    }
}

/// The UV ellipsoid mesh (see [`Object::sphere`]) with its analytic section.
fn uv_ellipsoid(name: &'static str, axes: Vec3, n: usize, m: usize) -> Result<Object, ObjectError> {
    check_segments("longitude_segments", n, 3)?;
    check_segments("latitude_segments", m, 2)?;
    check_faces(name, [n, m])?;
    // Vertex 0 is the north pole, then rings 1..m of n vertices, then the south pole.
    let mut vertices = Vec::with_capacity((m - 1) * n + 2);
    vertices.push(Vec3::new(0.0, 0.0, axes.z));
    for j in 1..m {
        // Polar angle pi j / m, computed so that the rings are mirror images about z = 0.
        let (cos_polar, sin_polar) = circle_point(j, 2 * m);
        for k in 0..n {
            let (c, s) = circle_point(k, n);
            vertices.push(Vec3::new(
                axes.x * sin_polar * c,
                axes.y * sin_polar * s,
                axes.z * cos_polar,
            ));
        }
    }
    vertices.push(Vec3::new(0.0, 0.0, -axes.z));
    let ring = |j: usize, k: usize| (1 + (j - 1) * n + k % n) as u32;
    let (north, south) = (0, vertices.len() as u32 - 1);
    let mut faces = Vec::with_capacity(n * m);
    for k in 0..n {
        faces.push(vec![north, ring(1, k), ring(1, k + 1)]);
    }
    for j in 1..m - 1 {
        for k in 0..n {
            faces.push(vec![
                ring(j, k),
                ring(j + 1, k),
                ring(j + 1, k + 1),
                ring(j, k + 1),
            ]);
        }
    }
    for k in 0..n {
        faces.push(vec![south, ring(m - 1, k + 1), ring(m - 1, k)]);
    }
    let mut object = assemble(name, vertices, faces)?;
    object.centre_of_mass = Vec3::zeros();
    object.section = ellipse_section(axes.x, axes.y, n);
    Ok(object)
}

/// The ellipse `(a cos t, b sin t, 0)` sampled at `t = 2 pi k / n`.
fn ellipse_section(a: Real, b: Real, n: usize) -> Section {
    let mut samples = SurfaceSamples::default();
    let mut angles = Vec::with_capacity(n);
    for k in 0..n {
        let (c, s) = circle_point(k, n);
        let p = Vec3::new(a * c, b * s, 0.0);
        samples.points.push(p);
        samples
            .normals
            .push(Vec3::new(c / a, s / b, 0.0).normalize());
        samples.areas.push((a * s).hypot(b * c) * TAU / n as Real);
        angles.push(if a == b {
            wrap_angle(TAU * k as Real / n as Real)
        } else {
            polar_angle(&p, &Vec3::zeros())
        });
    }
    samples.adjacency = loop_adjacency(&[n]);
    Section {
        samples,
        angles,
        height: 0.0,
    }
}

/// The rectangle `[-a, a] x [-b, b]` sampled at the middle of each of `s` cells per side.
fn rectangle_section(a: Real, b: Real, s: usize) -> Section {
    let mut samples = SurfaceSamples::default();
    // Each side: a start corner, the unit direction of travel, the half length of the side
    // along it, and the outward normal; counter-clockwise seen from +z.
    let sides = [
        (Vec3::new(0.0, -b, 0.0), Vec3::x(), a),
        (Vec3::new(a, 0.0, 0.0), Vec3::y(), b),
        (Vec3::new(0.0, b, 0.0), -Vec3::x(), a),
        (Vec3::new(-a, 0.0, 0.0), -Vec3::y(), b),
    ];
    for (middle, direction, half) in sides {
        let normal = Vec3::new(direction.y, -direction.x, 0.0);
        for i in 0..s {
            samples
                .points
                .push(middle + direction * (half * grid_fraction(2 * i + 1, s)));
            samples.normals.push(normal);
            samples.areas.push(2.0 * half / s as Real);
        }
    }
    samples.adjacency = loop_adjacency(&[4 * s]);
    let angles = samples
        .points
        .iter()
        .map(|p| polar_angle(p, &Vec3::zeros()))
        .collect();
    Section {
        samples,
        angles,
        height: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn paper_sphere_has_5184_outward_facets_with_the_right_totals() {
        let r = 0.0475;
        let o = Object::sphere(r, 72, 72).unwrap();
        assert!(o.warnings.is_empty(), "{:?}", o.warnings);
        assert_eq!(o.faces.len(), 5184);
        assert_eq!(o.facets.len(), 5184);
        assert_eq!(o.vertices.len(), 71 * 72 + 2);
        assert_eq!(o.centre_of_mass, Vec3::zeros());
        for k in 0..o.facets.len() {
            let n = o.facets.normals[k];
            assert!((n.norm() - 1.0).abs() < 1e-12);
            let p = o.facets.points[k];
            assert!(
                n.dot(&(p - o.centre_of_mass)) > 0.0,
                "facet {k} points inward"
            );
            // Small faces of the inscribed mesh: the normal is nearly radial at the centroid.
            assert!(n.dot(&p.normalize()) > 1.0 - 1e-3);
        }
        // The inscribed UV mesh underestimates the area by about (d_lon^2 + 2 d_lat^2) / 12
        // relative (~9e-4 at 72 x 72; 8.7e-4 measured) and the volume by about twice that
        // (1.7e-3 measured): allow 1.5e-3 and 3e-3.
        let area: Real = o.facets.areas.iter().sum();
        let true_area = 4.0 * PI * r * r;
        assert!(
            area < true_area && (true_area - area) / true_area < 1.5e-3,
            "{area} vs {true_area}"
        );
        let true_volume = 4.0 / 3.0 * PI * r.powi(3);
        assert!(o.volume < true_volume && (true_volume - o.volume) / true_volume < 3e-3);
        assert!((o.max_radius() - r).abs() < 1e-16);
    }

    #[test]
    fn uv_adjacency_is_symmetric_with_one_neighbour_per_edge() {
        for (n, m) in [(72, 72), (3, 2), (5, 3)] {
            let o = Object::sphere(1.0, n, m).unwrap();
            let adj = &o.facets.adjacency;
            assert_eq!(adj.len(), n * m);
            for f in 0..adj.len() {
                let expected = o.faces.face(o.facet_faces[f] as usize).len();
                assert_eq!(adj.neighbours(f).len(), expected, "face {f} of {n}x{m}");
                for &g in adj.neighbours(f) {
                    assert!(adj.neighbours(g as usize).contains(&(f as u32)));
                }
            }
            // Pole bands are triangles, the others quads.
            let triangles = o.faces.iter().filter(|f| f.len() == 3).count();
            assert_eq!(triangles, 2 * n);
        }
    }

    #[test]
    fn sphere_section_is_the_equator_ring_at_exact_angles() {
        let r = 0.0475;
        let o = Object::sphere(r, 72, 72).unwrap();
        let s = &o.section;
        assert_eq!(s.height, 0.0);
        assert_eq!(s.samples.len(), 72);
        for k in 0..72 {
            let p = s.samples.points[k];
            let angle = 2.0 * PI * k as Real / 72.0;
            assert_eq!(s.angles[k], angle);
            assert!((p - Vec3::new(r * angle.cos(), r * angle.sin(), 0.0)).norm() < 1e-17);
            assert!((s.samples.normals[k] - p / r).norm() < 1e-15);
            assert!((s.samples.areas[k] - 2.0 * PI * r / 72.0).abs() < 1e-17);
            // The equator ring of the mesh holds exactly these points.
            assert!(o.vertices.iter().any(|v| (v - p).norm() < 1e-17));
            let mut adj = s.samples.adjacency.neighbours(k).to_vec();
            adj.sort_unstable();
            let mut expected = vec![((k + 71) % 72) as u32, ((k + 1) % 72) as u32];
            expected.sort_unstable();
            assert_eq!(adj, expected);
        }
        for (degrees, index) in [
            (30.0, 6),
            (-30.0, 66),
            (330.0, 66),
            (140.0, 28),
            (200.0, 40),
        ] {
            let (i, d) = s.nearest_angle(Real::to_radians(degrees)).unwrap();
            assert_eq!(i, index, "{degrees} degrees");
            assert!(d < 1e-12);
        }
    }

    #[test]
    fn ellipsoid_section_is_analytic() {
        let (a, b, c) = (0.05, 0.03, 0.02);
        let o = Object::ellipsoid(Vec3::new(a, b, c), 36, 18).unwrap();
        assert!(o.warnings.is_empty());
        let s = &o.section;
        assert_eq!(s.samples.len(), 36);
        for k in 0..36 {
            let p = s.samples.points[k];
            assert!(((p.x / a).powi(2) + (p.y / b).powi(2) - 1.0).abs() < 1e-14);
            let n = s.samples.normals[k];
            // Normal to the ellipse: parallel to the gradient (x / a^2, y / b^2).
            let grad = Vec3::new(p.x / (a * a), p.y / (b * b), 0.0).normalize();
            assert!((n - grad).norm() < 1e-14);
            assert!((s.angles[k] - polar_angle(&p, &Vec3::zeros())).abs() < 1e-15);
        }
        // Arc lengths sum to the ellipse's perimeter (Ramanujan: 0.254_2...).
        let h = ((a - b) / (a + b)).powi(2);
        let perimeter = PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()));
        let total: Real = s.samples.areas.iter().sum();
        assert!(
            (total - perimeter).abs() / perimeter < 1e-9,
            "{total} vs {perimeter}"
        );
        // Volume of the inscribed mesh: 1.3% below 4/3 pi a b c at 36 x 18 (the sphere's
        // deficit estimate, about 2 (d_lon^2 + 2 d_lat^2) / 12); allow 2%.
        let v = 4.0 / 3.0 * PI * a * b * c;
        assert!(o.volume < v && (v - o.volume) / v < 2e-2);
    }

    #[test]
    fn cuboid_mass_properties_and_section_are_exact() {
        let h = Vec3::new(0.1, 0.2, 0.3);
        for s in [1, 2, 3] {
            let o = Object::cuboid(h, s).unwrap();
            assert!(o.warnings.is_empty());
            assert_eq!(o.faces.len(), 6 * s * s);
            assert_eq!(o.vertices.len(), 6 * s * s + 2);
            assert!((o.volume - 8.0 * h.x * h.y * h.z).abs() < 1e-16);
            let total: Real = o.facets.areas.iter().sum();
            assert!((total - 8.0 * (h.x * h.y + h.y * h.z + h.z * h.x)).abs() < 1e-15);
            // Recomputing the centre of mass from the mesh gives the origin as well.
            let fresh = Object::from_polygons(
                "box",
                o.vertices.clone(),
                o.faces.iter().map(<[u32]>::to_vec).collect(),
            )
            .unwrap();
            assert!(fresh.centre_of_mass.norm() < 1e-16);
            assert!(fresh.warnings.is_empty());
            let sec = &o.section;
            assert_eq!(sec.samples.len(), 4 * s);
            let perimeter: Real = sec.samples.areas.iter().sum();
            assert!((perimeter - 4.0 * (h.x + h.y)).abs() < 1e-15);
            for k in 0..4 * s {
                let (p, n) = (sec.samples.points[k], sec.samples.normals[k]);
                // On the side the normal points to.
                assert!((p.dot(&n) - h.dot(&n.abs())).abs() < 1e-16);
                assert_eq!(sec.samples.adjacency.neighbours(k).len(), 2);
            }
            // The mesh cut agrees with the analytic section as a set of normals and lengths.
            assert_eq!(fresh.section.samples.len() % 4, 0);
            let cut_perimeter: Real = fresh.section.samples.areas.iter().sum();
            assert!((cut_perimeter - perimeter).abs() < 1e-15);
        }
    }

    #[test]
    fn cylinder_is_closed_and_sectioned_at_vertex_longitudes() {
        let o = Object::cylinder(0.02, 0.1, 16, 3).unwrap();
        assert!(o.warnings.is_empty());
        assert_eq!(o.faces.len(), 16 * 5);
        // Prism volume: n/2 r^2 sin(2 pi / n) h.
        let v = 8.0 * 0.02f64.powi(2) * (TAU / 16.0).sin() * 0.1;
        assert!((o.volume - v).abs() / v < 1e-14);
        assert_eq!(o.section.samples.len(), 16);
        assert_eq!(o.section.angles[4], PI / 2.0);
        assert_eq!(o.section.samples.points[4], Vec3::new(0.0, 0.02, 0.0));
        for k in 0..o.facets.len() {
            assert!(o.facets.normals[k].dot(&o.facets.points[k]) > 0.0);
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = Object::sphere(-1.0, 8, 8).unwrap_err();
        assert!(
            matches!(e, ObjectError::InvalidDimension { name: "radius", .. }),
            "{e}"
        );
        let e = Object::sphere(Real::NAN, 8, 8).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::InvalidDimension { name: "radius", .. }
        ));
        let e = Object::sphere(1.0, 2, 8).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::TooFewSegments {
                name: "longitude_segments",
                value: 2,
                min: 3
            }
        ));
        let e = Object::sphere(1.0, 8, 1).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::TooFewSegments {
                name: "latitude_segments",
                min: 2,
                ..
            }
        ));
        let e = Object::sphere(1.0, usize::MAX, 3).unwrap_err();
        assert!(matches!(e, ObjectError::TooManyFaces { .. }), "{e}");
        let e = Object::ellipsoid(Vec3::new(1.0, 0.0, 1.0), 8, 8).unwrap_err();
        assert!(e.to_string().contains("semi_axes.y"), "{e}");
        let e = Object::cuboid(Vec3::new(1.0, 1.0, Real::INFINITY), 1).unwrap_err();
        assert!(e.to_string().contains("half_extents.z"), "{e}");
        let e = Object::cuboid(Vec3::repeat(1.0), 0).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::TooFewSegments {
                name: "segments_per_edge",
                ..
            }
        ));
        let e = Object::cylinder(1.0, 0.0, 8, 1).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::InvalidDimension { name: "height", .. }
        ));
        let e = Object::cylinder(1.0, 1.0, 8, 0).unwrap_err();
        assert!(matches!(
            e,
            ObjectError::TooFewSegments {
                name: "height_segments",
                ..
            }
        ));
        let e = Object::cylinder(1.0, 1.0, 1 << 30, usize::MAX).unwrap_err();
        assert!(matches!(e, ObjectError::TooManyFaces { .. }));
    }
}
