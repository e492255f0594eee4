//! Level of detail from object textures (thesis 000 ch. 7), pure CPU.
//!
//! * **Hierarchy** (§7.1.1). A kd-tree splits the cloud at the centre of mass of each node,
//!   alternating the x, y and z axes, into *patches* of at most 4^(levels − 1) points. Inside a
//!   patch every internal node has up to four children (two binary kd splits) and the leaves,
//!   level 0, are the input points, one each. Level `levels − 1` holds the patch's
//!   *representative* splat. Parent splats come from their children (`Splat::parent`).
//! * **Error** (§7.1.2). Each internal node has the perpendicular error of Sequential Point
//!   Trees (Dachsbacher et al. 2003), `Splat::perpendicular_error`.
//! * **Object texture** (§7.1). Per patch, its vertices stored contiguously, coarsest level
//!   first; the representative carries the offset and the count per level (`ObjectTexture`).
//! * **Level choice** (§7.2). The projected error e_p · sin α / |v| (in pixels) against a
//!   threshold ε picks one level per patch (`ObjectTexture::choose`); this is the CPU reference
//!   of the GPU expansion.

use glam::{Mat4, Vec3, Vec4};

use crate::scene::pack::{linear_component, oct_encode, srgb_byte};

use crate::layout::{
    GpuLodPatch, GpuLodVertex, LOD_BUDGET_BINS, LOD_BUDGET_BIN_BASE, LOD_MAX_LEVELS,
};

/// The thesis' number of levels (0: the input points; 3: the representatives).
pub const DEFAULT_LEVELS: u32 = 4;

/// Every level count the hierarchy accepts: a patch of 4^(levels − 1) points and a patch's
/// per-level counts fit the GPU's `uvec4` (`GpuLodPatch`).
pub const LEVELS: std::ops::RangeInclusive<u32> = 2..=LOD_MAX_LEVELS;

/// The point budget's bin of a projected error `e` > 0: its f32 bits >> 20 (exponent and three
/// mantissa bits, so eight bins per octave) from 2^-16 pixels, clamped to the bins
/// (`lod_budget_bin` in `glsl/lod/lod.glsl`).
pub fn budget_bin(e: f32) -> usize {
    let b = i64::from(e.to_bits() >> 20) - i64::from(LOD_BUDGET_BIN_BASE);
    b.clamp(0, i64::from(LOD_BUDGET_BINS) - 1) as usize
}

/// The smallest error of bin `k` ≥ 1 (exact: the f32 with bits (k + base) << 20).
pub fn budget_edge(k: usize) -> f32 {
    f32::from_bits((k as u32 + LOD_BUDGET_BIN_BASE) << 20)
}

/// A surface splat: centre, unit normal, radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Splat {
    pub position: Vec3,
    pub normal: Vec3,
    pub radius: f32,
}

impl Splat {
    /// The splat replacing `children` (each with the number of input points below it): centre
    /// of mass of the points, their mean normal, and the smallest radius about that centre
    /// whose disc covers every child's (the thesis combines the children without saying how;
    /// this is the construction of Sequential Point Trees).
    pub fn parent(children: &[(Splat, u32)]) -> Splat {
        let points: f32 = children.iter().map(|&(_, w)| w as f32).sum();
        let position = children
            .iter()
            .map(|&(s, w)| s.position * w as f32)
            .sum::<Vec3>()
            / points;
        let mean = children
            .iter()
            .map(|&(s, w)| s.normal * w as f32)
            .sum::<Vec3>();
        // Opposite normals cancel (a thin sheet seen from both sides): keep the first child's.
        let normal = mean.try_normalize().unwrap_or(children[0].0.normal);
        let radius = children
            .iter()
            .map(|&(s, _)| (s.position - position).length() + s.radius)
            .fold(0.0, f32::max);
        Splat {
            position,
            normal,
            radius,
        }
    }

    /// The perpendicular error of Sequential Point Trees (000 §7.1.2): the width of the
    /// slab parallel to this splat's tangent plane that holds every child's disc,
    /// e_p = max((c_i − p)·n + d_i) − min((c_i − p)·n − d_i), d_i = r_i √(1 − (n_i·n)²).
    pub fn perpendicular_error(&self, children: &[Splat]) -> f32 {
        let (mut hi, mut lo) = (f32::MIN, f32::MAX);
        for c in children {
            let cos = c.normal.dot(self.normal).clamp(-1.0, 1.0);
            let d = c.radius * (1.0 - cos * cos).sqrt();
            let h = (c.position - self.position).dot(self.normal);
            hi = hi.max(h + d);
            lo = lo.min(h - d);
        }
        if children.is_empty() {
            0.0
        } else {
            hi - lo
        }
    }
}

