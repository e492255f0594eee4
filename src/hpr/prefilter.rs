//! The points exact HPR can leave out of the convex hull without changing it: a flipped point
//! strictly inside the tetrahedron spanned by the viewpoint (the origin) and three other
//! flipped points is inside the hull of all of them, so it is no hull vertex and no facet
//! touches it. The three points come from grids of angular sectors (`approx::Sectors`, the
//! finest about [`POINTS_PER_SECTOR`] points per sector, then [`LEVELS`] − 1 grids each half
//! as fine): each sector's farthest flipped point (the original nearest the eye, on the front
//! surface; a coarse sector's is the farthest of its children's), and for a point the 2 × 2
//! blocks of sectors around its own on every grid, each split along the diagonal that makes
//! its outer surface (two triangles). Points behind the front surface, the hidden majority,
//! fall inside one of them; the hull then partitions only the rest, which is where Qhull
//! spends its time. The same test, with a finer grid, is the complete approximate visible
//! set (`hpr::complete`).
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

/// Grids: the finest, then each half as fine along both angles (the GPU's count).
pub const LEVELS: u32 = crate::gpu::layout::HPR_COMPLETE_LEVELS;

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

/// For every flipped point (viewpoint at the origin) in sector `cells[t]` of a `side` × `side`
/// grid (`side` a multiple of 2^(`levels` − 1)), whether it lies strictly inside a tetrahedron
/// of the origin and the extremes of three corners of a 2 × 2 block of sectors around its own,
/// on that grid or one of the `levels` − 1 grids each half as fine (coarsest first). A
/// sector's extreme is its farthest flipped point (the original nearest the eye; ties: the
/// lower index), a coarse sector's the farthest of its four children's.
pub fn certified_hidden(
    points: &[DVec3],
    cells: &[(u32, u32)],
    side: u32,
    levels: u32,
) -> Vec<bool> {
    let side = side as usize;
    let farther = |a: u32, b: u32| -> u32 {
        match (a, b) {
            (u32::MAX, _) => b,
            (_, u32::MAX) => a,
            _ => {
                let (ra, rb) = (
                    points[a as usize].length_squared(),
                    points[b as usize].length_squared(),
                );
                if rb > ra || (rb == ra && b < a) {
                    b
                } else {
                    a
                }
            }
        }
    };
    let mut finest = vec![u32::MAX; side * side];
    for (t, &(i, j)) in cells.iter().enumerate() {
        let cell = i as usize * side + j as usize;
        finest[cell] = farther(finest[cell], t as u32);
    }
    let mut grids = vec![Level {
        side,
        extremes: finest,
    }];
    for _ in 1..levels {
        let fine = grids.last().expect("a level");
        let s = fine.side / 2;
        let extremes = (0..s * s)
            .map(|c| {
                let (i, j) = (c / s, c % s);
                [(0, 0), (0, 1), (1, 0), (1, 1)]
                    .iter()
                    .map(|(di, dj)| fine.extremes[(2 * i + di) * fine.side + 2 * j + dj])
                    .fold(u32::MAX, farther)
            })
            .collect();
        grids.push(Level { side: s, extremes });
    }
    (0..points.len())
        .into_par_iter()
        .map(|t| {
            let (i, j) = cells[t];
            let q = points[t];
            grids.iter().enumerate().rev().any(|(l, level)| {
                let (i, j) = (i >> l, j >> l);
                level.covers(points, q, i64::from(i), i64::from(j))
            })
        })
        .collect()
}

/// The finest grid's side for `n` points at about `per_point` sectors per point (over the
/// square of angles; the object covers part of it): a multiple of 2^(`levels` − 1), at most
/// 2^(17 − levels) × 2^(levels − 1) = 65,536 per angle.
pub fn finest_side(n: usize, per_point: f64, levels: u32) -> u32 {
    let coarsest = (n as f64 * per_point).sqrt() as u32 >> (levels - 1);
    coarsest.clamp(2, 1 << (17 - levels)) << (levels - 1)
}

/// Indices of the flipped `points` (viewpoint at the origin) the hull needs: all but those
/// [`certified_hidden`] puts strictly inside a tetrahedron of the origin and three others.
pub fn hull_candidates(points: &[DVec3]) -> Vec<usize> {
    let n = points.len();
    let Some((centre, r)) = bounding_sphere(points).filter(|_| n >= 64) else {
        return (0..n).collect();
    };
    let side = finest_side(n, 1.0 / POINTS_PER_SECTOR as f64, LEVELS);
    let sectors = Sectors::new(centre, r, DVec3::ZERO, side);
    let cells: Vec<(u32, u32)> = points.par_iter().map(|&p| sectors.sector(p)).collect();
    let hidden = certified_hidden(points, &cells, side, LEVELS);
    (0..n).filter(|&t| !hidden[t]).collect()
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
