//! A CPU model of the pyramid's analysis and synthesis (000 4.2.2), texel for texel what
//! `glsl/pyramid/analysis.comp` and `synthesis.comp` compute, including the half-precision
//! storage of groups A and C. Device-free: the unit tests below check it against hand-computed
//! pyramids, and `tests/suite/pyramid.rs` checks the GPU passes against it.

use glam::{IVec2, Vec2, Vec3, Vec4};
use half::f16;

use crate::layout::PRIMITIVE_TUBE;

/// One texel (see `glsl/pyramid/pyramid.glsl`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Texel {
    /// View-space unit normal facing the camera.
    pub n: Vec3,
    /// Projected radius in level-0 pixels; negative for a texel the synthesis filled across
    /// an enclosed gap (its grown ellipse).
    pub radius: f32,
    /// Linear view depth; 0: empty.
    pub depth: f32,
    /// Half range of the depth interval (view units); negative for a texel the synthesis
    /// filled where the level was empty.
    pub half_range: f32,
    /// Ellipse centre minus pixel centre, in level-0 pixels.
    pub disp: Vec2,
    /// Linear albedo and primitive id.
    pub color: Vec4,
}

pub(crate) fn half(v: f32) -> f32 {
    f16::from_f32(v).to_f32()
}

impl Texel {
    pub fn is_empty(&self) -> bool {
        self.depth == 0.0
    }

    /// The texel as the storage images hold it: A and C in half precision.
    pub fn stored(self) -> Self {
        Self {
            n: Vec3::new(half(self.n.x), half(self.n.y), half(self.n.z)),
            radius: half(self.radius),
            color: Vec4::new(
                half(self.color.x),
                half(self.color.y),
                half(self.color.z),
                half(self.color.w),
            ),
            ..self
        }
    }

    pub(crate) fn overlaps(&self, other: &Texel) -> bool {
        (self.depth - other.depth).abs() <= self.half_range.abs() + other.half_range.abs()
    }
}

/// One level: `width` x `height` texels, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Texel>,
}

impl Level {
    pub fn empty(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            texels: vec![Texel::default(); (width * height) as usize],
        }
    }

    pub fn at(&self, q: IVec2) -> Texel {
        self.texels[(q.y as u32 * self.width + q.x as u32) as usize]
    }

    pub(crate) fn set(&mut self, q: IVec2, t: Texel) {
        self.texels[(q.y as u32 * self.width + q.x as u32) as usize] = t.stored();
    }

    pub(crate) fn size(&self) -> IVec2 {
        IVec2::new(self.width as i32, self.height as i32)
    }
}

/// Weighted sums of texels and their ellipse centres (see `Blend` in pyramid.glsl).
#[derive(Default)]
pub(crate) struct Blend {
    sum: Texel,
    centres: Vec2,
    weight: f32,
}

impl Blend {
    pub(crate) fn add(&mut self, t: &Texel, centre: Vec2, w: f32) {
        self.sum.n += w * t.n;
        self.sum.radius += w * t.radius.abs();
        self.sum.depth += w * t.depth;
        self.sum.half_range += w * t.half_range.abs();
        self.sum.color += w * t.color;
        self.centres += w * centre;
        self.weight += w;
    }

    /// The blended texel at pixel centre `x`, with the primitive id (and the fallback normal)
    /// of `front`.
    pub(crate) fn finish(&self, front: &Texel, x: Vec2) -> Texel {
        let (s, w) = (&self.sum, self.weight);
        let len = s.n.length();
        Texel {
            n: if len > 0.0 { s.n / len } else { front.n },
            radius: s.radius / w,
            depth: s.depth / w,
            half_range: s.half_range / w,
            disp: self.centres / w - x,
            color: (s.color / w).truncate().extend(front.color.w),
        }
    }
}

/// Centre of pixel `q` of `level` in level-0 pixels.
pub fn pixel_centre(q: IVec2, level: u32) -> Vec2 {
    (q.as_vec2() + 0.5) * (1u32 << level) as f32
}

/// Squared elliptical distance of `x` from texel `t`'s ellipse centred at `c` (a circle for a
/// tube's texel); `scale` is
/// (proj[0][0] width, proj[1][1] height), which maps view directions to pixel directions.
pub fn ellipse_distance2(t: &Texel, c: Vec2, x: Vec2, scale: Vec2) -> f32 {
    ellipse_distance2_grown(t, c, x, scale, 0.0)
}

/// How far, in texels of the level being synthesized, the synthesis grows the parents'
/// ellipses to fill an enclosed gap (`PYRAMID_FILL_REACH` in `glsl/pyramid/pyramid.glsl`).
pub const FILL_REACH: f32 = 1.5;

