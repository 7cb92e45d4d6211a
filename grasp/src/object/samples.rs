//! Compressed index lists and candidate contact points.

use std::f64::consts::{PI, TAU};

use crate::math::{Real, Vec3};

/// Compressed lists of `u32` (CSR layout), shared by [`Adjacency`] and [`Polygons`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
struct Csr {
    /// `offsets[i]..offsets[i + 1]` is the range of list `i` in `indices`; `offsets[0] == 0`.
    offsets: Vec<usize>,
    indices: Vec<u32>,
}

impl Csr {
    fn from_lists(lists: &[Vec<u32>]) -> Self {
        let mut offsets = Vec::with_capacity(lists.len() + 1);
        offsets.push(0);
        let mut indices = Vec::with_capacity(lists.iter().map(Vec::len).sum());
        for list in lists {
            indices.extend_from_slice(list);
            offsets.push(indices.len());
        }
        Self { offsets, indices }
    }

    fn get(&self, i: usize) -> &[u32] {
        match (self.offsets.get(i), self.offsets.get(i + 1)) {
            (Some(&a), Some(&b)) => &self.indices[a..b],
            _ => &[],
        }
    }

    fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
}

/// Compressed adjacency lists (CSR): for each node, the indices of its neighbours.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Adjacency(Csr);

impl Adjacency {
    /// Builds the compressed form of `lists` (`lists[i]` = neighbours of node `i`).
    pub fn from_lists(lists: &[Vec<u32>]) -> Self {
        Self(Csr::from_lists(lists))
    }

    /// The neighbours of node `i` (an empty slice if `i >= self.len()`).
    pub fn neighbours(&self, i: usize) -> &[u32] {
        self.0.get(i)
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The nodes within `rings` hops of node `i` but `i` itself, nearest first (in order of
    /// hops, then of index).
    pub fn rings(&self, i: usize, rings: usize) -> Vec<u32> {
        let mut found: Vec<u32> = vec![i as u32];
        let mut ring_start = 0;
        for _ in 0..rings {
            let ring_end = found.len();
            let mut next: Vec<u32> = found[ring_start..ring_end]
                .iter()
                .flat_map(|&m| self.neighbours(m as usize).iter().copied())
                .filter(|n| !found.contains(n))
                .collect();
            next.sort_unstable();
            next.dedup();
            found.extend(next);
            ring_start = ring_end;
        }
        found.remove(0);
        found
    }

    /// The nodes of `members` (sorted node indices) whose neighbours, to `rings` rings, are
    /// all members too: the set shrunk by `rings` hops of the graph (on a loop, `rings` nodes
    /// off each end of every arc). A node without neighbours is never removed.
    pub fn erode(&self, members: &[u32], rings: usize) -> Vec<u32> {
        let mut kept = members.to_vec();
        for _ in 0..rings {
            let inside = |m: u32| kept.binary_search(&m).is_ok();
            kept = kept
                .iter()
                .copied()
                .filter(|&m| self.neighbours(m as usize).iter().all(|&n| inside(n)))
                .collect();
        }
        kept
    }
}

/// A list of polygons (CSR of vertex indices), each counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Polygons(Csr);

impl Polygons {
    /// Builds the compressed form of `faces` (`faces[i]` = vertex indices of polygon `i`).
    pub fn from_lists(faces: &[Vec<u32>]) -> Self {
        Self(Csr::from_lists(faces))
    }

    /// The vertex indices of face `i` (an empty slice if `i >= self.len()`).
    pub fn face(&self, i: usize) -> &[u32] {
        self.0.get(i)
    }

    /// Iterates over the faces in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[u32]> + '_ {
        (0..self.len()).map(|i| self.face(i))
    }

    /// Number of faces.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are no faces.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Candidate contact points on a surface, with a neighbourhood graph for region growing.
///
/// All four fields have one entry per sample.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceSamples {
    /// Positions, in the body frame.
    pub points: Vec<Vec3>,
    /// Outward unit normals.
    pub normals: Vec<Vec3>,
    /// Face areas; for a planar section, the arc length each sample stands for.
    pub areas: Vec<Real>,
    /// Neighbourhood graph: faces sharing an edge; for a section, previous/next along a loop.
    pub adjacency: Adjacency,
}

impl SurfaceSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The sample nearest to `p` and its distance; `None` if there are no samples or `p` is
    /// not finite.
    pub fn nearest(&self, p: &Vec3) -> Option<(usize, Real)> {
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        self.points
            .iter()
            .map(|q| (q - p).norm_squared())
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, d2)| (i, d2.sqrt()))
    }
}

