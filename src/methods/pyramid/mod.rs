//! The pyramid point renderer (Marroquim 2008, ch. 4; `glsl/pyramid/`): points projected to
//! one pixel each, holes filled by an analysis/synthesis image pyramid of elliptical splats,
//! lit once per pixel.
//!
//! * Level 0 (000 4.2.1): the compute projection (`compute::project` with back-face culling:
//!   nearest point per pixel by 64-bit `atomicMin`), then `pyramid.level0` fetches the
//!   winners' attributes into the texel groups of Fig. 4.14: A = (normal, projected radius),
//!   B = (depth, depth-interval half range, displacement vector), C = (albedo, primitive id).
//!   `projection=1` draws them with the hardware point pipeline into three render targets
//!   instead (`pyramid.project-hw`), the thesis' own path, for measuring the two side by side.
//! * Analysis (4.2.2): one compute pass per level, bottom-up (`pyramid.analysis.L`).
//! * Synthesis (4.2.2): one compute pass per level, top-down (`pyramid.synthesis.L`).
//! * `pyramid.shade`: deferred Phong on the reconstructed normals with every light (4.2.3).
//!
//! Layouts (4.2.4, `layout` parameter): the thesis' ping-pong pair (0): each group lives in two
//! images with full mip chains, analysis writes level l into image l mod 2 reading level l - 1
//! from the other, a copy pass (`pyramid.copy`) gives the image that synthesis starts from the
//! top level it lacks, and synthesis of level l reads levels l + 1 and l from image l mod 2
//! and writes level l into the other, so no pass reads the image level it writes. Or a single
//! image per group (1), which Vulkan allows because barriers and views are per mip: analysis
//! reads level l - 1 and writes level l of the same image, synthesis updates level l in place
//! (each texel reads and writes only itself there); no copy.
//!
//! Radii and displacement vectors are kept in level-0 pixels at every level (the thesis keeps
//! them per level; the ellipse tests are the same). Levels halve with the Vulkan mip rule
//! (rounding down); where a level has an odd size its last parent row/column averages three
//! children. Deviation: the thesis gives no Gaussian width for the synthesis weights; here
//! w = exp(-falloff d²) with d the elliptical distance (1 on the rim) and `falloff` = 2 by
//! default, the splatting family's kernel.
//!
//! `kernel` is ch. 6's variant (`kernel3`, `kernel5`, `kernel7`): the same level 0, texels and
//! shading, with each splat stored in one level and a k × k search in place of synthesis.

pub mod reference;

use crate::layout::BINDING_BATCHES;
use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;

use super::compute::{project, ProjectOptions};
use super::{BuildContext, Feature, MethodInfo, ParamSpec, ZBUFFER_FORMAT};
use crate::gpu::{Blend, Buffer, GraphicsDesc, ImageDesc};
use crate::graph::{Access, Bind, BufferId, BufferRange, GraphBuilder, ImageId, Load, Stages};
use crate::layout::{
    PyramidParams, BINDING_FACE_VERTICES, BINDING_FRAME, BINDING_LOD_LIST, BINDING_LOD_VERTICES,
    BINDING_PYRAMID_LEVEL, BINDING_PYRAMID_OUT, BINDING_PYRAMID_PARENT, BINDING_SEGMENTS,
    BINDING_VISIBILITY, PYRAMID_GROUP, PYRAMID_SPEC_COLOR, PYRAMID_SPEC_CULL, PYRAMID_SPEC_HYBRID,
    PYRAMID_SPEC_TUBE,
};
use crate::methods::lod::gpu::{add_select, LodInputs};

/// Default scale of the per-point radii. The thesis sizes a splat by r_k, the distance to its
/// k-th nearest neighbour (4.2.1, k = 10); the clouds here carry the density spacing
/// r_k sqrt(pi / k) (`scene::preprocess`), so sqrt(10 / pi) restores r_k. Smaller ellipses
/// leave holes a parent's averaged ellipse no longer covers (on the dragon at 512², 1.0 leaves
/// 7.6 % of the surface open, 1.78 under 0.2 %).
pub const RADIUS_SCALE: f32 = 1.78;