/// [`ellipse_distance2`] with both axes widened to sqrt(axis² + grow²) when `grow` > 0.
pub fn ellipse_distance2_grown(t: &Texel, c: Vec2, x: Vec2, scale: Vec2, grow: f32) -> f32 {
    let d = x - c;
    let widen = |axis: f32| {
        if grow > 0.0 {
            (axis * axis + grow * grow).sqrt()
        } else {
            axis
        }
    };
    let a0 = t.radius.abs().max(1e-6);
    let a = widen(a0);
    // A tube's texel is a view-facing disc.
    if t.color.w as u32 == PRIMITIVE_TUBE {
        return d.dot(d) / (a * a);
    }
    let b = widen((a0 * t.n.z.abs()).max(1e-3 * a0));
    let m = Vec2::new(t.n.x * scale.x, t.n.y * scale.y);
    let len = m.length();
    if len < 1e-6 {
        return d.dot(d) / (a * a);
    }
    let m = m / len;
    let u = d.dot(m);
    let v = d.x * m.y - d.y * m.x;
    (u * u) / (b * b) + (v * v) / (a * a)
}

/// Analysis: every level from level 0 up to 1 x 1.
pub fn analysis(level0: Level) -> Vec<Level> {
    let mut levels = vec![level0];
    while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
        let child = levels.last().expect("a level");
        let (w, h) = ((child.width / 2).max(1), (child.height / 2).max(1));
        let level = levels.len() as u32;
        let mut out = Level::empty(w, h);
        for y in 0..h as i32 {
            for x in 0..w as i32 {
                let p = IVec2::new(x, y);
                out.set(p, parent(child, p, out.size(), level, |_| true));
            }
        }
        levels.push(out);
    }
    levels
}

/// Texel `p` of `level` (of `size`) from its children in `child` (the last row and column
/// take the odd remainder): the average of the children `moves` lets up whose depth intervals
/// overlap the front-most one's (ch. 4).
pub(crate) fn parent(
    child: &Level,
    p: IVec2,
    size: IVec2,
    level: u32,
    moves: impl Fn(&Texel) -> bool,
) -> Texel {
    let lo = 2 * p;
    let last = child.size() - 1;
    let hi = IVec2::new(
        if p.x == size.x - 1 { last.x } else { lo.x + 1 },
        if p.y == size.y - 1 { last.y } else { lo.y + 1 },
    )
    .min(last);
    let children: Vec<(IVec2, Texel)> = (lo.y..=hi.y)
        .flat_map(|y| (lo.x..=hi.x).map(move |x| IVec2::new(x, y)))
        .map(|c| (c, child.at(c)))
        .filter(|(_, t)| !t.is_empty() && moves(t))
        .collect();
    let Some(front) =
        children
            .iter()
            .map(|(_, t)| *t)
            .reduce(|f, t| if t.depth < f.depth { t } else { f })
    else {
        return Texel::default();
    };
    let mut blend = Blend::default();
    for (c, t) in children.iter().filter(|(_, t)| t.overlaps(&front)) {
        blend.add(t, pixel_centre(*c, level - 1) + t.disp, 1.0);
    }
    blend.finish(&front, pixel_centre(p, level))
}

/// Synthesis, top-down over the analysed `levels`; returns the reconstructed levels (the top
/// unchanged).
pub fn synthesis(mut levels: Vec<Level>, scale: Vec2, falloff: f32) -> Vec<Level> {
    for level in (0..levels.len().saturating_sub(1)).rev() {
        let (below, above) = levels.split_at_mut(level + 1);
        let (own, parent) = (&below[level], &above[0]);
        let mut out = Level::empty(own.width, own.height);
        for y in 0..own.height as i32 {
            for x in 0..own.width as i32 {
                let q = IVec2::new(x, y);
                out.set(q, rebuilt(own, parent, q, level as u32, scale, falloff));
            }
        }
        levels[level] = out;
    }
    levels
}

