//! The approximate convex hulls of 003 ch. 3 as HPR visibility operators: every method works
//! on the spherically flipped points plus the viewpoint (the origin) like [`super::exact`], and
//! a point is visible when its flipped image is a vertex of the approximate hull. Exact
//! duplicates and points at the viewpoint are handled as in [`super::exact`] (one flipped image
//! per position, every copy visible with it; points at the viewpoint hidden).
//!
//! * [`Hull::Bfp`] (Bentley, Faust and Preparata, §3.1, 3D form): a grid of cells over two axes
//!   of the bounding rectangle; per cell the points of least and greatest coordinate along the
//!   third axis, plus the points of least and greatest coordinate along the two grid axes;
//!   then the exact hull (Qhull) of those points and the viewpoint.
//!   Deviations: the thesis grids (k + 2) × (k + 2) squares over the world x and y axes; here
//!   `cells` is the whole count (a round(√cells)² grid, comparable with k sectors) and the axes
//!   are a frame whose third axis runs from the viewpoint to the flipped points' centroid, so
//!   that the result does not depend on how the model lies in its file (over world axes a view
//!   along x sees the flipped shell edge-on). The two extra rows and columns of the thesis'
//!   grid hold its extremes of x and y, kept here explicitly.
//! * [`Hull::Kavan`] (Kavan, Kolingerová and Žára, §3.2, the improved algorithm): an origin q
//!   inside the hull; the sphere of directions around q cut into k sectors of equal area; per
//!   sector the point of the sector maximising (p − q)·dᵢ; then the O(k²) refinement: each
//!   sector's extreme is replaced by the best of all sectors' extremes along dᵢ (this can drop
//!   but never add points). The visible points are the refined extremes; there are no triangles.
//! * [`Hull::Hybrid`] (§3.3): the sector extremes of Kavan's steps 1 and 2, then the exact hull
//!   (Qhull) of those extremes and the viewpoint; its vertices are visible and its facets away
//!   from the viewpoint are the triangles.
//!
//! Sectors: the thesis suggests Leopardi's recursive zonal equal-area partition (Fig. 3.4);
//! [`Sectors`] is its two-dimensional case: two polar caps of area 4π/k and collars of
//! near-square regions whose counts are rounded with carried remainders; unlike Leopardi the
//! collars are not rotated against each other. Each sector's direction dᵢ is its centre
//! (mid-area height, mid longitude; the pole for a cap). The partition's pole is perpendicular
//! to the view axis, so the flipped points, which lie in a narrow cone around that axis, fall on
//! the near-square regions about the equator rather than into a polar cap.
//!
//! q: the thesis takes the centroid (or the bounding-box centre) of the cloud. The centroid of
//! the flipped points lies within their thin shell, where the sectors around it would cut the
//! shell sideways; q here is the midpoint of the viewpoint and that centroid, a convex
//! combination of the set and so inside its hull, deep in the cone the flipped points span.

use anyhow::{bail, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{Flip, Radius, Visibility};

/// An approximate convex hull of 003 ch. 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hull {
    /// Bentley–Faust–Preparata over about `cells` grid cells (§3.1).
    Bfp { cells: u32 },
    /// Kavan et al. over `sectors` sectors with the O(k²) refinement (§3.2).
    Kavan { sectors: u32 },
    /// The exact hull of the `sectors` sector extremes (§3.3).
    Hybrid { sectors: u32 },
}

/// HPR of `points` seen from `viewpoint` with the approximate hull `hull` in place of the exact
/// one.
pub fn approximate_hull(
    points: &[Vec3],
    viewpoint: Vec3,
    radius: Radius,
    hull: Hull,
) -> Result<Visibility> {
    let (Hull::Bfp { cells: k } | Hull::Kavan { sectors: k } | Hull::Hybrid { sectors: k }) = hull;
    if k == 0 {
        bail!("an approximate hull needs at least one cell or sector");
    }
    let flip = Flip::new(points, viewpoint, radius)?;
    Ok(match hull {
        Hull::Bfp { cells } => flip.hull_of(&bfp_sample(&flip.points, cells)),
        Hull::Kavan { sectors } => {
            let extremes = SectorExtremes::new(&flip.points, sectors);
            flip.visibility(extremes.refined(&flip.points), Vec::new(), false)
        }
        Hull::Hybrid { sectors } => {
            let extremes = SectorExtremes::new(&flip.points, sectors);
            flip.hull_of(&extremes.sample())
        }
    })
}

