//! Text overlay for the viewer's HUD: an ASCII glyph atlas rasterized once from the bundled
//! DejaVu Sans, panels of colored text lines laid out into a bounded array of quads
//! (`GpuGlyph`), and the graph pass that draws them over the frame (`pass`).
//!
//! Layout is pure CPU and allocation-free: it fills a caller-owned slice of quads and stops at
//! its end, so the cost per frame is bounded by the text, never by the scene.

pub mod pass;

use std::sync::OnceLock;

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use anyhow::{anyhow, Result};
use glam::Vec4;

use crate::layout::{GpuGlyph, OVERLAY_ATLAS_WIDTH, OVERLAY_SOLID};

/// DejaVu Sans (Bitstream Vera license, see `assets/fonts/LICENSE`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Glyph height in pixels (the font's em size).
pub const FONT_PX: f32 = 15.0;
/// Most quads (glyphs and panel backgrounds) drawn per frame; text beyond is cut.
pub const CAPACITY: usize = 8192;
/// Distance of a panel from the window's edge, in pixels.
pub const MARGIN: f32 = 8.0;
/// Space between a panel's edge and its text, in pixels.
pub const PADDING: f32 = 6.0;
/// Tab stops (`\t` moves the pen to the next multiple from the line's start), in pixels.
pub const TAB: f32 = 88.0;
/// Panel background: dark blue-grey, about 75 % opaque.
pub const PANEL_COLOR: [u8; 4] = [16, 20, 30, 190];

/// First and last character in the atlas (printable ASCII); others are drawn as `?`.
const FIRST: u8 = b' ';
const LAST: u8 = b'~';

/// Where a glyph sits in the atlas and relative to the pen.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GlyphInfo {
    /// Atlas texel of the top-left corner.
    pub atlas: [u32; 2],
    /// Size in texels (0 for blank glyphs such as the space).
    pub size: [u32; 2],
    /// Offset of the top-left corner from the pen (x) and the line's top (y), in pixels.
    pub offset: [i32; 2],
    /// Horizontal advance in pixels.
    pub advance: f32,
}

/// The glyph atlas: R8 coverage, `OVERLAY_ATLAS_WIDTH` texels per row.
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    /// Coverage 0..=255, row-major; the length is a multiple of 4 (the GPU reads words).
    pub texels: Vec<u8>,
    /// Distance between baselines, in whole pixels.
    pub line_height: f32,
    glyphs: [GlyphInfo; (LAST - FIRST + 1) as usize],
}

impl Atlas {
    /// Rasterizes the printable ASCII characters at `px` pixels, packed in rows.
    pub fn new(px: f32) -> Result<Self> {
        let font = FontRef::try_from_slice(FONT)
            .map_err(|e| anyhow!("the embedded DejaVu Sans font is invalid: {e}"))?;
        let scaled = font.as_scaled(PxScale::from(px));
        let ascent = scaled.ascent().ceil();
        // Two pixels more than the font's spacing: `_` and `|` reach a pixel past it.
        let line_height = (scaled.ascent() - scaled.descent() + scaled.line_gap()).ceil() + 2.0;
        let width = OVERLAY_ATLAS_WIDTH;
        let mut glyphs = [GlyphInfo::default(); (LAST - FIRST + 1) as usize];
        // Shelf packing with one texel of space between glyphs, so no glyph reads a
        // neighbour's texels.
        let mut outlines = Vec::with_capacity(glyphs.len());
        let (mut x, mut y, mut row) = (0u32, 0u32, 0u32);
        for (slot, c) in glyphs.iter_mut().zip(FIRST..=LAST) {
            let id = font.glyph_id(char::from(c));
            slot.advance = scaled.h_advance(id);
            let glyph = id.with_scale_and_position(px, point(0.0, ascent));
            let Some(outline) = font.outline_glyph(glyph) else {
                continue;
            };
            let b = outline.px_bounds();
            let (w, h) = (b.width() as u32, b.height() as u32);
            if x + w > width {
                (x, y, row) = (0, y + row + 1, 0);
            }
            slot.atlas = [x, y];
            slot.size = [w, h];
            slot.offset = [b.min.x as i32, b.min.y as i32];
            outlines.push((outline, x, y));
            x += w + 1;
            row = row.max(h);
        }
        let height = y + row + 1;
        let mut texels = vec![0u8; (width * height) as usize];
        for (outline, ox, oy) in outlines {
            outline.draw(|dx, dy, c| {
                let i = ((oy + dy) * width + ox + dx) as usize;
                texels[i] = (c.clamp(0.0, 1.0) * 255.0).round() as u8;
            });
        }
        Ok(Self {
            width,
            height,
            texels,
            line_height,
            glyphs,
        })
    }

