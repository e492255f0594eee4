//! Hidden point removal on the GPU (003 ch. 4), compute only, and the methods built on it.
//!
//! Passes (the CPU reference is `crate::hpr::approx`, operation for operation):
//! * once per cloud, [`bounding_sphere`]: the centroid by per-workgroup partial sums and one
//!   workgroup adding them, then the radius by a workgroup maximum and a 64-bit-free atomic
//!   maximum of the radius' bits (`glsl/hpr/sphere.comp`), run as its own one-frame graph;
//! * per frame: `hpr.frame` (one thread: the sector frame from the view, √k from the viewport
//!   unless requested, R, the EMPTY grid), clears, `hpr.sector` (one thread per point: flip,
//!   sector, DIST; the sort-free 64-bit `atomicMax` of (DIST, ~index) per sector, or sort keys
//!   and values for the thesis' radix sort by sector and segmented maximum), then propagation:
//!   fixed (`hpr.gather`, one m × m gather from the extremes) or adaptive (`hpr.extract`, then
//!   up to `max_rounds` rounds of a 3 × 3 gather `hpr.round.N` ping-ponging between two
//!   buffers, each followed by `hpr.advance`, which empties the indirect dispatch of every
//!   later round once a round changed nothing); `hpr.visible` clears the extremes' bits in
//!   the hidden-point mask;
//! * `hpr-mesh` adds `hpr.triangulate` (the partial reconstruction, 003 §4.4: triangles
//!   appended to an index list) and draws it with an indexed indirect draw through the
//!   `mesh` method's raster and resolve passes.
//!
//! Converged adaptive rounds leave both ping-pong buffers equal (the last round that ran
//! wrote what it read), so the statically last destination holds the result.

pub mod visible;

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use ash::vk;
use gpu_allocator::MemoryLocation;

use super::compute::{self, ProjectOptions};
use super::{BuildContext, Feature, MethodInfo, ParamSpec};
use crate::gpu::{Buffer, Context};
use crate::gpu_scene::GpuScene;
use crate::graph::{Access, Bind, Binds, BufferId, BufferRange, GraphBuilder, Stages};
use crate::hpr::approx::Propagation;
use crate::layout::{
    FrameBlock, HprFrame, HprParams, BINDING_FRAME, BINDING_HPR_COMPLETE, BINDING_HPR_DST,
    BINDING_HPR_EMPTY, BINDING_HPR_FRAME, BINDING_HPR_KEYS, BINDING_HPR_MASK, BINDING_HPR_MAX,
    BINDING_HPR_PARTIALS, BINDING_HPR_SPHERE, BINDING_HPR_SRC, BINDING_HPR_TRIANGLES,
    BINDING_HPR_VALUES, BINDING_SEGMENTS, HPR_COMPLETE_LEVELS, HPR_GROUP, HPR_SECTOR_ATOMIC,
    HPR_SECTOR_SORT, HPR_SPEC_ADAPTIVE, HPR_SPEC_FROM_MAX, HPR_SPEC_MODE, HPR_SPEC_REACH,
    HPR_SPHERE_CENTRE, HPR_SPHERE_RADIUS, HPR_SPHERE_SUM, RESOLVE_GROUP, RESOLVE_SPEC_HIGH_QUALITY,
};
use crate::methods::common::sort::{add_segmented_max, add_sort, RadixSort};

/// Points per thread of the sphere reduction (`ITEMS` in `glsl/hpr/sphere.comp`).
const SPHERE_ITEMS: u32 = 16;

/// The workgroups covering `threads` threads (folded into rows by `dispatch_groups`).
fn groups(threads: u64) -> u64 {
    threads.div_ceil(u64::from(HPR_GROUP)).max(1)
}

/// How the GPU approximation runs.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// √k of the sector buffers: the largest grid a frame may use.
    pub sqrt_k_max: u32,
    pub params: HprParams,
    pub propagation: Propagation,
    /// The thesis' pipeline: radix sort by sector and a segmented maximum
    /// ([`sort`]); otherwise the sort-free 64-bit `atomicMax` per sector.
    pub sort: bool,
    /// Whether the sector extremes are computed when the complete set decides visibility
    /// (`params.complete_side` > 0): the reconstruction triangulates them, the points alone
    /// skip the sector and propagation passes.
    pub extremes: bool,
}

