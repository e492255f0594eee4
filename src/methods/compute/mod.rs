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

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use super::{BuildContext, Feature, MethodInfo, ParamSpec};
use crate::gpu::layout::{
    BINDING_ACCUM, BINDING_BATCHES, BINDING_FACE_VERTICES, BINDING_FRAME, BINDING_OUTPUT0,
    BINDING_SEGMENTS, BINDING_VISIBILITY, RESOLVE_GROUP,
};
use crate::gpu::{Binding, Pipeline};
use crate::graph::{Access, BufferId, BufferRange, Descriptor, Stages};

const QUANTIZED: ParamSpec = ParamSpec {
    name: "quantized",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "1: read 4/8/12-byte quantized positions chosen per batch; 0: f32 positions",
};

pub const COMPUTE: MethodInfo = MethodInfo {
    name: "compute",
    summary: "compute rasterizer: nearest point per pixel by 64-bit atomicMin (Schütz et al. 2021)",
    params: &[QUANTIZED],
    needs_faces: false,
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    needs_lod: false,
    needs_hpr: false,
    needs_normal_field: false,
    needs_surfels: false,
    build: build_nearest,
};

pub const COMPUTE_HQ: MethodInfo = MethodInfo {
    name: "compute-hq",
    summary: "compute rasterizer, high quality: points near the front blended with atomics",
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
    needs_faces: false,
    features: &[Feature::Int64Atomics],
    culls_batches: true,
    needs_lod: false,
    needs_hpr: false,
    needs_normal_field: false,
    needs_surfels: false,
    build: build_high_quality,
};

/// Bytes of the high-quality accumulators per pixel: r, g, b, count, nx, ny, nz, unused.
const ACCUM_BYTES: u64 = 32;

pub(crate) fn storage(binding: u32) -> Binding {
    Binding::new(
        binding,
        vk::DescriptorType::STORAGE_BUFFER,
        vk::ShaderStageFlags::COMPUTE,
    )
}

pub(crate) fn storage_image(binding: u32) -> Binding {
    Binding::new(
        binding,
        vk::DescriptorType::STORAGE_IMAGE,
        vk::ShaderStageFlags::COMPUTE,
    )
}

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
pub fn project(
    b: &mut BuildContext<'_>,
    prefix: &str,
    options: ProjectOptions,
) -> Result<Projection> {
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
    let bindings = [
        storage(BINDING_FRAME),
        storage(BINDING_SEGMENTS),
        storage(BINDING_BATCHES),
        storage(BINDING_VISIBILITY),
        storage(BINDING_ACCUM),
        storage(BINDING_FACE_VERTICES),
    ];
    let raster = |mode: u32| {
        Pipeline::compute_specialized(
            b.ctx,
            "compute/raster.comp",
            &bindings,
            &[
                (0, mode),
                (1, quantized),
                (2, u32::from(cull)),
                (3, u32::from(skip.is_some())),
            ],
        )
        .map(Arc::new)
    };
    let (frame, segments, batches) = (b.frame, b.segments, b.batches);
    let descriptors = [
        Descriptor::Buffer(BINDING_FRAME, frame),
        Descriptor::Buffer(BINDING_SEGMENTS, segments),
        Descriptor::Buffer(BINDING_BATCHES, batches),
        Descriptor::Buffer(BINDING_VISIBILITY, visibility),
        Descriptor::Buffer(BINDING_ACCUM, accum),
        // Without a mask the shader never reads it (dead code under its specialization, but
        // statically present): alias it to the visibility buffer every pass declares.
        Descriptor::Buffer(BINDING_FACE_VERTICES, skip.unwrap_or(visibility)),
    ];
    let compute = Stages::Compute;
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
    // One workgroup per batch, folded into 2D past the 65,535 groups every device allows.
    let batch_count = b.scene.streams.batch_count;
    let (gx, gy) = (batch_count.min(65_535), batch_count.div_ceil(65_535));
    let push = tolerance.to_le_bytes();
    let nearest = raster(0)?;
    // The visibility pass never touches the accumulators (dead code under its specialization,
    // but statically present): alias them to the visibility buffer it declares.
    let mut visibility_only = descriptors;
    visibility_only[4] = Descriptor::Buffer(BINDING_ACCUM, visibility);
    let mut pass = b
        .graph
        .pass(&format!("{prefix}.project"))
        .buffer(frame, Access::UniformRead(compute))
        .buffer(segments, Access::StorageRead(compute))
        .buffer(batches, Access::StorageRead(compute))
        .buffer(visibility, Access::StorageReadWrite(compute));
    if let Some(mask) = skip {
        pass = pass.buffer(mask, Access::StorageRead(compute));
    }
    pass.record(move |ctx| {
        ctx.bind(&nearest, &visibility_only);
        ctx.push(&nearest, &push);
        ctx.dispatch(gx, gy, 1);
    });
    if high_quality {
        let blend = raster(1)?;
        let mut pass = b
            .graph
            .pass(&format!("{prefix}.accumulate"))
            .buffer(frame, Access::UniformRead(compute))
            .buffer(segments, Access::StorageRead(compute))
            .buffer(batches, Access::StorageRead(compute))
            .buffer(visibility, Access::StorageRead(compute))
            .buffer(accum, Access::StorageReadWrite(compute));
        if let Some(mask) = skip {
            pass = pass.buffer(mask, Access::StorageRead(compute));
        }
        pass.record(move |ctx| {
            ctx.bind(&blend, &descriptors);
            ctx.push(&blend, &push);
            ctx.dispatch(gx, gy, 1);
        });
    }
    Ok(Projection { visibility, accum })
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
    )?;
    let resolve = resolve_pipeline(b, "compute/resolve.comp", &[(0, u32::from(high_quality))])?;
    add_resolve(
        b,
        &format!("{prefix}.resolve"),
        resolve,
        projection,
        high_quality,
    );
    Ok(())
}