/// Group A: normal.xyz, projected radius (level-0 pixels).
pub const FORMAT_A: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// Group B: linear depth, depth-interval half range, displacement vector (level-0 pixels).
pub const FORMAT_B: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
/// Group C: linear albedo, primitive id.
pub const FORMAT_C: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

/// Parameters the pyramid methods and the kernel pyramid (`kernel.rs`) share.
pub(crate) const RADIUS: ParamSpec = ParamSpec {
    name: "radius",
    default: RADIUS_SCALE,
    min: 0.05,
    max: 20.0,
    doc: "scale of the per-point radii (default: the thesis' r_k for k = 10)",
};
pub(crate) const COLOR: ParamSpec = ParamSpec {
    name: "color",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "1: interpolate the albedo group; 0: normals only, lit in the base color",
};
pub(crate) const CULL: ParamSpec = ParamSpec {
    name: "cull",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "back-face culling by normal in the projection",
};

const PROJECTION: ParamSpec = ParamSpec {
    name: "projection",
    default: 0.0,
    min: 0.0,
    max: 1.0,
    doc: "level 0 by 0: the compute projection (atomicMin), 1: the hardware point pipeline",
};
const LAYOUT: ParamSpec = ParamSpec {
    name: "layout",
    default: 0.0,
    min: 0.0,
    max: 1.0,
    doc: "0: ping-pong image pairs with a copy pass (the thesis), 1: one image per group \
          with per-mip barriers",
};
const FALLOFF: ParamSpec = ParamSpec {
    name: "falloff",
    default: 2.0,
    min: 0.0,
    max: 16.0,
    doc: "synthesis weight exp(-falloff d²), d the elliptical distance to a centre",
};
const SHOW: ParamSpec = ParamSpec {
    name: "show",
    default: -1.0,
    min: -1.0,
    max: 15.0,
    doc: "-1: the reconstruction; N: level N of the analysis magnified, without synthesis \
          (0: the raw projection)",
};

/// The parameters of `pyramid` and `pyramid-hybrid`.
const PARAMS: &[ParamSpec] = &[RADIUS, PROJECTION, LAYOUT, COLOR, CULL, FALLOFF, SHOW];

/// The parameters of `pyramid-lod`: the pyramid's, less the projection (the selection's list is
/// drawn by the hardware point pipeline), and the level of detail's threshold ε.
const LOD_PARAMS: &[ParamSpec] = &[
    RADIUS,
    LAYOUT,
    COLOR,
    CULL,
    FALLOFF,
    SHOW,
    super::lod::EPSILON,
];

pub const INFO: MethodInfo = MethodInfo {
    params: PARAMS,
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "pyramid",
        "pyramid point renderer: one pixel per point, holes filled by an analysis/synthesis \
         pyramid of ellipses, deferred Phong (000 ch. 4)",
        build,
    )
};

pub const HYBRID_INFO: MethodInfo = MethodInfo {
    params: PARAMS,
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "pyramid-hybrid",
        "pyramid point renderer with triangles: faces rasterized into level 0 with radius \
         0, the other points projected beside them (000 5.2)",
        build_hybrid,
    )
};

pub const LOD_INFO: MethodInfo = MethodInfo {
    params: LOD_PARAMS,
    needs_lod: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "pyramid-lod",
        "pyramid point renderer over the level of detail: the splats the object texture's \
         selection chooses projected into level 0 with their colors (000 ch. 7)",
        build_lod,
    )
};