impl Settings {
    /// A fixed √k × √k grid (buffers of exactly that size), the flipping radius `radius` in
    /// scene units, and `propagation` (its round cap for adaptive propagation).
    pub fn grid(sqrt_k: u32, radius: f64, propagation: Propagation, sort: bool) -> Self {
        Self {
            sqrt_k_max: sqrt_k,
            params: HprParams {
                sqrt_k,
                radius: radius as f32,
                max_rounds: match propagation {
                    Propagation::Adaptive { max_rounds } => max_rounds,
                    Propagation::Fixed(_) => 0,
                },
                max_edge: 10.0,
                ..Default::default()
            },
            propagation,
            sort,
            extremes: true,
        }
    }
}

/// The graph resources of one HPR evaluation.
#[derive(Clone, Copy, Debug)]
pub struct Hpr {
    /// `HprFrame`: the frame, counters and indirect arguments.
    pub state: BufferId,
    /// The final extreme per sector (u32, `HPR_EMPTY` where none), √k_max² entries of which
    /// the frame's √k² are used; `None` where [`Settings::extremes`] skipped them.
    pub extremes: Option<BufferId>,
    /// One bit per point, set for hidden points.
    pub hidden: BufferId,
}

/// The bounding sphere of `scene`'s points (centre xyz, radius bits): a 16-byte device buffer
/// the HPR passes read, reduced once per scene and kept in `HprScene::sphere` when the scene
/// was uploaded with HPR's data.
pub fn bounding_sphere(ctx: &Arc<Context>, scene: &GpuScene) -> Result<Arc<Buffer>> {
    let Some(hpr) = &scene.hpr else {
        return reduce_sphere(ctx, scene);
    };
    let mut cached = hpr
        .sphere
        .lock()
        .map_err(|_| anyhow::anyhow!("the HPR sphere cache was poisoned"))?;
    if let Some(sphere) = cached.as_ref() {
        return Ok(sphere.clone());
    }
    let sphere = reduce_sphere(ctx, scene)?;
    *cached = Some(sphere.clone());
    Ok(sphere)
}

/// The bounding sphere of `scene`'s points by parallel reduction in a one-frame graph.
fn reduce_sphere(ctx: &Arc<Context>, scene: &GpuScene) -> Result<Arc<Buffer>> {
    let n = scene.point_count;
    if n == 0 {
        bail!("hidden point removal needs at least one point");
    }
    let mut block: FrameBlock = bytemuck::Zeroable::zeroed();
    block.u.point_count = n;
    block.u.segment_points = scene.streams.segment_points;
    let frame_buffer = Arc::new(Buffer::with_data(
        ctx,
        "hpr.sphere.frame",
        bytemuck::bytes_of(&block),
        vk::BufferUsageFlags::STORAGE_BUFFER,
    )?);
    let sphere = Arc::new(Buffer::new(
        ctx,
        "hpr.sphere",
        16,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::GpuOnly,
    )?);
    let per_group = u64::from(HPR_GROUP * SPHERE_ITEMS);
    let partial_count = u64::from(n).div_ceil(per_group) as u32;
    let mut g = GraphBuilder::new();
    let frame = g.import_buffer("frame", frame_buffer);
    let segments = g.import_buffer("stream.segments", scene.streams.table.clone());
    let sphere_id = g.import_buffer("hpr.sphere", sphere.clone());
    let partials = g.buffer(
        "hpr.sphere.partials",
        u64::from(partial_count) * 16,
        vk::BufferUsageFlags::empty(),
    );
    let params = HprParams {
        point_count: n,
        // The centre pass reads the number of partials here.
        sqrt_k: partial_count,
        ..Default::default()
    };
    // Every variant statically references all four bindings (and validation counts every
    // store a shader holds): the writable ones are declared read-write.
    for (name, mode, size) in [
        ("hpr.sphere.sum", HPR_SPHERE_SUM, partial_count),
        ("hpr.sphere.centre", HPR_SPHERE_CENTRE, 1),
        ("hpr.sphere.radius", HPR_SPHERE_RADIUS, partial_count),
    ] {
        let binds = [
            Bind::reads(BINDING_FRAME, frame),
            if mode == HPR_SPHERE_CENTRE {
                Bind::unused(BINDING_SEGMENTS)
            } else {
                Bind::reads(BINDING_SEGMENTS, segments)
            },
            if mode == HPR_SPHERE_SUM {
                Bind::unused(BINDING_HPR_SPHERE)
            } else {
                Bind::updates(BINDING_HPR_SPHERE, sphere_id)
            },
            Bind::updates(BINDING_HPR_PARTIALS, partials),
        ];
        // The shader reads only x.
        g.compute(name, "hpr/sphere.comp", &binds)
            .spec(&[(HPR_SPEC_MODE, mode)])
            .push(&params)
            .dispatch_grid((size, 1));
    }
    g.compile(ctx)?.run_once(ctx)?;
    Ok(sphere)
}