/// The pipeline of a per-pixel resolve shader (`compute` and `compute-hq`, `ewa`): the frame,
/// the point streams, a projection's visibility and accumulator buffers in, the three
/// standard targets out.
pub(crate) fn resolve_pipeline(
    b: &BuildContext<'_>,
    shader: &str,
    specialization: &[(u32, u32)],
) -> Result<Arc<Pipeline>> {
    Ok(Arc::new(Pipeline::compute_specialized(
        b.ctx,
        shader,
        &[
            storage(BINDING_FRAME),
            storage(BINDING_SEGMENTS),
            storage(BINDING_VISIBILITY),
            storage(BINDING_ACCUM),
            storage_image(BINDING_OUTPUT0),
            storage_image(BINDING_OUTPUT0 + 1),
            storage_image(BINDING_OUTPUT0 + 2),
        ],
        specialization,
    )?))
}

/// Adds the resolve pass `name`: one thread per pixel of `resolve` (`resolve_pipeline`) over
/// `projection`, reading its accumulators only when `reads_accum`, writing the standard
/// targets.
pub(crate) fn add_resolve(
    b: &mut BuildContext<'_>,
    name: &str,
    resolve: Arc<Pipeline>,
    projection: Projection,
    reads_accum: bool,
) {
    let (frame, segments, t) = (b.frame, b.segments, b.targets);
    let Projection { visibility, accum } = projection;
    let compute = Stages::Compute;
    let mut pass = b
        .graph
        .pass(name)
        .buffer(frame, Access::UniformRead(compute))
        .buffer(segments, Access::StorageRead(compute))
        .buffer(visibility, Access::StorageRead(compute));
    if reads_accum {
        pass = pass.buffer(accum, Access::StorageRead(compute));
    }
    let groups = (
        b.width.div_ceil(RESOLVE_GROUP),
        b.height.div_ceil(RESOLVE_GROUP),
    );
    pass.image(t.color, Access::StorageWrite(compute))
        .image(t.depth, Access::StorageWrite(compute))
        .image(t.normal, Access::StorageWrite(compute))
        .record(move |ctx| {
            ctx.bind(
                &resolve,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_SEGMENTS, segments),
                    Descriptor::Buffer(BINDING_VISIBILITY, visibility),
                    Descriptor::Buffer(BINDING_ACCUM, accum),
                    Descriptor::StorageImage(BINDING_OUTPUT0, t.color, 0),
                    Descriptor::StorageImage(BINDING_OUTPUT0 + 1, t.depth, 0),
                    Descriptor::StorageImage(BINDING_OUTPUT0 + 2, t.normal, 0),
                ],
            );
            ctx.dispatch(groups.0, groups.1, 1);
        });
}

fn build_nearest(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, false)
}

fn build_high_quality(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, true)
}