/// A node of the hierarchy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub splat: Splat,
    /// Perpendicular error against the children (0 for the input points).
    pub error: f32,
    /// Input points below the node.
    pub points: u32,
    /// Level 0: the input point's index; above: the first child in the level below (the
    /// children are contiguous there).
    pub first: u32,
    /// Children (0 at level 0).
    pub children: u32,
}

/// The multiresolution hierarchy: nodes per level, each patch's nodes contiguous in every
/// level, patches in the same order in every level.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// `levels[l]`: the nodes of level l; `levels[0]` the input points, the last level the
    /// representatives (one per patch).
    pub levels: Vec<Vec<Node>>,
    /// `patch_nodes[p][l]`: the range of patch p's nodes in `levels[l]`.
    pub patch_nodes: Vec<Vec<std::ops::Range<u32>>>,
}

/// Splits `ids` at the centre of mass along `axis`, so that each side keeps at most `cap`
/// points: returns the size of the lower side. Deviation from the thesis: a split at the
/// centre of mass alone may leave more points on one side than the levels below can hold one
/// leaf each; the split then moves to the nearest position that fits (the thesis' leaves hold
/// at most one point without saying how). With `cap` ≥ `ids.len()` the split is the plain
/// centre of mass one (0 or `len` when every point has the same coordinate).
fn split(positions: &[Vec3], ids: &mut [u32], axis: usize, cap: usize) -> usize {
    let n = ids.len();
    let key = |i: &u32| positions[*i as usize][axis];
    let mean = ids.iter().map(|i| f64::from(key(i))).sum::<f64>() / n as f64;
    let below = ids.iter().filter(|i| f64::from(key(i)) < mean).count();
    let k = below.clamp(n.saturating_sub(cap), cap.min(n));
    // The k smallest coordinates first: with k = `below`, exactly the points below the mean.
    if k > 0 && k < n {
        ids.select_nth_unstable_by(k, |a, b| key(a).total_cmp(&key(b)));
    }
    k
}

impl Hierarchy {
    /// Builds the hierarchy of `levels` levels (`LEVELS`) over points with unit normals and
    /// radii.
    pub fn build(positions: &[Vec3], normals: &[Vec3], radii: &[f32], levels: u32) -> Hierarchy {
        assert!(
            LEVELS.contains(&levels),
            "levels {levels} outside {LEVELS:?}"
        );
        assert!(normals.len() == positions.len() && radii.len() == positions.len());
        let patch_cap = 4usize.pow(levels - 1);
        let mut h = Hierarchy {
            levels: vec![Vec::new(); levels as usize],
            patch_nodes: Vec::new(),
        };
        let mut ids: Vec<u32> = (0..positions.len() as u32).collect();
        // Top-level kd-tree, depth first (so consecutive patches are near each other): split at
        // the centre of mass while a node holds more than a patch. `depth` picks the axis.
        let mut stack = vec![(0..ids.len(), 0usize)];
        while let Some((range, depth)) = stack.pop() {
            if range.is_empty() {
                continue;
            }
            if range.len() <= patch_cap {
                let before: Vec<u32> = h.levels.iter().map(|l| l.len() as u32).collect();
                let leaves = &mut ids[range];
                h.node(
                    positions,
                    normals,
                    radii,
                    leaves,
                    levels as usize - 1,
                    depth,
                );
                h.patch_nodes.push(
                    h.levels
                        .iter()
                        .zip(before)
                        .map(|(l, b)| b..l.len() as u32)
                        .collect(),
                );
                continue;
            }
            // A degenerate axis (every coordinate equal) tries the next; coincident points
            // split in the middle.
            let slice = &mut ids[range.clone()];
            let n = slice.len();
            let k = (0..3)
                .map(|t| split(positions, slice, (depth + t) % 3, n))
                .find(|&k| k > 0 && k < n)
                .unwrap_or(n / 2);
            let mid = range.start + k;
            stack.push((mid..range.end, depth + 1));
            stack.push((range.start..mid, depth + 1));
        }
        h
    }

