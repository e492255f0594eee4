//! A CPU model of the pyramid with search kernels (000 ch. 6), texel for texel what
//! `glsl/pyramid/kernel_analysis.comp`, `kernel_interpolate.comp` and `kernel_resolve.comp`
//! compute, with the half-precision storage of groups A and C (`reference::Level::set`).
//! Device-free: the unit tests below check it against hand-built pyramids, and
//! `tests/suite/kernel.rs` checks the GPU passes against it.

use glam::{IVec2, Vec2, Vec3};

use crate::layout::PRIMITIVE_POINT;
use crate::methods::pyramid::reference::{ellipse_distance2, parent, pixel_centre, Level, Texel};

/// The level a splat of projected radius `radius` (level-0 pixels) is stored in for a
/// `kernel` × `kernel` search: the least l with kernel · 2^l ≥ 2 · radius, at most `top`.
///
/// Deviation: eq. 6.1 reads l = ⌈log2(D / t)⌉ with D "the projected radius"; here D is the
/// projected diameter 2r. The criterion of Fig. 6.1 is that the t × t kernel of level l, which
/// spans t · 2^l level-0 pixels, covers the whole projection, so that every pixel inside the
/// ellipse finds its centre; with the radius it would span only half of it. The integer loop
/// (the same in the shaders) keeps powers of two exact where `log2` may round either way.
pub fn kernel_level(radius: f32, kernel: u32, top: u32) -> u32 {
    let mut level = 0;
    while level < top && ((kernel << level) as f32) < 2.0 * radius {
        level += 1;
    }
    level
}

/// Levels the interpolation searches over a `width` × `height` base (6.2): a level is skipped
/// when the kernel one level below already covers all of that level from any of its texels,
/// i.e. the search stops at the first level at most (k + 1) / 2 texels wide and high (1024²
/// with 3 × 3: levels 0 to 9, the 1 × 1 level 10 skipped, 10 × 9 = 90 lookups per pixel).
pub fn searched_levels(width: u32, height: u32, kernel: u32) -> u32 {
    let reach = kernel.div_ceil(2);
    let levels = crate::methods::pyramid::level_count(width, height);
    (0..levels)
        .find(|&l| (width >> l).max(1) <= reach && (height >> l).max(1) <= reach)
        .map_or(levels, |l| l + 1)
}

/// Analysis (6.1) for a `kernel` × `kernel` search: levels 0 to `searched_levels` - 1. A child
/// travels on to its parent while its kernel level lies above its own level; the travelling
/// children of one parent are merged as in ch. 4 (the average of those whose depth intervals
/// overlap the front-most one's). A texel is stored in the level it is in when its kernel
/// level is at most that level; the top level stores everything that reaches it.
pub fn analysis(level0: Level, kernel: u32) -> Vec<Level> {
    let searched = searched_levels(level0.width, level0.height, kernel);
    let top = searched - 1;
    let mut levels = vec![level0];
    for level in 1..searched {
        let child = &levels[level as usize - 1];
        let (w, h) = ((child.width / 2).max(1), (child.height / 2).max(1));
        let mut out = Level::empty(w, h);
        for y in 0..h as i32 {
            for x in 0..w as i32 {
                let p = IVec2::new(x, y);
                let travels = |t: &Texel| kernel_level(t.radius, kernel, top) >= level;
                out.set(p, parent(child, p, out.size(), level, travels));
            }
        }
        levels.push(out);
    }
    levels
}

/// What the interpolation passes accumulate per level-0 pixel (the three RGBA32F images at
/// `BINDING_KERNEL_ACCUM`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Accum {
    pub n: Vec3,
    pub weight: f32,
    pub depth: f32,
    pub radius: f32,
    /// Depth and half range of the contribution the others are tested against.
    pub front_depth: f32,
    pub front_range: f32,
    pub color: Vec3,
}