/// What the HPR passes read that the caller owns.
#[derive(Clone, Copy, Debug)]
pub struct Inputs {
    pub frame: BufferId,
    pub segments: BufferId,
    /// The bounding sphere of [`bounding_sphere`].
    pub sphere: BufferId,
}

/// Declares the per-frame HPR passes on `g` (module docs).
pub fn add(
    g: &mut GraphBuilder,
    ctx: &Context,
    point_count: u32,
    inputs: Inputs,
    settings: &Settings,
) -> Result<Hpr> {
    let s_max = settings.sqrt_k_max.max(1);
    let params = HprParams {
        sqrt_k_max: s_max,
        point_count,
        ..settings.params
    };
    let usage = vk::BufferUsageFlags::empty();
    let state = g.buffer("hpr.state", std::mem::size_of::<HprFrame>() as u64, usage);
    let hidden = g.buffer(
        "hpr.hidden",
        u64::from(point_count.div_ceil(32).max(1)) * 4,
        usage,
    );
    let binds = [
        Bind::reads(BINDING_FRAME, inputs.frame),
        Bind::reads(BINDING_HPR_SPHERE, inputs.sphere),
        Bind::writes(BINDING_HPR_FRAME, state),
    ];
    g.compute("hpr.frame", "hpr/frame.comp", &binds)
        .push(&params)
        .dispatch(1);
    g.fill_buffer("hpr.clear.hidden", hidden, BufferRange::WHOLE, u32::MAX);
    let mut hpr = Hpr {
        state,
        extremes: None,
        hidden,
    };
    if params.complete_side == 0 || settings.extremes {
        let sectors = Sectors::add(g, ctx, &params, inputs, state, settings.sort)?;
        let extremes = sectors.propagate(g, &params, inputs, state, settings.propagation);
        hpr.extremes = Some(extremes);
        if params.complete_side == 0 {
            let binds = [
                Bind::updates(BINDING_HPR_FRAME, state),
                Bind::reads(BINDING_HPR_SRC, extremes),
                Bind::updates(BINDING_HPR_MASK, hidden),
            ];
            g.compute("hpr.visible", "hpr/visible.comp", &binds)
                .dispatch(groups(sectors.k_max));
            return Ok(hpr);
        }
    }
    add_complete(
        g,
        ctx,
        &params,
        (inputs.frame, inputs.segments, state),
        hidden,
    )?;
    Ok(hpr)
}

/// The per-sector buffers after `hpr.sector` (and the sort): the 64-bit extremes and the
/// occupied sectors.
#[derive(Clone, Copy)]
struct Sectors {
    k_max: u64,
    max64: BufferId,
    occupied: BufferId,
}