/// Levels of a pyramid over a `width` x `height` base down to 1 x 1.
pub fn level_count(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

/// One set of the three attribute groups, each an image with a mip chain.
#[derive(Clone, Copy, Debug)]
pub struct Group {
    pub a: ImageId,
    pub b: ImageId,
    /// The albedo group (`None` without colors: the shaders' C bindings then alias A, which
    /// they never touch under `COLOR = false`).
    pub c: Option<ImageId>,
}

impl Group {
    pub fn images(&self) -> impl Iterator<Item = ImageId> {
        [Some(self.a), Some(self.b), self.c].into_iter().flatten()
    }

    /// The three storage images of mip `mip` at bindings `base`, `base + 1`, `base + 2`,
    /// accessed with `access`.
    pub fn binds(&self, base: u32, mip: u32, access: Access) -> [Bind; 3] {
        [
            Bind::image(base, self.a, mip, access),
            Bind::image(base + 1, self.b, mip, access),
            Bind::image(base + 2, self.c.unwrap_or(self.a), mip, access),
        ]
    }
}

/// Workgroups covering level `level` of a `width` x `height` pyramid.
pub(crate) fn groups(width: u32, height: u32, level: u32) -> (u32, u32) {
    (
        (width >> level).max(1).div_ceil(PYRAMID_GROUP),
        (height >> level).max(1).div_ceil(PYRAMID_GROUP),
    )
}

/// The specialization constants of the pyramid shaders.
pub fn specialization(color: bool, cull: bool, hybrid: bool) -> [(u32, u32); 3] {
    [
        (PYRAMID_SPEC_COLOR, u32::from(color)),
        (PYRAMID_SPEC_CULL, u32::from(cull)),
        (PYRAMID_SPEC_HYBRID, u32::from(hybrid)),
    ]
}

/// A compute shader, its specialization constants and the prefix of its passes' names.
pub(crate) struct Passes<'a> {
    pub(crate) shader: &'a str,
    pub(crate) spec: &'a [(u32, u32)],
    pub(crate) prefix: &'a str,
}

/// A pyramid's images and the passes that reconstruct its level 0; usable on any graph (the
/// tests feed it synthetic level-0 texels).
pub struct Pyramid {
    /// The two image sets of the ping-pong layout (the same set twice for one image).
    pair: [Group; 2],
    pub levels: u32,
    pub width: u32,
    pub height: u32,
    pub single: bool,
    pub color: bool,
}

impl Pyramid {
    /// Declares the images of a `width` x `height` pyramid named `name`.
    pub fn new(
        graph: &mut GraphBuilder,
        name: &str,
        (width, height): (u32, u32),
        color: bool,
        single: bool,
    ) -> Self {
        let levels = level_count(width, height);
        Self::with_levels(graph, name, (width, height), color, single, levels)
    }

    /// `new` with only the first `levels` levels (the kernel pyramid's searched levels).
    pub fn with_levels(
        graph: &mut GraphBuilder,
        name: &str,
        (width, height): (u32, u32),
        color: bool,
        single: bool,
        levels: u32,
    ) -> Self {
        // Usage flags follow from the declared accesses.
        let desc = |format| ImageDesc {
            format,
            width,
            height,
            mip_levels: levels,
            usage: vk::ImageUsageFlags::empty(),
        };
        let mut group = |set: &str| Group {
            a: graph.image(&format!("{name}.{set}.a"), desc(FORMAT_A)),
            b: graph.image(&format!("{name}.{set}.b"), desc(FORMAT_B)),
            c: color.then(|| graph.image(&format!("{name}.{set}.c"), desc(FORMAT_C))),
        };
        let first = group("t0");
        let pair = [first, if single { first } else { group("t1") }];
        Self {
            pair,
            levels,
            width,
            height,
            single,
            color,
        }
    }

    /// The group analysis writes level `level` into (level 0: the projection's target).
    pub fn holder(&self, level: u32) -> Group {
        self.pair[(level % 2) as usize]
    }

    fn groups(&self, level: u32) -> (u32, u32) {
        groups(self.width, self.height, level)
    }

    /// Declares the analysis passes of levels 1..=`top`, bottom-up.
    pub fn add_analysis(
        &self,
        graph: &mut GraphBuilder,
        frame: BufferId,
        params: PyramidParams,
        top: u32,
    ) {
        let spec = specialization(self.color, false, false);
        let analysis = Passes {
            shader: "pyramid/analysis.comp",
            spec: &spec,
            prefix: "pyramid",
        };
        self.add_analysis_with(graph, frame, params, top, analysis);
    }