/// The unit axis from the viewpoint (origin) to the centroid of `points`; +z where that is
/// undefined (no points, or points all around the viewpoint).
fn view_axis(points: &[DVec3]) -> DVec3 {
    let sum: DVec3 = points.iter().sum();
    let centroid = sum / points.len().max(1) as f64;
    centroid.try_normalize().unwrap_or(DVec3::Z)
}

/// The points (indices into `points`) Bentley–Faust–Preparata keeps with about `cells` cells.
fn bfp_sample(points: &[DVec3], cells: u32) -> Vec<usize> {
    if points.is_empty() {
        return Vec::new();
    }
    let z_axis = view_axis(points);
    let (x_axis, y_axis) = z_axis.any_orthonormal_pair();
    let local = |p: DVec3| DVec3::new(p.dot(x_axis), p.dot(y_axis), p.dot(z_axis));
    // The bounding rectangle of the flipped points and the viewpoint (the origin).
    let (lo, hi) = points
        .iter()
        .fold((DVec3::ZERO, DVec3::ZERO), |(lo, hi), &p| {
            let l = local(p);
            (lo.min(l), hi.max(l))
        });
    let side = (cells as f64).sqrt().round().max(1.0) as usize;
    let cell = |c: f64, lo: f64, hi: f64| {
        if hi > lo {
            (((c - lo) / (hi - lo) * side as f64) as usize).min(side - 1)
        } else {
            0
        }
    };
    // Per cell the points of least and greatest z; ties keep the first.
    let mut lowest: Vec<Option<(usize, f64)>> = vec![None; side * side];
    let mut highest = lowest.clone();
    // The points of least and greatest x and y; ties keep the first.
    let mut axis_extremes = [(0usize, f64::MAX); 4];
    for (i, &p) in points.iter().enumerate() {
        let l = local(p);
        let c = cell(l.x, lo.x, hi.x) * side + cell(l.y, lo.y, hi.y);
        if lowest[c].is_none_or(|(_, z)| l.z < z) {
            lowest[c] = Some((i, l.z));
        }
        if highest[c].is_none_or(|(_, z)| l.z > z) {
            highest[c] = Some((i, l.z));
        }
        // Least x, greatest x (least −x), least y, greatest y.
        for (best, value) in axis_extremes.iter_mut().zip([l.x, -l.x, l.y, -l.y]) {
            if value < best.1 {
                *best = (i, value);
            }
        }
    }
    let mut kept: Vec<usize> = lowest
        .into_iter()
        .chain(highest)
        .flatten()
        .map(|(i, _)| i)
        .chain(axis_extremes.map(|(i, _)| i))
        .collect();
    kept.sort_unstable();
    kept.dedup();
    kept
}

/// Leopardi's zonal equal-area partition of the unit sphere into `k` sectors (the 2-sphere
/// case, collars unrotated), about the pole +z of its own frame.
struct Sectors {
    /// Cumulative sector counts at the zones' lower edges, from the north pole down; a zone's
    /// sectors are the ids from the previous entry (0 for the first) up to its own.
    ends: Vec<u32>,
    k: u32,
}

impl Sectors {
    fn new(k: u32) -> Self {
        let n = k as f64;
        let ends = match k {
            1 => vec![1],
            2 => vec![1, 2],
            _ => {
                use std::f64::consts::PI;
                let area = 4.0 * PI / n;
                let cap = 2.0 * (1.0 / n).sqrt().asin();
                let collars = ((PI - 2.0 * cap) / area.sqrt()).round().max(1.0) as usize;
                let width = (PI - 2.0 * cap) / collars as f64;
                // Area of the cap of colatitude t, in sectors.
                let cap_sectors = |t: f64| 2.0 * PI * (1.0 - t.cos()) / area;
                let mut ends = vec![1u32];
                let mut carried = 0.0;
                for c in 0..collars {
                    let t = cap + c as f64 * width;
                    let ideal = cap_sectors(t + width) - cap_sectors(t);
                    let count = (ideal + carried).round().max(1.0);
                    carried += ideal - count;
                    let end = if c + 1 == collars {
                        k - 1
                    } else {
                        (ends[c] + count as u32).min(k - 1)
                    };
                    ends.push(end);
                }
                ends.push(k);
                ends
            }
        };
        Sectors { ends, k }
    }

    /// The zone holding height `z` (the cosine of the colatitude): a cap of colatitude t holds
    /// (1 − cos t) k / 2 sectors' area.
    fn zone(&self, z: f64) -> usize {
        let before = (1.0 - z) * 0.5 * self.k as f64;
        self.ends
            .partition_point(|&e| (e as f64) <= before)
            .min(self.ends.len() - 1)
    }

