//! The compute rasterizer (Schütz, Kerbl, Wimmer 2021; Schütz et al. 2022), a projection
//! building block later methods reuse for their level 0.
//!
//! * `compute`: nearest point per pixel through a 64-bit visibility buffer (key = linear depth
//!   bits << 32 | point index, so ties go to the lower index, as the hardware point pipeline
//!   resolves them by draw order); a plain early-depth read before `atomicMin`; per-batch
//!   frustum culling; batches read 4, 8 or 12 bytes of quantized position per point depending
//!   on their projected size. A resolve pass fetches normal and color only for the winners.
//! * `compute-hq`: the high-quality mode. A visibility pass finds each pixel's nearest depth;
//!   every point within a relative depth `tolerance` of it then adds its albedo and normal with
//!   atomics; the resolve averages and shades them.

use anyhow::Result;
use ash::vk;

use super::{BuildContext, Feature, MethodInfo, ParamSpec};
use crate::graph::{Bind, Binds, BufferId, BufferRange};
use crate::layout::{
    BINDING_ACCUM, BINDING_BATCHES, BINDING_FACE_VERTICES, BINDING_FRAME, BINDING_SEGMENTS,
    BINDING_VISIBILITY, RASTER_SPEC_CULL, RASTER_SPEC_MODE, RASTER_SPEC_QUANTIZED,
    RASTER_SPEC_SKIP, RESOLVE_GROUP, RESOLVE_SPEC_HIGH_QUALITY,
};

const QUANTIZED: ParamSpec = ParamSpec {
    name: "quantized",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "1: read 4/8/12-byte quantized positions chosen per batch; 0: f32 positions",
};

pub const COMPUTE: MethodInfo = MethodInfo {
    params: &[QUANTIZED],
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    ..MethodInfo::new(
        "compute",
        "compute rasterizer: nearest point per pixel by 64-bit atomicMin (Schütz et al. 2021)",
        build_nearest,
    )
};

pub const COMPUTE_HQ: MethodInfo = MethodInfo {
    params: &[
        QUANTIZED,
        ParamSpec {
            name: "tolerance",
            default: 0.01,
            min: 0.0,
            max: 1.0,
            doc: "relative depth range behind the nearest point that is blended",
        },
    ],
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    ..MethodInfo::new(
        "compute-hq",
        "compute rasterizer, high quality: points near the front blended with atomics",
        build_high_quality,
    )
};

/// Bytes of the high-quality accumulators per pixel: r, g, b, count, nx, ny, nz, unused.
const ACCUM_BYTES: u64 = 32;

/// The visibility pass (and, for the high-quality mode, the accumulation pass) of the compute
/// rasterizer, writing into graph buffers; reusable by any method that needs points projected
/// to pixels.
pub struct Projection {
    /// `uint64_t` key per pixel: linear depth bits << 32 | point index; all ones where empty.
    pub visibility: BufferId,
    /// `ACCUM_BYTES` per pixel (high quality only; otherwise the visibility buffer again).
    pub accum: BufferId,
}

/// What `project` projects.
#[derive(Clone, Copy, Debug, Default)]
pub struct ProjectOptions {
    /// Also the accumulation pass of `compute-hq`.
    pub high_quality: bool,
    /// Skip points whose normal faces away from the eye (when the scene has normals).
    pub cull: bool,
    /// Skip the points whose bit is set in this buffer (`GpuScene::face_vertices`).
    pub skip: Option<BufferId>,
}