    /// The analysis passes `{prefix}.analysis.L` of levels 1..=`top`.
    pub(crate) fn add_analysis_with(
        &self,
        graph: &mut GraphBuilder,
        frame: BufferId,
        params: PyramidParams,
        top: u32,
        passes: Passes<'_>,
    ) {
        let compute = Stages::Compute;
        let binds = |level: u32| {
            let (src, dst) = (self.holder(level - 1), self.holder(level));
            let mut binds = vec![Bind::constants(BINDING_FRAME, frame)];
            binds.extend(src.binds(
                BINDING_PYRAMID_LEVEL,
                level - 1,
                Access::StorageRead(compute),
            ));
            binds.extend(dst.binds(BINDING_PYRAMID_OUT, level, Access::StorageWrite(compute)));
            binds
        };
        let prefix = passes.prefix;
        for level in 1..=top.min(self.levels - 1) {
            graph
                .compute(
                    &format!("{prefix}.analysis.{level}"),
                    passes.shader,
                    &binds(level),
                )
                .spec(passes.spec)
                .push(&PyramidParams { level, ..params })
                .dispatch_grid(self.groups(level));
        }
    }

    /// Declares the copy (ping-pong layout) and synthesis passes after a full analysis;
    /// returns the group holding the reconstructed level 0.
    pub fn add_synthesis(
        &self,
        graph: &mut GraphBuilder,
        frame: BufferId,
        params: PyramidParams,
    ) -> Group {
        let compute = Stages::Compute;
        if self.levels < 2 {
            return self.holder(0);
        }
        let binds = |level: u32| {
            let read = self.holder(level);
            let write = self.holder(level + 1 - u32::from(self.single));
            let (input, output) = if self.single {
                // One image set: level `level` is read and written in place.
                (
                    Access::StorageReadWrite(compute),
                    Access::StorageReadWrite(compute),
                )
            } else {
                (Access::StorageRead(compute), Access::StorageWrite(compute))
            };
            let mut binds = vec![Bind::constants(BINDING_FRAME, frame)];
            binds.extend(read.binds(
                BINDING_PYRAMID_PARENT,
                level + 1,
                Access::StorageRead(compute),
            ));
            binds.extend(read.binds(BINDING_PYRAMID_LEVEL, level, input));
            binds.extend(write.binds(BINDING_PYRAMID_OUT, level, output));
            (binds, write)
        };
        // Synthesis of level l reads image l mod 2; the first one (l = levels - 2) needs the
        // top level, which analysis wrote into the other image: the copy pass (Fig. 4.13).
        let top = self.levels - 1;
        if !self.single {
            let (src, dst) = (self.holder(top), self.holder(top + 1));
            let mut pass = graph.pass("pyramid.copy");
            for (s, d) in src.images().zip(dst.images()) {
                pass = pass.image_mips(s, top, 1, Access::TransferSrc).image_mips(
                    d,
                    top,
                    1,
                    Access::TransferDst,
                );
            }
            pass.record(move |ctx| {
                for (s, d) in src.images().zip(dst.images()) {
                    ctx.copy_mip(s, d, top);
                }
            });
        }
        let mut result = self.holder(0);
        for level in (0..top).rev() {
            let (binds, write) = binds(level);
            graph
                .compute(
                    &format!("pyramid.synthesis.{level}"),
                    "pyramid/synthesis.comp",
                    &binds,
                )
                .spec(&specialization(self.color, false, false))
                .push(&PyramidParams { level, ..params })
                .dispatch_grid(self.groups(level));
            result = write;
        }
        result
    }
}

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    let settings = Settings::of(b.config);
    build_with(b, settings, Level0::Points)
}

fn build_hybrid(b: &mut BuildContext<'_>) -> Result<()> {
    let settings = Settings::of(b.config);
    build_with(b, settings, Level0::Hybrid)
}

