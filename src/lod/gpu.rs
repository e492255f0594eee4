//! The object texture on the GPU and its expansion paths, which emit the same vertices for a
//! view (each patch's level chosen by `glsl/lod/lod.glsl`, the CPU reference being
//! `ObjectTexture::select`):
//!
//! * compute (`add_compute`): a selection pass writes the list of the chosen levels' vertex
//!   indices and an indirect draw's arguments (`add_select`); an indirect draw pulls the
//!   vertices through the list;
//! * mesh (`add_mesh`): a task shader chooses the levels of a group of patches and launches
//!   one mesh workgroup per patch, which emits that level's vertices;
//! * geometry (`add_geometry`, the thesis' path): one vertex per patch, the geometry shader
//!   chooses the level and emits its vertices.
//!
//! Every path draws points covering each splat's projected diameter into the standard targets
//! and counts the vertices it emits per level.

use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;

use super::ObjectTexture;
use crate::gpu::layout::{
    LodParams, BINDING_FRAME, BINDING_LOD_COUNTERS, BINDING_LOD_LIST, BINDING_LOD_PATCHES,
    BINDING_LOD_VERTICES, LOD_GROUP, LOD_MAX_LEVELS, LOD_PATCH_VERTICES, LOD_SPEC_COLOR_LEVELS,
    LOD_SPEC_RECORD, LOD_TASK_GROUP,
};
use crate::gpu::{Binding, Blend, Buffer, Context, GraphicsDesc, Pipeline};
use crate::graph::{
    Access, BufferId, BufferRange, Descriptor, GraphBuilder, ImageId, Load, Stages,
};
use crate::methods::compute::storage;
use crate::methods::{COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT};

/// Byte offset of the per-level vertex counts in the selection's counters (after the
/// `VkDrawIndirectCommand`).
pub const COUNTER_LEVELS_OFFSET: u64 = 16;

/// Bytes of the selection's counters: a `VkDrawIndirectCommand`, then the vertices selected
/// per level.
pub const COUNTER_BYTES: u64 = COUNTER_LEVELS_OFFSET + 4 * LOD_MAX_LEVELS as u64;

/// An object texture uploaded: its patches (`GpuLodPatch`) and vertices (`GpuLodVertex`).
pub struct GpuLod {
    pub patches: Arc<Buffer>,
    pub vertices: Arc<Buffer>,
    pub patch_count: u32,
    /// The object texture's levels (`ObjectTexture::levels`): the counters' per-level words
    /// a path writes.
    pub levels: u32,
    /// The longest list a view selects (`ObjectTexture::max_selected`).
    pub max_selected: u32,
}

impl GpuLod {
    pub fn upload(ctx: &Arc<Context>, texture: &ObjectTexture) -> Result<GpuLod> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let patches = texture.gpu_patches();
        let vertices = texture.gpu_vertices();
        Ok(GpuLod {
            patches: Arc::new(Buffer::with_data(
                ctx,
                "lod.patches",
                bytemuck::cast_slice(&patches),
                usage,
            )?),
            vertices: Arc::new(Buffer::with_data(
                ctx,
                "lod.vertices",
                bytemuck::cast_slice(&vertices),
                usage,
            )?),
            patch_count: patches.len() as u32,
            levels: texture.levels,
            max_selected: texture.max_selected(),
        })
    }
}

/// What a path writes.
#[derive(Clone, Copy, Debug)]
pub struct Selection {
    /// Indices into the object texture's vertices (`u32`), `max_selected` long; the first
    /// `counters`' vertex count hold this frame's selection, in no particular order.
    pub list: BufferId,
    /// `COUNTER_BYTES`: the `VkDrawIndirectCommand` of the list, the vertices per level.
    pub counters: BufferId,
}

/// The graph's ids of the frame block and of an uploaded object texture.
#[derive(Clone, Copy, Debug)]
pub struct LodInputs {
    pub frame: BufferId,
    pub patches: BufferId,
    pub vertices: BufferId,
}

