//! The viewer's tools: picking and measuring by clicks (`T` picks the tool), the clipping box
//! and the class filter, camera bookmarks, point size and budget keys, and the markers drawn
//! over the frame. Every scripted tool command prints one JSON line.

use anyhow::{Context as _, Result};
use glam::{DMat3, DVec3, IVec2, Mat4, Vec3, Vec4};
use serde_json::json;

use super::script::Tool;
use super::tools::{self, Measure, Pick, Screen, Target};
use super::Viewer;
use crate::frame::Frame;
use crate::gpu::layout::GpuBatch;
use crate::overlay::{HudLine, Mark};
use crate::scene::clip::{classification_field, ClipBox, Keep};
use crate::scene::scene_file::Bookmark;
use crate::scene::Camera;
use crate::streams::upload::DEFAULT_CHUNK_BYTES;

/// What a left click does (`T` cycles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClickTool {
    /// Show the point's coordinates and attributes.
    Pick,
    Measure(Measure),
    /// Two picks: an axis-aligned clipping box over their plan rectangle, the cloud's whole
    /// height.
    Box,
    /// Three picks: an edge, then the side the box extends to (an oriented box, the cloud's
    /// whole height).
    Oriented,
}

impl ClickTool {
    pub const ALL: [ClickTool; 7] = [
        ClickTool::Pick,
        ClickTool::Measure(Measure::Distance),
        ClickTool::Measure(Measure::Height),
        ClickTool::Measure(Measure::Polyline),
        ClickTool::Measure(Measure::Area),
        ClickTool::Box,
        ClickTool::Oriented,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ClickTool::Pick => "pick",
            ClickTool::Measure(m) => m.name(),
            ClickTool::Box => "clipping box",
            ClickTool::Oriented => "oriented clipping box",
        }
    }

    /// Picks the tool takes before it acts (`None`: any number, each one acts).
    fn points(self) -> Option<usize> {
        match self {
            ClickTool::Pick => Some(1),
            ClickTool::Measure(m) => m.points(),
            ClickTool::Box => Some(2),
            ClickTool::Oriented => Some(3),
        }
    }
}

/// A streamed file's drawn points near the cursor, read again for a pick: one cloud, and per
/// node its first point there and its name.
struct NodePoints {
    cloud: crate::scene::Cloud,
    nodes: Vec<(usize, String)>,
}

/// Marker colors: picked points, measurement lines, the clipping box.
const MARKER: [u8; 4] = [255, 214, 102, 255];
const OUTLINE: [u8; 4] = [20, 20, 20, 255];
const BOX: [u8; 4] = [110, 200, 255, 255];

/// Dotted-line quads between two projected points, about 6 pixels apart.
fn dotted(out: &mut Vec<Mark>, a: Vec3, b: Vec3, color: [u8; 4]) {
    let d = (b - a).truncate();
    let n = (d.length() / 6.0).ceil().clamp(1.0, 200.0) as usize;
    for k in 0..=n {
        let p = a.truncate() + d * (k as f32 / n as f32);
        out.push(Mark {
            rect: Vec4::new(p.x - 1.0, p.y - 1.0, p.x + 1.0, p.y + 1.0),
            color,
        });
    }
}

/// Window position of local point `p` (x, y in pixels, z > 0 in front), `None` behind the eye.
fn window_of(view_proj: Mat4, p: Vec3, width: u32, height: u32) -> Option<Vec3> {
    let c = view_proj * p.extend(1.0);
    (c.w > 0.0).then(|| {
        Vec3::new(
            (c.x / c.w * 0.5 + 0.5) * width as f32,
            (c.y / c.w * 0.5 + 0.5) * height as f32,
            c.w,
        )
    })
}

impl Viewer {
    /// The spacing `hpr::spacing` gives the cloud, computed on the first pick.
    fn spacing(&mut self) -> f64 {
        *self
            .spacing
            .get_or_insert_with(|| crate::hpr::spacing(&self.cloud))
    }