/// `pyramid-lod`: the object texture's selection for ε (`lod::gpu::add_select`, without a
/// point budget), its list drawn into level 0, then the pyramid as usual. The samples per
/// level are the selection's counters.
fn build_lod(b: &mut BuildContext<'_>) -> Result<()> {
    let Some(lod) = b.scene.lod.clone() else {
        bail!("method 'pyramid-lod' needs the scene's object texture (UploadOptions::lod)");
    };
    let inputs = LodInputs::import(b.graph, b.frame, &lod);
    let epsilon = b.config.get("epsilon");
    let selection = add_select(
        b.graph,
        "pyramid-lod",
        (b.frame, inputs.patches),
        &lod,
        (epsilon, 0),
    )?;
    b.samples = Some(selection.samples(&lod));
    let level0 = Level0::Lod {
        vertices: inputs.vertices,
        list: selection.list,
        counters: selection.counters,
    };
    build_with(b, Settings::of(b.config), level0)
}

/// The pyramid's parameters (`PARAMS`), read from a `pyramid` configuration or defaults.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    color: bool,
    hardware: bool,
    single: bool,
    cull: bool,
    show: f32,
    radius: f32,
    falloff: f32,
}

impl Settings {
    fn of(config: &super::MethodConfig) -> Self {
        Self {
            color: config.get("color") >= 0.5,
            hardware: config.get("projection") >= 0.5,
            single: config.get("layout") >= 0.5,
            cull: config.get("cull") >= 0.5,
            show: config.get("show").round(),
            radius: config.get("radius"),
            falloff: config.get("falloff"),
        }
    }

    /// Every parameter at its default.
    pub fn defaults() -> Self {
        Self::of(&super::MethodConfig {
            method: &INFO,
            params: Default::default(),
        })
    }
}

/// What level 0 is made of.
enum Level0 {
    /// Every point (`pyramid`).
    Points,
    /// The scene's faces and lines, then the points they do not use (`pyramid-hybrid`).
    Hybrid,
    /// Triangles an earlier pass appended to `indices` (drawn by the indexed indirect draw at
    /// `args`), then the points not set in `skip` (`hpr-mesh:pyramid=1`: HPR's reconstruction
    /// and its visible points).
    Indirect {
        indices: BufferId,
        args: BufferId,
        offset: u64,
        skip: BufferId,
    },
    /// The object-texture vertices in `list` (`pyramid-lod`), drawn by the indirect draw at the
    /// start of `counters`.
    Lod {
        vertices: BufferId,
        list: BufferId,
        counters: BufferId,
    },
}

/// The pyramid over HPR's reconstruction (`hpr-mesh:pyramid=1`): the triangles at `indices`
/// (indexed indirect draw at `args` + `offset`) rasterized into level 0, the points not set
/// in `skip` (the hidden ones) projected beside them, then analysis, synthesis and shading
/// with the pyramid's default parameters.
pub(crate) fn build_over_triangles(
    b: &mut BuildContext<'_>,
    indices: BufferId,
    (args, offset): (BufferId, u64),
    skip: BufferId,
) -> Result<()> {
    build_with(
        b,
        Settings::defaults(),
        Level0::Indirect {
            indices,
            args,
            offset,
            skip,
        },
    )
}