impl LodInputs {
    /// Imports `lod`'s buffers into `graph`.
    pub fn import(graph: &mut GraphBuilder, frame: BufferId, lod: &GpuLod) -> LodInputs {
        LodInputs {
            frame,
            patches: graph.import_buffer("lod.patches", lod.patches.clone()),
            vertices: graph.import_buffer("lod.vertices", lod.vertices.clone()),
        }
    }
}

/// How a path draws.
#[derive(Clone, Copy, Debug)]
pub struct DrawOptions {
    /// The threshold ε of the projected error, in pixels.
    pub epsilon: f32,
    /// Color by level (thesis Fig. 7.4) rather than with the base color.
    pub color_levels: bool,
    /// Largest point size in pixels.
    pub max_point_size: f32,
    /// Mesh and geometry paths: also append every emitted vertex index to the list (tests).
    pub record: bool,
}

/// Where a path draws: the standard targets and a reversed-Z depth buffer, all cleared.
#[derive(Clone, Copy, Debug)]
pub struct DrawTargets {
    pub color: ImageId,
    pub depth: ImageId,
    pub normal: ImageId,
    pub zbuffer: ImageId,
}

/// The counters of a path, reset by the pass `{prefix}.reset` (instance count 1, the rest 0),
/// and a list of `list_entries` indices (none: the list is the counters buffer again).
fn new_selection(graph: &mut GraphBuilder, prefix: &str, list_entries: Option<u32>) -> Selection {
    let usage = vk::BufferUsageFlags::empty();
    let counters = graph.buffer(&format!("{prefix}.counters"), COUNTER_BYTES, usage);
    let list = list_entries.map_or(counters, |n| {
        graph.buffer(&format!("{prefix}.list"), u64::from(n.max(1)) * 4, usage)
    });
    let mut reset = [0u32; COUNTER_BYTES as usize / 4];
    reset[1] = 1;
    graph.update_buffer(
        &format!("{prefix}.reset"),
        counters,
        0,
        bytemuck::cast_slice(&reset),
    );
    Selection { list, counters }
}

fn draw_params(lod: &GpuLod, options: &DrawOptions) -> LodParams {
    LodParams {
        epsilon: options.epsilon,
        patch_count: lod.patch_count,
        max_point_size: options.max_point_size,
        ..Default::default()
    }
}

/// Declares the reset of the counters and the selection pass over `patches` (the graph's id
/// of `lod.patches`) for the camera in `frame` and the threshold `epsilon` in pixels.
pub fn add_select(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    frame: BufferId,
    patches: BufferId,
    lod: &GpuLod,
    epsilon: f32,
) -> Result<Selection> {
    let selection = new_selection(graph, prefix, Some(lod.max_selected));
    let Selection { list, counters } = selection;
    let pipeline = Arc::new(Pipeline::compute(
        ctx,
        "lod/select.comp",
        &[
            storage(BINDING_FRAME),
            storage(BINDING_LOD_PATCHES),
            storage(BINDING_LOD_LIST),
            storage(BINDING_LOD_COUNTERS),
        ],
    )?);
    let params = LodParams {
        epsilon,
        patch_count: lod.patch_count,
        ..Default::default()
    };
    // One thread per patch, folded into 2D past the 65,535 groups every device allows.
    let groups = lod.patch_count.div_ceil(LOD_GROUP);
    let (gx, gy) = (groups.clamp(1, 65_535), groups.div_ceil(65_535).max(1));
    let compute = Stages::Compute;
    graph
        .pass(&format!("{prefix}.select"))
        .buffer(frame, Access::UniformRead(compute))
        .buffer(patches, Access::StorageRead(compute))
        .buffer(list, Access::StorageWrite(compute))
        .buffer(counters, Access::StorageReadWrite(compute))
        .record(move |ctx| {
            ctx.bind(
                &pipeline,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_LOD_PATCHES, patches),
                    Descriptor::Buffer(BINDING_LOD_LIST, list),
                    Descriptor::Buffer(BINDING_LOD_COUNTERS, counters),
                ],
            );
            ctx.push(&pipeline, bytemuck::bytes_of(&params));
            ctx.dispatch(gx, gy, 1);
        });
    Ok(selection)
}