impl Accum {
    /// Adds texel `t` with weight `w` under the occlusion test of ch. 4, applied in the order
    /// of the search: a texel whose depth interval overlaps the front contribution's joins
    /// it, one behind is discarded, one in front starts the sums anew.
    pub fn add(&mut self, t: &Texel, w: f32) {
        if self.weight > 0.0 {
            let overlap = (t.depth - self.front_depth).abs() <= t.half_range + self.front_range;
            if !overlap && t.depth > self.front_depth {
                return;
            }
            if !overlap {
                *self = Self::default();
            }
        }
        if self.weight == 0.0 {
            self.front_depth = t.depth;
            self.front_range = t.half_range;
        }
        self.n += w * t.n;
        self.weight += w;
        self.depth += w * t.depth;
        self.radius += w * t.radius;
        self.color += w * t.color.truncate();
    }

    /// The interpolated texel: weighted means, the front contribution's half range, no
    /// displacement, a point's primitive id; empty without contributions.
    pub fn resolve(&self) -> Texel {
        if self.weight == 0.0 {
            return Texel::default();
        }
        let w = self.weight;
        let len = self.n.length();
        Texel {
            n: if len > 0.0 { self.n / len } else { Vec3::Z },
            radius: self.radius / w,
            depth: self.depth / w,
            half_range: self.front_range,
            disp: Vec2::ZERO,
            color: (self.color / w).extend(PRIMITIVE_POINT as f32),
        }
    }
}

