//! The HUD as the viewer keeps it: `HudState` (shown or not, the panels and marks built last,
//! the figures sampled between rebuilds, the last action's outcome) and its rebuild from the
//! viewer's figures; what the panels say is `hud`'s.

use std::time::Instant;

use glam::{DVec3, Vec4};

use super::hud::{self, FrameRate, Hud, Stats};
use super::Viewer;
use crate::color::{self, Coloring, LegendEntry};
use crate::gpu_scene::streamed::StreamedScene;
use crate::gpu_scene::{GpuScene, SceneInfo};
use crate::layout::{COLOR_CLASSIFICATION, COLOR_ELEVATION, COLOR_RETURN};
use crate::overlay::{Corner, HudLine, Mark, Panel};
use crate::render::Renderer;
use crate::scene::{Camera, Cloud};

/// The HUD's state: whether and what it shows, and the figures it shows between rebuilds.
pub(super) struct HudState {
    /// The HUD is drawn (`Tab`).
    pub visible: bool,
    /// The key help is shown (`H`).
    pub help: bool,
    /// The HUD's panels, rebuilt when `dirty` (state changes, and twice a second).
    pub panels: Vec<Panel>,
    pub dirty: bool,
    /// The last action's outcome, shown in the HUD.
    pub status: String,
    pub rate: FrameRate,
    /// GPU allocator bytes (allocated, reserved), sampled with the frame rate.
    pub memory: Option<(u64, u64)>,
    /// The classification legend while coloring by classification (shown in the HUD).
    pub legend: Vec<LegendEntry>,
    /// The stats panel's legend lines: the index of the first and the classes.
    pub legend_rows: (usize, Vec<u32>),
    /// The renderer has finished no timed frame yet (after a start, a method, parameter or
    /// size change): the HUD says it is measuring and is rebuilt every frame until it has.
    pub measuring: bool,
    /// The HUD lists every pass (`U`) instead of per-family totals.
    pub expanded: bool,
    /// The HUD's solid quads (the colour ramp's scale bar, the load screen's bar), rebuilt
    /// with the panels.
    pub marks: Vec<Mark>,
    /// This frame's marks (`Viewer::fill_marks`), kept for the next frame's.
    pub frame_marks: Vec<Mark>,
}

impl HudState {
    /// A shown HUD without help, to be built, with `legend`.
    pub fn new(legend: Vec<LegendEntry>) -> Self {
        Self {
            visible: true,
            help: false,
            panels: Vec::new(),
            dirty: true,
            status: String::new(),
            rate: FrameRate::new(Instant::now()),
            memory: None,
            legend,
            legend_rows: (0, Vec::new()),
            measuring: true,
            expanded: false,
            marks: Vec::new(),
            frame_marks: Vec::new(),
        }
    }

    /// The panels and marks this frame draws (none while the HUD is hidden).
    pub fn shown(&self) -> (&[Panel], &[Mark]) {
        if self.visible {
            (&self.panels, &self.frame_marks)
        } else {
            (&[], &[])
        }
    }

    /// The legend class whose HUD line is at window pixel (x, y), if any.
    pub fn legend_class_at(&self, x: f32, y: f32) -> Option<u32> {
        let panel = self.panels.first().filter(|_| self.visible)?;
        let atlas = crate::overlay::atlas().ok()?;
        let row = crate::overlay::line_at(atlas, panel, (x, y))?;
        let (first, classes) = &self.legend_rows;
        row.checked_sub(*first)
            .and_then(|k| classes.get(k))
            .copied()
    }
}

/// The HUD's classification legend: the classes present while coloring by classification.
pub(super) fn legend_for(cloud: &Cloud, coloring: &Coloring) -> Vec<LegendEntry> {
    if coloring.mode == COLOR_CLASSIFICATION {
        color::legend(cloud)
    } else {
        Vec::new()
    }
}

/// What `renderer`'s method projects: its level-of-detail samples, the points of the batches
/// `camera` sees when it culls batches of the `uploaded` cloud, else every point.
fn projected(
    renderer: &Renderer,
    uploaded: Option<&(GpuScene, SceneInfo)>,
    camera: &Camera,
) -> hud::Projected {
    match uploaded {
        _ if renderer.config.method.needs_lod => {
            hud::Projected::LevelOfDetail(renderer.samples_per_level().map(<[u64]>::to_vec))
        }
        Some((scene, _)) if renderer.config.method.culls_batches => {
            let aspect = renderer.width as f32 / renderer.height.max(1) as f32;
            let view_proj = camera.projection(aspect) * camera.view();
            hud::Projected::InView(crate::point_streams::projected_points(
                view_proj,
                &scene.streams.host_batches,
            ))
        }
        _ => hud::Projected::All,
    }
}

/// A streamed file's HUD lines: points drawn and chosen, budget, tiles, nodes, loading, bytes
/// read, pool slots and skipped nodes.
fn stream_text(s: &StreamedScene) -> String {
    let t = s.stats();
    format!(
        "streamed {} of {} points, budget {} (, .)\n{}nodes {}, loading {}, read {:.1} MB, pool {} of {}{}",
        hud::thousands(t.drawn_points),
        hud::thousands(t.selected_points),
        hud::thousands(s.point_budget()),
        if t.tiles > 1 {
            format!("tiles open {} of {}, ", t.tiles_open, t.tiles)
        } else {
            String::new()
        },
        t.selected_nodes,
        t.loading,
        t.bytes_read as f64 / 1e6,
        t.used_slots,
        t.slots,
        if t.failed > 0 { format!(", {} skipped", t.failed) } else { String::new() }
    )
}