fn build_with(b: &mut BuildContext<'_>, settings: Settings, level0: Level0) -> Result<()> {
    let hybrid = matches!(level0, Level0::Hybrid | Level0::Indirect { .. });
    // A tube's texel needs its primitive id, kept in the albedo group.
    let color = settings.color || (hybrid && b.scene.tubes.is_some());
    let Settings {
        hardware,
        single,
        cull,
        show,
        ..
    } = settings;
    let pyramid = Pyramid::new(b.graph, "pyramid", (b.width, b.height), color, single);
    let params = PyramidParams {
        level: 0,
        level_count: pyramid.levels,
        radius_scale: settings.radius,
        falloff: settings.falloff,
    };
    // Hybrid scenes: faces and lines are drawn as such, the other points as points.
    let scene = b.scene;
    let import = |g: &mut GraphBuilder, name: &str, buffer: &Option<(Arc<Buffer>, u32)>| {
        buffer
            .as_ref()
            .map(|(buffer, count)| (g.import_buffer(name, buffer.clone()), *count))
    };
    let (mask, triangles, ribbons, tubes) = match (&level0, &scene.face_vertices) {
        (Level0::Hybrid, Some(mask)) => (
            Some(b.graph.import_buffer("face-vertices", mask.clone())),
            b.indices.map(|i| (i, scene.index_count)),
            import(b.graph, "ribbons", &scene.ribbons),
            import(b.graph, "tubes", &scene.tubes),
        ),
        _ => (None, None, None, None),
    };
    let lod_list = match level0 {
        Level0::Lod {
            vertices,
            list,
            counters,
        } => Some(Primitives::LodList(vertices, list, counters)),
        _ => None,
    };
    let (mask, indirect) = match level0 {
        Level0::Indirect {
            indices,
            args,
            offset,
            skip,
        } => (
            Some(skip),
            Some(Primitives::IndirectTriangles(indices, args, offset)),
        ),
        _ => (mask, None),
    };
    let drawn = [
        indirect,
        triangles.map(|(i, n)| Primitives::Triangles(i, n)),
        ribbons.map(|(i, n)| Primitives::Ribbons(i, n)),
        tubes.map(|(i, n)| Primitives::Tubes(i, n)),
    ];
    let spec = specialization(color, cull, mask.is_some());
    let frame = b.frame;
    let first = pyramid.holder(0);

    // Level 0: triangles and lines first (hybrid), then the points where they are nearer.
    let rasterized = drawn.iter().any(Option::is_some);
    let hardware = hardware || lod_list.is_some();
    let targets = (hardware || rasterized).then(|| raster_targets(b, first));
    if let Some(targets) = targets {
        for (k, primitives) in drawn.into_iter().flatten().enumerate() {
            rasterize(b, targets, &spec, params, primitives, k == 0);
        }
    }
    if let (true, Some(targets)) = (hardware, targets) {
        let points = lod_list.unwrap_or(Primitives::Points(mask));
        rasterize(b, targets, &spec, params, points, !rasterized);
    } else {
        let options = ProjectOptions {
            cull,
            skip: mask,
            ..Default::default()
        };
        add_level0(b, "pyramid", first, &spec, params, options);
    }

    // Analysis and synthesis, or the level shown without synthesis.
    let shown = (show >= 0.0).then(|| (show as u32).min(pyramid.levels - 1));
    let top = shown.unwrap_or(pyramid.levels - 1);
    pyramid.add_analysis(b.graph, frame, params, top);
    let (source, level) = match shown {
        Some(level) => (pyramid.holder(level), level),
        None => (pyramid.add_synthesis(b.graph, frame, params), 0),
    };
    add_shade(b, "pyramid", (source, level), &spec, params);
    Ok(())
}

/// Level 0 from the compute projection (000 4.2.1): `compute::project` with `options`, then
/// `{prefix}.level0` writing the winners' texels into level 0 of `first` (over what a raster
/// pass drew there, in hybrid scenes).
pub(crate) fn add_level0(
    b: &mut BuildContext<'_>,
    prefix: &str,
    first: Group,
    spec: &[(u32, u32)],
    params: PyramidParams,
    options: ProjectOptions,
) {
    let compute = Stages::Compute;
    let projection = project(b, prefix, options);
    // Level 0 is read (with triangles or lines they are there; without, the shader's
    // statically present read is dead code) and written in place.
    let in_place = Access::StorageReadWrite(compute);
    let mut binds = vec![
        Bind::constants(BINDING_FRAME, b.frame),
        Bind::reads(BINDING_SEGMENTS, b.segments),
        Bind::reads(BINDING_VISIBILITY, projection.visibility),
    ];
    binds.extend(first.binds(BINDING_PYRAMID_LEVEL, 0, in_place));
    binds.extend(first.binds(BINDING_PYRAMID_OUT, 0, in_place));
    b.graph
        .compute(&format!("{prefix}.level0"), "pyramid/level0.comp", &binds)
        .spec(spec)
        .push(&params)
        .dispatch_grid(groups(b.width, b.height, 0));
}

