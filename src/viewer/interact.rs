//! The viewer's tools at work: picking and measuring by clicks, the clipping box and the class
//! filter, camera bookmarks, and the markers drawn over the frame (their state is
//! `tool_state`'s). Every scripted tool command prints one JSON line.

use anyhow::{Context as _, Result};
use glam::{DMat3, DVec3, IVec2, Vec3};
use serde_json::json;

use super::script::Tool;
use super::tool_state::{window_of, ClickTool};
use super::tools::{self, Pick, Screen, Target};
use super::Viewer;
use crate::frame::Frame;
use crate::layout::GpuBatch;
use crate::point_streams::upload::DEFAULT_CHUNK_BYTES;
use crate::scene::clip::{classification_field, ClipBox, Keep};
use crate::scene::Camera;

/// A streamed file's drawn points near the cursor, read again for a pick: one cloud, and per
/// node its first point there and its name.
struct NodePoints {
    cloud: crate::scene::Cloud,
    nodes: Vec<(usize, String)>,
}

impl Viewer {
    /// The spacing `hpr::spacing` gives the cloud, computed on the first pick.
    fn spacing(&mut self) -> f64 {
        *self
            .tools
            .spacing
            .get_or_insert_with(|| crate::hpr::spacing(&self.scene.cloud))
    }

