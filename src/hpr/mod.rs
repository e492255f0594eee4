//! Hidden point removal (Katz, Tal and Basri 2007; 003 §2.1): the points of a bare cloud
//! visible from a viewpoint, without normals or a surface.
//!
//! [`exact`]: translate the cloud so the viewpoint is the origin, flip every point spherically
//! about a sphere of radius R (`p' = p + 2 (R - |p|) p / |p|`), and take the convex hull of the
//! flipped points and the viewpoint: a point is visible when its flipped image is a vertex of
//! the hull. The hull's facets that do not touch the viewpoint, mapped back to the original
//! points, are a partial surface of what is seen. The hull runs in f64 through Qhull (the
//! `qhull` crate): f32 hulls lose up to 31 % of the visible points at these radii.
//!
//! Degenerate inputs never panic: an empty cloud is an error; points at the viewpoint cannot be
//! flipped and are reported as hidden; exact duplicates (a hull holds one of them) are all
//! visible when one is; an input whose flipped points and viewpoint span less than three
//! dimensions ("initial simplex is flat") is retried with Qhull's joggle (`QJ`), and one that
//! still fails (fewer than four distinct points) has every flippable point visible.

pub mod approx;
pub mod hulls;
pub mod prefilter;
pub mod truth;
pub mod view;

use anyhow::{bail, Result};
use glam::{DVec3, Vec3};
use qhull::Qh;
use rayon::prelude::*;

use crate::scene::Cloud;

/// How the flipping radius R is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Radius {
    /// R = factor × the cloud's diameter (its bounding-box diagonal), the usual choice
    /// (Katz et al. use large factors: larger R keeps more points).
    Factor(f64),
    /// R in scene units.
    Absolute(f64),
    /// R from the sampling density: R = κ D² / s for the viewpoint's distance D to the
    /// cloud's centre and the sample spacing s ([`spacing`]), κ = [`DENSITY_KAPPA`]. Two
    /// neighbours δ = s / D apart as seen from the eye keep a point between them on the hull
    /// while it lies less than about R δ² = κ s behind them (the sagitta of the flipped shell,
    /// radius ≈ 2R, over 2δ), so R scales with D² / s: slanted or noisy surfaces (depth steps
    /// of a few spacings) stay visible, and back surfaces further behind are hidden. That is
    /// the dependence Mehra et al. 2010 derive for noisy samples; κ is calibrated against true
    /// visibility (the meshes' depth buffers, `docs/reports/lavapipe-hpr`): F1 peaks at
    /// κ ≈ 19 on both the armadillo and the dragon. Mehra et al.'s per-point robust operator
    /// is not implemented. Raised to 1.01 × the farthest point's distance where that is
    /// larger.
    Density { spacing: f64 },
}

/// κ of [`Radius::Density`].
pub const DENSITY_KAPPA: f64 = 16.0;

/// The sample spacing of `cloud`: the median of its per-point radii (the density spacing of
/// preprocessing, √(area per point)), else the bounding box diagonal / √n.
pub fn spacing(cloud: &Cloud) -> f64 {
    if let Some(radii) = cloud.radii.as_ref().filter(|r| !r.is_empty()) {
        let mut r: Vec<f32> = radii.clone();
        let mid = r.len() / 2;
        let (_, m, _) = r.select_nth_unstable_by(mid, f32::total_cmp);
        if *m > 0.0 && m.is_finite() {
            return f64::from(*m);
        }
    }
    let diag = cloud
        .bounds()
        .map_or(1.0, |(lo, hi)| f64::from((hi - lo).length()));
    (diag / (cloud.len().max(1) as f64).sqrt()).max(f64::MIN_POSITIVE)
}

/// The visible part of a cloud.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Visibility {
    /// Indices of the visible points, ascending.
    pub visible: Vec<u32>,
    /// Hull triangles that do not touch the viewpoint, over original point indices.
    pub triangles: Vec<[u32; 3]>,
    /// The flipping radius used.
    pub radius: f64,
    /// Points at the viewpoint (not flippable, reported hidden).
    pub at_viewpoint: usize,
    /// Whether Qhull needed its joggle (`QJ`): a flat input.
    pub joggled: bool,
}

