//! Legends: their rows, the room they need, and the box drawn beside or below a chart's plot.

use std::error::Error;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::style::SeriesStyle;
use super::{DrawResult, CHART_SIZE};

/// Height of one legend row in pixels.
pub(super) const LEGEND_ROW: i32 = 18;
/// Space inside a legend's box around its rows.
const LEGEND_PAD: i32 = 8;
/// Room of a legend row's swatch, the gap after it included.
const SWATCH: i32 = 30;
/// Indent of the rows under a legend's headings.
const INDENT: i32 = 10;
/// A chart's height beyond its legend: caption, note line, margins.
const ABOVE_AND_BELOW_LEGEND: i32 = 130;

/// What a legend row shows before its text.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Swatch {
    /// Nothing: a heading, flush left, over the indented rows that follow it.
    Heading,
    /// A filled block (a pass, a series' color).
    Block(RGBAColor),
    /// A line in a series' style.
    Line(RGBAColor, SeriesStyle),
    /// A dashed black line (a threshold).
    Threshold,
    /// A thick red line (the Pareto front).
    Front,
    /// A black cross (a configuration named but not plotted).
    Cross,
}

/// One row of a legend.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct LegendRow {
    pub(super) text: String,
    swatch: Swatch,
}

impl LegendRow {
    pub(super) fn new(text: impl Into<String>, swatch: Swatch) -> Self {
        Self {
            text: text.into(),
            swatch,
        }
    }
}

/// Height of the box of a legend of `rows` rows.
pub(super) fn legend_height(rows: usize) -> i32 {
    rows as i32 * LEGEND_ROW + 2 * LEGEND_PAD
}

pub(super) fn legend_font() -> TextStyle<'static> {
    TextStyle::from(("sans-serif", 14).into_font())
}

/// Offset of the swatch and of the text of `row` from the legend box's left edge.
fn legend_offsets(row: &LegendRow, headings: bool) -> (i32, i32) {
    let indent = if headings { INDENT } else { 0 };
    match row.swatch {
        Swatch::Heading => (LEGEND_PAD, LEGEND_PAD),
        _ => (LEGEND_PAD + indent, LEGEND_PAD + indent + SWATCH),
    }
}

/// The width a legend of `rows` needs on `area` (text measured there), at most `max`.
pub(super) fn legend_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    rows: &[LegendRow],
    max: i32,
) -> Result<i32, Box<dyn Error + Send + Sync>>
where
    DB::ErrorType: 'static,
{
    let headings = rows.iter().any(|r| r.swatch == Swatch::Heading);
    let font = legend_font();
    let mut width = 0;
    for row in rows {
        let (w, _) = area.estimate_text_size(&row.text, &font)?;
        width = width.max(legend_offsets(row, headings).1 + w as i32 + LEGEND_PAD);
    }
    Ok(width.min(max))
}

/// `text`, shortened with "…" until it is at most `width` pixels wide on `area`.
fn fit_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    width: i32,
) -> Result<String, Box<dyn Error + Send + Sync>>
where
    DB::ErrorType: 'static,
{
    let font = legend_font();
    let mut chars: Vec<char> = text.chars().collect();
    let mut out = text.to_string();
    while !chars.is_empty() && area.estimate_text_size(&out, &font)?.0 as i32 > width {
        chars.pop();
        out = chars.iter().collect::<String>() + "…";
    }
    Ok(out)
}

/// Draws `rows` in a white box with a black border, `width` wide, its top-left corner at
/// pixel `at` of `area`; a text too long for the box is shortened with "…". Fails when the
/// box does not fit in `area`, so no chart is written with part of its legend cut off.
pub(super) fn draw_legend_box<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    width: i32,
    rows: &[LegendRow],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    if rows.is_empty() {
        return Ok(());
    }
    let height = legend_height(rows.len());
    let (w, h) = area.dim_in_pixel();
    if x < 0 || y < 0 || x + width > w as i32 || y + height > h as i32 {
        return Err(format!(
            "a legend of {} rows ({width}x{height} px at {x},{y}) does not fit in {w}x{h} px",
            rows.len()
        )
        .into());
    }
    area.draw(&Rectangle::new(
        [(x, y), (x + width, y + height)],
        WHITE.filled(),
    ))?;
    area.draw(&Rectangle::new([(x, y), (x + width, y + height)], BLACK))?;
    let headings = rows.iter().any(|r| r.swatch == Swatch::Heading);
    let font = legend_font().pos(Pos::new(HPos::Left, VPos::Center));
    for (i, row) in rows.iter().enumerate() {
        let mid = y + LEGEND_PAD + i as i32 * LEGEND_ROW + LEGEND_ROW / 2;
        let (swatch, text) = legend_offsets(row, headings);
        let sx = x + swatch;
        match row.swatch {
            Swatch::Heading => {}
            Swatch::Block(color) => {
                area.draw(&Rectangle::new(
                    [(sx + 5, mid - 6), (sx + 17, mid + 6)],
                    color.filled(),
                ))?;
            }
            Swatch::Line(color, style) => style.swatch(area, (sx, mid), color)?,
            Swatch::Threshold => {
                area.draw(&DashedPathElement::new(
                    vec![(sx, mid), (sx + 22, mid)],
                    5,
                    3,
                    BLACK,
                ))?;
            }
            Swatch::Front => {
                area.draw(&PathElement::new(
                    vec![(sx, mid), (sx + 22, mid)],
                    RED.stroke_width(2),
                ))?;
            }
            Swatch::Cross => {
                area.draw(&Cross::new((sx + 11, mid), 5, BLACK.stroke_width(2)))?;
            }
        }
        let shown = fit_text(area, &row.text, width - text - LEGEND_PAD)?;
        area.draw(&Text::new(shown, (x + text, mid), font.clone()))?;
    }
    Ok(())
}

/// The height a chart needs for a legend of `rows` beside or below its plot.
pub(super) fn size_for_legend(rows: usize) -> (u32, u32) {
    let needed = legend_height(rows) + ABOVE_AND_BELOW_LEGEND;
    (CHART_SIZE.0, CHART_SIZE.1.max(needed.max(0) as u32))
}