/// Points indexed for nearest-point queries: a k-d tree, each node the median of its points
/// along the axis they spread widest on. Exact: the same point as comparing every one
/// ([`SurfaceSamples::nearest`]), ties to the lowest index; a query opens only the subtrees
/// nearer than the nearest point found so far, a few dozen of thousands of candidates for a
/// point near the surface. Built once; a query allocates nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NearestPoints {
    /// The points in tree order: the node over `lo..hi` is at `(lo + hi) / 2`, its left
    /// subtree over `lo..mid`, its right over `mid + 1..hi`.
    points: Vec<Vec3>,
    /// Each point's index in the points the tree was built from.
    index: Vec<u32>,
    /// Each node's splitting axis.
    axis: Vec<u8>,
}

impl NearestPoints {
    /// The tree over `points`.
    pub fn new(points: &[Vec3]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut axis = vec![0u8; points.len()];
        Self::build(points, &mut order, &mut axis);
        Self {
            points: order.iter().map(|&i| points[i as usize]).collect(),
            index: order,
            axis,
        }
    }

    /// Orders `order` (and sets `axis`) as the subtree over it.
    fn build(points: &[Vec3], order: &mut [u32], axis: &mut [u8]) {
        if order.is_empty() {
            return;
        }
        let (mut lo, mut hi) = (
            Vec3::repeat(Real::INFINITY),
            Vec3::repeat(Real::NEG_INFINITY),
        );
        for &i in order.iter() {
            lo = lo.inf(&points[i as usize]);
            hi = hi.sup(&points[i as usize]);
        }
        let k = (hi - lo).imax();
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |a, b| {
            points[*a as usize][k].total_cmp(&points[*b as usize][k])
        });
        axis[mid] = k as u8;
        let (left, rest) = order.split_at_mut(mid);
        let (left_axis, rest_axis) = axis.split_at_mut(mid);
        Self::build(points, left, left_axis);
        Self::build(points, &mut rest[1..], &mut rest_axis[1..]);
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The point nearest to `p` (its index in the points the tree was built from) and its
    /// distance; `None` if there are no points or `p` is not finite.
    pub fn nearest(&self, p: &Vec3) -> Option<(usize, Real)> {
        if self.points.is_empty() || !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut best = (Real::INFINITY, u32::MAX);
        self.search(p, 0, self.points.len(), &mut best);
        Some((best.1 as usize, best.0.sqrt()))
    }

    /// Searches the subtree over `lo..hi` for a point nearer to `p` than `best` (squared
    /// distance, index).
    fn search(&self, p: &Vec3, lo: usize, hi: usize, best: &mut (Real, u32)) {
        if lo >= hi {
            return;
        }
        let mid = (lo + hi) / 2;
        let d2 = (self.points[mid] - p).norm_squared();
        let i = self.index[mid];
        if d2 < best.0 || (d2 == best.0 && i < best.1) {
            *best = (d2, i);
        }
        let k = self.axis[mid] as usize;
        let across = p[k] - self.points[mid][k];
        // The points on the far side of the median are at least `across` away along its
        // axis: opened only when that could still beat (or tie) the best.
        let (near, far) = if across < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(p, near.0, near.1, best);
        if across * across <= best.0 {
            self.search(p, far.0, far.1, best);
        }
    }
}

