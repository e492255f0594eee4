//! The pyramid with search kernels (Marroquim 2008, ch. 6; `glsl/pyramid/kernel*`):
//! `kernel3`, `kernel5`, `kernel7`, the pyramid point renderer with its synthesis replaced by
//! a k × k search (k a specialization constant: one set of shaders, three variants).
//!
//! * Level 0 exactly as `pyramid` (6.1: "projects the points identically"): the compute
//!   projection with back-face culling and `pyramid/level0.comp` (`kernel.level0`).
//! * `kernel.analysis.L` (6.1), bottom-up over the levels searched only: each splat travels
//!   up to the level l = ⌈log2(D / k)⌉ where the k × k kernel spans it (`kernel_level`) and is
//!   stored there; travelling splats that meet in one texel are merged with ch. 4's occlusion
//!   test and average. Whether a texel is stored or travelling follows from its radius, so
//!   the texel layout is the pyramid's (one image per group: nothing reads back a level that
//!   a later pass rewrites, so the ping-pong pair has no purpose here).
//! * `kernel.interpolate.L` (6.2), level 0 first: every level-0 pixel searches the k × k
//!   texels around its own in level L and adds those stored there whose ellipse contains it
//!   with w = 1 - d, into three RGBA32F accumulators (one pass per level plus one
//!   accumulator read, as in the thesis; here read and written back only where a texel adds,
//!   and an empty texel costs one load).
//! * `kernel.resolve` turns the sums into a texel of level 0 and `kernel.shade` runs
//!   `pyramid/shade.comp` on it.
//!
//! Levels searched (6.2): up to the first level the kernel one level below covers entirely
//! (at most (k + 1) / 2 texels a side; 1024² with 3 × 3: 10 of 11 levels). Splats whose level
//! lies above are stored in that top level. The push constants are the pyramid's with
//! `level_count` = the levels searched.
//!
//! Deviations from the thesis:
//! * D in eq. 6.1 is the projected diameter, not the radius (`reference::kernel_level`).
//! * The interpolation's occlusion test is not spelled out in 6.2 ("the only difference ... is
//!   the weight"): ch. 4's test is applied sequentially in the order of the search (a texel
//!   overlapping the front contribution's depth interval joins it, one behind is dropped, one
//!   in front starts anew), since the levels are separate passes.
//! * d is the elliptical distance (ch. 4's ellipse, 1 on its rim) to the ellipse centre, the
//!   texel centre plus its displacement vector; pixels on or beyond the rim get nothing.
//! * The resolved texel takes the front contribution's depth-interval half range, and the
//!   radius scale defaults to the pyramid's (`RADIUS_SCALE`, the thesis' r_k of ch. 4).

pub mod reference;

use anyhow::Result;
use ash::vk;

use crate::gpu::ImageDesc;
use crate::graph::{Access, Bind, BufferId, GraphBuilder, Stages};
use crate::layout::{
    PyramidParams, BINDING_FRAME, BINDING_KERNEL_ACCUM, BINDING_PYRAMID_LEVEL, BINDING_PYRAMID_OUT,
    PYRAMID_SPEC_KERNEL,
};
use crate::methods::compute::ProjectOptions;
use crate::methods::pyramid::{
    add_level0, add_shade, groups, specialization, Group, Passes, Pyramid,
};
use crate::methods::{BuildContext, Feature, MethodConfig, MethodInfo, ParamSpec};
use reference::searched_levels;

/// The accumulators' format.
const FORMAT_ACCUM: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

const PARAMS: &[ParamSpec] = &[
    crate::methods::pyramid::RADIUS,
    crate::methods::pyramid::COLOR,
    crate::methods::pyramid::CULL,
    ParamSpec {
        name: "show",
        default: -1.0,
        min: -1.0,
        max: 15.0,
        doc: "-1: the reconstruction; N: level N of the analysis magnified (stored and \
              travelling splats), without interpolation",
    },
];

pub const KERNEL3: MethodInfo = MethodInfo {
    params: PARAMS,
    needs_surfels: true,
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    ..MethodInfo::new(
        "kernel3",
        "pyramid with search kernels, 3 x 3: each splat stored in the level where the kernel \
         spans it, every pixel searching every level (000 ch. 6)",
        build3,
    )
};

pub const KERNEL5: MethodInfo = MethodInfo {
    name: "kernel5",
    build: build5,
    summary: "pyramid with search kernels, 5 x 5 (000 ch. 6)",
    ..KERNEL3
};

pub const KERNEL7: MethodInfo = MethodInfo {
    name: "kernel7",
    build: build7,
    summary: "pyramid with search kernels, 7 x 7 (000 ch. 6)",
    ..KERNEL3
};

fn build3(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, 3)
}

fn build5(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, 5)
}

fn build7(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, 7)
}

/// The specialization constants of the kernel shaders.
pub fn kernel_specialization(color: bool, cull: bool, kernel: u32) -> [(u32, u32); 4] {
    let [a, b, c] = specialization(color, cull, false);
    [a, b, c, (PYRAMID_SPEC_KERNEL, kernel)]
}

/// A pyramid over the levels a `kernel` × `kernel` search needs, its accumulators and the
/// passes that reconstruct its level 0; usable on any graph (the tests feed it synthetic
/// level-0 texels).
pub struct KernelPyramid {
    pub pyramid: Pyramid,
    pub kernel: u32,
    /// The interpolation's accumulators (C only with colors).
    accum: Group,
    spec: [(u32, u32); 4],
}