    /// The points picks at `pixels` read: `None` for a loaded file (its cloud), else a
    /// streamed file's drawn nodes whose batch boxes reach the pick cones, read again.
    fn streamed_points(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        pixels: &[IVec2],
    ) -> Option<NodePoints> {
        let streamed = self.streamed.as_mut()?;
        let aspect = frame.width as f32 / frame.height.max(1) as f32;
        let view_proj = camera.projection(aspect) * camera.view();
        let half = glam::Vec2::new(frame.width as f32, frame.height as f32) * 0.5;
        let reach = (tools::CONE_RADIUS + 1) as f32;
        let near = |b: &GpuBatch| {
            let (mut lo, mut hi) = (glam::Vec2::INFINITY, glam::Vec2::NEG_INFINITY);
            for k in 0..8 {
                let corner = Vec3::new(
                    if k & 1 != 0 { b.max_x } else { b.min_x },
                    if k & 2 != 0 { b.max_y } else { b.min_y },
                    if k & 4 != 0 { b.max_z } else { b.min_z },
                );
                let c = view_proj * corner.extend(1.0);
                if c.w <= 0.0 {
                    // A box reaching behind the eye may cover any pixel.
                    return true;
                }
                let win = glam::Vec2::new(c.x, c.y) / c.w * half + half;
                lo = lo.min(win);
                hi = hi.max(win);
            }
            pixels.iter().any(|p| {
                let p = p.as_vec2() + 0.5;
                p.cmpge(lo - reach).all() && p.cmple(hi + reach).all()
            })
        };
        let (cloud, nodes) = streamed.drawn_points(near);
        Some(NodePoints { cloud, nodes })
    }

    /// Picks at `pixel` of `frame` (rendered with `camera`) among the loaded cloud's points,
    /// or `streamed`'s.
    fn pick_at(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        pixel: IVec2,
        streamed: Option<&NodePoints>,
    ) -> Pick {
        // A streamed file's nodes mix levels: the cone's own spacing estimate stands alone.
        let spacing = if streamed.is_some() {
            0.0
        } else {
            self.spacing()
        };
        let cloud = streamed.map_or(&self.cloud, |s| &s.cloud);
        let resolved = self.filter.active(cloud.origin);
        let target = Target {
            cloud,
            filter: resolved.as_ref(),
            spacing,
        };
        let screen = Screen {
            camera,
            width: frame.width,
            height: frame.height,
            depth: &frame.depth,
        };
        let x = pixel.x.clamp(0, frame.width as i32 - 1);
        let y = pixel.y.clamp(0, frame.height as i32 - 1);
        let mut pick = tools::pick(&target, &screen, IVec2::new(x, y));
        if let (Some(s), Some(p)) = (streamed, pick.picked.as_mut()) {
            let k = s.nodes.partition_point(|(first, _)| *first <= p.index) - 1;
            let (first, name) = &s.nodes[k];
            p.node = Some((name.clone(), p.index - first));
        }
        pick
    }

    /// Runs the tool commands that waited for `frame` (rendered with `camera`).
    pub(super) fn resolve_requests(&mut self, frame: &Frame, camera: &Camera) -> Result<()> {
        for request in std::mem::take(&mut self.requests) {
            let pixels: Vec<IVec2> = match &request {
                Tool::Pick(x, y) | Tool::Click(x, y) => vec![IVec2::new(*x, *y)],
                Tool::Measure(_, pixels) => pixels.iter().map(|&(x, y)| IVec2::new(x, y)).collect(),
                _ => Vec::new(),
            };
            let streamed = if pixels.is_empty() {
                None
            } else {
                self.streamed_points(frame, camera, &pixels)
            };
            let streamed = streamed.as_ref();
            match request {
                Tool::Pick(x, y) => {
                    let pick = self.pick_at(frame, camera, IVec2::new(x, y), streamed);
                    let cloud = streamed.map_or(&self.cloud, |s| &s.cloud);
                    println!("{}", json!({ "pick": pick.json(cloud) }));
                }
                Tool::Measure(kind, pixels) => {
                    let picks: Vec<Pick> = pixels
                        .iter()
                        .map(|&(x, y)| self.pick_at(frame, camera, IVec2::new(x, y), streamed))
                        .collect();
                    let cloud = streamed.map_or(&self.cloud, |s| &s.cloud);
                    let points: Option<Vec<DVec3>> = picks
                        .iter()
                        .map(|p| p.picked.as_ref().map(|q| q.world))
                        .collect();
                    let values = points
                        .as_deref()
                        .map(|p| tools::measure(kind, p, self.orbit.up))
                        .unwrap_or_default();
                    let mut out = serde_json::Map::new();
                    out.insert("kind".into(), json!(kind.name()));
                    out.insert(
                        "picks".into(),
                        picks.iter().map(|p| p.json(cloud)).collect(),
                    );
                    for (name, v) in &values {
                        out.insert((*name).into(), json!(v));
                    }
                    println!("{}", json!({ "measure": out }));
                    if let Some(points) = points {
                        self.tool = ClickTool::Measure(kind);
                        self.picks = points;
                        self.measured = values;
                    }
                }
                Tool::Count => {
                    let covered = frame.depth.iter().filter(|d| d.is_finite()).count();
                    println!(
                        "{}",
                        json!({ "count": {
                            "covered_pixels": covered,
                            "points": self.streamed.is_none().then(|| self.cloud.len()),
                            "kept_points": self
                                .streamed
                                .is_none()
                                .then(|| self.filter.count(&self.cloud)),
                        }})
                    );
                }
                Tool::Click(x, y) => {
                    let pick = self.pick_at(frame, camera, IVec2::new(x, y), streamed);
                    self.clicked(pick, streamed)?;
                }
                other => self.tool_now(other)?,
            }
        }
        self.hud_dirty = true;
        Ok(())
    }

