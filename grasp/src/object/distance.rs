//! Distance from a point to an object's surface.

use super::Object;
use crate::math::{Real, Vec3};

impl Object {
    /// Distance from body-frame point `p` to the surface (every face, fanned into triangles
    /// from its first vertex: exact for the convex polygons of the primitives and of meshes
    /// read as triangles).
    pub fn surface_distance(&self, p: &Vec3) -> Real {
        let v = &self.vertices;
        let mut best = Real::INFINITY;
        for face in self.faces.iter() {
            let a = v[face[0] as usize];
            for w in face[1..].windows(2) {
                let d = triangle_distance(p, &a, &v[w[0] as usize], &v[w[1] as usize]);
                best = best.min(d);
            }
        }
        best
    }
}

/// Distance from `p` to the triangle `abc`.
fn triangle_distance(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Real {
    (p - closest_on_triangle(p, a, b, c)).norm()
}

/// The point of the triangle `abc` closest to `p` (Ericson, Real-Time Collision Detection,
/// 5.1.5); a degenerate triangle's nearest vertex where its edges do not decide.
pub fn closest_on_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return a + ab * t;
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return a + ac * t;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + (c - b) * t;
    }
    let denom = va + vb + vc;
    if denom.abs() < Real::MIN_POSITIVE {
        // A degenerate triangle: its nearest vertex (the edges are covered above).
        return *[a, b, c]
            .into_iter()
            .min_by(|x, y| (p - *x).norm().total_cmp(&(p - *y).norm()))
            .unwrap_or(a);
    }
    let (v, w) = (vb / denom, vc / denom);
    a + ab * v + ac * w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_distance_of_a_sphere_mesh() {
        let o = Object::sphere(0.0475, 24, 12).unwrap();
        // A vertex of the equator ring.
        let on = Vec3::new(0.0475, 0.0, 0.0);
        assert!(o.surface_distance(&on) < 1e-15);
        // Between the facets and the sphere they approximate: within the chord error.
        let (lon, polar) = (7.5f64.to_radians(), 52.5f64.to_radians());
        let between = 0.0475
            * Vec3::new(
                polar.sin() * lon.cos(),
                polar.sin() * lon.sin(),
                polar.cos(),
            );
        let d = o.surface_distance(&between);
        assert!(
            d > 1e-6 && d < 0.0475 * (1.0 - 15f64.to_radians().cos()),
            "{d}"
        );
        let far = Vec3::new(1.4, 0.0, 0.0);
        assert!((o.surface_distance(&far) - (1.4 - 0.0475)).abs() < 1e-9);
        let inside = Vec3::zeros();
        let d = o.surface_distance(&inside);
        assert!(d > 0.045 && d <= 0.0475, "{d}");
    }
}
