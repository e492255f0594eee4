//! The post-processing stage: passes that run after any method's graph, on its standard
//! targets, before present and readback.
//!
//! * Eye-dome lighting (Boucheny 2009, as Potree and CloudCompare ship it): depth-based
//!   shading that needs no normals (`glsl/post/post.comp` states the formula).
//! * The background: pixels no method covered (depth 0) get an opaque color, so PNGs are
//!   opaque unless `transparent` is asked for.
//!
//! Both are one compute pass reading the method's color and depth and writing a new color
//! image (specialization constants select EDL and the background), named `post.edl` when it
//! shades and `post.background` when it only composites. With neither requested no pass is
//! added and the method's color is presented and read back as it is.

use ash::vk;
use glam::Vec4;

use crate::frame::Frame;
use crate::gpu::ImageDesc;
use crate::graph::{Access, Bind, GraphBuilder, ImageId, Stages};
use crate::layout::{
    PostParams, BINDING_INPUT0, BINDING_INPUT1, BINDING_OUTPUT0, POST_GROUP, POST_SPEC_BACKGROUND,
    POST_SPEC_EDL,
};
use crate::methods::{Targets, COLOR_FORMAT};
pub use crate::scene::appearance::{
    Background, Edl, DEFAULT_RADIUS, DEFAULT_STRENGTH, EDL_DEFAULT_ARG, MAX_STRENGTH, RADIUS_RANGE,
};

/// The post-processing a renderer adds after its method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PostOptions {
    /// Eye-dome lighting, off when `None`.
    pub edl: Option<Edl>,
    pub background: Background,
}

impl PostOptions {
    /// No post pass: the method's targets as they are (what the evaluation scores).
    pub const NONE: PostOptions = PostOptions {
        edl: None,
        background: Background::Transparent,
    };

    /// Whether this adds no pass.
    pub fn is_none(&self) -> bool {
        self.edl.is_none() && self.background == Background::Transparent
    }

    /// What a headless renderer runs on the GPU: the background alone costs a full-screen
    /// pass (12 ms at 1024x1024 on lavapipe), so without EDL it is left to [`composite`] on
    /// the read-back frame and timed frames carry no post pass; with EDL one pass does both.
    pub fn for_readback(&self) -> PostOptions {
        if self.edl.is_some() {
            *self
        } else {
            PostOptions::NONE
        }
    }

    /// What a window runs on the GPU: its swapchain is opaque, so empty pixels already show
    /// black and a black (or transparent) background needs no pass without EDL.
    pub fn for_display(&self) -> PostOptions {
        let black = matches!(
            self.background,
            Background::Transparent | Background::Color([0, 0, 0])
        );
        if self.edl.is_none() && black {
            PostOptions::NONE
        } else {
            *self
        }
    }

    /// The push constants of the post pass.
    pub fn params(&self) -> PostParams {
        let o = self
            .edl
            .unwrap_or_default()
            .offsets()
            .map(|[x, y]| [x as f32, y as f32]);
        let pair = |i: usize| Vec4::new(o[i][0], o[i][1], o[i + 1][0], o[i + 1][1]);
        let background = match self.background {
            Background::Transparent => Vec4::ZERO,
            Background::Color(rgb) => {
                let c = rgb.map(|v| f32::from(v) / 255.0);
                Vec4::new(c[0], c[1], c[2], 1.0)
            }
        };
        PostParams {
            offsets01: pair(0),
            offsets23: pair(2),
            offsets45: pair(4),
            offsets67: pair(6),
            background,
            strength: self.edl.map_or(0.0, |e| e.strength),
            ..PostParams::default()
        }
    }
}

/// Composites `background` under a read-back frame on the host, as the post pass does on the
/// GPU: empty pixels (no finite depth) take the background, covered ones become opaque. Does
/// nothing for `Transparent`; applying it twice changes nothing.
pub fn composite(frame: &mut Frame, background: Background) {
    let Background::Color([r, g, b]) = background else {
        return;
    };
    for (c, d) in frame.color.iter_mut().zip(&frame.depth) {
        *c = if d.is_finite() {
            [c[0], c[1], c[2], 255]
        } else {
            [r, g, b, 255]
        };
    }
}

/// Adds the post pass of `options` reading `targets` and returns the color image to present
/// and read back: `targets.color` itself when `options` adds no pass.
pub fn build(
    g: &mut GraphBuilder,
    targets: Targets,
    width: u32,
    height: u32,
    options: &PostOptions,
) -> ImageId {
    if options.is_none() {
        return targets.color;
    }
    let edl = options.edl.is_some();
    let background = options.background != Background::Transparent;
    // Usage flags follow from the accesses (storage here, transfer for present and readback).
    let color = g.image(
        "post.color",
        ImageDesc {
            format: COLOR_FORMAT,
            width,
            height,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::empty(),
        },
    );
    let read = Access::StorageRead(Stages::Compute);
    let binds = [
        Bind::image(BINDING_INPUT0, targets.color, 0, read),
        Bind::image(BINDING_INPUT1, targets.depth, 0, read),
        Bind::image(
            BINDING_OUTPUT0,
            color,
            0,
            Access::StorageWrite(Stages::Compute),
        ),
    ];
    let name = if edl { "post.edl" } else { "post.background" };
    g.compute(name, "post/post.comp", &binds)
        .spec(&[
            (POST_SPEC_EDL, u32::from(edl)),
            (POST_SPEC_BACKGROUND, u32::from(background)),
        ])
        .push(&options.params())
        .dispatch_grid((width.div_ceil(POST_GROUP), height.div_ceil(POST_GROUP)));
    color
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn only_requested_post_processing_adds_a_pass() {
        assert!(PostOptions::NONE.is_none());
        let opaque = PostOptions {
            edl: None,
            background: Background::DEFAULT,
        };
        assert!(!opaque.is_none());
        let p = PostOptions {
            edl: Some(Edl::new(2.0, 1.4).expect("valid")),
            background: Background::Color([255, 0, 51]),
        }
        .params();
        assert_eq!(p.offsets01, Vec4::new(1.0, 0.0, 1.0, 1.0));
        assert_eq!(p.offsets67, Vec4::new(0.0, -1.0, 1.0, -1.0));
        assert_eq!(p.background, Vec4::new(1.0, 0.0, 0.2, 1.0));
        assert_eq!(p.strength, 2.0);
    }
}