impl Sectors {
    /// Clears the sector buffers and declares `hpr.sector` (one thread per point: flip,
    /// sector, DIST) with the sort-free 64-bit extreme per sector, or the sort's keys and
    /// values and then the radix sort and the segmented maximum.
    fn add(
        g: &mut GraphBuilder,
        ctx: &Context,
        params: &HprParams,
        inputs: Inputs,
        state: BufferId,
        sort: bool,
    ) -> Result<Self> {
        let s_max = u64::from(params.sqrt_k_max);
        let k_max = s_max * s_max;
        let usage = vk::BufferUsageFlags::empty();
        let max64 = g.buffer("hpr.max64", (k_max + 1) * 8, usage);
        let occupied = g.buffer("hpr.empty", k_max * 4, usage);
        g.fill_buffer("hpr.clear.max", max64, BufferRange::WHOLE, 0);
        g.fill_buffer("hpr.clear.empty", occupied, BufferRange::WHOLE, 0);
        let point_count = params.point_count;
        let n = u64::from(point_count);
        // The sort outputs are dead code in the sort-free variant and the 64-bit extremes in
        // the sort variant (statically present).
        let binds = Binds::from([
            Bind::reads(BINDING_FRAME, inputs.frame),
            Bind::reads(BINDING_SEGMENTS, inputs.segments),
            Bind::reads(BINDING_HPR_FRAME, state),
            Bind::unused(BINDING_HPR_MAX),
            Bind::writes(BINDING_HPR_EMPTY, occupied),
            Bind::unused(BINDING_HPR_KEYS),
            Bind::unused(BINDING_HPR_VALUES),
        ]);
        let (mode, binds, sorted) = if sort {
            let radix = RadixSort::new(ctx)?;
            let keys = g.buffer("hpr.keys", n.max(1) * 4, usage);
            let values = g.buffer("hpr.values", n.max(1) * 8, usage);
            let binds = binds
                .with(Bind::writes(BINDING_HPR_KEYS, keys))
                .with(Bind::updates(BINDING_HPR_VALUES, values));
            (HPR_SECTOR_SORT, binds, Some((radix, keys, values)))
        } else {
            let binds = binds.with(Bind::updates(BINDING_HPR_MAX, max64));
            (HPR_SECTOR_ATOMIC, binds, None)
        };
        g.compute("hpr.sector", "hpr/sector.comp", &binds)
            .spec(&[(HPR_SPEC_MODE, mode)])
            .push(params)
            .dispatch(groups(n));
        if let Some((radix, keys, values)) = sorted {
            // Sector ids run to k_max (the sentinel of points at the eye).
            let key_bits = (32 - (k_max as u32).leading_zeros()).max(1);
            let (keys, values) = add_sort(g, &radix, keys, values, point_count, key_bits);
            add_segmented_max(g, keys, values, point_count, max64);
        }
        Ok(Self {
            k_max,
            max64,
            occupied,
        })
    }

    /// Propagation: fixed (`hpr.gather`, one m × m gather from the 64-bit extremes) or
    /// adaptive (`hpr.extract`, then rounds of a 3 × 3 gather ping-ponging between two
    /// buffers, each followed by `hpr.advance`); returns the buffer of the final extremes.
    fn propagate(
        self,
        g: &mut GraphBuilder,
        params: &HprParams,
        inputs: Inputs,
        state: BufferId,
        propagation: Propagation,
    ) -> BufferId {
        let ping = g.buffer(
            "hpr.extremes.a",
            self.k_max * 4,
            vk::BufferUsageFlags::empty(),
        );
        // A pass gathering into `dst` from the 64-bit extremes (`src` None) or from `src`; the
        // adaptive round's change flag is a store in every variant.
        let gather = |g: &mut GraphBuilder,
                      name: &str,
                      (reach, adaptive): (u32, bool),
                      src: Option<BufferId>,
                      dst: BufferId| {
            let binds = [
                Bind::reads(BINDING_FRAME, inputs.frame),
                Bind::reads(BINDING_SEGMENTS, inputs.segments),
                Bind::updates(BINDING_HPR_FRAME, state),
                match src {
                    None => Bind::reads(BINDING_HPR_MAX, self.max64),
                    Some(_) => Bind::unused(BINDING_HPR_MAX),
                },
                match src {
                    None => Bind::unused(BINDING_HPR_SRC),
                    Some(src) => Bind::reads(BINDING_HPR_SRC, src),
                },
                Bind::writes(BINDING_HPR_DST, dst),
                Bind::reads(BINDING_HPR_EMPTY, self.occupied),
            ];
            let pass = g
                .compute(name, "hpr/propagate.comp", &binds)
                .spec(&[
                    (HPR_SPEC_REACH, reach),
                    (HPR_SPEC_FROM_MAX, u32::from(src.is_none())),
                    (HPR_SPEC_ADAPTIVE, u32::from(adaptive)),
                ])
                .push(params);
            if adaptive {
                pass.dispatch_indirect(state, dispatch_offset());
            } else {
                pass.dispatch(groups(self.k_max));
            }
        };
        match propagation {
            Propagation::Fixed(m) => {
                gather(g, "hpr.gather", (m.max(1) / 2, false), None, ping);
                ping
            }
            Propagation::Adaptive { max_rounds } => {
                gather(g, "hpr.extract", (0, false), None, ping);
                let pong = g.buffer(
                    "hpr.extremes.b",
                    self.k_max * 4,
                    vk::BufferUsageFlags::empty(),
                );
                let (mut src, mut dst) = (ping, pong);
                for r in 0..max_rounds.max(1) {
                    gather(g, &format!("hpr.round.{r}"), (1, true), Some(src), dst);
                    let binds = [Bind::updates(BINDING_HPR_FRAME, state)];
                    g.compute(&format!("hpr.advance.{r}"), "hpr/advance.comp", &binds)
                        .dispatch(1);
                    std::mem::swap(&mut src, &mut dst);
                }
                src
            }
        }
    }
}