/// The colour ramp's scale bar (bottom left of a `width` x `height` window) while coloring by
/// a ramp: a panel naming the field and its range (in the file's coordinates: the local frame
/// is at `origin`), and the ramp's steps as `marks` above it; while coloring by return number,
/// the palette's key.
fn scale_bar(
    coloring: Coloring,
    field: &str,
    origin: DVec3,
    (width, height): (u32, u32),
    marks: &mut Vec<Mark>,
) -> Option<Panel> {
    if coloring.mode == COLOR_RETURN {
        // The return palette's key.
        let mut panel = Panel::new(Corner::BottomLeft);
        for number in 1..=5 {
            let [r, g, b] = color::return_color(number);
            let what = if number == 5 {
                "return 5 and later".to_string()
            } else {
                format!("return {number}")
            };
            panel.line(what, [r, g, b, 255]);
        }
        return Some(panel);
    }
    color::ramp_color(coloring.mode, 0.0)?;
    // Elevations are local: the scale names the file's.
    let shift = if coloring.mode == COLOR_ELEVATION {
        origin.dot(coloring.axis.as_dvec3())
    } else {
        0.0
    };
    let [lo, hi] = coloring.range.map(|v| f64::from(v) + shift);
    let mut panel = Panel::new(Corner::BottomLeft);
    panel.line(format!("{field}  {lo:.4} to {hi:.4}"), HudLine::TEXT);
    let line = crate::overlay::atlas().map_or(18.0, |a| a.line_height);
    let margin = crate::overlay::MARGIN;
    let panel_h = line + 2.0 * crate::overlay::PADDING;
    let (bar_w, bar_h) = (256.0f32.min(width as f32 - 2.0 * margin), 12.0);
    let bottom = height as f32 - margin - panel_h - 4.0;
    let steps = 64;
    for k in 0..steps {
        let t = (k as f32 + 0.5) / steps as f32;
        let [r, g, b] = color::ramp_color(coloring.mode, t)?;
        let x0 = margin + bar_w * k as f32 / steps as f32;
        marks.push(Mark {
            rect: Vec4::new(x0, bottom - bar_h, x0 + bar_w / steps as f32 + 0.5, bottom),
            color: [r, g, b, 255],
        });
    }
    Some(panel)
}

impl Viewer {
    /// Rebuilds the HUD's panels and the window title from the newest figures.
    pub(super) fn refresh_hud(&mut self) {
        if let Some(e) = &self.scene.estimation {
            self.hud.status = format!(
                "estimating normals and radii (k = {}): {} %",
                e.k,
                e.percent()
            );
        }
        let tool_lines = self.tools.lines();
        if let Some(s) = &self.scene.streamed {
            // A streamed file's classes are those of the nodes loaded so far.
            if s.info.coloring.mode == COLOR_CLASSIFICATION {
                self.hud.legend = s.legend();
            }
        }
        let Some(gpu) = self.gpu.as_mut() else {
            return;
        };
        let passes: Vec<(String, f64)> = gpu
            .renderer
            .last_timings()
            .into_iter()
            .filter(|(n, _)| !n.starts_with("present"))
            .collect();
        let Some(gpu) = self.gpu.as_ref() else {
            return;
        };
        let label = gpu.renderer.config.label();
        // A rebuilt renderer has no timings until its first frame's timestamps are collected
        // (when its slot comes round again, after the frames in flight): until then the HUD
        // says it is measuring, never showing another renderer's passes.
        self.hud.measuring = passes.is_empty();
        let projected = projected(
            &gpu.renderer,
            self.scene.uploaded.as_ref(),
            &self.orbit.camera(),
        );
        let stream = self.scene.streamed.as_ref().map(stream_text);
        let points = match &self.scene.streamed {
            Some(s) => s.stats().drawn_points,
            None => u64::from(gpu.renderer.info.points),
        };
        let hud = Hud::new(
            &Stats {
                method: &label,
                file: &self.opts.file,
                passes: &passes,
                points,
                stream: stream.as_deref(),
                projected,
                width: gpu.renderer.width,
                height: gpu.renderer.height,
                fps: self.hud.rate.fps,
                memory: self.hud.memory,
                use_color: self.drawing.use_color,
                edl: self.drawing.post.edl,
                color_by: &self.opts.color_by,
                legend: &self.hud.legend,
                status: &self.hud.status,
                expanded: self.hud.expanded,
                measuring: self.hud.measuring,
                hidden: &self.tools.filter.hidden,
                tools: &tool_lines,
            },
            self.hud.help,
        );
        self.hud.legend_rows = (
            hud.legend_at,
            self.hud.legend.iter().map(|e| e.class).collect(),
        );
        self.hud.panels = hud.panels();
        let size = (gpu.renderer.width, gpu.renderer.height);
        let coloring = gpu.renderer.info.coloring;
        gpu.window.set_title(&self.title(&label, &passes));
        self.hud.marks.clear();
        let origin = self.scene.cloud.origin;
        if let Some(panel) = scale_bar(
            coloring,
            &self.opts.color_by,
            origin,
            size,
            &mut self.hud.marks,
        ) {
            self.hud.panels.push(panel);
        }
        self.hud.dirty = false;
    }

    /// The window title: the viewer's, the method, the colour field and the passes' times.
    fn title(&self, label: &str, passes: &[(String, f64)]) -> String {
        let ms: Vec<String> = passes
            .iter()
            .map(|(n, ms)| format!("{n} {ms:.2}"))
            .collect();
        format!(
            "{} - {} - color: {} - {} ms{}{}",
            self.opts.title,
            label,
            self.opts.color_by,
            ms.join(" | "),
            if self.drawing.use_color {
                ""
            } else {
                " (no color)"
            },
            if self.hud.measuring {
                " (measuring)"
            } else {
                ""
            }
        )
    }
}