    /// The glyph drawn for `c` (`?` for characters outside printable ASCII; layout handles tabs).
    pub fn glyph(&self, c: char) -> &GlyphInfo {
        let b = u8::try_from(c)
            .ok()
            .filter(|b| (FIRST..=LAST).contains(b))
            .unwrap_or(b'?');
        &self.glyphs[(b - FIRST) as usize]
    }

    /// The pen position after `c`, from `pen` (pixels from the line's start).
    pub fn advance(&self, pen: f32, c: char) -> f32 {
        if c == '\t' {
            (pen / TAB).floor() * TAB + TAB
        } else {
            pen + self.glyph(c).advance
        }
    }

    /// Width of `text` in pixels (where its last advance ends).
    pub fn text_width(&self, text: &str) -> f32 {
        text.chars().fold(0.0, |pen, c| self.advance(pen, c))
    }
}

/// The atlas at `FONT_PX`, rasterized on first use.
pub fn atlas() -> Result<&'static Atlas> {
    static ATLAS: OnceLock<std::result::Result<Atlas, String>> = OnceLock::new();
    ATLAS
        .get_or_init(|| Atlas::new(FONT_PX).map_err(|e| format!("{e:#}")))
        .as_ref()
        .map_err(|e| anyhow!("{e}"))
}

/// One line of text in one color (RGBA8, sRGB-encoded).
#[derive(Clone, Debug, PartialEq)]
pub struct HudLine {
    pub text: String,
    pub color: [u8; 4],
}

impl HudLine {
    /// Normal text.
    pub const TEXT: [u8; 4] = [235, 235, 235, 255];
    /// Headings.
    pub const HEADING: [u8; 4] = [255, 214, 102, 255];
    /// Secondary text.
    pub const DIM: [u8; 4] = [160, 168, 180, 255];

    pub fn new(text: impl Into<String>, color: [u8; 4]) -> Self {
        Self {
            text: text.into(),
            color,
        }
    }
}

/// Which corner of the window a panel hangs from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corner {
    TopLeft,
    TopRight,
    BottomLeft,
}

/// A solid quad in window pixels (markers, scale-bar steps), drawn under the panels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mark {
    /// Left, top, right, bottom.
    pub rect: Vec4,
    pub color: [u8; 4],
}

/// A block of lines on a translucent background.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    pub corner: Corner,
    pub lines: Vec<HudLine>,
}

impl Panel {
    pub fn new(corner: Corner) -> Self {
        Self {
            corner,
            lines: Vec::new(),
        }
    }

    /// Appends a line.
    pub fn line(&mut self, text: impl Into<String>, color: [u8; 4]) -> &mut Self {
        self.lines.push(HudLine::new(text, color));
        self
    }
}

/// Packs an sRGB RGBA8 color as `unpackUnorm4x8` reads it.
fn pack(color: [u8; 4]) -> u32 {
    u32::from_le_bytes(color)
}

