//! Preprocessing for clouds without normals or splat radii: one exact k-nearest-neighbour
//! search per point on a uniform grid ([`super::knn`], rayon-parallel, in cell order), shared by
//!
//! * **normals** by PCA: the eigenvector of the smallest eigenvalue of the covariance of the
//!   point and its k neighbours, then oriented consistently by [`super::orient`] (towards the
//!   scanner, up for survey data, else by propagation over the nearest [`GRAPH_K`] neighbours).
//!   Degenerate neighbourhoods (duplicates, a single point) fall back to the sensor direction,
//!   then the outward direction, then +Z — never NaN — before the orientation.
//! * **radii**: with `r_k` the distance to the k-th nearest neighbour, either `r_k` itself
//!   ([`RadiusMode::KthNeighbour`]) or the spacing implied by the local density
//!   `rho = k / (pi r_k^2)`, `spacing = 1 / sqrt(rho) = r_k sqrt(pi / k)`
//!   ([`RadiusMode::DensitySpacing`], the default written to [`Cloud::radii`]: on a regular grid
//!   of spacing `h` it gives about `0.89 h` for k = 4..10, so splats overlap enough to close
//!   the surface without the blur of `r_k` ≈ `2 h` at k = 10). Radii are clamped below to
//!   [`MIN_RADIUS_FRACTION`] of the median radius, so duplicate points never get radius 0.
//!
//! Results can be cached next to the input file ([`save_cache`], [`load_cache`]).

use std::io;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use glam::{DVec3, Vec3};
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;

use super::cloud::Cloud;
use super::knn::Grid;
use super::orient::{self, Graph, Rule, GRAPH_K};
use super::progress::Progress;

/// Default neighbourhood size.
pub const DEFAULT_K: usize = 10;

/// The most neighbours an estimate uses: more are clamped (the k-NN rows take `k` entries per
/// point, and a normal's plane needs tens of points, not thousands).
pub const MAX_K: usize = 256;

/// Radii are at least this fraction of the median radius (duplicates have `r_k` = 0).
pub const MIN_RADIUS_FRACTION: f32 = 0.1;

/// Clouds at least this large show a progress bar (when stderr is a terminal).
pub const PROGRESS_MIN_POINTS: usize = 200_000;

/// How a splat radius is derived from the k-nearest-neighbour distance `r_k`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RadiusMode {
    /// `r_k`, the distance to the k-th nearest neighbour.
    KthNeighbour,
    /// `1 / sqrt(k / (pi r_k^2))`, the mean spacing implied by the local density.
    #[default]
    DensitySpacing,
}

/// Settings for [`preprocess`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PreprocessOptions {
    /// Neighbours per point (not counting the point itself); at least 1.
    pub k: usize,
    /// Which radius to write.
    pub radius: RadiusMode,
    /// Show a progress bar on stderr for large clouds when stderr is a terminal.
    pub progress: bool,
}

impl Default for PreprocessOptions {
    fn default() -> Self {
        PreprocessOptions {
            k: DEFAULT_K,
            radius: RadiusMode::default(),
            progress: true,
        }
    }
}

/// Points processed per parallel task (and per progress update).
const CHUNK: usize = 2048;

/// The k nearest neighbours of every point, excluding the point itself, nearest first.
#[derive(Clone, Debug)]
pub struct Neighbours {
    k: usize,
    /// The row of each point in `indices`, `dist2` and `counts`.
    rows: Vec<u32>,
    indices: Vec<u32>,
    dist2: Vec<f32>,
    counts: Vec<u32>,
}

impl Neighbours {
    /// Finds the `k` nearest neighbours of each point (fewer when the cloud has at most `k`
    /// finite points) on a grid ([`Grid`]). Non-finite points have no neighbours and are never
    /// anyone's neighbour. Rows are stored in the grid's cell order.
    pub fn compute(positions: &[Vec3], k: usize, progress: bool) -> Self {
        let k = k.clamp(1, MAX_K);
        let n = positions.len();
        let grid = Grid::build(positions, k);
        let bar = Progress::new("k-NN", n, progress && n >= PROGRESS_MIN_POINTS);
        // Non-finite points share one empty row after the sorted ones.
        let mut found = vec![(u32::MAX, 0f32); (grid.len() + 1) * k];
        grid.for_each(
            k,
            &mut found[..grid.len() * k],
            k,
            |_, near, row| {
                for (slot, &(d2, t)) in row.iter_mut().zip(near) {
                    *slot = (grid.input_index(t), d2);
                }
            },
            &|done| bar.advance(done),
        );
        bar.finish();
        let mut rows = vec![grid.len() as u32; n];
        for s in 0..grid.len() as u32 {
            rows[grid.input_index(s) as usize] = s;
        }
        let counts = found
            .par_chunks(k)
            .map(|row| row.iter().take_while(|e| e.0 != u32::MAX).count() as u32)
            .collect();
        let indices = found.par_iter().map(|e| e.0).collect();
        let dist2 = found.par_iter().map(|e| e.1).collect();
        Neighbours {
            k,
            rows,
            indices,
            dist2,
            counts,
        }
    }