/// The object's candidates in the hand's plane: the horizontal plane `z = height` through the
/// centre of mass.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Section {
    /// The samples; `areas` are arc lengths, `adjacency` links previous and next along each
    /// closed loop.
    pub samples: SurfaceSamples,
    /// `atan2(y - com.y, x - com.x)` of each point, in radians in `[0, 2 pi)`.
    pub angles: Vec<Real>,
    /// Height of the plane (the z coordinate of the centre of mass).
    pub height: Real,
}

impl Section {
    /// The sample whose angle is nearest to `angle_rad` (any real; taken modulo 2 pi) and the
    /// angular distance to it, in `[0, pi]`; `None` if the section is empty or the angle is not
    /// finite.
    pub fn nearest_angle(&self, angle_rad: Real) -> Option<(usize, Real)> {
        if !angle_rad.is_finite() {
            return None;
        }
        self.angles
            .iter()
            .map(|&a| angular_distance(a, angle_rad))
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

/// Distance between two angles on the circle, in `[0, pi]`.
pub(crate) fn angular_distance(a: Real, b: Real) -> Real {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d).clamp(0.0, PI)
}

/// `angle` reduced to `[0, 2 pi)`.
pub(crate) fn wrap_angle(angle: Real) -> Real {
    let a = angle.rem_euclid(TAU);
    // rem_euclid of a tiny negative number rounds up to exactly 2 pi.
    if a >= TAU { 0.0 } else { a }
}

/// The polar angle of `p` about `centre` in the xy plane, in `[0, 2 pi)`.
pub(crate) fn polar_angle(p: &Vec3, centre: &Vec3) -> Real {
    wrap_angle((p.y - centre.y).atan2(p.x - centre.x))
}

/// Previous/next adjacency of consecutive samples forming closed loops; `loops` are the
/// lengths of the loops, whose samples are stored one loop after the other.
pub(crate) fn loop_adjacency(loops: &[usize]) -> Adjacency {
    let mut lists = Vec::with_capacity(loops.iter().sum());
    let mut start = 0;
    for &n in loops {
        for k in 0..n {
            let prev = start + (k + n - 1) % n;
            let next = start + (k + 1) % n;
            let mut list: Vec<u32> = Vec::with_capacity(2);
            for j in [prev, next] {
                let j = j as u32;
                if j as usize != start + k && !list.contains(&j) {
                    list.push(j);
                }
            }
            lists.push(list);
        }
        start += n;
    }
    Adjacency::from_lists(&lists)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every point compared, ties to the first: what [`NearestPoints`] must answer.
    fn scan(points: &[Vec3], p: &Vec3) -> Option<(usize, Real)> {
        SurfaceSamples {
            points: points.to_vec(),
            ..Default::default()
        }
        .nearest(p)
    }

    proptest! {
        /// The tree answers as comparing every point does, index and distance, for clouds with
        /// repeated points and points on a grid (ties), queries near them and far.
        #[test]
        fn nearest_points_answer_as_comparing_every_point(
            cloud in prop::collection::vec((-5i32..5, -5i32..5, -5i32..5, any::<bool>()), 0..300),
            queries in prop::collection::vec((-80.0..80.0f64, -80.0..80.0f64, -80.0..80.0f64), 1..40),
        ) {
            // Grid points (exact ties for grid queries) and jittered ones, some repeated.
            let points: Vec<Vec3> = cloud
                .iter()
                .enumerate()
                .map(|(k, &(x, y, z, grid))| {
                    let jitter = if grid { 0.0 } else { 0.37 * ((k * 7919) % 13) as Real / 13.0 };
                    Vec3::new(x as Real + jitter, y as Real - jitter, z as Real * 0.5)
                })
                .collect();
            let tree = NearestPoints::new(&points);
            prop_assert_eq!(tree.len(), points.len());
            for (x, y, z) in queries {
                for p in [Vec3::new(x, y, z) * 0.1, Vec3::new(x.round(), y.round(), z.round()) * 0.1] {
                    let got = tree.nearest(&p);
                    let want = scan(&points, &p);
                    prop_assert_eq!(got.map(|g| g.0), want.map(|w| w.0), "{:?}", p);
                    if let (Some(g), Some(w)) = (got, want) {
                        prop_assert!((g.1 - w.1).abs() <= 1e-12, "{} vs {}", g.1, w.1);
                    }
                }
            }
        }
    }

    #[test]
    fn nearest_points_refuse_no_points_and_points_not_finite() {
        assert_eq!(NearestPoints::new(&[]).nearest(&Vec3::zeros()), None);
        let tree = NearestPoints::new(&[Vec3::x(), Vec3::y()]);
        assert_eq!(tree.nearest(&Vec3::new(Real::NAN, 0.0, 0.0)), None);
        assert_eq!(
            tree.nearest(&Vec3::new(0.9, 0.0, 0.0)).map(|n| n.0),
            Some(0)
        );
    }

    #[test]
    fn adjacency_round_trips_lists_and_tolerates_bad_index() {
        let adj = Adjacency::from_lists(&[vec![1, 2], vec![], vec![0]]);
        assert_eq!(adj.len(), 3);
        assert!(!adj.is_empty());
        assert_eq!(adj.neighbours(0), &[1, 2]);
        assert_eq!(adj.neighbours(1), &[] as &[u32]);
        assert_eq!(adj.neighbours(2), &[0]);
        assert_eq!(adj.neighbours(3), &[] as &[u32]);
        assert!(Adjacency::from_lists(&[]).is_empty());
        assert!(Adjacency::default().is_empty());
    }

    /// The rings about a node: on a loop of 12, two nodes a ring (nearest first); on a
    /// 3 x 3 grid (4-neighbours), the centre's first ring its four edge-neighbours and its
    /// second the corners; never the node itself, nor a node twice; 0 rings, none.
    #[test]
    fn rings_list_the_nodes_within_hops_nearest_first() {
        let ring = Adjacency::from_lists(
            &(0..12u32)
                .map(|i| vec![(i + 11) % 12, (i + 1) % 12])
                .collect::<Vec<_>>(),
        );
        assert_eq!(ring.rings(0, 1), vec![1, 11]);
        assert_eq!(ring.rings(0, 2), vec![1, 11, 2, 10]);
        assert_eq!(ring.rings(0, 6).len(), 11);
        assert_eq!(ring.rings(0, 0), Vec::<u32>::new());
        let grid = Adjacency::from_lists(
            &(0..9u32)
                .map(|i| {
                    let (r, c) = (i / 3, i % 3);
                    let mut n = Vec::new();
                    if r > 0 {
                        n.push(i - 3);
                    }
                    if c > 0 {
                        n.push(i - 1);
                    }
                    if c < 2 {
                        n.push(i + 1);
                    }
                    if r < 2 {
                        n.push(i + 3);
                    }
                    n
                })
                .collect::<Vec<_>>(),
        );
        assert_eq!(grid.rings(4, 1), vec![1, 3, 5, 7]);
        assert_eq!(grid.rings(4, 2), vec![1, 3, 5, 7, 0, 2, 6, 8]);
        assert_eq!(grid.rings(0, 1), vec![1, 3]);
        assert_eq!(grid.rings(0, 2), vec![1, 3, 2, 4, 6]);
    }

    /// On a loop of 12 nodes: two arcs shrink by a node off each end per ring, an arc of
    /// three is gone after two rings, the whole loop stays whole, no rings change nothing, and
    /// a node without neighbours stays.
    #[test]
    fn erosion_takes_rings_off_each_end_of_every_arc() {
        let n = 12_u32;
        let ring = Adjacency::from_lists(
            &(0..n)
                .map(|i| vec![(i + n - 1) % n, (i + 1) % n])
                .collect::<Vec<_>>(),
        );
        // The arcs 10, 11, 0, 1, 2 (across the seam) and 5, 6, 7.
        let members = [0, 1, 2, 5, 6, 7, 10, 11];
        assert_eq!(ring.erode(&members, 0), members);
        assert_eq!(ring.erode(&members, 1), [0, 1, 6, 11]);
        assert_eq!(ring.erode(&members, 2), [0]);
        assert_eq!(ring.erode(&members, 3), [] as [u32; 0]);
        let all: Vec<u32> = (0..n).collect();
        assert_eq!(ring.erode(&all, 3), all);
        let lone = Adjacency::from_lists(&[vec![], vec![2], vec![1]]);
        assert_eq!(lone.erode(&[0, 1], 1), [0]);
    }

    #[test]
    fn polygons_give_faces_in_order() {
        let p = Polygons::from_lists(&[vec![0, 1, 2], vec![2, 1, 3, 4]]);
        assert_eq!(p.len(), 2);
        assert_eq!(p.face(1), &[2, 1, 3, 4]);
        assert_eq!(p.iter().map(<[u32]>::len).collect::<Vec<_>>(), vec![3, 4]);
        assert_eq!(p.face(2), &[] as &[u32]);
    }

    #[test]
    fn loop_adjacency_links_previous_and_next() {
        let adj = loop_adjacency(&[3, 2, 1]);
        assert_eq!(adj.len(), 6);
        assert_eq!(adj.neighbours(0), &[2, 1]);
        assert_eq!(adj.neighbours(2), &[1, 0]);
        assert_eq!(adj.neighbours(3), &[4]);
        assert_eq!(adj.neighbours(4), &[3]);
        assert_eq!(adj.neighbours(5), &[] as &[u32]);
    }

    #[test]
    fn nearest_and_nearest_angle() {
        let samples = SurfaceSamples {
            points: vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)],
            normals: vec![Vec3::x(), Vec3::y()],
            areas: vec![1.0, 1.0],
            adjacency: loop_adjacency(&[2]),
        };
        let (i, d) = samples.nearest(&Vec3::new(0.0, 2.0, 0.0)).unwrap();
        assert_eq!(i, 1);
        assert!((d - 1.0).abs() < 1e-15);
        assert_eq!(samples.nearest(&Vec3::new(Real::NAN, 0.0, 0.0)), None);
        assert_eq!(SurfaceSamples::default().nearest(&Vec3::zeros()), None);

        let section = Section {
            samples,
            angles: vec![0.0, PI / 2.0],
            height: 0.0,
        };
        // -0.1 rad is 0.1 away from angle 0 across the wrap.
        let (i, d) = section.nearest_angle(-0.1).unwrap();
        assert_eq!(i, 0);
        assert!((d - 0.1).abs() < 1e-12);
        let (i, d) = section.nearest_angle(PI / 2.0 + TAU).unwrap();
        assert_eq!(i, 1);
        assert!(d < 1e-12);
        assert_eq!(section.nearest_angle(Real::INFINITY), None);
        assert_eq!(Section::default().nearest_angle(0.0), None);
    }

    #[test]
    fn angles_wrap_into_range() {
        assert_eq!(wrap_angle(-1e-20), 0.0);
        assert!((wrap_angle(-PI / 2.0) - 1.5 * PI).abs() < 1e-15);
        assert_eq!(wrap_angle(TAU), 0.0);
        let c = Vec3::new(1.0, 1.0, 5.0);
        assert!((polar_angle(&Vec3::new(1.0, 0.0, 0.0), &c) - 1.5 * PI).abs() < 1e-15);
        assert!((angular_distance(0.1, TAU - 0.1) - 0.2).abs() < 1e-12);
    }
}