/// Lays `marks` and `panels` out in a window of `(width, height)` pixels into `out`: the marks,
/// then per panel a background quad and one quad per visible glyph. Top panels hang from their
/// corner `MARGIN` pixels from the edges; one that would overlap an earlier panel goes below
/// it instead. Returns the quads written; what does not fit in `out` is cut.
pub fn layout(
    atlas: &Atlas,
    panels: &[Panel],
    marks: &[Mark],
    (width, height): (u32, u32),
    out: &mut [GpuGlyph],
) -> usize {
    let mut n = 0;
    let mut push = |q: GpuGlyph| {
        if n < out.len() {
            out[n] = q;
            n += 1;
            true
        } else {
            false
        }
    };
    for m in marks {
        if !push(GpuGlyph {
            rect: m.rect,
            color: pack(m.color),
            flags: OVERLAY_SOLID,
            ..GpuGlyph::default()
        }) {
            return n;
        }
    }
    // Panels placed so far: (left, right, bottom).
    let mut placed = [(0.0f32, 0.0f32, 0.0f32); 8];
    for (index, panel) in panels.iter().enumerate() {
        let text_w = panel
            .lines
            .iter()
            .map(|l| atlas.text_width(&l.text))
            .fold(0.0f32, f32::max)
            .ceil();
        let w = text_w + 2.0 * PADDING;
        let h = panel.lines.len() as f32 * atlas.line_height + 2.0 * PADDING;
        let x = match panel.corner {
            Corner::TopLeft | Corner::BottomLeft => MARGIN,
            Corner::TopRight => (width as f32 - MARGIN - w).max(0.0).round(),
        };
        let y = match panel.corner {
            Corner::BottomLeft => (height as f32 - MARGIN - h).max(0.0).round(),
            Corner::TopLeft | Corner::TopRight => {
                let y = placed[..index.min(placed.len())]
                    .iter()
                    .filter(|(l, r, _)| x < r + MARGIN && *l < x + w + MARGIN)
                    .map(|(_, _, bottom)| bottom + MARGIN)
                    .fold(MARGIN, f32::max);
                if let Some(slot) = placed.get_mut(index) {
                    *slot = (x, x + w, y + h);
                }
                y
            }
        };
        if !push(GpuGlyph {
            rect: Vec4::new(x, y, x + w, y + h),
            color: pack(PANEL_COLOR),
            flags: OVERLAY_SOLID,
            ..GpuGlyph::default()
        }) {
            return n;
        }
        for (i, line) in panel.lines.iter().enumerate() {
            let top = y + PADDING + i as f32 * atlas.line_height;
            let left = x + PADDING;
            let mut pen = 0.0;
            for c in line.text.chars() {
                let g = atlas.glyph(c);
                if c != '\t' && g.size[0] > 0 && g.size[1] > 0 {
                    let x0 = (left + pen).round() + g.offset[0] as f32;
                    let y0 = top + g.offset[1] as f32;
                    if !push(GpuGlyph {
                        rect: Vec4::new(x0, y0, x0 + g.size[0] as f32, y0 + g.size[1] as f32),
                        atlas_x: g.atlas[0],
                        atlas_y: g.atlas[1],
                        color: pack(line.color),
                        flags: 0,
                    }) {
                        return n;
                    }
                }
                pen = atlas.advance(pen, c);
            }
        }
    }
    n
}

