//! Exact k nearest neighbours on a uniform grid: the finite points are sorted by cell (one
//! parallel sort of 64-bit cell keys, z-major so the three cells of a row are adjacent), and the
//! neighbours of a point are searched in the 3×3×3 block of cells around its own, nine
//! contiguous runs of the sorted array that every point of the cell shares (copied out once per
//! cell). Only candidates within the distance from the point to the block's boundary are
//! kept, so the result is exact when k of them remain; otherwise the 5×5×5 block is searched
//! the same way, and a point still unresolved there (an outlier far from the rest) asks a k-d
//! tree built over the sorted points on first use. Ties are broken by sorted index, so the
//! result does not depend on the threads.
//!
//! The cell is sized from a strided sample of the cloud: the median k-th neighbour distance in
//! the sample, scaled to the full cloud's density as for a surface (distances shrink with the
//! square root of the point count), times [`CELL_FACTOR`], so the k-th neighbour of a surface
//! point usually lies within one cell. A volume-filling cloud gets a smaller cell than it could
//! use and resolves more points in the second block; results stay exact either way.

use std::num::NonZeroUsize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use glam::Vec3;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;

/// Bits of one axis in a cell key.
const AXIS_BITS: u32 = 21;
/// Cells per axis at most.
const AXIS_CELLS: u32 = 1 << AXIS_BITS;
/// Clouds of at most this many points are searched in one block covering all of them.
const SMALL_CLOUD: usize = 1024;
/// Points of the sample that sizes the cell.
const SAMPLE: usize = 16_384;
/// The cell edge over the estimated k-th neighbour distance.
const CELL_FACTOR: f32 = 1.5;

type Tree = ImmutableKdTree<f32, u32, 3, 32>;

/// The cells of a grid: cubes of edge `cell` from `origin`, `dims` of them per axis; a point
/// lies in the cell `floor((p - origin) / cell)` clamped to `[0, dims)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridFrame {
    pub origin: Vec3,
    pub cell: f32,
    pub dims: [u32; 3],
}

impl GridFrame {
    /// The frame for `k` neighbours over the points of `positions` listed in `finite` (see
    /// the module documentation for the cell size).
    pub fn new(positions: &[Vec3], finite: &[u32], k: usize) -> Self {
        let (lo, hi) = finite
            .par_iter()
            .map(|&i| (positions[i as usize], positions[i as usize]))
            .reduce(
                || (Vec3::INFINITY, Vec3::NEG_INFINITY),
                |a, b| (a.0.min(b.0), a.1.max(b.1)),
            );
        let extent = if finite.is_empty() {
            Vec3::ZERO
        } else {
            hi - lo
        };
        let mut cell = cell_size(positions, finite, extent, k);
        // Every axis fits its key bits, and the cell is never zero or subnormal.
        let widest = extent.max_element();
        cell = cell
            .max(widest / (AXIS_CELLS - 2) as f32)
            .max(f32::MIN_POSITIVE * 1e6);
        if !cell.is_finite() {
            cell = 1.0;
        }
        let origin = if finite.is_empty() { Vec3::ZERO } else { lo };
        let dims = ((extent / cell).floor().as_uvec3() + 1).min(glam::UVec3::splat(AXIS_CELLS - 1));
        GridFrame {
            origin,
            cell,
            dims: dims.to_array(),
        }
    }

    /// The cell of `p`.
    pub fn cell_of(&self, p: Vec3) -> [u32; 3] {
        let c = ((p - self.origin) / self.cell)
            .floor()
            .max(Vec3::ZERO)
            .as_uvec3();
        [
            c.x.min(self.dims[0] - 1),
            c.y.min(self.dims[1] - 1),
            c.z.min(self.dims[2] - 1),
        ]
    }
}

/// The indices of the finite points of `positions`, ascending.
pub fn finite_indices(positions: &[Vec3]) -> Vec<u32> {
    (0..positions.len() as u32)
        .into_par_iter()
        .filter(|&i| positions[i as usize].is_finite())
        .collect()
}