    /// The first sector, the sector count and the heights (top, bottom) of zone `zone`.
    fn zone_span(&self, zone: usize) -> (u32, u32, f64, f64) {
        let first = if zone == 0 { 0 } else { self.ends[zone - 1] };
        let height = |c: u32| 1.0 - 2.0 * c as f64 / self.k as f64;
        let end = self.ends[zone];
        (first, end - first, height(first), height(end))
    }

    /// The sector of unit direction `d`.
    fn sector(&self, d: DVec3) -> u32 {
        let zone = self.zone(d.z.clamp(-1.0, 1.0));
        let (first, count, _, _) = self.zone_span(zone);
        let turn = d.y.atan2(d.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
        first + ((turn * count as f64) as u32).min(count - 1)
    }

    /// The centre direction of every sector.
    fn directions(&self) -> Vec<DVec3> {
        let mut out = Vec::with_capacity(self.k as usize);
        for zone in 0..self.ends.len() {
            let (_, count, top, bottom) = self.zone_span(zone);
            for j in 0..count {
                out.push(if count == 1 && top == 1.0 {
                    DVec3::Z
                } else if count == 1 && bottom == -1.0 {
                    -DVec3::Z
                } else {
                    let z = 0.5 * (top + bottom);
                    let a = (j as f64 + 0.5) / count as f64 * std::f64::consts::TAU;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    DVec3::new(r * a.cos(), r * a.sin(), z)
                });
            }
        }
        out
    }
}

/// Kavan's steps 1 and 2 over the flipped points and the viewpoint.
struct SectorExtremes {
    /// The origin q of the sectors.
    q: DVec3,
    /// The direction dᵢ of every sector, in the world frame.
    directions: Vec<DVec3>,
    /// The extreme of every sector: an index into the points, `viewpoint` for the viewpoint,
    /// `None` for an empty sector.
    extremes: Vec<Option<usize>>,
    /// The viewpoint's index: the points' count.
    viewpoint: usize,
}

impl SectorExtremes {
    fn new(points: &[DVec3], k: u32) -> Self {
        let axis = view_axis(points);
        let q = if points.is_empty() {
            DVec3::ZERO
        } else {
            0.5 * points.iter().sum::<DVec3>() / points.len() as f64
        };
        // The partition's frame: x along the view axis, its pole perpendicular to it.
        let (pole, y) = axis.any_orthonormal_pair();
        let sectors = Sectors::new(k);
        let directions: Vec<DVec3> = sectors
            .directions()
            .into_iter()
            .map(|d| d.x * axis + d.y * y + d.z * pole)
            .collect();
        let mut best: Vec<Option<(usize, f64)>> = vec![None; k as usize];
        let viewpoint = points.len();
        for (i, p) in points
            .iter()
            .chain(std::iter::once(&DVec3::ZERO))
            .enumerate()
        {
            let w = *p - q;
            // A point at q lies in every sector's boundary; it goes to the first.
            let s = w.try_normalize().map_or(0, |d| {
                sectors.sector(DVec3::new(d.dot(axis), d.dot(y), d.dot(pole))) as usize
            });
            let dist = w.dot(directions[s]);
            if best[s].is_none_or(|(_, b)| dist > b) {
                best[s] = Some((i, dist));
            }
        }
        let extremes = best.into_iter().map(|b| b.map(|(i, _)| i)).collect();
        SectorExtremes {
            q,
            directions,
            extremes,
            viewpoint,
        }
    }

    /// The distinct extremes that are points (the viewpoint left out), ascending.
    fn sample(&self) -> Vec<usize> {
        let mut kept: Vec<usize> = self.extremes.iter().flatten().copied().collect();
        kept.sort_unstable();
        kept.dedup();
        kept.retain(|&i| i != self.viewpoint);
        kept
    }