/// The complete visible set's passes (beyond 003; `hpr::prefilter` is their CPU reference):
/// the nearest point per sector of the finest grid (`hpr.complete.nearest`), the coarser
/// grids (`hpr.complete.reduce.L`) and the per-point test in double precision
/// (`hpr.complete.classify`), which clears the hidden bit of every point it cannot certify
/// hidden and counts it.
fn add_complete(
    g: &mut GraphBuilder,
    ctx: &Context,
    params: &HprParams,
    (frame, segments, state): (BufferId, BufferId, BufferId),
    hidden: BufferId,
) -> Result<()> {
    if !ctx.caps.float64 {
        bail!(
            "{} lacks double precision in shaders (shaderFloat64): the complete visible set \
             needs it (complete=0 runs the sector approximation alone)",
            ctx.caps.device_name
        );
    }
    let side = u64::from(params.complete_side);
    let cells: u64 = (0..HPR_COMPLETE_LEVELS).map(|l| (side >> l).pow(2)).sum();
    let nearest = g.buffer("hpr.complete", cells * 8, vk::BufferUsageFlags::empty());
    g.fill_buffer("hpr.complete.clear", nearest, BufferRange::WHOLE, u32::MAX);
    let points = groups(u64::from(params.point_count));
    let binds = [
        Bind::reads(BINDING_FRAME, frame),
        Bind::reads(BINDING_SEGMENTS, segments),
        Bind::reads(BINDING_HPR_FRAME, state),
        Bind::updates(BINDING_HPR_COMPLETE, nearest),
    ];
    g.compute("hpr.complete.nearest", "hpr/complete_extremes.comp", &binds)
        .push(params)
        .dispatch(points);
    for level in 1..HPR_COMPLETE_LEVELS {
        let binds = [Bind::updates(BINDING_HPR_COMPLETE, nearest)];
        let name = format!("hpr.complete.reduce.{level}");
        g.compute(&name, "hpr/complete_reduce.comp", &binds)
            .spec(&[(HPR_SPEC_MODE, level)])
            .push(params)
            .dispatch(groups((side >> level).pow(2)));
    }
    let binds = [
        Bind::reads(BINDING_FRAME, frame),
        Bind::reads(BINDING_SEGMENTS, segments),
        Bind::updates(BINDING_HPR_FRAME, state),
        Bind::reads(BINDING_HPR_COMPLETE, nearest),
        Bind::updates(BINDING_HPR_MASK, hidden),
    ];
    g.compute(
        "hpr.complete.classify",
        "hpr/complete_classify.comp",
        &binds,
    )
    .push(params)
    .dispatch(points);
    Ok(())
}

/// The offset in `HprFrame` of the propagation rounds' indirect dispatch.
fn dispatch_offset() -> u64 {
    std::mem::offset_of!(HprFrame, groups_x) as u64
}

/// Bytes of `HprFrame` holding the reconstruction's indexed indirect draw.
pub fn draw_range() -> BufferRange {
    BufferRange::new(std::mem::offset_of!(HprFrame, index_count) as u64, 20)
}