/// The finite points of a cloud sorted by grid cell.
pub struct Grid {
    /// Distinct for every grid built in this process.
    id: u64,
    origin: Vec3,
    cell: f32,
    dims: [u32; 3],
    /// Sorted positions and their indices in the input.
    points: Vec<Vec3>,
    index: Vec<u32>,
    /// Cell of each sorted point, as `[x, y, z]`.
    cells: Vec<[u32; 3]>,
    /// Keys of the occupied cells, ascending, and the first sorted point of each (plus the
    /// number of points at the end).
    keys: Vec<u64>,
    starts: Vec<u32>,
    tree: OnceLock<Tree>,
}

/// Per-thread state of a search: the points of the last cell's 3×3×3 block and the best
/// neighbours found, `(squared distance, sorted index)`, nearest first.
#[derive(Default)]
pub struct Search {
    /// The grid ([`Grid::id`]) and cell whose block `near` holds.
    cell: Option<(u64, [u32; 3])>,
    /// The runs of the block being gathered.
    runs: Vec<(u32, u32)>,
    /// Per row of the 3×3×3 block, the first occupied cell at or after the row's start when
    /// `near` was last gathered ([`Grid::block`]).
    cursors: [usize; 9],
    best: Vec<(f32, u32)>,
    keys: Vec<u64>,
    /// The points of the cell's 3×3×3 block, and of a 5×5×5 block while one is searched.
    near: Gathered,
    far: Gathered,
}

/// Candidate points copied out of a block's runs: coordinates by axis and sorted indices.
#[derive(Default)]
struct Gathered {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    index: Vec<u32>,
    /// Squared distances (as bits) to the point searched for.
    dist2: Vec<u32>,
}

impl Gathered {
    fn gather(&mut self, grid: &Grid, runs: &[(u32, u32)]) {
        self.x.clear();
        self.y.clear();
        self.z.clear();
        self.index.clear();
        for &(a, b) in runs {
            let points = &grid.points[a as usize..b as usize];
            self.x.extend(points.iter().map(|p| p.x));
            self.y.extend(points.iter().map(|p| p.y));
            self.z.extend(points.iter().map(|p| p.z));
            self.index.extend(a..b);
        }
    }
}

impl Search {
    /// The neighbours of the last [`Grid::nearest`] query, `(squared distance, sorted index)`,
    /// nearest first.
    pub fn found(&self) -> &[(f32, u32)] {
        &self.best
    }
}

fn key([x, y, z]: [u32; 3]) -> u64 {
    (u64::from(z) << (2 * AXIS_BITS)) | (u64::from(y) << AXIS_BITS) | u64::from(x)
}

impl Grid {
    /// Sorts the finite points of `positions` into cells sized for `k` neighbours.
    pub fn build(positions: &[Vec3], k: usize) -> Self {
        let finite = finite_indices(positions);
        let frame = GridFrame::new(positions, &finite, k);
        let GridFrame { origin, cell, dims } = frame;
        let cell_of = |p: Vec3| frame.cell_of(p);
        let mut order: Vec<(u64, u32)> = finite
            .par_iter()
            .map(|&i| (key(cell_of(positions[i as usize])), i))
            .collect();
        order.par_sort_unstable();
        let points: Vec<Vec3> = order
            .par_iter()
            .map(|&(_, i)| positions[i as usize])
            .collect();
        let index: Vec<u32> = order.par_iter().map(|&(_, i)| i).collect();
        let cells: Vec<[u32; 3]> = points.par_iter().map(|&p| cell_of(p)).collect();
        let mut keys = Vec::new();
        let mut starts = Vec::new();
        for (s, &(k, _)) in order.iter().enumerate() {
            if keys.last() != Some(&k) {
                keys.push(k);
                starts.push(s as u32);
            }
        }
        starts.push(order.len() as u32);
        static NEXT_ID: AtomicU64 = AtomicU64::new(0);
        Grid {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            origin,
            cell,
            dims,
            points,
            index,
            cells,
            keys,
            starts,
            tree: OnceLock::new(),
        }
    }

    /// Number of finite points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no finite points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Position of sorted point `s`.
    pub fn position(&self, s: u32) -> Vec3 {
        self.points[s as usize]
    }

    /// Index in the input of sorted point `s`.
    pub fn input_index(&self, s: u32) -> u32 {
        self.index[s as usize]
    }

    /// The cell edge.
    pub fn cell(&self) -> f32 {
        self.cell
    }

