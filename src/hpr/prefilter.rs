//! The points exact HPR can leave out of the convex hull without changing it: a flipped point
//! strictly inside the tetrahedron spanned by the viewpoint (the origin) and three other
//! flipped points is inside the hull of all of them, so it is no hull vertex and no facet
//! touches it. The three points come from grids of angular sectors (`approx::Sectors`, the
//! finest about [`POINTS_PER_SECTOR`] points per sector, then [`LEVELS`] − 1 grids each half
//! as fine): each sector's farthest flipped point (the original nearest the eye, on the front
//! surface; a coarse sector's is the farthest of its children's), and for a point any three
//! of the extremes of the 3 × 3 sectors around its own on every grid (up to 84 triangles per
//! grid, found from 36 sign tests). Points behind the front surface, the hidden majority,
//! fall inside one of them; the hull then partitions only the rest, which is where Qhull
//! spends its time. The same test, with a finer grid, is the complete approximate visible
//! set (`hpr::complete`).
//!
//! A point is left out only when the orientation tests that put it inside the tetrahedron
//! clear their rounding error bounds by [`TOLERANCE`] (see [`strictly_inside_cone`]): the decision
//! is never within rounding of the hull's own, so the hull and its vertices are those of the
//! whole input (`tests/suite/hpr_exact.rs` compares both on scans, shells and both radius rules).

use glam::DVec3;
use rayon::prelude::*;

use super::approx::{bounding_sphere, Sectors};

/// Average flipped points per sector of the finest grid.
pub const POINTS_PER_SECTOR: usize = 8;

/// Grids: the finest, then each half as fine along both angles (the GPU's count).
pub const LEVELS: u32 = crate::layout::HPR_COMPLETE_LEVELS;

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
    /// origin and the extremes of three of the 3 × 3 sectors around (i, j) (any three: each
    /// such tetrahedron is inside the hull). The sign of q · (eₓ × e_y) is decided once per
    /// pair of extremes ([`pair_sides`]); a triangle whose three pairs put `q` certainly on
    /// its inner side is then tested by [`strictly_inside_cone`].
    fn covers(&self, points: &[DVec3], q: DVec3, i: i64, j: i64) -> bool {
        let mut e = [DVec3::ZERO; 9];
        let mut m = 0;
        for di in -1..=1 {
            for dj in -1..=1 {
                if let Some(v) = self.extreme(i + di, j + dj) {
                    e[m] = points[v as usize];
                    m += 1;
                }
            }
        }
        // The tetrahedron lies in the ball through its farthest vertex.
        let e = &e[..m];
        let reach = e.iter().map(|v| v.length_squared()).fold(0.0, f64::max);
        if m < 3 || q.length_squared() >= reach {
            return false;
        }
        let side = pair_sides(q, e);
        for x in 0..m {
            for y in x + 1..m {
                let s = side[x][y];
                if s == 0 {
                    continue;
                }
                for z in y + 1..m {
                    if side[y][z] == s
                        && side[z][x] == s
                        && strictly_inside_cone(q, [e[x], e[y], e[z]], s)
                    {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// For the extremes `e`, `side[x][y]`: the sign of q · (eₓ × e_y) where it clears its
/// rounding bound by [`TOLERANCE`] ulps of |q| |eₓ| |e_y|, else 0.
fn pair_sides(q: DVec3, e: &[DVec3]) -> [[i8; 9]; 9] {
    let ulps = TOLERANCE * f64::EPSILON;
    let nq = q.length();
    let mut side = [[0i8; 9]; 9];
    for x in 0..e.len() {
        for y in x + 1..e.len() {
            let t = q.dot(e[x].cross(e[y]));
            let bound = ulps * nq * e[x].length() * e[y].length();
            let s = if t > bound {
                1
            } else if t < -bound {
                -1
            } else {
                0
            };
            side[x][y] = s;
            side[y][x] = -s;
        }
    }
    side
}

/// For every flipped point (viewpoint at the origin) in sector `cells[t]` of a `side` × `side`
/// grid (`side` a multiple of 2^(`levels` − 1)), whether it lies strictly inside a tetrahedron
/// of the origin and the extremes of three of the 3 × 3 sectors around its own, on that grid or one of the `levels` − 1 grids each half as fine (coarsest first). A
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

/// Whether `q`, certainly on the inner side (sign `s`) of the three planes through the origin
/// and two of `a`, `b`, `c` ([`pair_sides`]), lies strictly inside the tetrahedron (origin,
/// `a`, `b`, `c`), decided only where rounding cannot change the answer: the tetrahedron's
/// orientation must be `s` and `q` must be on the origin's side of the face (`a`, `b`, `c`) by
/// more than [`TOLERANCE`] ulps of that determinant's bound. The face uses the differences to
/// `q`, which subtraction of two doubles gives to half an ulp, so points a hair from the face
/// are decided as well as the hull decides them.
fn strictly_inside_cone(q: DVec3, [a, b, c]: [DVec3; 3], s: i8) -> bool {
    let sign = f64::from(s);
    let det = a.dot(b.cross(c));
    if det * sign <= 0.0 || !det.is_finite() {
        return false;
    }
    let (da, db, dc) = (a - q, b - q, c - q);
    let depth = da.dot(db.cross(dc));
    depth * sign > TOLERANCE * f64::EPSILON * da.length() * db.length() * dc.length()
}