/// A points pipeline drawing into the standard targets with reversed-Z depth, shaded by
/// `splat/points.frag`.
fn draw_pipeline(
    ctx: &Arc<Context>,
    shaders: &[&str],
    bindings: &[Binding],
    options: &DrawOptions,
) -> Result<Arc<Pipeline>> {
    Ok(Arc::new(Pipeline::graphics(
        ctx,
        &GraphicsDesc {
            shaders,
            bindings,
            color_formats: &[COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT],
            blends: &[Blend::Replace; 3],
            depth_format: Some(ZBUFFER_FORMAT),
            depth_test: true,
            depth_write: true,
            depth_compare: vk::CompareOp::GREATER,
            topology: vk::PrimitiveTopology::POINT_LIST,
            cull: vk::CullModeFlags::NONE,
            specialization: &[
                (LOD_SPEC_COLOR_LEVELS, u32::from(options.color_levels)),
                (LOD_SPEC_RECORD, u32::from(options.record)),
            ],
        },
    )?))
}

fn binding(binding: u32, stages: vk::ShaderStageFlags) -> Binding {
    Binding::new(binding, vk::DescriptorType::STORAGE_BUFFER, stages)
}

/// The compute path: `add_select`, then one indirect draw of the list into `targets`.
pub fn add_compute(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    lod: &GpuLod,
    inputs: LodInputs,
    options: DrawOptions,
    targets: DrawTargets,
) -> Result<Selection> {
    let LodInputs {
        frame,
        patches,
        vertices,
    } = inputs;
    let selection = add_select(ctx, graph, prefix, frame, patches, lod, options.epsilon)?;
    let Selection { list, counters } = selection;
    let vertex = vk::ShaderStageFlags::VERTEX;
    let pipeline = draw_pipeline(
        ctx,
        &["lod/points.vert", "splat/points.frag"],
        &[
            binding(BINDING_FRAME, vertex | vk::ShaderStageFlags::FRAGMENT),
            binding(BINDING_LOD_VERTICES, vertex),
            binding(BINDING_LOD_LIST, vertex),
        ],
        &options,
    )?;
    let params = draw_params(lod, &options);
    let t = targets;
    graph
        .pass(&format!("{prefix}.draw"))
        .buffer(frame, Access::UniformRead(Stages::Graphics))
        .buffer(vertices, Access::StorageRead(Stages::Vertex))
        .buffer(list, Access::StorageRead(Stages::Vertex))
        .buffer_range(counters, BufferRange::new(0, 16), Access::IndirectRead)
        .color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(t.zbuffer, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(
                &pipeline,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_LOD_VERTICES, vertices),
                    Descriptor::Buffer(BINDING_LOD_LIST, list),
                ],
            );
            ctx.push(&pipeline, bytemuck::bytes_of(&params));
            ctx.draw_indirect(counters, 0, 1, 16);
        });
    Ok(selection)
}