pub(crate) fn rebuilt(
    own: &Level,
    parent: &Level,
    q: IVec2,
    level: u32,
    scale: Vec2,
    falloff: f32,
) -> Texel {
    let t = own.at(q);
    let above = parent.at((q / 2).min(parent.size() - 1));
    let occluded =
        !above.is_empty() && t.depth - t.half_range > above.depth + above.half_range.abs();
    if !t.is_empty() && !occluded {
        return t;
    }
    let x = pixel_centre(q, level);
    let mut grow = 0.0;
    let gap = !occluded && level < FILL_LEVELS && enclosed(own, q);
    let (mut cands, valid) = gather(parent, q, x, level, scale, grow, gap);
    if cands.is_empty() && gap && valid == 4 {
        // An enclosed gap (see synthesis.comp): the parents' ellipses grown to reach it; the
        // filled texel keeps the grown radius.
        grow = FILL_REACH * (1u32 << level) as f32;
        cands = gather(parent, q, x, level, scale, grow, gap).0;
    }
    let Some(front) = cands
        .iter()
        .map(|c| c.0)
        .reduce(|f, t| if t.depth < f.depth { t } else { f })
    else {
        // An occluded texel no parent covers keeps its value (see synthesis.comp).
        return if occluded { t } else { Texel::default() };
    };
    let mut blend = Blend::default();
    for (p, c, d2) in cands.iter().filter(|c| c.0.overlaps(&front)) {
        blend.add(p, *c, (-falloff * d2).exp());
    }
    let mut out = blend.finish(&front, x);
    if grow > 0.0 {
        out.radius = -out.radius.hypot(grow);
    }
    if !occluded {
        out.half_range = -out.half_range;
    }
    out
}

/// How far, in texels, [`enclosed`] looks for valid texels on each side
/// (`PYRAMID_FILL_SPAN` in `glsl/pyramid/pyramid.glsl`).
pub const FILL_SPAN: i32 = 4;

/// The gap fill runs on levels below this one (`PYRAMID_FILL_LEVELS`): gaps up to 4 × 4
/// pixels; wider openings are background between parts of the model.
pub const FILL_LEVELS: u32 = 3;

/// Whether texel `q` has a valid texel within [`FILL_SPAN`] texels in each of the four axis
/// directions (a gap enclosed by the surface; see synthesis.comp).
pub(crate) fn enclosed(own: &Level, q: IVec2) -> bool {
    [IVec2::X, IVec2::NEG_X, IVec2::Y, IVec2::NEG_Y]
        .into_iter()
        .all(|step| {
            (1..=FILL_SPAN)
                .map(|k| q + step * k)
                .take_while(|p| p.cmpge(IVec2::ZERO).all() && p.cmplt(own.size()).all())
                .any(|p| !own.at(p).is_empty())
        })
}