/// The line of `panel`, laid out first from the top-left corner (as `layout` places it),
/// under window pixel `(x, y)`; `None` outside its text.
pub fn line_at(atlas: &Atlas, panel: &Panel, (x, y): (f32, f32)) -> Option<usize> {
    let width = panel
        .lines
        .iter()
        .map(|l| atlas.text_width(&l.text))
        .fold(0.0f32, f32::max)
        .ceil();
    let top = MARGIN + PADDING;
    if x < MARGIN || x > MARGIN + width + 2.0 * PADDING || y < top {
        return None;
    }
    let row = ((y - top) / atlas.line_height) as usize;
    (row < panel.lines.len()).then_some(row)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_at_finds_the_line_a_glyph_is_drawn_on() {
        let a = atlas().expect("atlas");
        let mut p = Panel::new(Corner::TopLeft);
        for text in ["first", "second line", "third"] {
            p.line(text, HudLine::TEXT);
        }
        let mut out = vec![GpuGlyph::default(); 64];
        let n = layout(a, std::slice::from_ref(&p), &[], (640, 480), &mut out);
        // Quads after the background: the glyphs of the lines in order ("first" has 5).
        let glyph_line = |k: usize| match k {
            0..5 => 0,
            5..15 => 1,
            _ => 2,
        };
        for (k, q) in out[1..n].iter().enumerate() {
            let centre = ((q.rect.x + q.rect.z) * 0.5, (q.rect.y + q.rect.w) * 0.5);
            assert_eq!(line_at(a, &p, centre), Some(glyph_line(k)), "glyph {k}");
        }
        assert_eq!(line_at(a, &p, (MARGIN + 1.0, 1.0)), None, "above the text");
        assert_eq!(line_at(a, &p, (600.0, 30.0)), None, "right of the panel");
        let below = MARGIN + PADDING + 3.5 * a.line_height;
        assert_eq!(line_at(a, &p, (20.0, below)), None, "below the last line");
    }

    fn one_line(text: &str) -> Vec<Panel> {
        let mut p = Panel::new(Corner::TopLeft);
        p.line(text, HudLine::TEXT);
        vec![p]
    }

    #[test]
    fn the_atlas_holds_every_printable_ascii_glyph_without_overlap() {
        let a = atlas().expect("atlas");
        assert_eq!(a.width, OVERLAY_ATLAS_WIDTH);
        assert_eq!(a.texels.len(), (a.width * a.height) as usize);
        assert_eq!(a.texels.len() % 4, 0);
        assert!(a.line_height >= FONT_PX && a.line_height <= 2.0 * FONT_PX);
        let mut boxes = Vec::new();
        for c in (FIRST..=LAST).map(char::from) {
            let g = a.glyph(c);
            assert!(g.advance > 0.0, "{c:?}");
            if c == ' ' {
                assert_eq!(g.size, [0, 0]);
                continue;
            }
            assert!(g.size[0] > 0 && g.size[1] > 0, "{c:?} has no texels");
            assert!(g.atlas[0] + g.size[0] <= a.width && g.atlas[1] + g.size[1] <= a.height);
            // Glyphs sit between the line's top and the next line's top.
            assert!(
                g.offset[1] >= 0 && g.offset[1] + g.size[1] as i32 <= a.line_height as i32,
                "{c:?}: {g:?}"
            );
            let texels = (0..g.size[1])
                .flat_map(|y| (0..g.size[0]).map(move |x| (x, y)))
                .map(|(x, y)| a.texels[((g.atlas[1] + y) * a.width + g.atlas[0] + x) as usize]);
            assert!(texels.into_iter().any(|t| t > 64), "{c:?} is blank");
            boxes.push((c, g.atlas, g.size));
        }
        for (i, (c, p, s)) in boxes.iter().enumerate() {
            for (d, q, t) in &boxes[i + 1..] {
                let apart = p[0] + s[0] <= q[0]
                    || q[0] + t[0] <= p[0]
                    || p[1] + s[1] <= q[1]
                    || q[1] + t[1] <= p[1];
                assert!(apart, "{c:?} and {d:?} overlap in the atlas");
            }
        }
        // Outside printable ASCII: the question mark.
        assert_eq!(a.glyph('é'), a.glyph('?'));
        assert_eq!(a.glyph('\t'), a.glyph('?'));
    }

    #[test]
    fn text_becomes_a_panel_and_one_quad_per_visible_glyph() {
        let a = atlas().expect("atlas");
        let mut out = vec![GpuGlyph::default(); 16];
        let n = layout(a, &one_line("Hi y"), &[], (640, 480), &mut out);
        // Panel + H, i, y (the space has no quad).
        assert_eq!(n, 4);
        let panel = out[0];
        assert_eq!(panel.flags, OVERLAY_SOLID);
        assert_eq!(panel.color, u32::from_le_bytes(PANEL_COLOR));
        let text_w = a.text_width("Hi y").ceil();
        assert_eq!(
            panel.rect,
            Vec4::new(
                MARGIN,
                MARGIN,
                MARGIN + text_w + 2.0 * PADDING,
                MARGIN + a.line_height + 2.0 * PADDING
            )
        );
        let (h, i, y) = (a.glyph('H'), a.glyph('i'), a.glyph('y'));
        let pen = MARGIN + PADDING;
        let top = MARGIN + PADDING;
        assert_eq!(out[1].rect.x, pen + h.offset[0] as f32);
        assert_eq!(out[1].rect.y, top + h.offset[1] as f32);
        assert_eq!(out[1].rect.z - out[1].rect.x, h.size[0] as f32);
        assert_eq!(out[1].rect.w - out[1].rect.y, h.size[1] as f32);
        assert_eq!([out[1].atlas_x, out[1].atlas_y], h.atlas);
        assert_eq!(out[1].color, u32::from_le_bytes(HudLine::TEXT));
        assert_eq!(out[1].flags, 0);
        assert_eq!(
            out[2].rect.x,
            (pen + h.advance).round() + i.offset[0] as f32
        );
        let y_pen = pen + h.advance + i.advance + a.glyph(' ').advance;
        assert_eq!(out[3].rect.x, y_pen.round() + y.offset[0] as f32);
        // The descender reaches below the baseline of the capital.
        assert!(out[3].rect.w > out[1].rect.w);
        // Every glyph lies inside its panel.
        for q in &out[1..n] {
            assert!(
                q.rect.x >= panel.rect.x && q.rect.z <= panel.rect.z,
                "{q:?}"
            );
            assert!(
                q.rect.y >= panel.rect.y && q.rect.w <= panel.rect.w,
                "{q:?}"
            );
        }
    }

    #[test]
    fn lines_stack_and_right_panels_hang_from_the_right_edge() {
        let a = atlas().expect("atlas");
        let mut left = Panel::new(Corner::TopLeft);
        left.line("A", HudLine::TEXT).line("B", HudLine::HEADING);
        let mut right = Panel::new(Corner::TopRight);
        right.line("C", HudLine::DIM);
        let mut out = vec![GpuGlyph::default(); 16];
        let n = layout(a, &[left, right], &[], (640, 480), &mut out);
        assert_eq!(n, 5);
        assert_eq!(out[2].rect.y - out[1].rect.y, a.line_height);
        assert_eq!(out[2].color, u32::from_le_bytes(HudLine::HEADING));
        let panel = out[3];
        assert_eq!(panel.flags, OVERLAY_SOLID);
        assert_eq!(panel.rect.z, 640.0 - MARGIN);
        assert!(out[4].rect.x > panel.rect.x && out[4].rect.z < panel.rect.z);
    }

    #[test]
    fn a_panel_that_would_overlap_goes_below() {
        let a = atlas().expect("atlas");
        let mut left = Panel::new(Corner::TopLeft);
        left.line("a fairly long line of statistics", HudLine::TEXT);
        let mut right = Panel::new(Corner::TopRight);
        right.line("key help", HudLine::TEXT);
        let panels = [left, right];
        let mut out = vec![GpuGlyph::default(); 64];
        let n = layout(a, &panels, &[], (2000, 480), &mut out);
        let solid: Vec<Vec4> = out[..n]
            .iter()
            .filter(|q| q.flags == OVERLAY_SOLID)
            .map(|q| q.rect)
            .collect();
        assert_eq!(solid[1].y, MARGIN, "side by side in a wide window");
        let n = layout(a, &panels, &[], (200, 480), &mut out);
        let solid: Vec<Vec4> = out[..n]
            .iter()
            .filter(|q| q.flags == OVERLAY_SOLID)
            .map(|q| q.rect)
            .collect();
        assert_eq!(solid[1].y, solid[0].w + MARGIN, "stacked in a narrow one");
        assert_eq!(solid[1].z, 200.0 - MARGIN);
    }

    #[test]
    fn tabs_align_columns() {
        let a = atlas().expect("atlas");
        let mut p = Panel::new(Corner::TopLeft);
        p.line("M\tx", HudLine::TEXT)
            .line("Wide key\tx", HudLine::TEXT);
        let mut out = vec![GpuGlyph::default(); 16];
        let n = layout(a, &[p], &[], (640, 480), &mut out);
        let x = a.glyph('x');
        let column = |q: &GpuGlyph| q.rect.x - x.offset[0] as f32;
        let xs: Vec<f32> = out[..n]
            .iter()
            .filter(|q| q.atlas_x == x.atlas[0] && q.atlas_y == x.atlas[1])
            .map(column)
            .collect();
        assert_eq!(xs, vec![MARGIN + PADDING + TAB; 2]);
        assert_eq!(a.text_width("M\tx"), TAB + x.advance);
        assert_eq!(a.text_width("\t"), TAB);
    }

    #[test]
    fn layout_stops_at_capacity() {
        let a = atlas().expect("atlas");
        let text = "x".repeat(100);
        let mut out = vec![GpuGlyph::default(); 40];
        assert_eq!(layout(a, &one_line(&text), &[], (640, 480), &mut out), 40);
        // The last quad is the 39th glyph, in order.
        let x = a.glyph('x');
        let pen = MARGIN + PADDING + 38.0 * x.advance;
        assert_eq!(out[39].rect.x, pen.round() + x.offset[0] as f32);
        let mut none: [GpuGlyph; 0] = [];
        assert_eq!(layout(a, &one_line("abc"), &[], (640, 480), &mut none), 0);
        let mut one = [GpuGlyph::default(); 1];
        assert_eq!(layout(a, &one_line("abc"), &[], (640, 480), &mut one), 1);
        assert_eq!(one[0].flags, OVERLAY_SOLID);
    }
}