    /// A click's pick (among `streamed`'s points for a streamed file), applied by the
    /// current tool.
    fn clicked(&mut self, pick: Pick, streamed: Option<&NodePoints>) -> Result<()> {
        let cloud = streamed.map_or(&self.cloud, |s| &s.cloud);
        println!("{}", json!({ "pick": pick.json(cloud) }));
        let Some(p) = pick.picked else {
            return self.outcome(Ok(format!(
                "no visible point within {} pixels of {}, {}",
                tools::PICK_RADIUS,
                pick.pixel.x,
                pick.pixel.y
            )));
        };
        if self.tool.points().is_some_and(|n| self.picks.len() >= n) {
            self.picks.clear();
            self.measured.clear();
        }
        self.picks.push(p.world);
        let n = self.picks.len();
        match self.tool {
            ClickTool::Pick => {
                let a = tools::attributes(streamed.map_or(&self.cloud, |s| &s.cloud), p.index);
                let index = match &p.node {
                    Some((node, i)) => format!("{i} of {node}"),
                    None => p.index.to_string(),
                };
                let message = format!(
                    "point {index} at {:.3}, {:.3}, {:.3}  {a}",
                    p.world.x, p.world.y, p.world.z
                );
                self.outcome(Ok(message))
            }
            ClickTool::Measure(m) => {
                self.measured = tools::measure(m, &self.picks, self.orbit.up);
                let values: serde_json::Map<_, _> = self
                    .measured
                    .iter()
                    .map(|(k, v)| ((*k).to_string(), json!(v)))
                    .collect();
                println!(
                    "{}",
                    json!({ "measure": { "kind": m.name(), "points": n, "values": values } })
                );
                Ok(())
            }
            ClickTool::Box if n == 2 => {
                let (lo, hi) = self.vertical_extent();
                let axis = self.orbit.up.vector().as_dvec3().abs();
                let flat = |p: DVec3, v: f64| p - axis * p.dot(axis) + axis * v;
                let b = ClipBox::aligned(flat(self.picks[0], lo), flat(self.picks[1], hi));
                self.set_clip(Some(b))
            }
            ClickTool::Oriented if n == 3 => {
                let (lo, hi) = self.vertical_extent();
                let w = self.orbit.up.vector().as_dvec3();
                let flat = |p: DVec3| p - w * p.dot(w);
                let (a, b, c) = (
                    flat(self.picks[0]),
                    flat(self.picks[1]),
                    flat(self.picks[2]),
                );
                let Some(u) = (b - a).try_normalize() else {
                    return self.outcome(Err(anyhow::anyhow!("the box's edge has no length")));
                };
                let v = w.cross(u);
                let side = (c - a).dot(v);
                let centre = (a + b) * 0.5 + v * side * 0.5 + w * (lo + hi) * 0.5;
                let half = DVec3::new(a.distance(b) * 0.5, side.abs() * 0.5, (hi - lo) * 0.5);
                self.set_clip(Some(ClipBox::oriented(
                    centre,
                    half,
                    DMat3::from_cols(u, v, w),
                )))
            }
            ClickTool::Box | ClickTool::Oriented => self.outcome(Ok(format!(
                "{}: point {n} of {}",
                self.tool.name(),
                self.tool.points().unwrap_or(n)
            ))),
        }
    }