    /// The sorted point runs of the `(2 r + 1)³` block of cells around `c`. `cursors` holds
    /// one entry per row of the block (`(2 r + 1)²`): where the search for the row's first
    /// cell starts, updated to what it found. Cells visited in ascending order move every row
    /// forward, so the search gallops a few steps from the last position (zeros: from the
    /// start).
    fn block(&self, c: [u32; 3], r: u32, cursors: &mut [usize], runs: &mut Vec<(u32, u32)>) {
        runs.clear();
        let span = |a: u32, d: u32| a.saturating_sub(r)..=(a + r).min(d - 1);
        let xs = span(c[0], self.dims[0]);
        let side = (2 * r + 1) as usize;
        for (row, cursor) in cursors.iter_mut().enumerate().take(side * side) {
            let (dz, dy) = ((row / side) as u32, (row % side) as u32);
            let (Some(z), Some(y)) = ((c[2] + dz).checked_sub(r), (c[1] + dy).checked_sub(r))
            else {
                continue;
            };
            if z >= self.dims[2] || y >= self.dims[1] {
                continue;
            }
            let lo = key([*xs.start(), y, z]);
            let hi = key([*xs.end(), y, z]);
            let a = self.first_at_least(lo, *cursor);
            *cursor = a;
            let b = a + self.keys[a..].iter().take_while(|&&k| k <= hi).count();
            if a < b {
                runs.push((self.starts[a], self.starts[b]));
            }
        }
    }

    /// The first occupied cell whose key is at least `lo`, galloping forward from `from` (from
    /// the start when `from` is already past it).
    fn first_at_least(&self, lo: u64, from: usize) -> usize {
        let keys = &self.keys;
        let mut a = from.min(keys.len());
        if a > 0 && keys[a - 1] >= lo {
            a = 0;
        }
        let mut step = 1;
        while a + step < keys.len() && keys[a + step - 1] < lo {
            a += step;
            step *= 2;
        }
        a + keys[a..(a + step).min(keys.len())].partition_point(|&k| k < lo)
    }

    /// Whether the block of radius `r` around `c` holds every cell.
    fn covers_all(&self, c: [u32; 3], r: u32) -> bool {
        (0..3).all(|a| c[a] <= r && c[a] + r + 1 >= self.dims[a])
    }

    /// Squared distance from `p` (in cell `c`) to the nearest face of the block of radius `r`.
    fn inner_bound2(&self, p: Vec3, c: [u32; 3], r: u32) -> f32 {
        let mut bound = f32::INFINITY;
        for a in 0..3 {
            let lo = c[a] as f32 - r as f32;
            let hi = (c[a] + r + 1) as f32;
            let at = (p[a] - self.origin[a]) / self.cell;
            if lo > 0.0 {
                bound = bound.min(at - lo);
            }
            if (hi as u32) < self.dims[a] {
                bound = bound.min(hi - at);
            }
        }
        // A hair inside the block: rounding never lets a point beyond it count as searched.
        let d = bound.max(0.0) * self.cell * (1.0 - 1e-5);
        d * d
    }

    /// The candidates of `runs` within squared distance `limit` (as bits) of sorted point `s`,
    /// as keys: non-negative floats order as their bits, and the sorted index in the low half
    /// breaks ties, so the result does not depend on the scan order.
    fn collect(&self, s: u32, from: &mut Gathered, limit: u32, keys: &mut Vec<u64>) {
        let p = self.points[s as usize];
        let n = from.index.len();
        // Distances in one pass the compiler vectorizes (the same operations, in the same
        // order, as `Vec3::length_squared`), then a compaction without branches.
        from.dist2.clear();
        from.dist2
            .extend(from.x.iter().zip(&from.y).zip(&from.z).map(|((x, y), z)| {
                let (dx, dy, dz) = (x - p.x, y - p.y, z - p.z);
                (dx * dx + dy * dy + dz * dz).to_bits()
            }));
        keys.clear();
        keys.resize(n, 0);
        let mut kept = 0;
        for (&d2, &t) in from.dist2.iter().zip(&from.index) {
            keys[kept] = (u64::from(d2) << 32) | u64::from(t);
            kept += usize::from(d2 <= limit);
        }
        keys.truncate(kept);
    }