/// Declares clear, visibility (and accumulation) passes of `b`'s point streams.
pub fn project(b: &mut BuildContext<'_>, prefix: &str, options: ProjectOptions) -> Projection {
    let ProjectOptions {
        high_quality,
        cull,
        skip,
    } = options;
    let pixels = u64::from(b.width) * u64::from(b.height);
    let quantized = u32::from(b.config.get("quantized") >= 0.5);
    let tolerance = if high_quality {
        b.config.get("tolerance")
    } else {
        0.0
    };
    // Usage flags follow from the declared accesses.
    let usage = vk::BufferUsageFlags::empty();
    let visibility = b
        .graph
        .buffer(&format!("{prefix}.visibility"), pixels * 8, usage);
    let accum = if high_quality {
        b.graph
            .buffer(&format!("{prefix}.accum"), pixels * ACCUM_BYTES, usage)
    } else {
        visibility
    };
    let (frame, segments, batches) = (b.frame, b.segments, b.batches);
    let visibility_binds = Binds::from([
        Bind::constants(BINDING_FRAME, frame),
        Bind::reads(BINDING_SEGMENTS, segments),
        Bind::reads(BINDING_BATCHES, batches),
        Bind::updates(BINDING_VISIBILITY, visibility),
        // The visibility pass never touches the accumulators.
        Bind::unused(BINDING_ACCUM),
        match skip {
            Some(mask) => Bind::reads(BINDING_FACE_VERTICES, mask),
            None => Bind::unused(BINDING_FACE_VERTICES),
        },
    ]);
    let spec = |mode: u32| {
        [
            (RASTER_SPEC_MODE, mode),
            (RASTER_SPEC_QUANTIZED, quantized),
            (RASTER_SPEC_CULL, u32::from(cull)),
            (RASTER_SPEC_SKIP, u32::from(skip.is_some())),
        ]
    };
    // Empty pixels hold the largest key; the accumulators start at zero.
    b.graph.fill_buffer(
        &format!("{prefix}.clear"),
        visibility,
        BufferRange::WHOLE,
        u32::MAX,
    );
    if high_quality {
        b.graph.fill_buffer(
            &format!("{prefix}.clear-accum"),
            accum,
            BufferRange::WHOLE,
            0,
        );
    }
    // One workgroup per batch.
    let batch_count = u64::from(b.scene.streams.batch_count);
    let shader = "compute/raster.comp";
    b.graph
        .compute(&format!("{prefix}.project"), shader, &visibility_binds)
        .spec(&spec(0))
        .push(&tolerance)
        .dispatch(batch_count);
    if high_quality {
        let accumulate_binds = visibility_binds
            .with(Bind::reads(BINDING_VISIBILITY, visibility))
            .with(Bind::updates(BINDING_ACCUM, accum));
        b.graph
            .compute(&format!("{prefix}.accumulate"), shader, &accumulate_binds)
            .spec(&spec(1))
            .push(&tolerance)
            .dispatch(batch_count);
    }
    Projection { visibility, accum }
}

fn build(b: &mut BuildContext<'_>, high_quality: bool) -> Result<()> {
    let prefix = if high_quality {
        "compute-hq"
    } else {
        "compute"
    };
    let projection = project(
        b,
        prefix,
        ProjectOptions {
            high_quality,
            ..Default::default()
        },
    );
    let binds = resolve_binds(b, projection, high_quality);
    let groups = b.pixel_groups(RESOLVE_GROUP);
    b.graph
        .compute(&format!("{prefix}.resolve"), "compute/resolve.comp", &binds)
        .spec(&[(RESOLVE_SPEC_HIGH_QUALITY, u32::from(high_quality))])
        .dispatch_grid(groups);
    Ok(())
}

/// The bindings of a per-pixel resolve shader (`compute` and `compute-hq`, `ewa`): the frame,
/// the point streams, a projection's visibility buffer and, when `reads_accum`, its
/// accumulators in, the three standard targets out.
pub(crate) fn resolve_binds(
    b: &BuildContext<'_>,
    projection: Projection,
    reads_accum: bool,
) -> Binds {
    let mut binds = Binds::from([
        Bind::constants(BINDING_FRAME, b.frame),
        Bind::reads(BINDING_SEGMENTS, b.segments),
        Bind::reads(BINDING_VISIBILITY, projection.visibility),
        if reads_accum {
            Bind::reads(BINDING_ACCUM, projection.accum)
        } else {
            Bind::unused(BINDING_ACCUM)
        },
    ]);
    for bind in b.targets.compute_writes() {
        binds.push(bind);
    }
    binds
}

fn build_nearest(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, false)
}

fn build_high_quality(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, true)
}