    /// The cloud's extent along the up axis, in file coordinates (a little beyond).
    fn vertical_extent(&self) -> (f64, f64) {
        let w = self.orbit.up.vector().as_dvec3();
        let (lo, hi) = self.cloud.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let (a, b) = (
            (self.cloud.origin + lo.as_dvec3()).dot(w),
            (self.cloud.origin + hi.as_dvec3()).dot(w),
        );
        let pad = (b - a).abs() * 0.01 + 1e-6;
        (a.min(b) - pad, a.max(b) + pad)
    }

    /// Runs a tool command that needs no frame.
    pub(super) fn tool_now(&mut self, tool: Tool) -> Result<()> {
        match tool {
            Tool::Locate(p) => {
                let local = (DVec3::from(p) - self.cloud.origin).as_vec3();
                let (w, h) = self.size();
                let camera = self.orbit.camera();
                let view_proj = camera.projection(w as f32 / h.max(1) as f32) * camera.view();
                let at = tools::pixel_of(view_proj, local, w, h);
                println!(
                    "{}",
                    json!({ "locate": {
                        "position": p,
                        "pixel": at.map(|(px, _)| [px.x, px.y]),
                        "view_depth": at.map(|(_, d)| d),
                    }})
                );
                Ok(())
            }
            Tool::ClipBox(b) => self.set_clip(Some(b)),
            Tool::ClipKeep(keep) => {
                let b = self
                    .clip_box
                    .context("no clipping box yet (`clip box ...` or the box tools)")?;
                self.set_clip(Some(ClipBox { keep, ..b }))
            }
            Tool::ClipOff => self.set_clip(None),
            Tool::Filter { classes, hide } => {
                for c in classes {
                    self.filter.hidden.set(c, hide);
                }
                self.filter_changed()
            }
            Tool::FilterOnly(classes) => {
                for c in 0..=255u8 {
                    self.filter.hidden.set(c, !classes.contains(&c));
                }
                self.filter_changed()
            }
            Tool::FilterAll => {
                self.filter.hidden = Default::default();
                self.filter_changed()
            }
            Tool::Pick(..) | Tool::Measure(..) | Tool::Count | Tool::Click(..) => {
                self.requests.push(tool);
                Ok(())
            }
        }
    }

    /// The window's size in pixels (the swapchain's).
    pub(super) fn size(&self) -> (u32, u32) {
        self.gpu.as_ref().map_or((1, 1), |g| {
            (g.swapchain.extent.width, g.swapchain.extent.height)
        })
    }

    /// Sets (or clears) the clipping box, remembering the box when it is switched off.
    fn set_clip(&mut self, clip: Option<ClipBox>) -> Result<()> {
        if clip.is_some() {
            self.clip_box = clip;
        }
        self.filter.clip = clip;
        self.filter_changed()
    }

    /// `B`: the box keeps its inside, then its outside, then is off.
    pub(super) fn cycle_clip(&mut self) -> Result<()> {
        let Some(b) = self.clip_box else {
            return self.outcome(Ok(
                "no clipping box: draw one with the box tools (T) first".into()
            ));
        };
        let next = match self.filter.clip.map(|c| c.keep) {
            None => Some(ClipBox {
                keep: Keep::Inside,
                ..b
            }),
            Some(Keep::Inside) => Some(ClipBox {
                keep: Keep::Outside,
                ..b
            }),
            Some(Keep::Outside) => None,
        };
        self.set_clip(next)
    }