/// Declares the partial reconstruction (003 §4.4) of `hpr`: an index list of at most
/// 2 (√k_max − 1)² triangles, counted in `HprFrame::index_count`.
pub fn add_triangulation(
    g: &mut GraphBuilder,
    inputs: Inputs,
    hpr: &Hpr,
    settings: &Settings,
) -> Result<BufferId> {
    let s_max = u64::from(settings.sqrt_k_max.max(2));
    let blocks = (s_max - 1) * (s_max - 1);
    let indices = g.buffer(
        "hpr.triangles",
        blocks * 6 * 4,
        vk::BufferUsageFlags::empty(),
    );
    let params = HprParams {
        sqrt_k_max: settings.sqrt_k_max,
        ..settings.params
    };
    let extremes = hpr
        .extremes
        .context("the reconstruction triangulates the sector extremes, which were skipped")?;
    let binds = [
        Bind::reads(BINDING_FRAME, inputs.frame),
        Bind::reads(BINDING_SEGMENTS, inputs.segments),
        Bind::updates(BINDING_HPR_FRAME, hpr.state),
        Bind::reads(BINDING_HPR_SRC, extremes),
        Bind::writes(BINDING_HPR_TRIANGLES, indices),
    ];
    g.compute("hpr.triangulate", "hpr/triangulate.comp", &binds)
        .push(&params)
        .dispatch(groups(blocks));
    Ok(indices)
}

const SECTORS: ParamSpec = ParamSpec {
    name: "sectors",
    default: 0.0,
    min: 0.0,
    max: 8192.0,
    doc: "√k, sectors per angular direction; 0: one per pixel of the object's projection",
};
const MAX_SECTORS: ParamSpec = ParamSpec {
    name: "max_sectors",
    default: 1024.0,
    min: 2.0,
    max: 8192.0,
    doc: "√k of the sector buffers (the largest grid a frame may use)",
};
const M: ParamSpec = ParamSpec {
    name: "m",
    default: 0.0,
    min: 0.0,
    max: 31.0,
    doc: "0: adaptive propagation; odd m: one fixed m x m gather (003 4.3)",
};
const ROUNDS: ParamSpec = ParamSpec {
    name: "rounds",
    default: 32.0,
    min: 1.0,
    max: 1024.0,
    doc: "adaptive propagation: the most rounds (reported when reached)",
};
const RADIUS: ParamSpec = ParamSpec {
    name: "radius",
    default: 0.0,
    min: 0.0,
    max: 1e9,
    doc: "R as a factor of the bounding box's diagonal (as `surfel hpr --radius-factor` and Open3D's diameter); 0: from the sampling density",
};
const SORT: ParamSpec = ParamSpec {
    name: "sort",
    default: 0.0,
    min: 0.0,
    max: 1.0,
    doc: "1: radix sort by sector and segmented maximum (the thesis); 0: 64-bit atomicMax",
};

const COMPLETE: ParamSpec = ParamSpec {
    name: "complete",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "1: the complete visible set (every point decided, beyond 003; needs shaderFloat64, without which the default falls back to 0); 0: the distinct sector extremes (003 4.2)",
};

const PARAMS: &[ParamSpec] = &[SECTORS, MAX_SECTORS, M, ROUNDS, RADIUS, SORT, COMPLETE];

const MESH_PARAMS: &[ParamSpec] = &[
    SECTORS,
    MAX_SECTORS,
    M,
    ROUNDS,
    RADIUS,
    SORT,
    COMPLETE,
    ParamSpec {
        name: "max_edge",
        default: 8.0,
        min: 0.5,
        max: 4096.0,
        doc: "the longest projected triangle edge kept, in pixels",
    },
    ParamSpec {
        name: "pyramid",
        default: 0.0,
        min: 0.0,
        max: 1.0,
        doc: "1: the triangles and the visible points through the pyramid (000 5.2)",
    },
];

pub const INFO: MethodInfo = MethodInfo {
    params: PARAMS,
    features: &[Feature::Int64Atomics],
    needs_hpr: true,
    ..MethodInfo::new(
        "hpr",
        "hidden point removal on the GPU (003 ch. 4), the visible points by the compute rasterizer",
        build_points,
    )
};

pub const MESH_INFO: MethodInfo = MethodInfo {
    params: MESH_PARAMS,
    features: &[Feature::Int64Atomics],
    needs_hpr: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "hpr-mesh",
        "HPR's partial surface reconstruction (003 4.4), drawn as triangles",
        build_mesh,
    )
};