/// `{prefix}.shade`: deferred shading (000 4.2.3) of level `level` of `source` (magnified
/// when above 0) into the standard targets.
pub(crate) fn add_shade(
    b: &mut BuildContext<'_>,
    prefix: &str,
    (source, level): (Group, u32),
    spec: &[(u32, u32)],
    params: PyramidParams,
) {
    let mut binds = vec![Bind::constants(BINDING_FRAME, b.frame)];
    binds.extend(source.binds(
        BINDING_PYRAMID_LEVEL,
        level,
        Access::StorageRead(Stages::Compute),
    ));
    binds.extend(b.targets.compute_writes());
    b.graph
        .compute(&format!("{prefix}.shade"), "pyramid/shade.comp", &binds)
        .spec(spec)
        .push(&PyramidParams { level, ..params })
        .dispatch_grid(groups(b.width, b.height, 0));
}

/// Level 0 as render targets: the three groups' first level (an albedo target nothing reads
/// without colors: the fragment shader always writes it) and a depth buffer.
#[derive(Clone, Copy)]
struct RasterTargets {
    a: ImageId,
    b: ImageId,
    c: ImageId,
    zbuffer: ImageId,
}

fn raster_targets(b: &mut BuildContext<'_>, level0: Group) -> RasterTargets {
    let desc = |format, usage| ImageDesc {
        format,
        width: b.width,
        height: b.height,
        mip_levels: 1,
        usage,
    };
    let zbuffer = b.graph.image(
        "pyramid.zbuffer",
        desc(
            ZBUFFER_FORMAT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        ),
    );
    let c = match level0.c {
        Some(c) => c,
        None => b.graph.image(
            "pyramid.raster-albedo",
            desc(FORMAT_C, vk::ImageUsageFlags::empty()),
        ),
    };
    RasterTargets {
        a: level0.a,
        b: level0.b,
        c,
        zbuffer,
    }
}

/// What a raster pass draws into level 0.
#[derive(Clone, Copy)]
enum Primitives {
    /// Every point through the hardware point pipeline (skipping those set in the mask).
    Points(Option<BufferId>),
    /// The mesh's triangles: index buffer and count (radius 0: never expanded, 000 5.2).
    Triangles(BufferId, u32),
    /// Triangles whose count an earlier pass wrote: index buffer, and the indexed indirect
    /// draw's buffer and offset.
    IndirectTriangles(BufferId, BufferId, u64),
    /// Ribbon segments: index buffer and count (000 5.1.1).
    Ribbons(BufferId, u32),
    /// Tube segments: index buffer and count (000 5.1.2).
    Tubes(BufferId, u32),
    /// The object-texture vertices (`GpuLodVertex`) whose indices a selection wrote to a list:
    /// vertices, list, and the counters starting with the list's indirect draw.
    LodList(BufferId, BufferId, BufferId),
}