    /// Adds the node of level `level` over `ids` (at most 4^level points) and its subtree;
    /// returns the index of the node in its level.
    fn node(
        &mut self,
        positions: &[Vec3],
        normals: &[Vec3],
        radii: &[f32],
        ids: &mut [u32],
        level: usize,
        depth: usize,
    ) -> u32 {
        if level == 0 {
            let i = ids[0] as usize;
            let splat = Splat {
                position: positions[i],
                normal: normals[i],
                radius: radii[i],
            };
            let node = Node {
                splat,
                error: 0.0,
                points: 1,
                first: ids[0],
                children: 0,
            };
            self.levels[0].push(node);
            return self.levels[0].len() as u32 - 1;
        }
        // Four children from two binary splits: one along `depth`'s axis, then each half along
        // the next; every quarter holds at most 4^(level − 1) points.
        let cap = 4usize.pow(level as u32 - 1);
        let half = split(positions, ids, depth % 3, 2 * cap);
        let (lo, hi) = ids.split_at_mut(half);
        let a = split(positions, lo, (depth + 1) % 3, cap);
        let b = split(positions, hi, (depth + 1) % 3, cap);
        let (q0, q1) = lo.split_at_mut(a);
        let (q2, q3) = hi.split_at_mut(b);
        let mut first = None;
        let mut children = 0;
        for q in [q0, q1, q2, q3] {
            if !q.is_empty() {
                let c = self.node(positions, normals, radii, q, level - 1, depth + 2);
                first.get_or_insert(c);
                children += 1;
            }
        }
        let first = first.expect("a node holds at least one point");
        let below = &self.levels[level - 1][first as usize..(first + children) as usize];
        let weighted: Vec<(Splat, u32)> = below.iter().map(|c| (c.splat, c.points)).collect();
        let splat = Splat::parent(&weighted);
        let splats: Vec<Splat> = below.iter().map(|c| c.splat).collect();
        let node = Node {
            splat,
            error: splat.perpendicular_error(&splats),
            points: below.iter().map(|c| c.points).sum(),
            first,
            children,
        };
        self.levels[level].push(node);
        self.levels[level].len() as u32 - 1
    }

    pub fn level_count(&self) -> u32 {
        self.levels.len() as u32
    }

    pub fn patch_count(&self) -> usize {
        self.patch_nodes.len()
    }
}

/// The sRGB color of every node of `h`: the input point's at level 0, above the mean of the
/// children's linear colors weighted by the points below each (so the mean of the points).
fn node_colors(h: &Hierarchy, colors: Option<&[[u8; 4]]>) -> Vec<Vec<[u8; 4]>> {
    let Some(colors) = colors else {
        return h.levels.iter().map(|l| vec![[255; 4]; l.len()]).collect();
    };
    let linear = |c: [u8; 4]| Vec3::from_array(std::array::from_fn(|k| linear_component(c[k])));
    let mut means: Vec<Vec<Vec3>> = Vec::with_capacity(h.levels.len());
    means.push(
        h.levels[0]
            .iter()
            .map(|n| linear(colors[n.first as usize]))
            .collect(),
    );
    for l in 1..h.levels.len() {
        let below = (&h.levels[l - 1], &means[l - 1]);
        let level = h.levels[l]
            .iter()
            .map(|n| {
                let children = n.first as usize..(n.first + n.children) as usize;
                let sum: Vec3 = children
                    .map(|c| below.1[c] * below.0[c].points as f32)
                    .sum();
                sum / n.points as f32
            })
            .collect();
        means.push(level);
    }
    means
        .iter()
        .map(|l| {
            l.iter()
                .map(|c| [srgb_byte(c.x), srgb_byte(c.y), srgb_byte(c.z), 255])
                .collect()
        })
        .collect()
}

/// One patch of the object texture: the representative splat, the offset of its vertices and
/// the count and error of every level.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    pub representative: Splat,
    /// First vertex of the patch in `ObjectTexture::vertices`.
    pub offset: u32,
    /// Vertices per level, `counts[levels − 1]` = 1 (the representative).
    pub counts: Vec<u32>,
    /// `errors[l]`: the largest perpendicular error of the patch's nodes at levels 1..=l
    /// (0 at level 0), so drawing level l instead of the points costs at most this much.
    pub errors: Vec<f32>,
}

impl Patch {
    /// First vertex of level `level` in `ObjectTexture::vertices`.
    pub fn level_offset(&self, level: u32) -> u32 {
        self.offset + self.counts[level as usize + 1..].iter().sum::<u32>()
    }
}

/// A vertex of the object texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    pub splat: Splat,
    /// sRGB color: level 0 the point's, above the mean of its points' colors in linear space
    /// (white without colors).
    pub color: [u8; 4],
    pub level: u32,
    /// Level 0: the input point's index; above: the node's index in its level.
    pub source: u32,
}

/// The object texture (000 §7.1): every patch's vertices contiguous, coarsest level first.
/// Deviation from the thesis: the representative is stored too, as the patch's first vertex,
/// so every level, the representative's included, is one contiguous range of one vertex
/// format; the thesis keeps it only in the vertex stream sent to the GPU.
#[derive(Clone, Debug)]
pub struct ObjectTexture {
    pub levels: u32,
    pub patches: Vec<Patch>,
    pub vertices: Vec<Vertex>,
}