/// The parents among the four nearest to texel `q` of `level` (centre `x`) whose ellipses,
/// grown by `grow`, cover `x` (with their centres and squared distances), and how many of the
/// four are inside the level and not empty; parents filled across a gap only when `gap`.
pub(crate) fn gather(
    parent: &Level,
    q: IVec2,
    x: Vec2,
    level: u32,
    scale: Vec2,
    grow: f32,
    gap: bool,
) -> (Vec<(Texel, Vec2, f32)>, usize) {
    let base = IVec2::new((q.x - 1) >> 1, (q.y - 1) >> 1);
    let mut cands = Vec::new();
    let mut valid = 0;
    for k in 0..4 {
        let pq = base + IVec2::new(k & 1, k >> 1);
        if pq.cmplt(IVec2::ZERO).any() || pq.cmpge(parent.size()).any() {
            continue;
        }
        let p = parent.at(pq);
        if p.is_empty() {
            continue;
        }
        valid += 1;
        if p.radius < 0.0 && !gap {
            continue;
        }
        let c = pixel_centre(pq, level + 1) + p.disp;
        let d2 = ellipse_distance2_grown(&p, c, x, scale, grow);
        if d2 <= 1.0 {
            cands.push((p, c, d2));
        }
    }
    (cands, valid)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A front-facing texel of `radius`, `depth` and `color`.
    pub(crate) fn texel(radius: f32, depth: f32, color: Vec3) -> Texel {
        Texel {
            n: Vec3::Z,
            radius,
            depth,
            half_range: 0.1,
            disp: Vec2::ZERO,
            color: color.extend(0.0),
        }
    }

    /// A 4 x 4 level 0: red (r 1.5, depth 2) at (0, 0), green (r 2.5, depth 2.1, its interval
    /// overlapping red's) at (1, 0), blue far behind (depth 5) at (1, 1).
    fn sample() -> Level {
        let mut l = Level::empty(4, 4);
        l.set(IVec2::new(0, 0), texel(1.5, 2.0, Vec3::X));
        l.set(IVec2::new(1, 0), texel(2.5, 2.1, Vec3::Y));
        l.set(IVec2::new(1, 1), texel(1.0, 5.0, Vec3::Z));
        l
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-3 * b.abs().max(1.0)
    }

    #[test]
    fn analysis_averages_the_front_children_and_tracks_the_centre() {
        let levels = analysis(sample());
        assert_eq!(levels.len(), 3);
        assert_eq!((levels[1].width, levels[2].width), (2, 1));
        // Red and green join (intervals overlap), blue is occluded: r 2, depth 2.05, centre
        // the mean of (0.5, 0.5) and (1.5, 0.5) = (1, 0.5), the parent's pixel centre (1, 1).
        let p = levels[1].at(IVec2::ZERO);
        assert!(close(p.radius, 2.0) && close(p.depth, 2.05), "{p:?}");
        assert!(close(p.color.x, 0.5) && close(p.color.y, 0.5) && p.color.z == 0.0);
        assert_eq!(p.disp, Vec2::new(0.0, -0.5));
        for q in [IVec2::new(1, 0), IVec2::new(0, 1), IVec2::new(1, 1)] {
            assert!(levels[1].at(q).is_empty());
        }
        // The top: the same ellipse, its centre (1, 0.5) seen from (2, 2).
        let top = levels[2].at(IVec2::ZERO);
        assert_eq!(top.disp, Vec2::new(-1.0, -1.5));
        assert!(close(top.depth, 2.05));
    }

    #[test]
    fn synthesis_fills_covered_holes_and_replaces_occluded_texels() {
        let levels = synthesis(analysis(sample()), Vec2::new(4.0, -4.0), 2.0);
        let l0 = &levels[0];
        let parent = analysis(sample())[1].at(IVec2::ZERO);
        // Pixels whose centre lies within r = 2 of (1, 0.5) and that have the parent among
        // their four nearest: the holes (2, 0), (0, 1), (2, 1) and the occluded blue (1, 1) take
        // the parent's attributes with the displacement to its centre.
        for (q, filled) in [
            ((2, 0), true),
            ((0, 1), true),
            ((1, 1), true),
            ((2, 1), true),
            ((3, 0), false),
            ((0, 2), false),
            ((1, 2), false),
            ((3, 3), false),
        ] {
            let q = IVec2::new(q.0, q.1);
            let t = l0.at(q);
            assert_eq!(!t.is_empty(), filled, "{q}: {t:?}");
            if filled {
                assert!(close(t.depth, parent.depth) && close(t.radius, parent.radius));
                assert_eq!(t.disp, Vec2::new(1.0, 0.5) - pixel_centre(q, 0), "{q}");
            }
        }
        // The projected texels in front stay as they were.
        assert_eq!(l0.at(IVec2::ZERO), sample().at(IVec2::ZERO));
        assert_eq!(l0.at(IVec2::new(1, 0)), sample().at(IVec2::new(1, 0)));
        // Level 1 gains nothing: no level-1 pixel centre lies within 2 of (1, 0.5) but its own.
        assert_eq!(levels[1].texels.iter().filter(|t| !t.is_empty()).count(), 1);
    }

    #[test]
    fn ellipse_axes_follow_the_projected_normal() {
        // Normal tilted towards +x by 60 degrees: minor axis along x, half the radius.
        let n = Vec3::new(60f32.to_radians().sin(), 0.0, 0.5);
        let t = Texel {
            n,
            radius: 4.0,
            ..texel(4.0, 1.0, Vec3::ONE)
        };
        let scale = Vec2::new(3.0, -3.0);
        let c = Vec2::ZERO;
        assert!(close(
            ellipse_distance2(&t, c, Vec2::new(2.0, 0.0), scale),
            1.0
        ));
        assert!(close(
            ellipse_distance2(&t, c, Vec2::new(0.0, 4.0), scale),
            1.0
        ));
        assert!(ellipse_distance2(&t, c, Vec2::new(2.5, 0.0), scale) > 1.0);
        assert!(ellipse_distance2(&t, c, Vec2::new(0.0, 3.9), scale) < 1.0);
    }

    #[test]
    fn odd_sizes_fold_the_last_row_and_column_into_the_last_parent() {
        let mut l = Level::empty(5, 3);
        l.set(IVec2::new(4, 2), texel(1.0, 1.0, Vec3::ONE));
        let levels = analysis(l);
        assert_eq!(
            levels
                .iter()
                .map(|l| (l.width, l.height))
                .collect::<Vec<_>>(),
            vec![(5, 3), (2, 1), (1, 1)]
        );
        let p = levels[1].at(IVec2::new(1, 0));
        assert!(!p.is_empty());
        // Centre (4.5, 2.5) seen from the level-1 pixel centre (3, 1).
        assert_eq!(p.disp, Vec2::new(1.5, 1.5));
    }
}