    /// The `k` nearest candidates of `runs` within squared distance `limit` of sorted point `s`
    /// into `search.best`, nearest first.
    fn scan(&self, s: u32, k: usize, from: &mut Gathered, limit: f32, search: &mut Search) {
        let limit = if limit.is_nan() {
            0
        } else {
            limit.max(0.0).to_bits()
        };
        // First within twice the last point's squared k-th distance, when that is nearer
        // (neighbouring points have similar spacing): fewer candidates to select from.
        let guess = match search.best.last() {
            Some(&(d2, _)) if search.best.len() == k => (d2 * 2.0).to_bits().min(limit),
            _ => limit,
        };
        self.collect(s, from, guess, &mut search.keys);
        if guess < limit && search.keys.len() <= k {
            self.collect(s, from, limit, &mut search.keys);
        }
        // The k smallest keys by insertion into a sorted prefix (the candidates are few).
        let keys = &mut search.keys;
        let mut len = 0;
        for j in 0..keys.len() {
            let e = keys[j];
            if e as u32 == s || (len == k && e >= keys[k - 1]) {
                continue;
            }
            let mut at = len.min(k - 1);
            while at > 0 && keys[at - 1] > e {
                keys[at] = keys[at - 1];
                at -= 1;
            }
            keys[at] = e;
            len = (len + 1).min(k);
        }
        search.best.clear();
        search.best.extend(
            keys[..len]
                .iter()
                .map(|&e| (f32::from_bits((e >> 32) as u32), e as u32)),
        );
    }

    /// Finds the `k` nearest neighbours of sorted point `s` (fewer when the cloud has no more),
    /// excluding the point itself; read them with [`Search::found`].
    pub fn nearest(&self, s: u32, k: usize, search: &mut Search) {
        let c = self.cells[s as usize];
        let p = self.points[s as usize];
        let at = Some((self.id, c));
        if search.cell != at {
            self.block(c, 1, &mut search.cursors, &mut search.runs);
            search.near.gather(self, &search.runs);
            search.cell = at;
        }
        // Within the block's inner bound, or everything when the block holds every cell: a
        // point beyond the bound can only be a neighbour of a result the block cannot verify.
        let limit = |r: u32| {
            if self.covers_all(c, r) {
                f32::INFINITY
            } else {
                self.inner_bound2(p, c, r)
            }
        };
        let done = |r: u32, best: &[(f32, u32)]| self.covers_all(c, r) || best.len() == k;
        let mut near = std::mem::take(&mut search.near);
        self.scan(s, k, &mut near, limit(1), search);
        search.near = near;
        if done(1, &search.best) {
            return;
        }
        let mut far = std::mem::take(&mut search.far);
        let mut cursors = [0; 25];
        self.block(c, 2, &mut cursors, &mut search.runs);
        far.gather(self, &search.runs);
        self.scan(s, k, &mut far, limit(2), search);
        search.far = far;
        if done(2, &search.best) {
            return;
        }
        let tree = self.tree.get_or_init(|| {
            let coords: Vec<[f32; 3]> = self.points.iter().map(|p| p.to_array()).collect();
            Tree::new_from_slice(&coords)
        });
        let want = NonZeroUsize::new((k + 1).min(self.len())).unwrap_or(NonZeroUsize::MIN);
        search.best.clear();
        for nb in tree.nearest_n::<SquaredEuclidean>(&p.to_array(), want) {
            if nb.item != s && search.best.len() < k {
                search.best.push((nb.distance, nb.item));
            }
        }
    }

    /// Runs `f(sorted index, neighbours, out)` for every point in parallel, `out` being the
    /// point's `width` entries of `out` (sorted order); `progress` gets the points done.
    pub fn for_each<T: Send>(
        &self,
        k: usize,
        out: &mut [T],
        width: usize,
        f: impl Fn(u32, &[(f32, u32)], &mut [T]) + Sync,
        progress: &(dyn Fn(usize) + Sync),
    ) {
        const CHUNK: usize = 4096;
        assert!(
            width > 0 && out.len() == self.len() * width,
            "one row of {width} per point"
        );
        out.par_chunks_mut(CHUNK * width)
            .enumerate()
            .for_each(|(c, rows)| {
                let mut search = Search::default();
                let first = c * CHUNK;
                let count = rows.len() / width;
                for j in 0..count {
                    let s = (first + j) as u32;
                    self.nearest(s, k, &mut search);
                    f(s, search.found(), &mut rows[j * width..(j + 1) * width]);
                }
                progress(count);
            });
    }
}