    /// Applies the filter: uploads the class stream the first time a class is hidden, hands
    /// the resolved filter to the renderer, reports what it keeps.
    pub(super) fn filter_changed(&mut self) -> Result<()> {
        if !self.filter.hidden.is_empty() {
            let field = classification_field(&self.cloud);
            if let (Some(ctx), Some((scene, _)), Some(field)) =
                (self.ctx.clone(), self.scene.as_mut(), field)
            {
                if scene.streams.classes.is_none() {
                    scene
                        .streams
                        .add_classes(&ctx, &self.cloud, field, DEFAULT_CHUNK_BYTES)?;
                    // The graph binds the segment table `add_classes` replaced.
                    self.rebuild()?;
                }
            }
        }
        self.push_filter();
        let kept = if self.streamed.is_some() {
            None
        } else {
            Some(self.filter.count(&self.cloud))
        };
        println!(
            "{}",
            json!({ "filter": {
                "hidden_classes": self.filter.hidden.list(),
                "clip": self.filter.clip,
                "kept_points": kept,
                "points": self.cloud.len(),
            }})
        );
        self.hud_dirty = true;
        let clip = match self.filter.clip.map(|c| c.keep) {
            None => "off",
            Some(Keep::Inside) => "inside",
            Some(Keep::Outside) => "outside",
        };
        self.status = match kept {
            Some(k) => format!(
                "{} of {} points kept (box: {clip})",
                super::hud::thousands(k as u64),
                super::hud::thousands(self.cloud.len() as u64)
            ),
            None => format!("box: {clip}"),
        };
        Ok(())
    }

    /// Hands the filter to the renderer (after every rebuild, too).
    pub(super) fn push_filter(&mut self) {
        let resolved = self.filter.active(self.cloud.origin);
        if let Some(gpu) = self.gpu.as_mut() {
            gpu.renderer.set_filter(resolved);
        }
    }

    /// Toggles a legend class (a click on its line).
    pub(super) fn toggle_class(&mut self, class: u8) -> Result<()> {
        let hidden = !self.filter.hidden.contains(class);
        self.filter.hidden.set(class, hidden);
        self.filter_changed()
    }

    /// `Ctrl+N` stores the camera as bookmark N (file coordinates); `N` recalls it.
    pub(super) fn bookmark(&mut self, slot: u8, store: bool) -> Result<()> {
        let origin = self.cloud.origin;
        if store {
            let c = self.orbit.camera();
            let b = Bookmark {
                slot,
                eye: (origin + c.eye.as_dvec3()).to_array(),
                target: (origin + c.target.as_dvec3()).to_array(),
            };
            self.bookmarks.retain(|b| b.slot != slot);
            self.bookmarks.push(b);
            self.bookmarks.sort_by_key(|b| b.slot);
            return self.outcome(Ok(format!("bookmark {slot} stored (K saves bookmarks)")));
        }
        let Some(b) = self.bookmarks.iter().find(|b| b.slot == slot).copied() else {
            return self.outcome(Ok(format!("no bookmark {slot} (Ctrl+{slot} stores one)")));
        };
        let local = |p: [f64; 3]| (DVec3::from(p) - origin).as_vec3();
        let home = self.orbit.home;
        let camera = Camera::look_at_up(self.orbit.up, local(b.eye), local(b.target), 1.0);
        self.orbit = super::Orbit::from_camera(
            &Camera {
                near: home.near,
                fov_y: home.fov_y,
                ..camera
            },
            self.orbit.up,
        );
        self.orbit.home = home;
        self.outcome(Ok(format!("bookmark {slot}")))
    }

    /// `+` / `-`: scales the method's point size (`size`, pixels) or splat radius (`radius`).
    pub(super) fn scale_points(&mut self, factor: f32) -> Result<()> {
        let mut config = self.config();
        let Some(spec) = config
            .method
            .params
            .iter()
            .find(|p| p.name == "size" || p.name == "radius")
        else {
            return self.outcome(Ok(format!(
                "{} draws 1-pixel points: + and - size points, splats and EWA",
                config.method.name
            )));
        };
        let old = config.get(spec.name);
        let value = if spec.name == "size" {
            // Whole pixels, at least one more or less.
            let v = (old * factor).round();
            if factor > 1.0 {
                v.max(old + 1.0)
            } else {
                v.min(old - 1.0)
            }
        } else {
            old * factor
        };
        let value = value.clamp(spec.min.max(1e-3), spec.max);
        config.params.insert(spec.name.into(), value);
        self.opts.method = config.clone();
        if spec.name == "size" {
            // The point size is a frame uniform: no rebuild.
            if let Some(gpu) = self.gpu.as_mut() {
                gpu.renderer.config = config;
            }
        } else {
            self.rebuild()?;
        }
        self.outcome(Ok(format!("{} {value}", spec.name)))
    }