    /// The reference [`Neighbours::compute`] is measured and tested against: one query of a
    /// k-d tree per point, rows in input order.
    pub fn compute_with_tree(positions: &[Vec3], k: usize) -> Self {
        let k = k.clamp(1, MAX_K);
        let n = positions.len();
        let tree = FiniteTree::new(positions);
        let mut indices = vec![0u32; n * k];
        let mut dist2 = vec![0f32; n * k];
        let mut counts = vec![0u32; n];
        indices
            .par_chunks_mut(CHUNK * k)
            .zip(dist2.par_chunks_mut(CHUNK * k))
            .zip(counts.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(chunk, ((idx, d2), cnt))| {
                let mut found = Vec::with_capacity(k);
                for (j, count) in cnt.iter_mut().enumerate() {
                    tree.nearest(positions, chunk * CHUNK + j, k, &mut found);
                    for (m, &(i, d)) in found.iter().enumerate() {
                        idx[j * k + m] = i;
                        d2[j * k + m] = d;
                    }
                    *count = found.len() as u32;
                }
            });
        Neighbours {
            k,
            rows: (0..n as u32).collect(),
            indices,
            dist2,
            counts,
        }
    }

    /// Neighbourhood size requested.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Indices and squared distances of the neighbours of point `i`, nearest first.
    pub fn of(&self, i: usize) -> (&[u32], &[f32]) {
        let row = self.rows[i] as usize;
        let m = self.counts[row] as usize;
        let start = row * self.k;
        (
            &self.indices[start..start + m],
            &self.dist2[start..start + m],
        )
    }
}

/// A k-d tree over the finite points of a cloud.
struct FiniteTree {
    /// Input index of each tree item.
    finite: Vec<u32>,
    tree: Option<ImmutableKdTree<f32, u32, 3, 32>>,
}

impl FiniteTree {
    fn new(positions: &[Vec3]) -> Self {
        let finite = super::knn::finite_indices(positions);
        let coords: Vec<[f32; 3]> = finite
            .par_iter()
            .map(|&i| positions[i as usize].to_array())
            .collect();
        let tree = (coords.len() >= 2).then(|| ImmutableKdTree::new_from_slice(&coords));
        FiniteTree { finite, tree }
    }

    /// The `k` nearest neighbours of point `i` (fewer when the cloud has no more), excluding
    /// the point itself, as `(input index, squared distance)`, nearest first, into `found`.
    fn nearest(&self, positions: &[Vec3], i: usize, k: usize, found: &mut Vec<(u32, f32)>) {
        found.clear();
        let p = positions[i];
        let Some(tree) = &self.tree else { return };
        if !p.is_finite() {
            return;
        }
        let want = NonZeroUsize::new((k + 1).min(self.finite.len())).unwrap_or(NonZeroUsize::MIN);
        let mut skipped_self = false;
        for nb in tree.nearest_n::<SquaredEuclidean>(&p.to_array(), want) {
            let original = self.finite[nb.item as usize];
            if original as usize == i && !skipped_self {
                skipped_self = true;
                continue;
            }
            if found.len() < k {
                found.push((original, nb.distance));
            }
        }
    }
}

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations. Returns the
/// eigenvalues in ascending order and the matching unit eigenvectors.
pub fn symmetric_eigen3(m: [[f64; 3]; 3]) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let norm2: f64 = a.iter().flatten().map(|x| x * x).sum();
    for _sweep in 0..50 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if off.is_nan() || off <= norm2 * 1e-30 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = if theta.abs() > 1e100 {
                0.5 / theta
            } else {
                theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for col in 0..3 {
                a[p][col] = c * row_p[col] - s * row_q[col];
                a[q][col] = s * row_p[col] + c * row_q[col];
            }
            for row in v.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let values = order.map(|i| a[i][i]);
    let vectors = order.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize_or_zero());
    (values, vectors)
}

/// Where to point normals.
fn reference_direction(p: Vec3, sensor: Option<Vec3>, centroid: Vec3) -> Vec3 {
    match sensor {
        Some(s) => s - p,
        None => p - centroid,
    }
}