/// The cloud's diameter [`Radius::Factor`] multiplies: its bounding box's diagonal (Open3D's
/// `diameter` in its HPR example), 0 for no points.
pub fn diagonal(points: &[Vec3]) -> f64 {
    let (lo, hi) = points
        .par_iter()
        .map(|p| (p.as_dvec3(), p.as_dvec3()))
        .reduce(
            || (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        );
    if points.is_empty() {
        0.0
    } else {
        (hi - lo).length()
    }
}

/// The flipping radius for `points` seen from `viewpoint`; an error unless it exceeds every
/// point's distance from the viewpoint.
pub fn flip_radius(points: &[Vec3], viewpoint: Vec3, radius: Radius) -> Result<f64> {
    if points.is_empty() {
        bail!("hidden point removal needs at least one point");
    }
    let eye = viewpoint.as_dvec3();
    let max_norm = points
        .iter()
        .map(|p| (p.as_dvec3() - eye).length())
        .fold(0.0, f64::max);
    let r = match radius {
        Radius::Factor(f) => f * diagonal(points),
        Radius::Absolute(r) => r,
        Radius::Density { spacing } => {
            let centre = points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / points.len() as f64;
            let d = centre.distance(eye);
            (DENSITY_KAPPA * d * d / spacing).max(1.01 * max_norm)
        }
    };
    if !(r.is_finite() && r > max_norm) {
        bail!(
            "the flipping radius {r} must exceed the farthest point's distance from the \
             viewpoint, {max_norm} (raise the radius factor)"
        );
    }
    Ok(r)
}

/// Exact HPR of `points` seen from `viewpoint`: the hull of the flipped points that
/// [`prefilter::hull_candidates`] keeps (the same hull as of all of them, see there).
pub fn exact(points: &[Vec3], viewpoint: Vec3, radius: Radius) -> Result<Visibility> {
    let flip = Flip::new(points, viewpoint, radius)?;
    Ok(flip.hull_of(&prefilter::hull_candidates(&flip.points)))
}

/// The complete approximate visible set (beyond 003, which returns one extreme per sector):
/// every point HPR's hull could hold, decided per point without a hull. A point is hidden
/// when [`prefilter::certified_hidden`] puts its flipped image strictly inside a tetrahedron
/// of the eye and three sector extremes, on the sector grid of 003 ch. 4 (the frame of
/// [`approx::Sectors`] about the cloud's bounding sphere) with `side` sectors per angle (a
/// rounded up to a multiple of 32 by [`complete_grid`]; `None`: [`complete_side`]) and the
/// five grids each
/// half as fine. A true hull vertex is never inside such a tetrahedron, so every point exact
/// HPR finds is kept (recall 1); hidden points above every tested triangle are kept too.
pub fn complete(
    points: &[Vec3],
    viewpoint: Vec3,
    radius: Radius,
    side: Option<u32>,
) -> Result<Visibility> {
    let flip = Flip::new(points, viewpoint, radius)?;
    let side = side.map_or_else(|| complete_side(flip.points.len()), complete_grid);
    let eye = viewpoint.as_dvec3();
    let relative: Vec<DVec3> = points.par_iter().map(|p| p.as_dvec3() - eye).collect();
    let (centre, r) = approx::bounding_sphere(&relative).unwrap_or((DVec3::X, 0.0));
    let sectors = approx::Sectors::new(centre, r, DVec3::ZERO, side);
    let cells: Vec<(u32, u32)> = flip.points.par_iter().map(|&p| sectors.sector(p)).collect();
    let hidden = prefilter::certified_hidden(&flip.points, &cells, side, prefilter::LEVELS);
    let on_hull = (0..flip.points.len()).filter(|&t| !hidden[t]);
    Ok(flip.visibility(on_hull, Vec::new(), false))
}

/// Sectors per point of [`complete`]'s default finest grid. On the bunny, the armadillo, the
/// Buddha, the dragon and the Autzen tile F1 against exact HPR rises from 1 to 4 sectors per
/// point (0.934 to 0.981, 0.882 to 0.973, 0.878 to 0.970, 0.952 to 0.981, 0.956 to 0.990) and
/// by at most 0.008 at 8.
pub const COMPLETE_SECTORS_PER_POINT: f64 = 4.0;

/// The largest finest grid of [`complete`], per angle: its six grids hold 89 M sectors (716 MB
/// of 64-bit keys on the GPU, within one storage binding), enough for about 17 M points at
/// [`COMPLETE_SECTORS_PER_POINT`] (F1 gains little from more).
pub const COMPLETE_MAX_SIDE: u32 = 8192;

/// The default finest grid of [`complete`] for `n` points.
pub fn complete_side(n: usize) -> u32 {
    complete_grid(prefilter::finest_side(
        n,
        COMPLETE_SECTORS_PER_POINT,
        prefilter::LEVELS,
    ))
}

/// `side` sectors per angle as a grid [`complete`] can use: rounded up to a multiple of
/// 2^(levels − 1), at most [`COMPLETE_MAX_SIDE`].
pub fn complete_grid(side: u32) -> u32 {
    let unit = 1 << (prefilter::LEVELS - 1);
    (side.max(1).div_ceil(unit) * unit).min(COMPLETE_MAX_SIDE)
}

/// [`exact`] with every flipped point given to the hull: the reference its prefilter is tested
/// against.
pub fn exact_reference(points: &[Vec3], viewpoint: Vec3, radius: Radius) -> Result<Visibility> {
    let flip = Flip::new(points, viewpoint, radius)?;
    let all: Vec<usize> = (0..flip.points.len()).collect();
    Ok(flip.hull_of(&all))
}

/// The spherically flipped cloud shared by [`exact`] and the approximate hulls
/// ([`hulls`]): the viewpoint at the origin, one flipped point per distinct flippable position.
pub(crate) struct Flip {
    /// The flipping radius R.
    pub(crate) radius: f64,
    /// The flipped points (the viewpoint is the origin).
    pub(crate) points: Vec<DVec3>,
    /// The original index of each flipped point.
    pub(crate) original: Vec<u32>,
    /// Each original point's representative: the first point at its position.
    representative: Vec<u32>,
    /// Whether each original point is away from the viewpoint (flippable).
    flippable: Vec<bool>,
    /// Points at the viewpoint.
    at_viewpoint: usize,
}

impl Flip {
    pub(crate) fn new(points: &[Vec3], viewpoint: Vec3, radius: Radius) -> Result<Self> {
        let eye = viewpoint.as_dvec3();
        let r = flip_radius(points, viewpoint, radius)?;
        let n = points.len();
        // Exact duplicates (relative to the eye, -0 as +0): sorted by position, each takes the
        // first index of its run as its representative.
        let mut order: Vec<([u64; 3], u32)> = (0..n as u32)
            .into_par_iter()
            .map(|i| {
                let p = points[i as usize].as_dvec3() - eye;
                ([p.x, p.y, p.z].map(|c| (c + 0.0).to_bits()), i)
            })
            .collect();
        order.par_sort_unstable();
        let mut representative = vec![0u32; n];
        let mut run = 0;
        for (k, &(key, i)) in order.iter().enumerate() {
            if k == 0 || order[k - 1].0 != key {
                run = i;
            }
            representative[i as usize] = run;
        }
        drop(order);
        let flippable: Vec<bool> = points.par_iter().map(|p| p.as_dvec3() != eye).collect();
        let original: Vec<u32> = (0..n as u32)
            .into_par_iter()
            .filter(|&i| flippable[i as usize] && representative[i as usize] == i)
            .collect();
        let flipped = original
            .par_iter()
            .map(|&i| {
                let p = points[i as usize].as_dvec3() - eye;
                let d = p.length();
                p + 2.0 * (r - d) * p / d
            })
            .collect();
        Ok(Flip {
            radius: r,
            points: flipped,
            original,
            representative,
            at_viewpoint: flippable.iter().filter(|&&f| !f).count(),
            flippable,
        })
    }

    /// The visibility given by the convex hull of the flipped points `subset` (indices into
    /// `points`) and the viewpoint: its vertices are visible, its facets without the viewpoint
    /// are the triangles. A flat input is retried joggled (`QJ`); one that still fails (fewer
    /// than four distinct points) has all of `subset` visible.
    pub(crate) fn hull_of(&self, subset: &[usize]) -> Visibility {
        let viewpoint_index = subset.len();
        let coords: Vec<f64> = subset
            .iter()
            .map(|&i| self.points[i])
            .chain(std::iter::once(DVec3::ZERO))
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        let mut joggled = false;
        let hull = match hull(&coords, "Qt") {
            Ok(h) => Some(h),
            Err(_) => {
                joggled = true;
                hull(&coords, "QJ").ok()
            }
        };
        let Some((vertices, facets)) = hull else {
            return self.visibility(subset.iter().copied(), Vec::new(), joggled);
        };
        let triangles = facets
            .into_iter()
            .filter(|f| !f.contains(&viewpoint_index))
            .map(|f| f.map(|v| self.original[subset[v]]))
            .collect();
        let on_hull = vertices
            .into_iter()
            .filter(|&v| v != viewpoint_index)
            .map(|v| subset[v]);
        self.visibility(on_hull, triangles, joggled)
    }

    /// The visibility where the flipped points `on_hull` (indices into `points`) are visible,
    /// with every exact duplicate of them.
    pub(crate) fn visibility(
        &self,
        on_hull: impl IntoIterator<Item = usize>,
        triangles: Vec<[u32; 3]>,
        joggled: bool,
    ) -> Visibility {
        let mut visible_rep = vec![false; self.representative.len()];
        for i in on_hull {
            visible_rep[self.original[i] as usize] = true;
        }
        let visible = (0..self.representative.len())
            .filter(|&i| self.flippable[i] && visible_rep[self.representative[i] as usize])
            .map(|i| i as u32)
            .collect();
        Visibility {
            visible,
            triangles,
            radius: self.radius,
            at_viewpoint: self.at_viewpoint,
            joggled,
        }
    }
}

/// Precision, recall and F1 of the ascending index list `found` against `truth` (1 where both
/// are empty).
pub fn agreement(found: &[u32], truth: &[u32]) -> (f64, f64, f64) {
    let (mut i, mut j, mut hits) = (0, 0, 0usize);
    while i < found.len() && j < truth.len() {
        match found[i].cmp(&truth[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                hits += 1;
                i += 1;
                j += 1;
            }
        }
    }
    let ratio = |n: usize| if n == 0 { 1.0 } else { hits as f64 / n as f64 };
    let (p, r) = (ratio(found.len()), ratio(truth.len()));
    let f1 = if p + r > 0.0 {
        2.0 * p * r / (p + r)
    } else {
        0.0
    };
    (p, r, f1)
}

/// The visible points of `cloud` with all their attributes, and the hull's triangles over them
/// as faces (a partial surface of what is seen).
pub fn visible_cloud(cloud: &Cloud, v: &Visibility) -> Cloud {
    let keep: Vec<usize> = v.visible.iter().map(|&i| i as usize).collect();
    let mut new_index = vec![u32::MAX; cloud.len()];
    for (k, &i) in keep.iter().enumerate() {
        new_index[i] = k as u32;
    }
    let mut out = cloud.select(&keep, |_| 1.0);
    let faces: Vec<[u32; 3]> = v
        .triangles
        .iter()
        .map(|t| t.map(|i| new_index[i as usize]))
        .filter(|t| t.iter().all(|&i| i != u32::MAX))
        .collect();
    out.faces = (!faces.is_empty()).then_some(faces);
    out
}

/// The convex hull of `coords` (xyz triples) with Qhull option `option`: the input indices of
/// its vertices and its triangles (`Qt`/`QJ` give simplicial facets).
fn hull(coords: &[f64], option: &str) -> Result<(Vec<usize>, Vec<[usize; 3]>)> {
    let qh = Qh::builder()
        .qhull_args(option.split(' '))?
        .build_managed(3, coords.to_vec())
        .map_err(|e| anyhow::anyhow!("qhull: {e}"))?;
    let vertices = qh.vertices().filter_map(|v| v.index(&qh)).collect();
    let mut facets = Vec::new();
    for f in qh.facets() {
        let Some(set) = f.vertices() else { continue };
        let ids: Vec<usize> = set.iter().filter_map(|v| v.index(&qh)).collect();
        if let [a, b, c] = ids[..] {
            facets.push([a, b, c]);
        }
    }
    Ok((vertices, facets))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on the unit sphere (a Fibonacci lattice of `n`).
    pub(super) fn sphere(n: usize) -> Vec<Vec3> {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let r = (1.0 - y * y).sqrt();
                let a = golden * i as f32;
                Vec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect()
    }

    #[test]
    fn a_sphere_seen_from_outside_shows_its_facing_cap() {
        // From distance 4 the geometric horizon is where cos(angle to the eye) = 1/4: points
        // well inside the cap are visible, points well behind it are not; the band between
        // depends on R (larger R: the visible set approaches the true cap).
        let points = sphere(4000);
        let eye = Vec3::new(0.0, 0.0, 4.0);
        let v = exact(&points, eye, Radius::Factor(100.0)).unwrap();
        let visible: std::collections::HashSet<u32> = v.visible.iter().copied().collect();
        for (i, p) in points.iter().enumerate() {
            let c = p.z; // cos of the angle between the point and the eye direction
            if c > 0.35 {
                assert!(visible.contains(&(i as u32)), "facing point {p} hidden");
            }
            if c < 0.15 {
                assert!(!visible.contains(&(i as u32)), "back point {p} visible");
            }
        }
        assert!(!v.triangles.is_empty() && !v.joggled);
        assert!(v.triangles.iter().flatten().all(|&i| visible.contains(&i)));
    }

    #[test]
    fn from_inside_a_sphere_every_point_is_visible() {
        // Seen from its centre (or anywhere inside), a sphere shows all of its points: the
        // flipped points all lie on the hull, which encloses the viewpoint.
        let points = sphere(2000);
        for eye in [Vec3::ZERO, Vec3::new(0.3, -0.2, 0.1)] {
            let v = exact(&points, eye, Radius::Factor(100.0)).unwrap();
            assert_eq!(v.visible.len(), points.len(), "{eye}");
        }
    }

    #[test]
    fn complete_grids_are_multiples_of_the_coarsest_and_capped() {
        assert_eq!(complete_grid(1), 32);
        assert_eq!(complete_grid(33), 64);
        assert_eq!(complete_grid(1 << 20), COMPLETE_MAX_SIDE);
        // About four sectors per point: 2,000 per angle for a million points.
        assert_eq!(complete_side(1_000_000), 1984);
        assert_eq!(complete_side(1 << 30), COMPLETE_MAX_SIDE);
    }

    #[test]
    fn agreement_counts_common_indices() {
        assert_eq!(agreement(&[1, 2, 3, 4], &[2, 4, 6, 8]), (0.5, 0.5, 0.5));
        assert_eq!(agreement(&[], &[]), (1.0, 1.0, 1.0));
        assert_eq!(agreement(&[1], &[]).1, 1.0);
        assert_eq!(agreement(&[], &[1]), (1.0, 0.0, 0.0));
    }

    #[test]
    fn a_cubes_corners_show_the_three_facing_faces() {
        // Seen along the diagonal from (5, 5, 5): seven corners face the eye, (-1,-1,-1) hides.
        let corners: Vec<Vec3> = (0..8)
            .map(|k| {
                Vec3::new(
                    if k & 1 == 0 { -1.0 } else { 1.0 },
                    if k & 2 == 0 { -1.0 } else { 1.0 },
                    if k & 4 == 0 { -1.0 } else { 1.0 },
                )
            })
            .collect();
        let v = exact(&corners, Vec3::splat(5.0), Radius::Factor(100.0)).unwrap();
        assert_eq!(v.visible, vec![1, 2, 3, 4, 5, 6, 7]);
    }

    #[test]
    fn duplicates_coplanar_inputs_single_points_and_bad_radii() {
        // Duplicates: every copy of a visible point is visible.
        let mut points = sphere(500);
        let front = (0..points.len())
            .max_by(|&a, &b| points[a].z.total_cmp(&points[b].z))
            .unwrap();
        points.push(points[front]);
        points.push(points[front]);
        let v = exact(&points, Vec3::new(0.0, 0.0, 4.0), Radius::Factor(100.0)).unwrap();
        for i in [front, 500, 501] {
            assert!(v.visible.contains(&(i as u32)), "{i}");
        }
        // A flat grid seen from within its plane: the flipped points stay in that plane with
        // the viewpoint, so Qhull's initial simplex is flat without the joggle.
        let grid: Vec<Vec3> = (0..100)
            .map(|k| Vec3::new((k % 10) as f32, (k / 10) as f32, 0.0))
            .collect();
        let v = exact(&grid, Vec3::new(4.5, -5.0, 0.0), Radius::Factor(100.0)).unwrap();
        assert!(v.joggled);
        // The near row faces the viewpoint.
        assert!((0..10).all(|i| v.visible.contains(&i)), "{:?}", v.visible);
        // One point, and a point at the viewpoint.
        let v = exact(&[Vec3::ONE], Vec3::ZERO, Radius::Absolute(10.0)).unwrap();
        assert_eq!(v.visible, vec![0]);
        let v = exact(&[Vec3::ONE, Vec3::ZERO], Vec3::ZERO, Radius::Absolute(10.0)).unwrap();
        assert_eq!((v.visible.clone(), v.at_viewpoint), (vec![0], 1));
        // Errors, not panics.
        assert!(exact(&[], Vec3::ZERO, Radius::Factor(10.0)).is_err());
        let e = exact(&[Vec3::ONE * 10.0], Vec3::ZERO, Radius::Absolute(1.0)).unwrap_err();
        assert!(e.to_string().contains("must exceed"), "{e}");
    }
}