/// The mesh path: task workgroups of `LOD_TASK_GROUP` patches choose levels and launch one
/// mesh workgroup per patch, drawing into `targets`. The counters hold the vertices emitted
/// per level; with `options.record` the list holds every emitted index and the first counter
/// their number (otherwise the list is the counters buffer again, never written).
pub fn add_mesh(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    lod: &GpuLod,
    inputs: LodInputs,
    options: DrawOptions,
    targets: DrawTargets,
) -> Result<Selection> {
    let LodInputs {
        frame,
        patches,
        vertices,
    } = inputs;
    let selection = new_selection(graph, prefix, options.record.then_some(lod.max_selected));
    let Selection { list, counters } = selection;
    let task = vk::ShaderStageFlags::TASK_EXT;
    let mesh = vk::ShaderStageFlags::MESH_EXT;
    let pipeline = draw_pipeline(
        ctx,
        &["lod/select.task", "lod/points.mesh", "splat/points.frag"],
        &[
            binding(BINDING_FRAME, task | mesh | vk::ShaderStageFlags::FRAGMENT),
            binding(BINDING_LOD_PATCHES, task),
            binding(BINDING_LOD_VERTICES, mesh),
            binding(BINDING_LOD_LIST, mesh),
            binding(BINDING_LOD_COUNTERS, mesh),
        ],
        &options,
    )?;
    let params = draw_params(lod, &options);
    let groups = lod.patch_count.div_ceil(LOD_TASK_GROUP);
    let (gx, gy) = (groups.clamp(1, 65_535), groups.div_ceil(65_535).max(1));
    let t = targets;
    let mut pass = graph
        .pass(&format!("{prefix}.draw"))
        .buffer(frame, Access::UniformRead(Stages::Graphics))
        .buffer(patches, Access::StorageRead(Stages::Mesh))
        .buffer(vertices, Access::StorageRead(Stages::Mesh))
        .buffer(counters, Access::StorageReadWrite(Stages::Mesh));
    if options.record {
        pass = pass.buffer(list, Access::StorageWrite(Stages::Mesh));
    }
    pass.color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(t.zbuffer, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(
                &pipeline,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_LOD_PATCHES, patches),
                    Descriptor::Buffer(BINDING_LOD_VERTICES, vertices),
                    Descriptor::Buffer(BINDING_LOD_LIST, list),
                    Descriptor::Buffer(BINDING_LOD_COUNTERS, counters),
                ],
            );
            ctx.push(&pipeline, bytemuck::bytes_of(&params));
            ctx.draw_mesh_tasks(gx, gy, 1);
        });
    Ok(selection)
}

/// The geometry path: one vertex per patch; the geometry shader chooses the level and emits
/// its vertices (at most `LOD_PATCH_VERTICES`), drawing into `targets`. The counters and the
/// list are as `add_mesh`'s.
pub fn add_geometry(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    lod: &GpuLod,
    inputs: LodInputs,
    options: DrawOptions,
    targets: DrawTargets,
) -> Result<Selection> {
    if ctx.caps.max_geometry_output_vertices < LOD_PATCH_VERTICES {
        bail!(
            "the geometry path emits up to {LOD_PATCH_VERTICES} vertices per patch; the device \
             allows {}",
            ctx.caps.max_geometry_output_vertices
        );
    }
    let LodInputs {
        frame,
        patches,
        vertices,
    } = inputs;
    let selection = new_selection(graph, prefix, options.record.then_some(lod.max_selected));
    let Selection { list, counters } = selection;
    let geometry = vk::ShaderStageFlags::GEOMETRY;
    let pipeline = draw_pipeline(
        ctx,
        &["lod/patch.vert", "lod/expand.geom", "splat/points.frag"],
        &[
            binding(BINDING_FRAME, geometry | vk::ShaderStageFlags::FRAGMENT),
            binding(BINDING_LOD_PATCHES, geometry),
            binding(BINDING_LOD_VERTICES, geometry),
            binding(BINDING_LOD_LIST, geometry),
            binding(BINDING_LOD_COUNTERS, geometry),
        ],
        &options,
    )?;
    let params = draw_params(lod, &options);
    let patch_count = lod.patch_count;
    let t = targets;
    let stages = Stages::Graphics;
    let mut pass = graph
        .pass(&format!("{prefix}.draw"))
        .buffer(frame, Access::UniformRead(stages))
        .buffer(patches, Access::StorageRead(stages))
        .buffer(vertices, Access::StorageRead(stages))
        .buffer(counters, Access::StorageReadWrite(stages));
    if options.record {
        pass = pass.buffer(list, Access::StorageWrite(stages));
    }
    pass.color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(t.zbuffer, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(
                &pipeline,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_LOD_PATCHES, patches),
                    Descriptor::Buffer(BINDING_LOD_VERTICES, vertices),
                    Descriptor::Buffer(BINDING_LOD_LIST, list),
                    Descriptor::Buffer(BINDING_LOD_COUNTERS, counters),
                ],
            );
            ctx.push(&pipeline, bytemuck::bytes_of(&params));
            ctx.draw(patch_count, 1);
        });
    Ok(selection)
}