/// A unit normal used when the neighbourhood defines none.
fn fallback_normal(p: Vec3, sensor: Option<Vec3>, centroid: Vec3) -> Vec3 {
    let d = reference_direction(p, sensor, centroid).normalize_or_zero();
    if d != Vec3::ZERO && d.is_finite() {
        return d;
    }
    let outward = (p - centroid).normalize_or_zero();
    if outward != Vec3::ZERO && outward.is_finite() {
        outward
    } else {
        Vec3::Z
    }
}

/// The eigenvalues (ascending) of symmetric `c` and the unit eigenvector of the smallest, in
/// closed form: the trigonometric solution of the characteristic cubic, then the largest cross
/// product of two rows of `c - λ0 I`. `None` where that is ill-conditioned (the two smallest
/// eigenvalues within 1e-6 of the largest, or no cross product left), for
/// [`symmetric_eigen3`] to decide.
fn smallest_eigenpair(c: &[[f64; 3]; 3]) -> Option<([f64; 3], DVec3)> {
    let off = c[0][1] * c[0][1] + c[0][2] * c[0][2] + c[1][2] * c[1][2];
    let q = (c[0][0] + c[1][1] + c[2][2]) / 3.0;
    let (a, b, d) = (c[0][0] - q, c[1][1] - q, c[2][2] - q);
    let p = ((a * a + b * b + d * d + 2.0 * off) / 6.0).sqrt();
    if !(p > 0.0 && p.is_finite()) {
        return None;
    }
    // det((c - q I) / p) / 2 = cos 3φ.
    let det = a * (b * d - c[1][2] * c[1][2]) - c[0][1] * (c[0][1] * d - c[1][2] * c[0][2])
        + c[0][2] * (c[0][1] * c[1][2] - b * c[0][2]);
    let phi = (det / (2.0 * p * p * p)).clamp(-1.0, 1.0).acos() / 3.0;
    let high = q + 2.0 * p * phi.cos();
    let low = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let mid = 3.0 * q - high - low;
    if mid - low <= 1e-6 * high.abs() {
        return None;
    }
    let rows = [
        DVec3::new(c[0][0] - low, c[0][1], c[0][2]),
        DVec3::new(c[0][1], c[1][1] - low, c[1][2]),
        DVec3::new(c[0][2], c[1][2], c[2][2] - low),
    ];
    let v = [
        rows[0].cross(rows[1]),
        rows[0].cross(rows[2]),
        rows[1].cross(rows[2]),
    ]
    .into_iter()
    .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))?;
    let len2 = v.length_squared();
    (len2 > 0.0 && len2.is_finite()).then(|| ([low, mid, high], v / len2.sqrt()))
}

/// PCA normal of point `p` and its neighbours, or `None` when they span no plane direction.
fn pca_normal(p: Vec3, neighbours: impl Iterator<Item = Vec3> + Clone) -> Option<Vec3> {
    let p = p.as_dvec3();
    // Work relative to the point itself: small numbers, no cancellation.
    let rel = |q: Vec3| q.as_dvec3() - p;
    let (sum, count) = neighbours
        .clone()
        .fold((DVec3::ZERO, 1.0), |(s, c), q| (s + rel(q), c + 1.0));
    let mean = sum / count;
    let mut c = [[0.0f64; 3]; 3];
    let mut add = |d: DVec3| {
        let d = d.to_array();
        for r in 0..3 {
            for s in r..3 {
                c[r][s] += d[r] * d[s];
            }
        }
    };
    add(-mean);
    for q in neighbours {
        add(rel(q) - mean);
    }
    c[1][0] = c[0][1];
    c[2][0] = c[0][2];
    c[2][1] = c[1][2];
    let (values, normal) = smallest_eigenpair(&c).unwrap_or_else(|| {
        let (values, vectors) = symmetric_eigen3(c);
        (values, vectors[0])
    });
    // Needs spread in at least two directions; a line or a single repeated point has no normal.
    if !(values[1] > values[2] * 1e-12 && values[2] > 0.0) {
        return None;
    }
    let n = normal.as_vec3();
    (n.is_finite() && n != Vec3::ZERO).then_some(n)
}

/// The normal of `p` from its PCA normal (oriented by the reference direction) or the fallback.
fn oriented_normal(pca: Option<Vec3>, p: Vec3, sensor: Option<Vec3>, centre: Vec3) -> Vec3 {
    let normal = match pca {
        Some(n) if n.dot(reference_direction(p, sensor, centre)) < 0.0 => -n,
        Some(n) => n,
        None => fallback_normal(p, sensor, centre),
    };
    if normal.is_finite() {
        normal
    } else {
        Vec3::Z
    }
}