    /// `,` / `.`: a streamed file's point budget, or a level-of-detail method's sample budget.
    pub(super) fn scale_any_budget(&mut self, factor: f64) -> Result<()> {
        if self.streamed.is_some() {
            return self.scale_budget(factor);
        }
        let mut config = self.config();
        let Some(spec) = config.method.params.iter().find(|p| p.name == "budget") else {
            return self.outcome(Ok(format!(
                "{} has no budget (level of detail and streamed files have one)",
                config.method.name
            )));
        };
        let value = ((f64::from(config.get("budget")) * factor) as f32).clamp(spec.min, spec.max);
        config.params.insert("budget".into(), value);
        self.opts.method = config;
        self.rebuild()?;
        self.outcome(Ok(format!("sample budget {value}")))
    }

    /// Fills `frame_marks` (kept between frames, so no frame allocates) with the current
    /// frame's markers: the HUD's scale bar, the edges of the clipping box while it clips, the
    /// measurement's lines and the picked points.
    pub(super) fn fill_marks(&mut self, camera: &Camera) {
        let (w, h) = self.size();
        let view_proj = camera.projection(w as f32 / h.max(1) as f32) * camera.view();
        let origin = self.cloud.origin;
        let at = |p: DVec3| window_of(view_proj, (p - origin).as_vec3(), w, h);
        let out = &mut self.frame_marks;
        out.clear();
        out.extend_from_slice(&self.hud_marks);
        if let Some(b) = self.filter.clip {
            let corners = b.corners().map(at);
            for (i, j) in [
                (0, 1),
                (2, 3),
                (4, 5),
                (6, 7),
                (0, 2),
                (1, 3),
                (4, 6),
                (5, 7),
                (0, 4),
                (1, 5),
                (2, 6),
                (3, 7),
            ] {
                if let (Some(a), Some(b)) = (corners[i], corners[j]) {
                    dotted(out, a, b, BOX);
                }
            }
        }
        let n = self.picks.len();
        let lines = match self.tool {
            ClickTool::Measure(Measure::Area) if n > 2 => n,
            ClickTool::Measure(_) => n.saturating_sub(1),
            _ => 0,
        };
        for k in 0..lines {
            if let (Some(a), Some(b)) = (at(self.picks[k]), at(self.picks[(k + 1) % n])) {
                dotted(out, a, b, MARKER);
            }
        }
        for p in self.picks.iter().filter_map(|&p| at(p)) {
            out.push(Mark {
                rect: Vec4::new(p.x - 5.0, p.y - 5.0, p.x + 5.0, p.y + 5.0),
                color: OUTLINE,
            });
            out.push(Mark {
                rect: Vec4::new(p.x - 3.0, p.y - 3.0, p.x + 3.0, p.y + 3.0),
                color: MARKER,
            });
        }
    }

    /// The HUD lines of the tool and the measurement.
    pub(super) fn tool_lines(&self) -> Vec<HudLine> {
        let mut out = vec![HudLine::new(
            format!("tool: {} (T), click to pick, X clears", self.tool.name()),
            HudLine::TEXT,
        )];
        for (name, v) in &self.measured {
            out.push(HudLine::new(
                tools::measure_line(name, *v),
                HudLine::HEADING,
            ));
        }
        if let Some(b) = self.filter.clip {
            let keep = match b.keep {
                Keep::Inside => "inside",
                Keep::Outside => "outside",
            };
            out.push(HudLine::new(
                format!(
                    "clip {keep}: centre {:.2}, {:.2}, {:.2}, half {:.2}, {:.2}, {:.2} (B)",
                    b.centre[0], b.centre[1], b.centre[2], b.half[0], b.half[1], b.half[2]
                ),
                HudLine::TEXT,
            ));
        }
        out
    }
}