/// Interpolation (6.2) over the analysed `levels` (all of them searched): every level-0 pixel
/// visits the `kernel` × `kernel` texels around its own texel in each level, level 0 first;
/// a texel stored there whose ellipse contains the pixel centre adds with w = 1 - d (eq. 6.2),
/// d the elliptical distance to the ellipse centre (the texel's centre plus its displacement;
/// 1 on the rim). `scale` as in `reference::ellipse_distance2`.
pub fn interpolate(levels: &[Level], kernel: u32, scale: Vec2) -> Level {
    let top = levels.len() as u32 - 1;
    let base = &levels[0];
    let reach = (kernel as i32 - 1) / 2;
    let mut out = Level::empty(base.width, base.height);
    for y in 0..base.height as i32 {
        for x in 0..base.width as i32 {
            let px = IVec2::new(x, y);
            let centre = pixel_centre(px, 0);
            let mut accum = Accum::default();
            for (l, level) in levels.iter().enumerate() {
                let q = IVec2::new(x >> l, y >> l).min(level.size() - 1);
                for dy in -reach..=reach {
                    for dx in -reach..=reach {
                        let c = q + IVec2::new(dx, dy);
                        if c.cmplt(IVec2::ZERO).any() || c.cmpge(level.size()).any() {
                            continue;
                        }
                        let t = level.at(c);
                        if t.is_empty() || kernel_level(t.radius, kernel, top) > l as u32 {
                            continue;
                        }
                        let d2 = ellipse_distance2(
                            &t,
                            pixel_centre(c, l as u32) + t.disp,
                            centre,
                            scale,
                        );
                        if d2 < 1.0 {
                            accum.add(&t, 1.0 - d2.sqrt());
                        }
                    }
                }
            }
            out.set(px, accum.resolve());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::Vec4;

    use super::*;
    use crate::methods::pyramid::reference::tests::texel;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-3 * b.abs().max(1.0)
    }

    const SCALE: Vec2 = Vec2::new(4.0, -4.0);

    #[test]
    fn a_splat_is_stored_where_the_kernel_spans_its_diameter() {
        // t · 2^l ≥ D = 2r, the boundary included.
        for (radius, kernel, level) in [
            (0.0, 3, 0),
            (1.0, 3, 0),
            (1.5, 3, 0),
            (1.51, 3, 1),
            (3.0, 3, 1),
            (3.01, 3, 2),
            (12.0, 3, 3),
            (12.0, 5, 3),
            (12.0, 7, 2),
            (2.5, 5, 0),
            (2.6, 5, 1),
            (3.5, 7, 0),
            (100.0, 7, 5),
        ] {
            assert_eq!(
                kernel_level(radius, kernel, 10),
                level,
                "r {radius}, k {kernel}"
            );
        }
        // Eq. 6.1 with D = 2r wherever D > t.
        for r in [1.6f32, 2.9, 7.0, 40.0, 300.0] {
            for k in [3u32, 5, 7] {
                let d = 2.0 * r;
                if d > k as f32 {
                    let eq = (d / k as f32).log2().ceil() as u32;
                    assert_eq!(kernel_level(r, k, 20), eq, "r {r}, k {k}");
                }
            }
        }
        // Clamped to the top level searched.
        assert_eq!(kernel_level(1000.0, 3, 4), 4);
    }

    #[test]
    fn levels_the_kernel_below_covers_are_not_searched() {
        // 6.2: 1024² with 3 × 3 searches 10 of the 11 levels; Fig. 6.2: 16² searches 4 of 5.
        assert_eq!(searched_levels(1024, 1024, 3), 10);
        assert_eq!(searched_levels(16, 16, 3), 4);
        // 5 × 5 covers a 3 × 3 level, 7 × 7 a 4 × 4 one.
        assert_eq!(searched_levels(1024, 1024, 5), 10);
        assert_eq!(searched_levels(1024, 1024, 7), 9);
        assert_eq!(searched_levels(12, 12, 5), 3);
        assert_eq!(searched_levels(1920, 1080, 3), 11);
        assert_eq!(searched_levels(1, 1, 3), 1);
    }

    #[test]
    fn analysis_stores_each_splat_in_its_level_and_merges_only_travellers() {
        // 8 × 8 with 3 × 3: levels 0, 1, 2 (2 × 2, the last searched).
        let mut l0 = Level::empty(8, 8);
        // P: small, stored at level 0.
        l0.set(IVec2::new(0, 0), texel(1.0, 2.0, Vec3::X));
        // Q and R travel to level 1 and meet in its pixel (1, 0); S behind them is dropped.
        l0.set(IVec2::new(2, 0), texel(3.0, 2.0, Vec3::X));
        l0.set(IVec2::new(3, 1), texel(3.0, 2.05, Vec3::Y));
        l0.set(IVec2::new(2, 1), texel(3.0, 5.0, Vec3::Z));
        // U: level 2. V: far larger than the top level, clamped to it.
        l0.set(IVec2::new(6, 6), texel(6.0, 3.0, Vec3::ONE));
        l0.set(IVec2::new(7, 0), texel(100.0, 4.0, Vec3::ONE));
        let levels = analysis(l0, 3);
        assert_eq!(levels.len(), 3);
        let l1 = &levels[1];
        assert!(l1.at(IVec2::new(0, 0)).is_empty(), "P stays at level 0");
        let qr = l1.at(IVec2::new(1, 0));
        assert!(close(qr.depth, 2.025) && close(qr.radius, 3.0), "{qr:?}");
        assert!(close(qr.color.x, 0.5) && close(qr.color.y, 0.5) && qr.color.z == 0.0);
        // Centre: the mean of (2.5, 0.5) and (3.5, 1.5), the pixel centre (3, 1).
        assert_eq!(qr.disp, Vec2::ZERO);
        assert_eq!(kernel_level(qr.radius, 3, 2), 1, "stored at level 1");
        let u = l1.at(IVec2::new(3, 3));
        assert_eq!(u.disp, Vec2::new(-0.5, -0.5));
        assert_eq!(kernel_level(u.radius, 3, 2), 2, "U travels through level 1");
        let v = l1.at(IVec2::new(3, 0));
        assert_eq!(v.disp, Vec2::new(0.5, -0.5));
        let l2 = &levels[2];
        assert!(l2.at(IVec2::new(0, 0)).is_empty(), "Q + R stay at level 1");
        assert_eq!(l2.at(IVec2::new(1, 1)).disp, Vec2::new(0.5, 0.5));
        assert_eq!(l2.at(IVec2::new(1, 0)).disp, Vec2::new(1.5, -1.5));
        assert!(l2.at(IVec2::new(0, 1)).is_empty());
    }

    /// 8 × 8, three levels: A (red, r 1, depth 2) stored at level 0 in (3, 3); B (blue, r 3,
    /// depth 2.05, its interval overlapping A's) at level 1 in (1, 1), centred on (3, 3);
    /// C (green, r 1.4, depth 5) at level 0 in (5, 3).
    fn hand_built() -> Vec<Level> {
        let mut l0 = Level::empty(8, 8);
        l0.set(IVec2::new(3, 3), texel(1.0, 2.0, Vec3::X));
        l0.set(IVec2::new(5, 3), texel(1.4, 5.0, Vec3::Y));
        let mut l1 = Level::empty(4, 4);
        l1.set(IVec2::new(1, 1), texel(3.0, 2.05, Vec3::Z));
        vec![l0, l1, Level::empty(2, 2)]
    }

    #[test]
    fn interpolation_weighs_by_one_minus_the_distance() {
        let out = interpolate(&hand_built(), 3, SCALE);
        let at = |x, y| out.at(IVec2::new(x, y));
        // (3, 3): A at distance 0 (w 1) and B at √0.5 of its radius 3 blend.
        let wb = 1.0 - 0.5f32.sqrt() / 3.0;
        let t = at(3, 3);
        assert!(close(t.depth, (2.0 + wb * 2.05) / (1.0 + wb)), "{t:?}");
        assert!(close(t.radius, (1.0 + wb * 3.0) / (1.0 + wb)), "{t:?}");
        let blue = wb / (1.0 + wb);
        assert!(close(t.color.x, 1.0 - blue) && close(t.color.z, blue) && t.color.y == 0.0);
        assert_eq!((t.n, t.half_range, t.disp), (Vec3::Z, 0.1, Vec2::ZERO));
        // (4, 3): A's rim (d = 1) adds nothing; C (depth 5, found first at level 0) is
        // replaced by B in front of it: B alone.
        let t = at(4, 3);
        assert!(close(t.depth, 2.05) && close(t.radius, 3.0), "{t:?}");
        assert_eq!(t.color, Vec4::new(0.0, 0.0, 1.0, 0.0));
        // (6, 3): C alone (B is beyond the kernel and its radius).
        let t = at(6, 3);
        assert!(close(t.depth, 5.0) && close(t.radius, 1.4), "{t:?}");
        assert_eq!(t.color, Vec4::new(0.0, 1.0, 0.0, 0.0));
        // (1, 1): B at 1.5 √2 from its centre, alone; (0, 5) and (7, 7) beyond every ellipse.
        assert!(close(at(1, 1).depth, 2.05));
        assert!(at(0, 5).is_empty() && at(7, 7).is_empty());
        let covered = out.texels.iter().filter(|t| !t.is_empty()).count();
        // B's disc of radius 3 about (3, 3) holds 32 pixel centres (offsets of half-integers);
        // C adds (6, 3) outside it.
        assert_eq!(covered, 33);
    }

    #[test]
    fn the_accumulation_keeps_the_front_surface() {
        let front = texel(2.0, 2.0, Vec3::X);
        let near = texel(2.0, 2.15, Vec3::Y);
        let behind = texel(2.0, 4.0, Vec3::Z);
        let mut a = Accum::default();
        a.add(&behind, 0.5);
        a.add(&front, 0.25);
        a.add(&behind, 1.0);
        a.add(&near, 0.75);
        let t = a.resolve();
        assert_eq!(a.weight, 1.0);
        assert!(close(t.depth, 0.25 * 2.0 + 0.75 * 2.15), "{t:?}");
        assert_eq!(t.color, Vec4::new(0.25, 0.75, 0.0, 0.0));
    }

    #[test]
    fn texels_in_transit_are_not_interpolated() {
        // A level-0 texel whose kernel level is 1 counts only once analysis has carried it up.
        let mut l0 = Level::empty(8, 8);
        l0.set(IVec2::new(3, 3), texel(3.0, 2.0, Vec3::X));
        let raw = vec![l0.clone(), Level::empty(4, 4), Level::empty(2, 2)];
        assert!(interpolate(&raw, 3, SCALE)
            .texels
            .iter()
            .all(Texel::is_empty));
        let out = interpolate(&analysis(l0, 3), 3, SCALE);
        let t = out.at(IVec2::new(3, 3));
        assert!(close(t.depth, 2.0) && close(t.radius, 3.0), "{t:?}");
        // Its disc of radius 3 about (3.5, 3.5): 25 pixel centres (integer offsets u, v with
        // u² + v² < 9).
        assert_eq!(out.texels.iter().filter(|t| !t.is_empty()).count(), 25);
    }
}