/// The mean of the finite points (the origin when there is none): normals without a sensor
/// point away from it.
pub fn centroid(positions: &[Vec3]) -> Vec3 {
    let (sum, count) = positions
        .iter()
        .filter(|p| p.is_finite())
        .fold((DVec3::ZERO, 0usize), |(s, c), p| (s + p.as_dvec3(), c + 1));
    if count == 0 {
        Vec3::ZERO
    } else {
        (sum / count as f64).as_vec3()
    }
}

/// The scanner the first estimate faces before [`orient`] re-signs it: the first scan's.
fn first_sensor(cloud: &Cloud) -> Option<Vec3> {
    cloud
        .sensors
        .first()
        .map(|s| s.position)
        .filter(|s| s.is_finite())
}

/// Estimates a unit normal per point of `cloud` from its neighbourhood, oriented by the cloud's
/// [`Rule`] (see the module documentation for the fallbacks). Never returns NaN.
pub fn estimate_normals(cloud: &Cloud, neighbours: &Neighbours, progress: bool) -> Vec<Vec3> {
    let positions = &cloud.positions;
    let centre = centroid(positions);
    let sensor = first_sensor(cloud);
    let bar = Progress::new(
        "normals",
        positions.len(),
        progress && positions.len() >= PROGRESS_MIN_POINTS,
    );
    let mut normals = vec![Vec3::Z; positions.len()];
    normals
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            for (j, normal) in out.iter_mut().enumerate() {
                let i = chunk * CHUNK + j;
                let p = positions[i];
                let (idx, _) = neighbours.of(i);
                let near = idx.iter().map(|&j| positions[j as usize]);
                *normal = oriented_normal(pca_normal(p, near), p, sensor, centre);
            }
            bar.advance(out.len());
        });
    bar.finish();
    let mut graph = Graph::new(positions.len());
    graph
        .rows
        .par_chunks_mut(GRAPH_K)
        .enumerate()
        .for_each(|(i, row)| {
            for (slot, &j) in row.iter_mut().zip(neighbours.of(i).0) {
                *slot = j;
            }
        });
    orient::orient(cloud, &mut normals, &graph, Rule::for_cloud(cloud));
    normals
}

/// Radius used when no point has a neighbour at a positive distance: 1% of the bounding-box
/// diagonal, or 1.0 for an empty, single-point or all-duplicate cloud.
fn fallback_radius(positions: &[Vec3]) -> f32 {
    let mut finite = positions.iter().filter(|p| p.is_finite());
    let Some(first) = finite.next() else {
        return 1.0;
    };
    let (lo, hi) = finite.fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let diagonal = (hi - lo).length();
    if diagonal > 0.0 && diagonal.is_finite() {
        diagonal * 0.01
    } else {
        1.0
    }
}

/// A splat radius per point from the neighbour distances (see [`RadiusMode`]); always finite and
/// positive.
pub fn estimate_radii(positions: &[Vec3], neighbours: &Neighbours, mode: RadiusMode) -> Vec<f32> {
    let mut radii: Vec<f32> = (0..neighbours.len())
        .into_par_iter()
        .map(|i| {
            let d2 = neighbours.of(i).1;
            radius_of(d2.last().copied(), d2.len(), mode)
        })
        .collect();
    floor_radii(positions, &mut radii);
    radii
}

/// The radius of a point with `count` neighbours, the farthest at squared distance `last`
/// (0 without any).
fn radius_of(last: Option<f32>, count: usize, mode: RadiusMode) -> f32 {
    let Some(last) = last else { return 0.0 };
    let r_k = last.max(0.0).sqrt();
    match mode {
        RadiusMode::KthNeighbour => r_k,
        RadiusMode::DensitySpacing => r_k * (std::f32::consts::PI / count as f32).sqrt(),
    }
}

/// Raises every radius to at least [`MIN_RADIUS_FRACTION`] of the median positive radius
/// ([`fallback_radius`] when there is none).
fn floor_radii(positions: &[Vec3], radii: &mut [f32]) {
    let mut positive: Vec<f32> = radii
        .iter()
        .copied()
        .filter(|r| *r > 0.0 && r.is_finite())
        .collect();
    let floor = if positive.is_empty() {
        fallback_radius(positions)
    } else {
        let mid = positive.len() / 2;
        let (_, median, _) = positive.select_nth_unstable_by(mid, f32::total_cmp);
        *median * MIN_RADIUS_FRACTION
    };
    for r in radii.iter_mut() {
        if r.is_nan() || *r < floor {
            *r = floor;
        }
    }
}

/// Computes what the cloud lacks: normals (when `cloud.normals` is `None`) and radii (when
/// `cloud.radii` is `None`), from one k-NN search per point, in the grid's cell order; the
/// same results as [`estimate_normals`] and [`estimate_radii`] over [`Neighbours::compute`],
/// without storing the neighbours.
pub fn preprocess(cloud: &mut Cloud, options: &PreprocessOptions) {
    preprocess_with(cloud, options, &|_| {});
}