/// What the level choice sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodView {
    pub eye: Vec3,
    /// Pixels per unit of tan(angle) at distance 1: viewport height / (2 tan(fov_y / 2)).
    pub focal_pixels: f32,
    /// The threshold ε in pixels.
    pub epsilon: f32,
    /// Projection × view: patches outside its frustum are culled.
    pub view_proj: Mat4,
}

impl LodView {
    /// The view the GPU's level choice reads from the frame uniforms (`glsl/lod/lod.glsl`):
    /// the eye of a rigid `view` matrix and the focal length in pixels of `proj` over a
    /// viewport `height` pixels tall.
    pub fn from_camera(view: Mat4, proj: Mat4, height: f32, epsilon: f32) -> LodView {
        LodView {
            // As lod.glsl computes it: −Rᵀt for the rotation R and translation t.
            eye: -(glam::Mat3::from_mat4(view).transpose() * view.w_axis.truncate()),
            focal_pixels: proj.y_axis.y.abs() * height * 0.5,
            epsilon,
            view_proj: proj * view,
        }
    }
}

impl ObjectTexture {
    /// The object texture of `h`, its vertices colored from `colors` (the input points',
    /// indexed as the hierarchy's level 0 `first`), or white.
    pub fn new(h: &Hierarchy, colors: Option<&[[u8; 4]]>) -> ObjectTexture {
        let levels = h.level_count();
        let node_colors = node_colors(h, colors);
        let mut patches = Vec::with_capacity(h.patch_count());
        let mut vertices = Vec::with_capacity(h.levels.iter().map(Vec::len).sum());
        for ranges in &h.patch_nodes {
            let offset = vertices.len() as u32;
            let mut errors = vec![0.0f32; levels as usize];
            for l in (0..levels as usize).rev() {
                for k in ranges[l].clone() {
                    let n = &h.levels[l][k as usize];
                    vertices.push(Vertex {
                        splat: n.splat,
                        color: node_colors[l][k as usize],
                        level: l as u32,
                        source: if l == 0 { n.first } else { k },
                    });
                }
            }
            for l in 1..levels as usize {
                let worst = ranges[l]
                    .clone()
                    .map(|k| h.levels[l][k as usize].error)
                    .fold(0.0, f32::max);
                errors[l] = errors[l - 1].max(worst);
            }
            patches.push(Patch {
                representative: h.levels[levels as usize - 1]
                    [ranges[levels as usize - 1].start as usize]
                    .splat,
                offset,
                counts: ranges.iter().map(|r| r.end - r.start).collect(),
                errors,
            });
        }
        ObjectTexture {
            levels,
            patches,
            vertices,
        }
    }

    /// The level of `patch` for `view` (000 §7.1.2–7.2): the coarsest level whose error,
    /// projected as e_p · sin α / |v| (α the angle between the view vector v and the
    /// representative's normal) and scaled to pixels, is at most ε. Silhouettes (α near 90°)
    /// and near patches get finer levels.
    pub fn choose(&self, patch: &Patch, view: &LodView) -> u32 {
        let scale = Self::projected_scale(patch, view);
        (0..self.levels)
            .rev()
            .find(|&l| patch.errors[l as usize] * scale <= view.epsilon)
            .unwrap_or(0)
    }

    /// The factor projecting `patch`'s perpendicular errors to pixels: sin α / |v| times the
    /// focal length (`lod_scale` in `glsl/lod/lod.glsl`).
    pub fn projected_scale(patch: &Patch, view: &LodView) -> f32 {
        let v = patch.representative.position - view.eye;
        let distance = v.length().max(f32::MIN_POSITIVE);
        let cos = (v.dot(patch.representative.normal) / distance).clamp(-1.0, 1.0);
        (1.0 - cos * cos).sqrt() / distance * view.focal_pixels
    }