    /// The points picks at `pixels` read: `None` for a loaded file (its cloud), else a
    /// streamed file's drawn nodes whose batch boxes reach the pick cones, read again.
    fn streamed_points(
        &mut self,
        frame: &Frame,
        camera: &Camera,
        pixels: &[IVec2],
    ) -> Option<NodePoints> {
        let streamed = self.scene.streamed.as_mut()?;
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
        let cloud = streamed.map_or(&self.scene.cloud, |s| &s.cloud);
        let resolved = self.tools.filter.active(cloud.origin);
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
        for request in std::mem::take(&mut self.tools.requests) {
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
                    let cloud = streamed.map_or(&self.scene.cloud, |s| &s.cloud);
                    println!("{}", json!({ "pick": pick.json(cloud) }));
                }
                Tool::Measure(kind, pixels) => {
                    let picks: Vec<Pick> = pixels
                        .iter()
                        .map(|&(x, y)| self.pick_at(frame, camera, IVec2::new(x, y), streamed))
                        .collect();
                    let cloud = streamed.map_or(&self.scene.cloud, |s| &s.cloud);
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
                        self.tools.tool = ClickTool::Measure(kind);
                        self.tools.picks = points;
                        self.tools.measured = values;
                    }
                }
                Tool::Count => {
                    let covered = frame.depth.iter().filter(|d| d.is_finite()).count();
                    println!(
                        "{}",
                        json!({ "count": {
                            "covered_pixels": covered,
                            "points": self.scene.streamed.is_none().then(|| self.scene.cloud.len()),
                            "kept_points": self
                                .scene
                                .streamed
                                .is_none()
                                .then(|| self.tools.filter.count(&self.scene.cloud)),
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
        self.hud.dirty = true;
        Ok(())
    }

    /// A click's pick (among `streamed`'s points for a streamed file), applied by the
    /// current tool.
    fn clicked(&mut self, pick: Pick, streamed: Option<&NodePoints>) -> Result<()> {
        let cloud = streamed.map_or(&self.scene.cloud, |s| &s.cloud);
        println!("{}", json!({ "pick": pick.json(cloud) }));
        let Some(p) = pick.picked else {
            return self.outcome(Ok(format!(
                "no visible point within {} pixels of {}, {}",
                tools::PICK_RADIUS,
                pick.pixel.x,
                pick.pixel.y
            )));
        };
        if self
            .tools
            .tool
            .points()
            .is_some_and(|n| self.tools.picks.len() >= n)
        {
            self.tools.picks.clear();
            self.tools.measured.clear();
        }
        self.tools.picks.push(p.world);
        let n = self.tools.picks.len();
        match self.tools.tool {
            ClickTool::Pick => {
                let a =
                    tools::attributes(streamed.map_or(&self.scene.cloud, |s| &s.cloud), p.index);
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
                self.tools.measured = tools::measure(m, &self.tools.picks, self.orbit.up);
                let values: serde_json::Map<_, _> = self
                    .tools
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
                let b =
                    ClipBox::aligned(flat(self.tools.picks[0], lo), flat(self.tools.picks[1], hi));
                self.set_clip(Some(b))
            }
            ClickTool::Oriented if n == 3 => {
                let (lo, hi) = self.vertical_extent();
                let w = self.orbit.up.vector().as_dvec3();
                let flat = |p: DVec3| p - w * p.dot(w);
                let (a, b, c) = (
                    flat(self.tools.picks[0]),
                    flat(self.tools.picks[1]),
                    flat(self.tools.picks[2]),
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
                self.tools.tool.name(),
                self.tools.tool.points().unwrap_or(n)
            ))),
        }
    }

    /// The cloud's extent along the up axis, in file coordinates (a little beyond).
    fn vertical_extent(&self) -> (f64, f64) {
        let w = self.orbit.up.vector().as_dvec3();
        let (lo, hi) = self
            .scene
            .cloud
            .bounds()
            .unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let (a, b) = (
            (self.scene.cloud.origin + lo.as_dvec3()).dot(w),
            (self.scene.cloud.origin + hi.as_dvec3()).dot(w),
        );
        let pad = (b - a).abs() * 0.01 + 1e-6;
        (a.min(b) - pad, a.max(b) + pad)
    }

    /// Runs a tool command that needs no frame.
    pub(super) fn tool_now(&mut self, tool: Tool) -> Result<()> {
        match tool {
            Tool::Locate(p) => {
                let local = (DVec3::from(p) - self.scene.cloud.origin).as_vec3();
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
                    .tools
                    .clip_box
                    .context("no clipping box yet (`clip box ...` or the box tools)")?;
                self.set_clip(Some(ClipBox { keep, ..b }))
            }
            Tool::ClipOff => self.set_clip(None),
            Tool::Filter { classes, hide } => {
                for c in classes {
                    self.tools.filter.hidden.set(c, hide);
                }
                self.filter_changed()
            }
            Tool::FilterOnly(classes) => {
                for c in 0..=255u8 {
                    self.tools.filter.hidden.set(c, !classes.contains(&c));
                }
                self.filter_changed()
            }
            Tool::FilterAll => {
                self.tools.filter.hidden = Default::default();
                self.filter_changed()
            }
            Tool::Pick(..) | Tool::Measure(..) | Tool::Count | Tool::Click(..) => {
                self.tools.requests.push(tool);
                Ok(())
            }
        }
    }

    /// Sets (or clears) the clipping box, remembering the box when it is switched off.
    fn set_clip(&mut self, clip: Option<ClipBox>) -> Result<()> {
        self.tools.set_clip(clip);
        self.filter_changed()
    }

    /// `B`: the box keeps its inside, then its outside, then is off.
    pub(super) fn cycle_clip(&mut self) -> Result<()> {
        let Some(b) = self.tools.clip_box else {
            return self.outcome(Ok(
                "no clipping box: draw one with the box tools (T) first".into()
            ));
        };
        let next = match self.tools.filter.clip.map(|c| c.keep) {
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
        if !self.tools.filter.hidden.is_empty() {
            let field = classification_field(&self.scene.cloud);
            if let (Some(ctx), Some((scene, _)), Some(field)) =
                (self.ctx.clone(), self.scene.uploaded.as_mut(), field)
            {
                if scene.streams.classes.is_none() {
                    scene.streams.add_classes(
                        &ctx,
                        &self.scene.cloud,
                        field,
                        DEFAULT_CHUNK_BYTES,
                    )?;
                    // The graph binds the segment table `add_classes` replaced.
                    self.rebuild()?;
                }
            }
        }
        self.push_filter();
        let kept = if self.scene.streamed.is_some() {
            None
        } else {
            Some(self.tools.filter.count(&self.scene.cloud))
        };
        println!(
            "{}",
            json!({ "filter": {
                "hidden_classes": self.tools.filter.hidden.list(),
                "clip": self.tools.filter.clip,
                "kept_points": kept,
                "points": self.scene.cloud.len(),
            }})
        );
        self.hud.dirty = true;
        let clip = match self.tools.filter.clip.map(|c| c.keep) {
            None => "off",
            Some(Keep::Inside) => "inside",
            Some(Keep::Outside) => "outside",
        };
        self.hud.status = match kept {
            Some(k) => format!(
                "{} of {} points kept (box: {clip})",
                super::hud::thousands(k as u64),
                super::hud::thousands(self.scene.cloud.len() as u64)
            ),
            None => format!("box: {clip}"),
        };
        Ok(())
    }

    /// Hands the filter to the renderer (after every rebuild, too).
    pub(super) fn push_filter(&mut self) {
        let resolved = self.tools.filter.active(self.scene.cloud.origin);
        if let Some(gpu) = self.gpu.as_mut() {
            gpu.renderer.set_filter(resolved);
        }
    }

    /// Toggles a legend class (a click on its line).
    pub(super) fn toggle_class(&mut self, class: u8) -> Result<()> {
        let hidden = !self.tools.filter.hidden.contains(class);
        self.tools.filter.hidden.set(class, hidden);
        self.filter_changed()
    }

    /// `Ctrl+N` stores the camera as bookmark N (file coordinates); `N` recalls it.
    pub(super) fn bookmark(&mut self, slot: u8, store: bool) -> Result<()> {
        let origin = self.scene.cloud.origin;
        if store {
            self.tools
                .store_bookmark(slot, &self.orbit.camera(), origin);
            return self.outcome(Ok(format!("bookmark {slot} stored (K saves bookmarks)")));
        }
        let Some(b) = self
            .tools
            .bookmarks
            .iter()
            .find(|b| b.slot == slot)
            .copied()
        else {
            return self.outcome(Ok(format!("no bookmark {slot} (Ctrl+{slot} stores one)")));
        };
        let local = |p: [f64; 3]| (DVec3::from(p) - origin).as_vec3();
        let home = self.orbit.home;
        let camera = Camera::look_at_up(self.orbit.up, local(b.eye), local(b.target), 1.0);
        self.orbit.look(&Camera {
            near: home.near,
            fov_y: home.fov_y,
            ..camera
        });
        self.outcome(Ok(format!("bookmark {slot}")))
    }

    /// Fills the HUD's `frame_marks` (kept between frames, so no frame allocates) with the
    /// current frame's markers: the HUD's scale bar, the edges of the clipping box while it
    /// clips, the measurement's lines and the picked points.
    pub(super) fn fill_marks(&mut self, camera: &Camera) {
        let (w, h) = self.size();
        let view_proj = camera.projection(w as f32 / h.max(1) as f32) * camera.view();
        let origin = self.scene.cloud.origin;
        let at = |p: DVec3| window_of(view_proj, (p - origin).as_vec3(), w, h);
        let out = &mut self.hud.frame_marks;
        out.clear();
        out.extend_from_slice(&self.hud.marks);
        self.tools.push_marks(out, at);
    }
}