/// [`preprocess`], calling `progress` with the number of points each step finished (from the
/// worker threads), for a caller that shows its own progress (the viewer's HUD).
pub fn preprocess_with(
    cloud: &mut Cloud,
    options: &PreprocessOptions,
    progress: &(dyn Fn(usize) + Sync),
) {
    let (want_normals, want_radii) = (cloud.normals.is_none(), cloud.radii.is_none());
    if !want_normals && !want_radii {
        return;
    }
    let k = options.k.clamp(1, MAX_K);
    let positions = &cloud.positions;
    let n = positions.len();
    let grid = Grid::build(positions, k);
    let centre = centroid(positions);
    let sensor = first_sensor(cloud);
    let label = if want_normals { "normals" } else { "radii" };
    let bar = Progress::new(label, n, options.progress && n >= PROGRESS_MIN_POINTS);
    let mut found = vec![(Vec3::Z, 0f32, [orient::NONE; GRAPH_K]); grid.len()];
    grid.for_each(
        k,
        &mut found,
        1,
        |s, near, out| {
            let p = grid.position(s);
            if want_normals {
                let pca = pca_normal(p, near.iter().map(|e| grid.position(e.1)));
                out[0].0 = oriented_normal(pca, p, sensor, centre);
                for (slot, e) in out[0].2.iter_mut().zip(near) {
                    *slot = grid.input_index(e.1);
                }
            }
            out[0].1 = radius_of(near.last().map(|e| e.0), near.len(), options.radius);
        },
        &|done| {
            bar.advance(done);
            progress(done);
        },
    );
    bar.finish();
    // Non-finite points keep +Z and get the radius floor, as without neighbours.
    let mut normals = vec![Vec3::Z; n];
    let mut radii = vec![0f32; n];
    let mut graph = Graph::new(if want_normals { n } else { 0 });
    for (s, (normal, radius, row)) in found.into_iter().enumerate() {
        let i = grid.input_index(s as u32) as usize;
        normals[i] = normal;
        radii[i] = radius;
        if want_normals {
            graph.rows[i * GRAPH_K..(i + 1) * GRAPH_K].copy_from_slice(&row);
        }
    }
    if want_normals {
        orient::orient(cloud, &mut normals, &graph, Rule::for_cloud(cloud));
        cloud.normals = Some(normals);
    }
    if want_radii {
        floor_radii(positions, &mut radii);
        cloud.radii = Some(radii);
    }
}

/// Completes `cloud` from an estimate made elsewhere (the GPU path): per point in input order,
/// `xyz` its oriented unit normal and `w` the squared distance to its k-th nearest neighbour,
/// or `w < 0` for a point the estimate left unresolved, which is searched here exactly (a k-d
/// tree over the finite points); `graph` holds each resolved point's nearest neighbours.
/// Writes what the cloud lacks, as [`preprocess`] does: the same orientation, the same radii
/// rule and floor, non-finite points +Z and the floor. Returns the number of points searched
/// here.
pub fn complete_from(
    cloud: &mut Cloud,
    options: &PreprocessOptions,
    estimate: &[glam::Vec4],
    mut graph: Graph,
) -> usize {
    let (want_normals, want_radii) = (cloud.normals.is_none(), cloud.radii.is_none());
    if !want_normals && !want_radii {
        return 0;
    }
    let positions = &cloud.positions;
    assert_eq!(estimate.len(), positions.len(), "one estimate per point");
    let k = options.k.clamp(1, MAX_K);
    let unresolved: Vec<u32> = (0..positions.len() as u32)
        .into_par_iter()
        .filter(|&i| estimate[i as usize].w < 0.0 && positions[i as usize].is_finite())
        .collect();
    let mut normals: Vec<Vec3> = estimate.par_iter().map(|e| e.truncate()).collect();
    let mut radii: Vec<f32> = estimate
        .par_iter()
        .map(|e| {
            let far2 = (e.w >= 0.0).then_some(e.w);
            radius_of(far2, k, options.radius)
        })
        .collect();
    if !unresolved.is_empty() {
        let tree = FiniteTree::new(positions);
        let centre = centroid(positions);
        let sensor = first_sensor(cloud);
        let exact: Vec<(Vec3, f32, [u32; GRAPH_K])> = unresolved
            .par_iter()
            .map_init(Vec::new, |found, &i| {
                tree.nearest(positions, i as usize, k, found);
                let p = positions[i as usize];
                let near = found.iter().map(|&(j, _)| positions[j as usize]);
                let normal = oriented_normal(pca_normal(p, near), p, sensor, centre);
                let far2 = found.last().map(|e| e.1);
                let mut row = [orient::NONE; GRAPH_K];
                for (slot, &(j, _)) in row.iter_mut().zip(found.iter()) {
                    *slot = j;
                }
                (normal, radius_of(far2, found.len(), options.radius), row)
            })
            .collect();
        for (&i, (normal, radius, row)) in unresolved.iter().zip(exact) {
            let i = i as usize;
            normals[i] = normal;
            radii[i] = radius;
            graph.rows[i * GRAPH_K..(i + 1) * GRAPH_K].copy_from_slice(&row);
        }
    }
    if want_normals {
        orient::orient(cloud, &mut normals, &graph, Rule::for_cloud(cloud));
        cloud.normals = Some(normals);
    }
    if want_radii {
        floor_radii(positions, &mut radii);
        cloud.radii = Some(radii);
    }
    unresolved.len()
}