    /// Kavan's step 3: every non-empty sector takes the best of all sectors' extremes along its
    /// direction; the distinct results that are points, ascending.
    fn refined(&self, points: &[DVec3]) -> Vec<usize> {
        debug_assert_eq!(self.viewpoint, points.len());
        let mut candidates: Vec<usize> = self.extremes.iter().flatten().copied().collect();
        candidates.sort_unstable();
        candidates.dedup();
        let at = |i: usize| points.get(i).copied().unwrap_or(DVec3::ZERO) - self.q;
        let offsets: Vec<DVec3> = candidates.iter().map(|&i| at(i)).collect();
        let mut refined: Vec<usize> = self
            .extremes
            .par_iter()
            .zip(&self.directions)
            .filter(|(e, _)| e.is_some())
            .map(|(_, d)| {
                let mut best = (0, f64::MIN);
                for (c, o) in offsets.iter().enumerate() {
                    let dist = o.dot(*d);
                    if dist > best.1 {
                        best = (c, dist);
                    }
                }
                candidates[best.0]
            })
            .collect();
        refined.sort_unstable();
        refined.dedup();
        refined.retain(|&i| i != self.viewpoint);
        refined
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hpr::{agreement, exact, tests::sphere};

    const FACTOR: Radius = Radius::Factor(100.0);

    fn eye() -> Vec3 {
        Vec3::new(0.0, 0.0, 4.0)
    }

    #[test]
    fn the_hulls_keep_exactly_visible_points_and_find_more_with_larger_k() {
        // Measured on 20,000 points (exact: 7,645 visible), recall at k = 1024, 4096, 16384:
        // BFP 0.114, 0.423, 0.776 (precision 0.886, 0.960, 0.986); Kavan 0.007, 0.019, 0.060;
        // hybrid 0.010, 0.035, 0.130 (precision 0.993 or more). The sector methods see the
        // flipped cap from q through only a few per cent of the sphere of directions.
        let points = sphere(20_000);
        let truth = exact(&points, eye(), FACTOR).unwrap();
        type Make = fn(u32) -> Hull;
        let methods: [(Make, f64, f64); 3] = [
            (|k| Hull::Bfp { cells: k }, 0.7, 0.95),
            (|k| Hull::Kavan { sectors: k }, 0.05, 0.98),
            (|k| Hull::Hybrid { sectors: k }, 0.11, 0.98),
        ];
        for (make, last_recall, min_precision) in methods {
            let mut recalls = Vec::new();
            for k in [1024, 4096, 16384] {
                let v = approximate_hull(&points, eye(), FACTOR, make(k)).unwrap();
                let (precision, recall, _) = agreement(&v.visible, &truth.visible);
                if k >= 4096 {
                    assert!(precision >= min_precision, "{:?}: {precision}", make(k));
                }
                recalls.push(recall);
            }
            assert!(recalls.windows(2).all(|w| w[1] > w[0]), "{recalls:?}");
            assert!(recalls[2] >= last_recall, "{:?}: {recalls:?}", make(16384));
        }
        // The hull of the sector extremes keeps more of them than the refinement does.
        let count = |h| {
            approximate_hull(&points, eye(), FACTOR, h)
                .unwrap()
                .visible
                .len()
        };
        assert!(count(Hull::Hybrid { sectors: 4096 }) > count(Hull::Kavan { sectors: 4096 }));
    }

    #[test]
    fn visible_points_are_among_the_sampled_extremes() {
        let points = sphere(5_000);
        let flip = Flip::new(&points, eye(), FACTOR).unwrap();
        let originals =
            |kept: Vec<usize>| -> Vec<u32> { kept.into_iter().map(|i| flip.original[i]).collect() };
        let bfp = originals(bfp_sample(&flip.points, 1024));
        let extremes = SectorExtremes::new(&flip.points, 4096);
        let sectors = originals(extremes.sample());
        let refined = originals(extremes.refined(&flip.points));
        assert!(refined.iter().all(|i| sectors.contains(i)));
        for (hull, sample) in [
            (Hull::Bfp { cells: 1024 }, &bfp),
            (Hull::Hybrid { sectors: 4096 }, &sectors),
            (Hull::Kavan { sectors: 4096 }, &refined),
        ] {
            let v = approximate_hull(&points, eye(), FACTOR, hull).unwrap();
            assert!(!v.visible.is_empty());
            assert!(v.visible.iter().all(|i| sample.contains(i)), "{hull:?}");
            assert!(v.triangles.iter().flatten().all(|i| v.visible.contains(i)));
        }
        // At most 2 × 32² cell extremes and 4 axis extremes; one extreme per sector.
        assert!(bfp.len() <= 2 * 32 * 32 + 4 && sectors.len() <= 4096);
    }

    #[test]
    fn one_bfp_cell_keeps_the_extremes_of_all_three_axes() {
        let flip = Flip::new(&sphere(3_000), eye(), FACTOR).unwrap();
        let z = view_axis(&flip.points);
        let (x, y) = z.any_orthonormal_pair();
        let arg = |axis: DVec3, sign: f64| {
            (0..flip.points.len())
                .max_by(|&a, &b| {
                    (sign * flip.points[a].dot(axis)).total_cmp(&(sign * flip.points[b].dot(axis)))
                })
                .unwrap()
        };
        let mut expected: Vec<usize> = [x, y, z]
            .into_iter()
            .flat_map(|axis| [arg(axis, 1.0), arg(axis, -1.0)])
            .collect();
        expected.sort_unstable();
        expected.dedup();
        assert_eq!(expected.len(), 6);
        assert_eq!(bfp_sample(&flip.points, 1), expected);
    }

    #[test]
    fn sectors_have_equal_areas_and_contain_their_directions() {
        let directions: Vec<DVec3> = sphere(200_000).iter().map(|p| p.as_dvec3()).collect();
        for k in [1, 2, 3, 7, 200, 4096] {
            let sectors = Sectors::new(k);
            let centres = sectors.directions();
            assert_eq!(centres.len(), k as usize);
            for (i, d) in centres.iter().enumerate() {
                assert_eq!(sectors.sector(*d), i as u32, "k = {k}");
            }
            let mut counts = vec![0usize; k as usize];
            for d in &directions {
                counts[sectors.sector(*d) as usize] += 1;
            }
            let expected = directions.len() as f64 / k as f64;
            // Lattice points per area agree within sampling noise (about 49 per sector at
            // k = 4096).
            let tolerance = 0.02 * expected + 4.0 * expected.sqrt();
            for (i, &c) in counts.iter().enumerate() {
                assert!(
                    (c as f64 - expected).abs() <= tolerance,
                    "k {k} sector {i}: {c}"
                );
            }
        }
    }

    #[test]
    fn degenerate_inputs_give_an_answer_or_an_error() {
        let all = |k| {
            [
                Hull::Bfp { cells: k },
                Hull::Kavan { sectors: k },
                Hull::Hybrid { sectors: k },
            ]
        };
        for hull in all(64) {
            assert!(approximate_hull(&[], Vec3::ZERO, FACTOR, hull).is_err());
            let e = approximate_hull(&[Vec3::ONE * 10.0], Vec3::ZERO, Radius::Absolute(1.0), hull)
                .unwrap_err();
            assert!(e.to_string().contains("must exceed"), "{e}");
            // One point, and one at the viewpoint beside it.
            let v = approximate_hull(&[Vec3::ONE], Vec3::ZERO, Radius::Absolute(10.0), hull);
            assert_eq!(v.unwrap().visible, vec![0], "{hull:?}");
            let two = [Vec3::ONE, Vec3::ZERO];
            let v = approximate_hull(&two, Vec3::ZERO, Radius::Absolute(10.0), hull).unwrap();
            assert_eq!((v.visible, v.at_viewpoint), (vec![0], 1), "{hull:?}");
            // Only points at the viewpoint: nothing to see.
            let v = approximate_hull(&[Vec3::ZERO; 3], Vec3::ZERO, Radius::Absolute(1.0), hull);
            assert!(v.unwrap().visible.is_empty());
            // Duplicates of a visible point are all visible with it.
            let mut points = sphere(2_000);
            let alone = approximate_hull(&points, eye(), FACTOR, hull).unwrap();
            let front = alone.visible[0] as usize;
            points.extend([points[front]; 2]);
            let v = approximate_hull(&points, eye(), FACTOR, hull).unwrap();
            for i in [front, 2_000, 2_001] {
                assert!(v.visible.contains(&(i as u32)), "{hull:?} {i}");
            }
            // A flat grid seen from within its plane, the viewpoint on a point of the sphere
            // and at its centre: answers, no panic.
            let grid: Vec<Vec3> = (0..100)
                .map(|k| Vec3::new((k % 10) as f32, (k / 10) as f32, 0.0))
                .collect();
            let v = approximate_hull(&grid, Vec3::new(4.5, -5.0, 0.0), FACTOR, hull).unwrap();
            assert!(!v.visible.is_empty());
            let on_point = approximate_hull(&points, points[7], FACTOR, hull).unwrap();
            assert_eq!(on_point.at_viewpoint, 1);
            let inside = approximate_hull(&points, Vec3::ZERO, FACTOR, hull).unwrap();
            assert!(!inside.visible.is_empty());
        }
        for hull in all(0) {
            let e = approximate_hull(&[Vec3::ONE], Vec3::ZERO, FACTOR, hull).unwrap_err();
            assert!(e.to_string().contains("at least one"), "{e}");
        }
        // One cell or sector still answers.
        for hull in all(1) {
            assert!(approximate_hull(&sphere(100), eye(), FACTOR, hull).is_ok());
        }
    }
}