/// The settings of a method configuration; `density` is R / |C − C_e|² from the sampling
/// density (`HprScene::density`).
fn settings(b: &BuildContext<'_>) -> Result<Settings> {
    let cfg = b.config;
    let hpr = b.scene.hpr.as_ref().with_context(|| {
        format!(
            "method '{}' needs the scene's HPR data (UploadOptions::hpr)",
            cfg.method.name
        )
    })?;
    let m = cfg.get("m").round() as u32;
    let factor = cfg.get("radius");
    Ok(Settings {
        sqrt_k_max: cfg.get("max_sectors").round() as u32,
        params: HprParams {
            sqrt_k: cfg.get("sectors").round() as u32,
            max_rounds: cfg.get("rounds").round() as u32,
            radius: factor * hpr.diagonal,
            density: if factor > 0.0 { 0.0 } else { hpr.density },
            max_edge: cfg.get("max_edge"),
            // `hpr-mesh` reads the hidden mask only through the pyramid; by default (not asked
            // for) a device without double precision runs the sector extremes alone.
            complete_side: if cfg.get("complete") >= 0.5
                && (cfg.method.name != MESH_INFO.name || cfg.get("pyramid") >= 0.5)
                && (b.ctx.caps.float64 || cfg.params.contains_key("complete"))
            {
                crate::hpr::complete_side(b.scene.point_count as usize)
            } else {
                0
            },
            ..Default::default()
        },
        propagation: if m == 0 {
            Propagation::Adaptive {
                max_rounds: cfg.get("rounds").round() as u32,
            }
        } else {
            Propagation::Fixed(m | 1)
        },
        sort: cfg.get("sort") >= 0.5,
        extremes: cfg.method.name == MESH_INFO.name,
    })
}

fn add_for_method(b: &mut BuildContext<'_>) -> Result<(Hpr, Inputs, Settings)> {
    let sphere = bounding_sphere(b.ctx, b.scene)?;
    let inputs = Inputs {
        frame: b.frame,
        segments: b.segments,
        sphere: b.graph.import_buffer_with(
            "hpr.sphere",
            sphere,
            Access::StorageWrite(Stages::Compute),
        ),
    };
    let settings = settings(b)?;
    let hpr = add(b.graph, b.ctx, b.scene.point_count, inputs, &settings)?;
    Ok((hpr, inputs, settings))
}

fn build_points(b: &mut BuildContext<'_>) -> Result<()> {
    let (hpr, _, _) = add_for_method(b)?;
    let projection = compute::project(
        b,
        "hpr.points",
        ProjectOptions {
            skip: Some(hpr.hidden),
            ..Default::default()
        },
    );
    let binds = compute::resolve_binds(b, projection, false);
    let groups = b.pixel_groups(RESOLVE_GROUP);
    b.graph
        .compute("hpr.points.resolve", "compute/resolve.comp", &binds)
        .spec(&[(RESOLVE_SPEC_HIGH_QUALITY, 0)])
        .dispatch_grid(groups);
    Ok(())
}

fn build_mesh(b: &mut BuildContext<'_>) -> Result<()> {
    let (hpr, inputs, settings) = add_for_method(b)?;
    let indices = add_triangulation(b.graph, inputs, &hpr, &settings)?;
    if b.config.get("pyramid") >= 0.5 {
        let args = (hpr.state, draw_range().offset);
        return super::pyramid::build_over_triangles(b, indices, args, hpr.hidden);
    }
    super::mesh::add_mesh(
        b,
        "hpr-mesh",
        1,
        super::mesh::Indices::Indirect {
            indices,
            args: hpr.state,
            range: draw_range(),
        },
    )
}

/// What one GPU evaluation of HPR found (indices in stream order).
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// The bounding sphere of the reduction.
    pub centre: glam::Vec3,
    pub radius: f32,
    /// The frame's state after the passes: √k, rounds, visible count, triangles.
    pub state: HprFrame,
    /// The final extreme of each of the frame's √k² sectors (`HPR_EMPTY` where none; empty
    /// where [`Settings::extremes`] skipped them).
    pub extremes: Vec<u32>,
    /// The visible points, ascending.
    pub visible: Vec<u32>,
    /// The reconstruction's triangles (when `triangulate`), in the order they were appended.
    pub triangles: Vec<[u32; 3]>,
}

