//! The points exact HPR can leave out of the convex hull without changing it: a flipped point
//! strictly inside the tetrahedron spanned by the viewpoint (the origin) and three other
//! flipped points is inside the hull of all of them, so it is no hull vertex and no facet
//! touches it. The three points come from a grid of angular sectors (`approx::Sectors`, about
//! [`POINTS_PER_SECTOR`] points each): each sector's farthest flipped point (the original
//! nearest the eye, on the front surface), and for a point the triangles of the 2 × 2 blocks
//! of sectors around its own (both diagonals of each, sixteen triangles). Points behind the
//! front surface, the hidden majority, fall inside one of them; the hull then partitions only
//! the rest, which is where Qhull spends its time.
//!
//! A point is left out only when the orientation tests that put it inside the tetrahedron
//! clear their rounding error bounds by [`TOLERANCE`] (see [`strictly_inside`]): the decision
//! is never within rounding of the hull's own, so the hull and its vertices are those of the
//! whole input (`tests/hpr_exact.rs` compares both on scans, shells and both radius rules).

use glam::DVec3;
use rayon::prelude::*;

use super::approx::{bounding_sphere, Sectors};

/// Average flipped points per sector of the finest grid.
pub const POINTS_PER_SECTOR: usize = 8;

/// Grids: the finest, then each half as fine along both angles.
pub const LEVELS: u32 = 6;

/// How many ulps of its error bound an orientation determinant must clear to be trusted.
pub const TOLERANCE: f64 = 64.0;

/// One grid of sectors and the extreme point of each (`u32::MAX` where it holds none).
struct Level {
    side: usize,
    extremes: Vec<u32>,
}

impl Level {
    /// The extreme of sector (i, j), if the sector is on the grid and holds a point.
    fn extreme(&self, i: i64, j: i64) -> Option<u32> {
        let s = self.side as i64;
        if i < 0 || j < 0 || i >= s || j >= s {
            return None;
        }
        let e = self.extremes[(i * s + j) as usize];
        (e != u32::MAX).then_some(e)
    }

    /// Whether `q` (in sector (i, j) of this grid) lies strictly inside a tetrahedron of the
    /// origin and the extremes of three corners of a 2 × 2 block of sectors around (i, j).
    fn covers(&self, points: &[DVec3], q: DVec3, i: i64, j: i64) -> bool {
        for (bi, bj) in [(-1, -1), (-1, 0), (0, -1), (0, 0)] {
            let quad = [
                self.extreme(i + bi, j + bj),
                self.extreme(i + bi + 1, j + bj),
                self.extreme(i + bi + 1, j + bj + 1),
                self.extreme(i + bi, j + bj + 1),
            ];
            let [Some(a), Some(b), Some(c), Some(d)] = quad else {
                continue;
            };
            let [a, b, c, d] = [a, b, c, d].map(|v| points[v as usize]);
            // The quad's outer surface: split along a-c when d lies on the origin's side of
            // the plane of a, b and c (a ridge along a-c), else along b-d.
            let ridge_ac = (a - d).dot((b - d).cross(c - d)) * a.dot(b.cross(c)) > 0.0;
            let triangles = if ridge_ac {
                [(a, b, c), (a, c, d)]
            } else {
                [(a, b, d), (b, c, d)]
            };
            if triangles
                .into_iter()
                .any(|(a, b, c)| strictly_inside(q, a, b, c))
            {
                return true;
            }
        }
        false
    }
}

/// Indices of the flipped `points` (viewpoint at the origin) the hull needs: all but those
/// strictly inside a tetrahedron of the origin and three others.
pub fn hull_candidates(points: &[DVec3]) -> Vec<usize> {
    let n = points.len();
    let Some((centre, r)) = bounding_sphere(points).filter(|_| n >= 64) else {
        return (0..n).collect();
    };
    // The finest grid's side is a multiple of 2^(LEVELS - 1), so a sector's index on a
    // coarser grid is its index on the finest shifted right.
    let coarsest = ((n / POINTS_PER_SECTOR) as f64).sqrt() as u32 >> (LEVELS - 1);
    let sqrt_k = coarsest.max(2) << (LEVELS - 1);
    let finest = Sectors::new(centre, r, DVec3::ZERO, sqrt_k);
    let cells: Vec<(u32, u32)> = points.par_iter().map(|&p| finest.sector(p)).collect();
    let levels: Vec<Level> = (0..LEVELS)
        .map(|l| {
            let side = (sqrt_k >> l) as usize;
            let sectors = Sectors::new(centre, r, DVec3::ZERO, side as u32);
            // The extreme of a sector: the point furthest along its direction (ties: the
            // lower index), as the approximation's MAX.
            let directions: Vec<DVec3> = (0..side * side)
                .map(|c| sectors.direction((c / side) as u32, (c % side) as u32))
                .collect();
            let mut extremes = vec![u32::MAX; side * side];
            let mut best = vec![f64::NEG_INFINITY; side * side];
            for (t, (&(i, j), p)) in cells.iter().zip(points).enumerate() {
                let cell = (i >> l) as usize * side + (j >> l) as usize;
                let along = p.dot(directions[cell]);
                if along > best[cell] {
                    best[cell] = along;
                    extremes[cell] = t as u32;
                }
            }
            Level { side, extremes }
        })
        .collect();
    (0..n)
        .into_par_iter()
        .filter(|&t| {
            let (i, j) = cells[t];
            let q = points[t];
            !levels.iter().enumerate().rev().any(|(l, level)| {
                let (i, j) = (i >> l, j >> l);
                level.extremes[i as usize * level.side + j as usize] != t as u32
                    && level.covers(points, q, i64::from(i), i64::from(j))
            })
        })
        .collect()
}
/// Whether `q` lies strictly inside the tetrahedron (origin, `a`, `b`, `c`), decided only
/// where rounding cannot change the answer: each of the four orientation determinants (`q`
/// against a face) must have the sign of the tetrahedron's own by more than [`TOLERANCE`]
/// times its bound. The faces through the origin use the points as they are (error at most a
/// few ulps of |x| |y| |z|); the face (`a`, `b`, `c`) uses the differences to `q`, which
/// subtraction of two doubles gives to half an ulp, so points a hair from that face are
/// decided as well as the hull decides them.
fn strictly_inside(q: DVec3, a: DVec3, b: DVec3, c: DVec3) -> bool {
    let det = a.dot(b.cross(c));
    if det == 0.0 || !det.is_finite() {
        return false;
    }
    let sign = det.signum();
    let sides = [q.dot(b.cross(c)), a.dot(q.cross(c)), a.dot(b.cross(q))];
    // Most candidates fail here: outside the cone, or clearly outside the far face.
    if sides.iter().any(|&s| s * sign <= 0.0) {
        return false;
    }
    let (da, db, dc) = (a - q, b - q, c - q);
    let depth = da.dot(db.cross(dc));
    if depth * sign <= 0.0 {
        return false;
    }
    let ulps = TOLERANCE * f64::EPSILON;
    let (nq, na, nb, nc) = (q.length(), a.length(), b.length(), c.length());
    let bounds = [nq * nb * nc, na * nq * nc, na * nb * nq];
    sides
        .iter()
        .zip(bounds)
        .all(|(&s, bound)| s * sign > ulps * bound)
        && depth * sign > ulps * da.length() * db.length() * dc.length()
}
