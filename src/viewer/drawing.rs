//! How the cloud is drawn and the keys that change it: `Drawing` (the method, point colors,
//! post-processing), and the method's parameters (pyramid level, point size, budgets), the
//! colour field and the lights.

use anyhow::{Context as _, Result};

use super::hud_state::legend_for;
use super::Viewer;
use crate::color;
use crate::methods::{MethodConfig, METHODS};
use crate::point_streams::upload::DEFAULT_CHUNK_BYTES;
use crate::post::PostOptions;

/// What the viewer draws with now.
pub(super) struct Drawing {
    /// The method's index in `METHODS` (`M`, `N`).
    pub method: usize,
    /// Points keep their colors (`C`).
    pub use_color: bool,
    /// The post-processing shown now (`E` switches EDL on and off).
    pub post: PostOptions,
}

impl Viewer {
    /// The current method's configuration: the one given at start (with the parameters keys
    /// changed) while it is that method, else its defaults.
    pub(super) fn config(&self) -> MethodConfig {
        let m = &METHODS[self.drawing.method];
        if m.name == self.opts.method.method.name {
            self.opts.method.clone()
        } else {
            MethodConfig {
                method: m,
                params: Default::default(),
            }
        }
    }

    /// The next (`step` 1) or previous method the device, the scene and the cloud support.
    pub(super) fn switch_method(&mut self, step: isize) -> Result<()> {
        let has_faces = self
            .scene
            .uploaded
            .as_ref()
            .is_some_and(|(s, _)| s.indices.is_some());
        let caps = self.ctx.as_ref().map(|c| c.caps.clone());
        // Normals and radii the cloud has or will have (none with `--k 0`).
        let surfels = (self.scene.cloud.normals.is_some() && self.scene.cloud.radii.is_some())
            || self.scene.estimation.is_some();
        for _ in 0..METHODS.len() {
            self.drawing.method =
                (self.drawing.method as isize + step).rem_euclid(METHODS.len() as isize) as usize;
            let m = &METHODS[self.drawing.method];
            let supported = caps.as_ref().is_none_or(|c| m.unsupported(c).is_none());
            // A streamed file has only the nodes in view, and the normal fields when asked.
            let streamable = self.scene.streamed.as_ref().is_none_or(|s| {
                !(m.needs_lod || m.needs_hpr || m.needs_faces)
                    && (!m.needs_normal_field || s.scene.streams.normal_field)
                    && (!m.needs_surfels || s.info.has_normals)
            });
            let surfels = surfels || self.scene.streamed.is_some();
            if supported
                && streamable
                && (!m.needs_faces || has_faces)
                && (!m.needs_surfels || surfels)
            {
                break;
            }
        }
        self.upload_what_the_method_reads()?;
        println!("method {}", METHODS[self.drawing.method].name);
        self.rebuild()
    }

    /// Adds to the uploaded scene what the method reads and the scene was uploaded without
    /// (`GpuScene::complete`): an event, not per frame.
    fn upload_what_the_method_reads(&mut self) -> Result<()> {
        let method = &METHODS[self.drawing.method];
        if method.needs_surfels {
            self.poll_estimation(true)?;
        }
        let (Some(ctx), Some((scene, _))) = (self.ctx.clone(), self.scene.uploaded.as_mut()) else {
            return Ok(());
        };
        scene.complete(
            &ctx,
            &self.scene.cloud,
            &method.upload_options(Default::default()),
        )?;
        Ok(())
    }

    /// For a method with a `show` parameter (the pyramid's), shows the next coarser (`step` 1)
    /// or finer level: -1 is the reconstruction, 0 the raw projection, N level N of the analysis.
    pub(super) fn step_level(&mut self, step: i32) -> Result<()> {
        let mut config = self.config();
        let Some(spec) = config.method.params.iter().find(|p| p.name == "show") else {
            return self.outcome(Ok(format!("{} shows no levels", config.method.name)));
        };
        let level = (config.get("show") + step as f32).clamp(spec.min, spec.max);
        config.params.insert("show".into(), level);
        self.opts.method = config;
        self.rebuild()?;
        let what = match level as i32 {
            -1 => "the reconstruction".to_string(),
            0 => "level 0 as projected".to_string(),
            l => format!("level {l} of the analysis"),
        };
        self.outcome(Ok(format!("showing {what}")))
    }

    /// Colors by the next field of `color::fields`: swaps the uploaded scalar stream (an event,
    /// not per frame) and rebuilds the renderer on the new segment table.
    pub(super) fn cycle_color(&mut self) -> Result<()> {
        if self.scene.streamed.is_some() {
            // Reported, not failed: a scripted tour goes on.
            let e = "V is off for a streamed file: its colour field is chosen when it opens \
                     (--color-by)";
            println!("{}", serde_json::json!({ "error": e }));
            return self.outcome(Ok(e.into()));
        }
        let cloud = &self.scene.cloud;
        let fields = color::fields(cloud);
        let name = color::next_field(&fields, &self.opts.color_by)
            .context("no field to color by")?
            .to_owned();
        let coloring = color::select(cloud, &name, self.orbit.up).map_err(anyhow::Error::msg)?;
        let ctx = self.ctx.clone().context("context")?;
        if let Some((scene, info)) = self.scene.uploaded.as_mut() {
            scene.streams.select_scalar(
                &ctx,
                &self.scene.cloud,
                coloring.scalar,
                DEFAULT_CHUNK_BYTES,
            )?;
            info.coloring = coloring;
        }
        self.hud.legend = legend_for(&self.scene.cloud, &coloring);
        println!("color by {name}");
        self.opts.color_by = name;
        self.rebuild()
    }

    /// Switches eye-dome lighting off, or on with the parameters given at start (else the
    /// defaults), and rebuilds the graph.
    pub(super) fn toggle_edl(&mut self) -> Result<()> {
        self.drawing.post.edl = match self.drawing.post.edl {
            Some(_) => None,
            None => Some(self.opts.post.edl.unwrap_or_default()),
        };
        self.rebuild()
    }

    /// `G`: one light more, from none to nine and round again (`scene::lights::sweep`).
    pub(super) fn cycle_lights(&mut self) -> Result<()> {
        let count = (self.opts.lights.len() as u32 + 1) % 10;
        let radius = self
            .scene
            .uploaded
            .as_ref()
            .map_or(1.0, |(_, info)| info.radius);
        self.opts.lights = crate::scene::lights::sweep(count, radius);
        self.outcome(Ok(format!("lights: {count}")))
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
        if self.scene.streamed.is_some() {
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

    /// Scales a streamed file's point budget by `factor` (at least one node's worth).
    fn scale_budget(&mut self, factor: f64) -> Result<()> {
        let streamed = self
            .scene
            .streamed
            .as_mut()
            .context("the point budget is for streamed files (--stream)")?;
        let budget = ((streamed.point_budget() as f64 * factor) as u64).max(10_000);
        streamed.set_point_budget(budget);
        println!("point budget {budget}");
        self.hud.dirty = true;
        Ok(())
    }
}