/// Runs the HPR passes once outside the frame loop, seen through `view` and `proj` on a
/// `width` x `height` viewport, and reads the results back (the `surfel hpr --gpu` command
/// and the tests).
pub fn evaluate(
    ctx: &Arc<Context>,
    scene: &GpuScene,
    (view, proj): (glam::Mat4, glam::Mat4),
    (width, height): (u32, u32),
    settings: &Settings,
    triangulate: bool,
) -> Result<Evaluation> {
    let sphere = bounding_sphere(ctx, scene)?;
    let mut block: FrameBlock = bytemuck::Zeroable::zeroed();
    block.u.view = view;
    block.u.proj = proj;
    block.u.view_proj = proj * view;
    let (w, h) = (width as f32, height as f32);
    block.u.viewport = glam::Vec4::new(w, h, 1.0 / w, 1.0 / h);
    block.u.point_count = scene.point_count;
    block.u.segment_points = scene.streams.segment_points;
    let frame_buffer = Arc::new(Buffer::with_data(
        ctx,
        "frame",
        bytemuck::bytes_of(&block),
        vk::BufferUsageFlags::STORAGE_BUFFER,
    )?);
    let mut g = GraphBuilder::new();
    let inputs = Inputs {
        frame: g.import_buffer("frame", frame_buffer),
        segments: g.import_buffer("stream.segments", scene.streams.table.clone()),
        sphere: g.import_buffer_with("hpr.sphere", sphere, Access::StorageWrite(Stages::Compute)),
    };
    let hpr = add(&mut g, ctx, scene.point_count, inputs, settings)?;
    let s_max = u64::from(settings.sqrt_k_max.max(1));
    // Read back: the sphere, the state, the hidden mask, then the extremes and the triangles
    // where present.
    let mut outputs: Vec<(BufferId, u64)> = vec![
        (inputs.sphere, 16),
        (hpr.state, std::mem::size_of::<HprFrame>() as u64),
        (
            hpr.hidden,
            u64::from(scene.point_count.div_ceil(32).max(1)) * 4,
        ),
    ];
    if let Some(extremes) = hpr.extremes {
        outputs.push((extremes, s_max * s_max * 4));
    }
    if triangulate {
        let indices = add_triangulation(&mut g, inputs, &hpr, settings)?;
        let s = s_max.max(2);
        outputs.push((indices, (s - 1) * (s - 1) * 24));
    }
    let hosts = outputs
        .iter()
        .map(|&(_, n)| Buffer::readback(ctx, "hpr.readback", n).map(Arc::new))
        .collect::<Result<Vec<_>>>()?;
    let mut ids = Vec::new();
    for (i, (&(src, n), buffer)) in outputs.iter().zip(&hosts).enumerate() {
        let id = g.import_buffer("hpr.readback", buffer.clone());
        g.copy_buffer(
            &format!("hpr.download.{i}"),
            src,
            id,
            &[vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: n,
            }],
        );
        ids.push(id);
    }
    let mut done = g.pass("hpr.download.host");
    for &id in &ids {
        done = done.buffer(id, Access::HostRead);
    }
    done.record(|_| {});
    g.compile(ctx)?.run_once(ctx)?;
    let words = |b: &Buffer| -> Result<Vec<u32>> {
        Ok(bytemuck::pod_collect_to_vec::<u8, u32>(b.mapped()?))
    };
    let sphere_words = words(&hosts[0])?;
    let state: HprFrame = bytemuck::pod_read_unaligned(hosts[1].mapped()?);
    let k = (state.sqrt_k * state.sqrt_k) as usize;
    let hidden = words(&hosts[2])?;
    let visible = (0..scene.point_count)
        .filter(|&i| hidden[(i / 32) as usize] & (1 << (i % 32)) == 0)
        .collect();
    let extremes = match hpr.extremes {
        Some(_) => {
            let mut all = words(&hosts[3])?;
            all.truncate(k);
            all
        }
        None => Vec::new(),
    };
    let triangles = match hosts.get(3 + usize::from(hpr.extremes.is_some())) {
        Some(b) => {
            let all = words(b)?;
            let n = (state.index_count as usize).min(all.len());
            all[..n]
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
        None => Vec::new(),
    };
    Ok(Evaluation {
        centre: glam::Vec3::new(
            f32::from_bits(sphere_words[0]),
            f32::from_bits(sphere_words[1]),
            f32::from_bits(sphere_words[2]),
        ),
        radius: f32::from_bits(sphere_words[3]),
        state,
        extremes,
        visible,
        triangles,
    })
}