    /// The point budget, the CPU reference of `glsl/lod/budget_*.comp`: the
    /// threshold that fills at most `budget` samples by error priority. Refining a visible
    /// patch from level l to l − 1 adds counts[l − 1] − counts[l] samples and is demanded by
    /// the projected error e_l; refinements are admitted by decreasing e_l, in bins of an
    /// eighth of an octave (`budget_bin`), until the budget is full. Returns `view.epsilon`
    /// when everything it demands fits, else the smallest bin edge whose admitted refinements
    /// fit, else infinity (every patch at its coarsest level). Drawn with the returned
    /// threshold, the view's samples (`histogram`) never exceed the budget when it is at least
    /// the patch count.
    pub fn budget_threshold(&self, view: &LodView, budget: u32) -> f32 {
        let mut base = 0u64;
        let mut bins = [0u64; LOD_BUDGET_BINS as usize];
        for p in self.patches.iter().filter(|p| self.in_view(p, view)) {
            let top = self.levels as usize - 1;
            base += u64::from(p.counts[top]);
            let scale = Self::projected_scale(p, view);
            for l in (1..=top).rev() {
                let e = p.errors[l] * scale;
                if e > view.epsilon {
                    bins[budget_bin(e)] += u64::from(p.counts[l - 1] - p.counts[l]);
                }
            }
        }
        let budget = u64::from(budget);
        let mut suffix = 0;
        // The smallest k whose refinements (bins k and above) fit; the sums fall with k.
        let mut first_fit = LOD_BUDGET_BINS as usize;
        for k in (0..bins.len()).rev() {
            suffix += bins[k];
            if base + suffix <= budget {
                first_fit = k;
            }
        }
        match first_fit {
            0 => view.epsilon,
            k if k == bins.len() => f32::INFINITY,
            k => budget_edge(k),
        }
    }

    /// Whether `patch`'s bounding sphere (the representative's, which covers its
    /// descendants) reaches into `view`'s frustum: inside the four side planes and in front of
    /// the eye's plane, as `lod_in_view` in `glsl/lod/lod.glsl` tests it.
    pub fn in_view(&self, patch: &Patch, view: &LodView) -> bool {
        let m = view.view_proj;
        let (x, y, w) = (m.row(0), m.row(1), m.row(3));
        let c = patch.representative.position.extend(1.0);
        let r = patch.representative.radius;
        [w + x, w - x, w + y, w - y, w]
            .iter()
            .all(|p| p.dot(c) >= -r * p.truncate().length())
    }

    /// The vertices `view` draws: per patch, the chosen level's range (empty for a patch
    /// outside the view).
    pub fn select(&self, view: &LodView) -> Vec<std::ops::Range<u32>> {
        self.patches
            .iter()
            .map(|p| {
                if !self.in_view(p, view) {
                    return p.offset..p.offset;
                }
                let l = self.choose(p, view);
                let first = p.level_offset(l);
                first..first + p.counts[l as usize]
            })
            .collect()
    }

    /// The patches as the GPU reads them (`GpuLodPatch`); levels past `levels` repeat the last
    /// error and count no vertex.
    pub fn gpu_patches(&self) -> Vec<GpuLodPatch> {
        self.patches
            .iter()
            .map(|p| {
                let at = |l: usize| p.errors[l.min(p.errors.len() - 1)];
                let count = |l: usize| p.counts.get(l).copied().unwrap_or(0);
                let r = p.representative;
                GpuLodPatch {
                    sphere: r.position.extend(r.radius),
                    normal: r.normal.extend(0.0),
                    errors: Vec4::new(at(0), at(1), at(2), at(3)),
                    counts: [count(0), count(1), count(2), count(3)],
                    offset: p.offset,
                    levels: self.levels,
                    ..Default::default()
                }
            })
            .collect()
    }

    /// The vertices as the GPU reads them (`GpuLodVertex`).
    pub fn gpu_vertices(&self) -> Vec<GpuLodVertex> {
        self.vertices
            .iter()
            .map(|v| GpuLodVertex {
                sphere: v.splat.position.extend(v.splat.radius),
                normal_color: [
                    oct_encode(v.splat.normal),
                    u32::from_le_bytes(v.color),
                    v.level,
                    0,
                ],
            })
            .collect()
    }

    /// The most vertices any view selects: every patch at its finest level, the input points.
    pub fn max_selected(&self) -> u32 {
        self.patches.iter().map(|p| p.counts[0]).sum()
    }