/// A graphics pass drawing `primitives` into level 0 (`pyramid.project-hw` or
/// `pyramid.triangles`), clearing the targets first or loading what an earlier pass drew.
fn rasterize(
    b: &mut BuildContext<'_>,
    t: RasterTargets,
    spec: &[(u32, u32)],
    params: PyramidParams,
    primitives: Primitives,
    clear: bool,
) {
    let (vertex, topology, name) = match primitives {
        Primitives::Points(_) => (
            "pyramid/project.vert",
            vk::PrimitiveTopology::POINT_LIST,
            "pyramid.project-hw",
        ),
        Primitives::Triangles(..) | Primitives::IndirectTriangles(..) => (
            "pyramid/triangles.vert",
            vk::PrimitiveTopology::TRIANGLE_LIST,
            "pyramid.triangles",
        ),
        Primitives::Ribbons(..) => (
            "pyramid/lines.vert",
            vk::PrimitiveTopology::LINE_LIST,
            "pyramid.ribbons",
        ),
        Primitives::Tubes(..) => (
            "pyramid/lines.vert",
            vk::PrimitiveTopology::LINE_LIST,
            "pyramid.tubes",
        ),
        Primitives::LodList(..) => (
            "pyramid/project_lod.vert",
            vk::PrimitiveTopology::POINT_LIST,
            "pyramid.project-lod",
        ),
    };
    let mut spec = spec.to_vec();
    spec.push((
        PYRAMID_SPEC_TUBE,
        u32::from(matches!(primitives, Primitives::Tubes(..))),
    ));
    // The object texture's list reads its vertices; every other draw the point streams and
    // the mask of points drawn as faces, read only by the hybrid variant of project.vert.
    let vertex_read = Access::StorageRead(Stages::Vertex);
    let mut binds = vec![Bind::buffer(
        BINDING_FRAME,
        b.frame,
        Access::UniformRead(Stages::Graphics),
    )];
    binds.extend(match primitives {
        Primitives::LodList(vertices, list, _) => [
            Bind::buffer(BINDING_LOD_VERTICES, vertices, vertex_read),
            Bind::buffer(BINDING_LOD_LIST, list, vertex_read),
        ],
        Primitives::Points(Some(mask)) => [
            Bind::buffer(BINDING_SEGMENTS, b.segments, vertex_read),
            Bind::buffer(BINDING_FACE_VERTICES, mask, vertex_read),
        ],
        _ => [
            Bind::buffer(BINDING_SEGMENTS, b.segments, vertex_read),
            Bind::unused_in(BINDING_FACE_VERTICES, Stages::Vertex),
        ],
    });
    binds.push(match primitives {
        Primitives::Points(_) => Bind::buffer(BINDING_BATCHES, b.batches, vertex_read),
        _ => Bind::unused_in(BINDING_BATCHES, Stages::Vertex),
    });
    let desc = GraphicsDesc {
        shaders: vec![vertex, "pyramid/project.frag"],
        color_formats: vec![FORMAT_A, FORMAT_B, FORMAT_C],
        blends: vec![Blend::Replace; 3],
        depth_format: Some(ZBUFFER_FORMAT),
        depth_test: true,
        depth_write: true,
        depth_compare: vk::CompareOp::GREATER,
        topology,
        specialization: spec,
        ..Default::default()
    };
    let load = if clear {
        Load::Clear([0.0; 4])
    } else {
        Load::Load
    };
    let points = b.scene.draw_points.clone();
    b.graph
        .draw(name, desc, &binds)
        .push(&params)
        .declare(|pass| match primitives {
            Primitives::Points(_) => pass,
            Primitives::LodList(_, _, counters) => {
                pass.buffer_range(counters, BufferRange::new(0, 16), Access::IndirectRead)
            }
            Primitives::Triangles(indices, _)
            | Primitives::Ribbons(indices, _)
            | Primitives::Tubes(indices, _) => pass.buffer(indices, Access::IndexRead),
            Primitives::IndirectTriangles(indices, args, offset) => pass
                .buffer(indices, Access::IndexRead)
                .buffer_range(args, BufferRange::new(offset, 20), Access::IndirectRead),
        })
        .color(t.a, load)
        .color(t.b, load)
        .color(t.c, load)
        .depth(t.zbuffer, load)
        .draw(move |ctx| match primitives {
            Primitives::Points(_) => ctx.draw(points.get(), 1),
            Primitives::Triangles(indices, count)
            | Primitives::Ribbons(indices, count)
            | Primitives::Tubes(indices, count) => ctx.draw_indexed(indices, count),
            Primitives::IndirectTriangles(indices, args, offset) => {
                ctx.draw_indexed_indirect(indices, args, offset, 1, 20)
            }
            Primitives::LodList(_, _, counters) => ctx.draw_indirect(counters, 0, 1, 16),
        });
}