/// The cell edge for `k` neighbours (see the module documentation).
fn cell_size(positions: &[Vec3], finite: &[u32], extent: Vec3, k: usize) -> f32 {
    let n = finite.len();
    let widest = extent.max_element();
    if n <= SMALL_CLOUD || k + 1 >= n {
        // One block covers everything: a brute-force search.
        return widest.max(f32::MIN_POSITIVE);
    }
    let stride = n.div_ceil(SAMPLE);
    let sample: Vec<[f32; 3]> = finite
        .iter()
        .step_by(stride)
        .map(|&i| positions[i as usize].to_array())
        .collect();
    let m = sample.len();
    if k + 1 >= m {
        return widest.max(f32::MIN_POSITIVE);
    }
    let tree = Tree::new_from_slice(&sample);
    let want = NonZeroUsize::new(k + 1).unwrap_or(NonZeroUsize::MIN);
    let mut rk: Vec<f32> = sample
        .par_iter()
        .step_by(8)
        .map(|p| {
            tree.nearest_n::<SquaredEuclidean>(p, want)
                .last()
                .map_or(0.0, |nb| nb.distance.sqrt())
        })
        .collect();
    let mid = rk.len() / 2;
    let (_, median, _) = rk.select_nth_unstable_by(mid, f32::total_cmp);
    let scaled = *median * (m as f32 / n as f32).sqrt() * CELL_FACTOR;
    if scaled > 0.0 && scaled.is_finite() {
        scaled
    } else {
        // All duplicates in the sample: a cell a thousandth of the cloud's extent.
        (widest * 1e-3).max(f32::MIN_POSITIVE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// The k nearest by brute force: sorted distances.
    fn brute(points: &[Vec3], i: usize, k: usize) -> Vec<f32> {
        let mut d: Vec<f32> = points
            .iter()
            .enumerate()
            .filter(|&(j, q)| j != i && q.is_finite())
            .map(|(_, q)| (*q - points[i]).length_squared())
            .collect();
        d.sort_by(f32::total_cmp);
        d.truncate(k);
        d
    }

    fn check(points: &[Vec3], k: usize) {
        let grid = Grid::build(points, k);
        let mut search = Search::default();
        for s in 0..grid.len() as u32 {
            grid.nearest(s, k, &mut search);
            let i = grid.input_index(s) as usize;
            let got: Vec<f32> = search.found().iter().map(|e| e.0).collect();
            assert_eq!(got, brute(points, i, k), "point {i}");
            for &(d2, t) in search.found() {
                assert_eq!(d2, (grid.position(t) - points[i]).length_squared());
            }
        }
    }

    #[test]
    fn matches_brute_force_on_surfaces_volumes_and_outliers() {
        let mut rng = SplitMix64::new(7);
        // A wavy surface, a filled box, clusters far apart and single outliers.
        let surface: Vec<Vec3> = (0..3000)
            .map(|_| {
                let (u, v) = (rng.next_f64() as f32 * 4.0, rng.next_f64() as f32 * 4.0);
                Vec3::new(u, v, (u * 2.0).sin() * 0.3)
            })
            .collect();
        check(&surface, 10);
        let volume: Vec<Vec3> = (0..3000)
            .map(|_| {
                Vec3::new(
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                )
            })
            .collect();
        check(&volume, 10);
        let mut mixed = surface.clone();
        mixed.extend((0..40).map(|i| Vec3::new(100.0 + i as f32 * 37.0, -50.0, 9.0)));
        mixed.push(Vec3::splat(f32::NAN));
        mixed.extend(std::iter::repeat_n(Vec3::new(1.0, 1.0, 0.0), 30));
        check(&mixed, 10);
        check(&mixed[..12], 10);
        check(&mixed[..2], 1);
    }

    #[test]
    fn degenerate_clouds_have_no_or_few_neighbours() {
        let grid = Grid::build(&[], 10);
        assert!(grid.is_empty());
        let grid = Grid::build(&[Vec3::splat(f32::INFINITY), Vec3::ONE], 10);
        let mut search = Search::default();
        grid.nearest(0, 10, &mut search);
        assert!(search.found().is_empty());
        let same = vec![Vec3::splat(3.0); 5000];
        let grid = Grid::build(&same, 4);
        grid.nearest(17, 4, &mut search);
        assert_eq!(search.found().len(), 4);
        assert!(search.found().iter().all(|e| e.0 == 0.0 && e.1 != 17));
    }
}