    /// Vertices drawn per level for `view`.
    pub fn histogram(&self, view: &LodView) -> Vec<u64> {
        let mut h = vec![0u64; self.levels as usize];
        for p in self.patches.iter().filter(|p| self.in_view(p, view)) {
            let l = self.choose(p, view);
            h[l as usize] += u64::from(p.counts[l as usize]);
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// A view from `eye` towards the origin whose frustum (150°) holds the whole unit sphere,
    /// with the level choice's focal length and ε given separately.
    fn wide_view(eye: Vec3, focal_pixels: f32, epsilon: f32) -> LodView {
        let view = Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
        let proj = Mat4::perspective_infinite_reverse_rh(150f32.to_radians(), 1.0, 0.01);
        LodView {
            focal_pixels,
            ..LodView::from_camera(view, proj, 1.0, epsilon)
        }
    }

    #[test]
    fn patches_outside_the_view_are_culled() {
        let (p, n, r) = sphere(10_000);
        let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
        let proj = Mat4::perspective_infinite_reverse_rh(40f32.to_radians(), 1.0, 0.01);
        let at = |eye: Vec3, target: Vec3| {
            LodView::from_camera(Mat4::look_at_rh(eye, target, Vec3::Y), proj, 512.0, 1.0)
        };
        let seen = |v: &LodView| t.patches.iter().filter(|p| t.in_view(p, v)).count();
        // Framing the sphere: every patch; looking away: none, and nothing is selected;
        // close up (the sphere fills more than the frustum): some.
        assert_eq!(
            seen(&at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO)),
            t.patches.len()
        );
        let away = at(Vec3::new(0.0, 0.0, 4.0), Vec3::new(0.0, 0.0, 8.0));
        assert_eq!(seen(&away), 0);
        assert!(t.select(&away).iter().all(|r| r.is_empty()));
        assert_eq!(t.histogram(&away).iter().sum::<u64>(), 0);
        let close = seen(&at(Vec3::new(0.0, 0.0, 1.6), Vec3::ZERO));
        assert!(close > 0 && close < t.patches.len(), "{close}");
    }

    /// A grid of `n` × `n` points on z = f(x, y) with normals and radii (spacing 1 / n).
    fn surface(n: usize, f: impl Fn(f32, f32) -> (f32, Vec3)) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let mut p = Vec::new();
        let mut nrm = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                let (z, normal) = f(x, y);
                p.push(Vec3::new(x, y, z));
                nrm.push(normal);
            }
        }
        let r = vec![0.75 / n as f32; p.len()];
        (p, nrm, r)
    }

    fn plane(n: usize) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        surface(n, |_, _| (0.0, Vec3::Z))
    }

    /// A sphere patch of radius `r` through the origin's neighbourhood (curvature 1 / r).
    fn sphere_cap(n: usize, r: f32) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        surface(n, |x, y| {
            let c = Vec3::new(0.5, 0.5, -r);
            let d = Vec3::new(x - 0.5, y - 0.5, 0.0);
            let z = (r * r - d.length_squared()).sqrt() - r;
            let p = Vec3::new(x, y, z);
            (z, (p - c).normalize())
        })
    }

    fn random_cloud(n: usize, seed: u64) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let mut rng = SplitMix64::new(seed);
        let p: Vec<Vec3> = (0..n)
            .map(|_| {
                Vec3::new(
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                ) * 2.0
                    - 1.0
            })
            .collect();
        let nrm = p.iter().map(|q| q.normalize_or(Vec3::Z)).collect();
        let r = (0..n)
            .map(|_| 0.01 + 0.02 * rng.next_f64() as f32)
            .collect();
        (p, nrm, r)
    }

    #[test]
    fn lod_finest_level_is_the_input_once() {
        for levels in LEVELS {
            let (p, n, r) = random_cloud(5_000, 7);
            let h = Hierarchy::build(&p, &n, &r, levels);
            let mut seen = vec![0u32; p.len()];
            for node in &h.levels[0] {
                seen[node.first as usize] += 1;
                assert_eq!(node.splat.position, p[node.first as usize]);
            }
            assert!(seen.iter().all(|&s| s == 1), "levels {levels}");
            let t = ObjectTexture::new(&h, None);
            let mut seen = vec![0u32; p.len()];
            for v in t.vertices.iter().filter(|v| v.level == 0) {
                seen[v.source as usize] += 1;
            }
            assert!(seen.iter().all(|&s| s == 1), "levels {levels}");
        }
    }

    #[test]
    fn lod_degenerate_clouds() {
        // Coincident points, a line, one point.
        for p in [
            vec![Vec3::ONE; 300],
            (0..300).map(|i| Vec3::X * i as f32).collect(),
            vec![Vec3::ZERO],
        ] {
            let n = vec![Vec3::Z; p.len()];
            let r = vec![0.1; p.len()];
            let h = Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS);
            assert_eq!(h.levels[0].len(), p.len());
            assert!(h.patch_nodes.iter().all(|r| r[3].len() == 1));
        }
    }

    #[test]
    fn lod_counts_and_offsets_are_consistent() {
        let (p, n, r) = random_cloud(20_000, 3);
        let h = Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS);
        let t = ObjectTexture::new(&h, None);
        assert_eq!(
            t.vertices.len(),
            h.levels.iter().map(Vec::len).sum::<usize>()
        );
        assert_eq!(t.patches.len(), h.levels[3].len());
        let mut next = 0;
        for patch in &t.patches {
            assert_eq!(patch.offset, next);
            assert_eq!(patch.counts[3], 1);
            // At most 4 children per node: 4, 16, 64 vertices below the representative.
            for l in 0..3 {
                assert!(patch.counts[l] >= 1 && patch.counts[l] <= 4u32.pow(3 - l as u32));
                assert!(patch.counts[l] >= patch.counts[l + 1]);
            }
            for l in 0..4 {
                let first = patch.level_offset(l);
                for v in &t.vertices[first as usize..(first + patch.counts[l as usize]) as usize] {
                    assert_eq!(v.level, l);
                }
            }
            assert_eq!(
                t.vertices[patch.offset as usize].splat,
                patch.representative
            );
            assert!(patch.errors.windows(2).all(|w| w[0] <= w[1]));
            next += patch.counts.iter().sum::<u32>();
        }
        assert_eq!(next as usize, t.vertices.len());
        // Children ranges: every node of level l ≥ 1 owns a contiguous, disjoint range whose
        // points add up.
        for l in 1..4 {
            let mut covered = 0;
            for node in &h.levels[l] {
                assert_eq!(node.first, covered);
                assert!((1..=4).contains(&node.children));
                covered += node.children;
                let below = &h.levels[l - 1][node.first as usize..covered as usize];
                assert_eq!(node.points, below.iter().map(|c| c.points).sum::<u32>());
            }
            assert_eq!(covered as usize, h.levels[l - 1].len());
        }
    }

    #[test]
    fn lod_parents_cover_children() {
        let (p, n, r) = random_cloud(10_000, 11);
        let h = Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS);
        for l in 1..4 {
            for node in &h.levels[l] {
                let below = &h.levels[l - 1][node.first as usize..][..node.children as usize];
                for c in below {
                    let reach = (c.splat.position - node.splat.position).length() + c.splat.radius;
                    assert!(reach <= node.splat.radius * (1.0 + 1e-5) + 1e-6);
                }
                assert!((node.splat.normal.length() - 1.0).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn lod_perpendicular_error_is_zero_on_a_plane_and_grows_with_curvature() {
        let worst = |(p, n, r): (Vec<Vec3>, Vec<Vec3>, Vec<f32>)| {
            let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
            t.patches.iter().map(|p| p.errors[3]).fold(0.0, f32::max)
        };
        let flat = worst(plane(64));
        assert!(flat < 1e-5, "plane: {flat}");
        let gentle = worst(sphere_cap(64, 4.0));
        let curved = worst(sphere_cap(64, 1.0));
        assert!(gentle > 1e-4, "gentle: {gentle}");
        assert!(curved > 2.0 * gentle, "curved {curved} vs gentle {gentle}");
        // A single parent: children on a tilted pair of discs.
        let parent = Splat {
            position: Vec3::ZERO,
            normal: Vec3::Z,
            radius: 1.0,
        };
        let child = |z: f32, normal: Vec3| Splat {
            position: Vec3::new(0.0, 0.0, z),
            normal,
            radius: 0.5,
        };
        assert_eq!(parent.perpendicular_error(&[child(0.0, Vec3::Z)]), 0.0);
        let e = parent.perpendicular_error(&[child(0.25, Vec3::Z), child(-0.25, Vec3::Z)]);
        assert!((e - 0.5).abs() < 1e-6);
        // A child perpendicular to the parent spans its whole radius both ways.
        let e = parent.perpendicular_error(&[child(0.0, Vec3::X)]);
        assert!((e - 1.0).abs() < 1e-6);
    }

    /// A unit sphere of points with outward normals.
    fn sphere(n: usize) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let p = crate::scene::sample::fibonacci_sphere(n);
        let r = vec![(4.0 / n as f32).sqrt(); n];
        (p.clone(), p, r)
    }

    fn mean_level(t: &ObjectTexture, view: &LodView) -> f32 {
        let total: u32 = t.patches.iter().map(|p| t.choose(p, view)).sum();
        total as f32 / t.patches.len() as f32
    }

    #[test]
    fn lod_far_cameras_choose_coarse_levels_and_near_ones_fine() {
        let (p, n, r) = sphere(40_000);
        let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
        let view = |d: f32| wide_view(Vec3::new(0.0, 0.0, d), 1000.0, 0.5);
        let levels: Vec<f32> = [1.5, 3.0, 10.0, 100.0, 1000.0]
            .iter()
            .map(|&d| mean_level(&t, &view(d)))
            .collect();
        assert!(levels.windows(2).all(|w| w[0] <= w[1]), "{levels:?}");
        assert!(levels[0] < 1.5, "{levels:?}");
        assert!(levels[4] > 2.9, "{levels:?}");
        // Fewer vertices when far.
        let near: u64 = t.histogram(&view(1.5)).iter().sum();
        let far: u64 = t.histogram(&view(1000.0)).iter().sum();
        assert!(far * 10 < near, "near {near}, far {far}");
        // ε = 0 draws the input points but where the error or sin α vanishes.
        let all = LodView {
            epsilon: 0.0,
            ..view(3.0)
        };
        let h = t.histogram(&all);
        assert!(h[0] as f64 >= 0.99 * p.len() as f64, "{h:?}");
    }

    #[test]
    fn lod_silhouettes_get_finer_levels() {
        let (p, n, r) = sphere(40_000);
        let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
        let view = wide_view(Vec3::new(0.0, 0.0, 6.0), 1000.0, 0.5);
        // Patches facing the eye (normal within 30° of the view axis) vs on the silhouette
        // (within 15° of perpendicular).
        let (mut front, mut rim) = (Vec::new(), Vec::new());
        for patch in &t.patches {
            let v = (patch.representative.position - view.eye).normalize();
            let cos = v.dot(patch.representative.normal).abs();
            let level = t.choose(patch, &view) as f32;
            if cos > 0.866 {
                front.push(level);
            } else if cos < 0.259 {
                rim.push(level);
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        assert!(!front.is_empty() && !rim.is_empty());
        assert!(
            mean(&rim) + 0.5 < mean(&front),
            "rim {} front {}",
            mean(&rim),
            mean(&front)
        );
    }

    #[test]
    fn budget_bins_are_an_eighth_of_an_octave_with_exact_edges() {
        for k in 1..LOD_BUDGET_BINS as usize {
            let edge = budget_edge(k);
            assert_eq!(budget_bin(edge), k);
            assert_eq!(budget_bin(f32::from_bits(edge.to_bits() - 1)), k - 1);
        }
        assert_eq!(budget_edge(8), 2f32.powi(-15));
        assert_eq!(budget_edge(128), 1.0);
        assert_eq!(budget_bin(1e-30), 0);
        assert_eq!(budget_bin(1e30), LOD_BUDGET_BINS as usize - 1);
        assert_eq!(budget_bin(f32::INFINITY), LOD_BUDGET_BINS as usize - 1);
    }

    #[test]
    fn lod_budget_admits_the_largest_errors_first_and_never_overflows() {
        let (p, n, r) = sphere(40_000);
        let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
        let view = wide_view(Vec3::new(0.0, 0.0, 2.0), 1000.0, 0.05);
        let total =
            |epsilon: f32| -> u64 { t.histogram(&LodView { epsilon, ..view }).iter().sum() };
        let demanded = total(view.epsilon);
        let patches = t.patches.len() as u64;
        assert!(demanded > 4 * patches, "{demanded}");
        let mut last = (f32::INFINITY, 0);
        for budget in [
            patches,
            demanded / 4,
            demanded / 2,
            demanded - 1,
            demanded,
            2 * demanded,
        ] {
            let threshold = t.budget_threshold(&view, budget as u32);
            let drawn = total(threshold);
            assert!(drawn <= budget, "budget {budget}: {drawn} drawn");
            // A larger budget lowers the threshold and draws more.
            assert!(threshold <= last.0 && drawn >= last.1, "budget {budget}");
            last = (threshold, drawn);
            if budget >= demanded {
                assert_eq!(threshold, view.epsilon);
                assert_eq!(drawn, demanded);
            } else {
                assert!(threshold > view.epsilon, "budget {budget}");
                // The next lower bin edge would overflow: the threshold is the smallest that
                // fits.
                if threshold.is_finite() {
                    let lower = f32::from_bits(threshold.to_bits() - (1 << 20));
                    assert!(total(lower.max(view.epsilon)) > budget, "budget {budget}");
                }
                // Well under the budget only where a bin's refinements are coarse.
                assert!(drawn * 10 >= budget * 7, "budget {budget}: {drawn} drawn");
            }
        }
    }

    #[test]
    fn lod_selection_ranges_hold_one_level_per_patch() {
        let (p, n, r) = sphere(10_000);
        let t = ObjectTexture::new(&Hierarchy::build(&p, &n, &r, DEFAULT_LEVELS), None);
        let view = wide_view(Vec3::new(0.0, 0.0, 4.0), 800.0, 1.0);
        let ranges = t.select(&view);
        let hist = t.histogram(&view);
        assert_eq!(
            ranges
                .iter()
                .map(|r| u64::from(r.end - r.start))
                .sum::<u64>(),
            hist.iter().sum::<u64>()
        );
        for (patch, range) in t.patches.iter().zip(&ranges) {
            let l = t.choose(patch, &view);
            assert!(t.vertices[range.start as usize..range.end as usize]
                .iter()
                .all(|v| v.level == l));
        }
    }
}