const CACHE_MAGIC: &[u8; 8] = b"SURFELPC";
const CACHE_VERSION: u32 = 2;
const CACHE_HEADER: usize = 8 + 4 + 4 + 4 + 8 + 8 + 8 + 4;

/// The cache file for `input`: `<input>.surfel-cache` beside it.
pub fn cache_path(input: &Path) -> PathBuf {
    let mut name = input.as_os_str().to_owned();
    name.push(".surfel-cache");
    PathBuf::from(name)
}

/// Size and modification time (seconds, nanoseconds) of the input, the cache's validity key.
fn input_stamp(input: &Path) -> Option<(u64, u64, u32)> {
    let meta = std::fs::metadata(input).ok()?;
    let modified = meta.modified().ok()?.duration_since(UNIX_EPOCH).ok()?;
    Some((meta.len(), modified.as_secs(), modified.subsec_nanos()))
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn cache_header(options: &PreprocessOptions, points: usize, stamp: (u64, u64, u32)) -> Vec<u8> {
    let mut h = Vec::with_capacity(CACHE_HEADER);
    h.extend_from_slice(CACHE_MAGIC);
    h.extend_from_slice(&CACHE_VERSION.to_le_bytes());
    h.extend_from_slice(&(options.k as u32).to_le_bytes());
    let mode: u32 = match options.radius {
        RadiusMode::KthNeighbour => 0,
        RadiusMode::DensitySpacing => 1,
    };
    h.extend_from_slice(&mode.to_le_bytes());
    h.extend_from_slice(&(points as u64).to_le_bytes());
    h.extend_from_slice(&stamp.0.to_le_bytes());
    h.extend_from_slice(&stamp.1.to_le_bytes());
    h.extend_from_slice(&stamp.2.to_le_bytes());
    h
}

/// Reads cached normals and radii for `input`, or `None` when there is no cache or it does not
/// match: wrong magic/version, other `k` or radius mode, other point count, the input's size or
/// modification time changed since the cache was written, wrong length, or a bad checksum.
pub fn load_cache(
    input: &Path,
    options: &PreprocessOptions,
    points: usize,
) -> Option<(Vec<Vec3>, Vec<f32>)> {
    let stamp = input_stamp(input)?;
    let expected_len = CACHE_HEADER
        .checked_add(points.checked_mul(16)?)?
        .checked_add(8)?;
    let meta = std::fs::metadata(cache_path(input)).ok()?;
    if meta.len() != expected_len as u64 {
        return None;
    }
    let bytes = std::fs::read(cache_path(input)).ok()?;
    if bytes.len() != expected_len
        || bytes[..CACHE_HEADER] != cache_header(options, points, stamp)[..]
    {
        return None;
    }
    let (body, sum) = bytes.split_at(expected_len - 8);
    if fnv1a(body).to_le_bytes() != sum {
        return None;
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let (normal_bytes, radius_bytes) = body[CACHE_HEADER..].split_at(points * 12);
    let normals: Vec<Vec3> = normal_bytes
        .chunks_exact(12)
        .map(|c| Vec3::new(f(&c[0..4]), f(&c[4..8]), f(&c[8..12])))
        .collect();
    let radii: Vec<f32> = radius_bytes.chunks_exact(4).map(f).collect();
    let sane =
        normals.iter().all(|n| n.is_finite()) && radii.iter().all(|r| r.is_finite() && *r > 0.0);
    sane.then_some((normals, radii))
}

/// Writes normals and radii for `input` to its cache file (via a temporary file and a rename,
/// so a crash never leaves a half-written cache under the real name).
pub fn save_cache(
    input: &Path,
    options: &PreprocessOptions,
    normals: &[Vec3],
    radii: &[f32],
) -> io::Result<()> {
    if normals.len() != radii.len() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} normals but {} radii", normals.len(), radii.len()),
        ));
    }
    let stamp = input_stamp(input).ok_or_else(|| {
        io::Error::other(format!(
            "{}: cannot read size and modification time",
            input.display()
        ))
    })?;
    let mut bytes = cache_header(options, normals.len(), stamp);
    bytes.reserve(normals.len() * 16 + 8);
    for n in normals {
        for c in n.to_array() {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    for r in radii {
        bytes.extend_from_slice(&r.to_le_bytes());
    }
    let sum = fnv1a(&bytes);
    bytes.extend_from_slice(&sum.to_le_bytes());
    let target = cache_path(input);
    let mut tmp = target.clone().into_os_string();
    tmp.push(".tmp");
    std::fs::write(&tmp, &bytes)?;
    std::fs::rename(&tmp, &target)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, h: f32) -> Vec<Vec3> {
        (0..n * n)
            .map(|i| Vec3::new((i % n) as f32 * h, (i / n) as f32 * h, 0.0))
            .collect()
    }

    #[test]
    fn the_closed_form_eigenpair_matches_jacobi() {
        let mut rng = crate::rng::SplitMix64::new(11);
        let mut solved = 0;
        for case in 0..2000 {
            // Covariances of flat, elongated and round neighbourhoods at scales 1e-4 .. 1e4.
            let scale = 10f64.powi(case % 9 - 4);
            let spread = [
                1.0,
                0.3 + rng.next_f64(),
                [1e-6, 1e-3, 0.1, 0.9][case as usize % 4],
            ];
            let rotation = glam::DQuat::from_euler(
                glam::EulerRot::XYZ,
                rng.next_f64() * 6.3,
                rng.next_f64() * 6.3,
                rng.next_f64() * 6.3,
            );
            let axes = glam::DMat3::from_quat(rotation);
            let mut c = [[0.0; 3]; 3];
            for (k, s) in spread.iter().enumerate() {
                let v = axes.col(k);
                for r in 0..3 {
                    for t in 0..3 {
                        c[r][t] += s * scale * v[r] * v[t];
                    }
                }
            }
            let (values, vectors) = symmetric_eigen3(c);
            let Some((fast, normal)) = smallest_eigenpair(&c) else {
                continue;
            };
            solved += 1;
            for (a, b) in fast.iter().zip(values) {
                assert!(
                    (a - b).abs() <= 1e-9 * values[2],
                    "{case}: {fast:?} vs {values:?}"
                );
            }
            assert!(normal.dot(vectors[0]).abs() > 1.0 - 1e-9, "{case}");
        }
        // Only near-equal smallest eigenvalues are left to Jacobi.
        assert!(solved > 1900, "{solved}");
    }

    #[test]
    fn eigen_known_matrices() {
        let (values, vectors) =
            symmetric_eigen3([[2.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 1.0]]);
        assert_eq!(values, [1.0, 2.0, 3.0]);
        assert!((vectors[0].abs() - DVec3::Z).length() < 1e-12);
        // [[2,1,0],[1,2,0],[0,0,5]]: eigenvalues 1, 3, 5.
        let m = [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]];
        let (values, vectors) = symmetric_eigen3(m);
        for (v, e) in values.iter().zip([1.0, 3.0, 5.0]) {
            assert!((v - e).abs() < 1e-12);
        }
        for (value, vector) in values.iter().zip(vectors) {
            let mv = DVec3::new(
                m[0][0] * vector.x + m[0][1] * vector.y + m[0][2] * vector.z,
                m[1][0] * vector.x + m[1][1] * vector.y + m[1][2] * vector.z,
                m[2][0] * vector.x + m[2][1] * vector.y + m[2][2] * vector.z,
            );
            assert!((mv - vector * *value).length() < 1e-12);
        }
        let (values, _) = symmetric_eigen3([[4.0, 2.0, 2.0], [2.0, 4.0, 2.0], [2.0, 2.0, 4.0]]);
        for (v, e) in values.iter().zip([2.0, 2.0, 8.0]) {
            assert!((v - e).abs() < 1e-12, "{values:?}");
        }
        let (values, vectors) = symmetric_eigen3([[0.0; 3]; 3]);
        assert_eq!(values, [0.0; 3]);
        assert!(vectors.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn plane_normals_point_to_sensor_or_outward() {
        let tilt = glam::Quat::from_rotation_x(0.3);
        let points: Vec<Vec3> = grid(20, 0.1).into_iter().map(|p| tilt * p).collect();
        let nb = Neighbours::compute(&points, 10, false);
        let expected = tilt * Vec3::Z;
        let seen_from = |position: Vec3| Cloud {
            positions: points.clone(),
            sensors: vec![crate::scene::Sensor { first: 0, position }],
            ..Cloud::default()
        };
        let towards = estimate_normals(&seen_from(Vec3::new(1.0, 1.0, 5.0)), &nb, false);
        let away = estimate_normals(&seen_from(Vec3::new(1.0, 1.0, -5.0)), &nb, false);
        for (a, b) in towards.iter().zip(&away) {
            assert!((*a - expected).length() < 1e-4, "{a}");
            assert!((*b + expected).length() < 1e-4, "{b}");
        }
        // Without a sensor: a sphere's normals point outward.
        let sphere: Vec<Vec3> = (0..2000)
            .map(|i| {
                let t = i as f32 * 2.399_963;
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 2000.0;
                let r = (1.0 - z * z).sqrt();
                Vec3::new(r * t.cos(), r * t.sin(), z)
            })
            .collect();
        let nb = Neighbours::compute(&sphere, 10, false);
        let bare = Cloud {
            positions: sphere.clone(),
            ..Cloud::default()
        };
        let normals = estimate_normals(&bare, &nb, false);
        for (p, n) in sphere.iter().zip(&normals) {
            assert!(p.dot(*n) > 0.95);
        }
    }

    #[test]
    fn grid_radius_matches_spacing() {
        let h = 0.5;
        let points = grid(30, h);
        let nb = Neighbours::compute(&points, 8, false);
        let kth = estimate_radii(&points, &nb, RadiusMode::KthNeighbour);
        let density = estimate_radii(&points, &nb, RadiusMode::DensitySpacing);
        // Interior point: 4 neighbours at h and 4 at h*sqrt(2).
        let i = 15 * 30 + 15;
        assert!((kth[i] - h * 2f32.sqrt()).abs() < 1e-5);
        let spacing = h * 2f32.sqrt() * (std::f32::consts::PI / 8.0).sqrt();
        assert!((density[i] - spacing).abs() < 1e-5);
        let nb4 = Neighbours::compute(&points, 4, false);
        let r4 = estimate_radii(&points, &nb4, RadiusMode::KthNeighbour);
        assert!((r4[i] - h).abs() < 1e-6);
    }

    #[test]
    fn degenerate_clouds_do_not_panic() {
        let options = PreprocessOptions::default();
        for positions in [
            vec![],
            vec![Vec3::ONE],
            vec![Vec3::splat(2.0); 100],
            vec![Vec3::ZERO, Vec3::X],
            vec![
                Vec3::ZERO,
                Vec3::splat(f32::NAN),
                Vec3::Y,
                Vec3::X,
                Vec3::new(1.0, 1.0, 0.0),
            ],
        ] {
            let mut cloud = Cloud {
                positions: positions.clone(),
                ..Cloud::default()
            };
            preprocess(&mut cloud, &options);
            let normals = cloud.normals.unwrap();
            let radii = cloud.radii.unwrap();
            assert_eq!(normals.len(), positions.len());
            assert!(normals
                .iter()
                .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-5));
            assert!(radii.iter().all(|r| r.is_finite() && *r > 0.0), "{radii:?}");
        }
        // Duplicates among spread points get a fraction of the median, not 0.
        let mut points = grid(10, 1.0);
        points.extend(std::iter::repeat_n(Vec3::ZERO, 20));
        let nb = Neighbours::compute(&points, 4, false);
        let radii = estimate_radii(&points, &nb, RadiusMode::KthNeighbour);
        assert!((radii[0] - 0.1).abs() < 1e-6);
    }

    #[test]
    fn cache_round_trip_and_staleness() {
        let dir = std::env::temp_dir().join(format!("surfel-cache-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("in.xyz");
        std::fs::write(&input, "0 0 0\n1 0 0\n").unwrap();
        let options = PreprocessOptions::default();
        let normals = vec![Vec3::Z, Vec3::X];
        let radii = vec![0.5, 0.25];
        save_cache(&input, &options, &normals, &radii).unwrap();
        assert_eq!(
            load_cache(&input, &options, 2),
            Some((normals.clone(), radii.clone()))
        );
        assert_eq!(load_cache(&input, &options, 3), None);
        let other_k = PreprocessOptions { k: 7, ..options };
        assert_eq!(load_cache(&input, &other_k, 2), None);
        // Corrupt one payload byte: checksum rejects it.
        let path = cache_path(&input);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[CACHE_HEADER + 1] ^= 0x40;
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(load_cache(&input, &options, 2), None);
        // Fresh cache, then the input changes: stale.
        save_cache(&input, &options, &normals, &radii).unwrap();
        std::fs::write(&input, "0 0 0\n1 0 0\n2 0 0\n").unwrap();
        assert_eq!(load_cache(&input, &options, 2), None);
        std::fs::write(&path, b"garbage").unwrap();
        assert_eq!(load_cache(&input, &options, 2), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