impl KernelPyramid {
    /// Declares the images of a `width` x `height` kernel pyramid named `name`.
    pub fn new(
        graph: &mut GraphBuilder,
        name: &str,
        (width, height): (u32, u32),
        kernel: u32,
        color: bool,
    ) -> Self {
        let levels = searched_levels(width, height, kernel);
        let pyramid = Pyramid::with_levels(graph, name, (width, height), color, true, levels);
        let desc = ImageDesc {
            format: FORMAT_ACCUM,
            width,
            height,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::empty(),
        };
        let accum = Group {
            a: graph.image(&format!("{name}.accum.a"), desc),
            b: graph.image(&format!("{name}.accum.b"), desc),
            c: color.then(|| graph.image(&format!("{name}.accum.c"), desc)),
        };
        Self {
            pyramid,
            kernel,
            accum,
            spec: kernel_specialization(color, false, kernel),
        }
    }

    /// The group holding level 0 (the projection's target, then the result).
    pub fn level0(&self) -> Group {
        self.pyramid.holder(0)
    }

    /// The push constants of every pass.
    pub fn params(&self, radius_scale: f32) -> PyramidParams {
        PyramidParams {
            level: 0,
            level_count: self.pyramid.levels,
            radius_scale,
            falloff: 0.0,
        }
    }

    /// Declares the analysis passes `kernel.analysis.L` of levels 1..=`top`.
    pub fn add_analysis(
        &self,
        graph: &mut GraphBuilder,
        frame: BufferId,
        params: PyramidParams,
        top: u32,
    ) {
        let analysis = Passes {
            shader: "kernel/analysis.comp",
            spec: &self.spec,
            prefix: "kernel",
        };
        self.pyramid
            .add_analysis_with(graph, frame, params, top, analysis);
    }

    /// Declares the interpolation passes of every level searched and the resolve into level 0
    /// (after a full analysis); returns the group holding the result.
    pub fn add_interpolation(
        &self,
        graph: &mut GraphBuilder,
        frame: BufferId,
        params: PyramidParams,
    ) -> Group {
        let compute = Stages::Compute;
        let (width, height) = (self.pyramid.width, self.pyramid.height);
        let source = self.level0();
        let interpolate_binds = |level: u32| {
            // The first pass starts the sums (its statically present read is dead code).
            let sums = if level == 0 {
                Access::StorageWrite(compute)
            } else {
                Access::StorageReadWrite(compute)
            };
            let mut binds = vec![Bind::constants(BINDING_FRAME, frame)];
            binds.extend(source.binds(BINDING_PYRAMID_LEVEL, level, Access::StorageRead(compute)));
            binds.extend(self.accum.binds(BINDING_KERNEL_ACCUM, 0, sums));
            binds
        };
        for level in 0..self.pyramid.levels {
            graph
                .compute(
                    &format!("kernel.interpolate.{level}"),
                    "kernel/interpolate.comp",
                    &interpolate_binds(level),
                )
                .spec(&self.spec)
                .push(&PyramidParams { level, ..params })
                .dispatch_grid(groups(width, height, 0));
        }

        let mut binds = vec![Bind::constants(BINDING_FRAME, frame)];
        binds.extend(
            self.accum
                .binds(BINDING_KERNEL_ACCUM, 0, Access::StorageRead(compute)),
        );
        binds.extend(source.binds(BINDING_PYRAMID_OUT, 0, Access::StorageWrite(compute)));
        graph
            .compute("kernel.resolve", "kernel/resolve.comp", &binds)
            .spec(&self.spec)
            .push(&PyramidParams { level: 0, ..params })
            .dispatch_grid(groups(width, height, 0));
        source
    }
}

/// The parameters of `kernel3`, `kernel5` and `kernel7` (`PARAMS`).
struct Settings {
    radius: f32,
    color: bool,
    cull: bool,
    show: f32,
}

impl Settings {
    fn of(config: &MethodConfig) -> Self {
        Self {
            radius: config.get("radius"),
            color: config.get("color") >= 0.5,
            cull: config.get("cull") >= 0.5,
            show: config.get("show").round(),
        }
    }
}

fn build(b: &mut BuildContext<'_>, kernel: u32) -> Result<()> {
    let Settings {
        radius,
        color,
        cull,
        show,
    } = Settings::of(b.config);
    let kp = KernelPyramid::new(b.graph, "kernel", (b.width, b.height), kernel, color);
    let params = kp.params(radius);
    let spec = kernel_specialization(color, cull, kernel);
    let options = ProjectOptions {
        cull,
        ..Default::default()
    };
    add_level0(b, "kernel", kp.level0(), &spec, params, options);
    let levels = kp.pyramid.levels;
    let shown = (show >= 0.0).then(|| (show as u32).min(levels - 1));
    kp.add_analysis(b.graph, b.frame, params, shown.unwrap_or(levels - 1));
    let source = match shown {
        Some(level) => (kp.pyramid.holder(level), level),
        None => (kp.add_interpolation(b.graph, b.frame, params), 0),
    };
    add_shade(b, "kernel", source, &spec, params);
    Ok(())
}
