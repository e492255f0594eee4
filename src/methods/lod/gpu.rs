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
//! Every path draws each splat as a square of its projected diameter or a perspective-correct
//! disc (`splat/flat.frag`) into the standard targets and counts the vertices it emits per
//! level. With a point budget (`DrawOptions::budget`, `add_budget`) two passes before the path
//! raise the threshold the levels are chosen with until the frame's samples fit.

use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;

use crate::gpu::layout::{
    LodParams, BINDING_FRAME, BINDING_LOD_COUNTERS, BINDING_LOD_LIST, BINDING_LOD_PATCHES,
    BINDING_LOD_VERTICES, LOD_BUDGET_BINS, LOD_GROUP, LOD_MAX_LEVELS, LOD_PATCH_VERTICES,
    LOD_SPEC_COLOR_LEVELS, LOD_SPEC_GEOMETRY_CHUNK, LOD_SPEC_RECORD, LOD_TASK_GROUP,
    SPLAT_RASTER_PERSPECTIVE, SPLAT_RASTER_SQUARES, SPLAT_SHADING_FLAT, SPLAT_SPEC_RASTER,
    SPLAT_SPEC_SHADING,
};
use crate::gpu::{Binding, Blend, Context, GeometryOutput, GraphicsDesc, Pipeline};
use crate::graph::{
    bind, Access, Bind, BufferId, BufferRange, GraphBuilder, ImageId, Load, PassBuilder, Stages,
};
use crate::methods::{SampleCounters, COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT};
use crate::upload::GpuLod;

/// Byte offset in the counters of the vertices selected per level (`LOD_MAX_LEVELS` u32),
/// after the list's `VkDrawIndirectCommand`.
pub const PER_LEVEL_OFFSET: u64 = 16;

/// Byte offset in the counters of the threshold (f32) the paths choose levels with: ε, or
/// what the point budget raised it to. Then the budget's coarsest samples (u32), two pads and
/// `LOD_BUDGET_BINS` bins (u32; `LOD_COUNTERS_MEMBERS` in `glsl/lod/lod.glsl`).
pub const THRESHOLD_OFFSET: u64 = PER_LEVEL_OFFSET + 4 * LOD_MAX_LEVELS as u64;

/// Output components of one geometry-shader vertex as the limits count them: `gl_PerVertex`
/// (position, point size, one clip and one cull distance: 7) and the splat interface of
/// `splat/flat.frag` (color, normal, centre, radius, size: 11).
pub const GEOMETRY_VERTEX_COMPONENTS: u32 = 18;

/// The geometry path's default vertices per invocation: 32 × 18 = 576 components, within the
/// 1024 of `maxGeometryTotalOutputComponents` every device offers (64 would need 1152), so
/// a patch's finest level takes two invocations.
pub const DEFAULT_GEOMETRY_CHUNK: u32 = 32;

/// Bytes of the selection's counters.
pub const COUNTER_BYTES: u64 = THRESHOLD_OFFSET + 16 + 4 * LOD_BUDGET_BINS as u64;

/// What a path writes.
#[derive(Clone, Copy, Debug)]
pub struct Selection {
    /// Indices into the object texture's vertices (`u32`), `max_selected` long; the first
    /// `counters`' vertex count hold this frame's selection, in no particular order.
    pub list: BufferId,
    /// `COUNTER_BYTES`: the `VkDrawIndirectCommand` of the list, the vertices per level.
    pub counters: BufferId,
}

impl Selection {
    /// The per-level sample counts in the counters, as a method publishes them
    /// (`BuildContext::samples`) for an object texture of `lod`'s levels.
    pub fn samples(&self, lod: &GpuLod) -> SampleCounters {
        SampleCounters {
            buffer: self.counters,
            offset: PER_LEVEL_OFFSET,
            levels: lod.levels,
        }
    }
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
    /// Draw perspective-correct discs (002 eqs. 5.4-5.5) rather than image-aligned squares
    /// of the projected diameter (eq. 5.1).
    pub discs: bool,
    /// Largest point size in pixels.
    pub max_point_size: f32,
    /// Mesh and geometry paths: also append every emitted vertex index to the list (tests).
    pub record: bool,
    /// The most samples a frame projects (0: no budget), filled by error priority
    /// (`add_budget`).
    pub budget: u32,
    /// Geometry path: the vertices one geometry invocation emits, its declared output limit
    /// (a power of two up to `LOD_PATCH_VERTICES`; the patch's level is split over
    /// `LOD_PATCH_VERTICES / geometry_chunk` invocations).
    pub geometry_chunk: u32,
}

impl DrawOptions {
    /// Threshold `epsilon`, the base color, squares, no budget, points up to 16 pixels,
    /// `DEFAULT_GEOMETRY_CHUNK` vertices per geometry invocation.
    pub fn new(epsilon: f32) -> DrawOptions {
        DrawOptions {
            epsilon,
            color_levels: false,
            discs: false,
            max_point_size: 16.0,
            record: false,
            budget: 0,
            geometry_chunk: DEFAULT_GEOMETRY_CHUNK,
        }
    }
}

/// Where a path draws: the standard targets and a reversed-Z depth buffer, all cleared.
#[derive(Clone, Copy, Debug)]
pub struct DrawTargets {
    pub color: ImageId,
    pub depth: ImageId,
    pub normal: ImageId,
    pub zbuffer: ImageId,
}

impl DrawTargets {
    /// `pass` drawing into the targets, all cleared.
    fn cleared(self, pass: PassBuilder<'_>) -> PassBuilder<'_> {
        pass.color(self.color, Load::Clear([0.0; 4]))
            .color(self.depth, Load::Clear([0.0; 4]))
            .color(self.normal, Load::Clear([0.0; 4]))
            .depth(self.zbuffer, Load::Clear([0.0; 4]))
    }
}

/// The counters of a path, reset by the pass `{prefix}.reset` (instance count 1, threshold
/// `epsilon`, the rest 0), and a list of `list_entries` indices (none: the list is the counters
/// buffer again).
fn new_selection(
    graph: &mut GraphBuilder,
    prefix: &str,
    list_entries: Option<u32>,
    epsilon: f32,
) -> Selection {
    let usage = vk::BufferUsageFlags::empty();
    let counters = graph.buffer(&format!("{prefix}.counters"), COUNTER_BYTES, usage);
    let list = list_entries.map_or(counters, |n| {
        graph.buffer(&format!("{prefix}.list"), u64::from(n.max(1)) * 4, usage)
    });
    let mut reset = [0u32; COUNTER_BYTES as usize / 4];
    reset[1] = 1;
    reset[THRESHOLD_OFFSET as usize / 4] = epsilon.to_bits();
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
        budget: options.budget,
    }
}

/// Declares `name`: one dispatch of `shader` with one thread per patch, reading the frame
/// and the patches, updating the counters and, when given, writing the list.
fn add_patch_pass(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    name: &str,
    (shader, params): (&str, LodParams),
    lod: &GpuLod,
    (frame, patches, counters): (BufferId, BufferId, BufferId),
    list: Option<BufferId>,
) -> Result<()> {
    let mut binds = vec![
        Bind::constants(BINDING_FRAME, frame),
        Bind::reads(BINDING_LOD_PATCHES, patches),
        Bind::updates(BINDING_LOD_COUNTERS, counters),
    ];
    if let Some(list) = list {
        binds.push(Bind::writes(BINDING_LOD_LIST, list));
    }
    let pipeline = Pipeline::compute(ctx, shader, &bind::compute_layout(&binds))?;
    let groups = u64::from(lod.patch_count.div_ceil(LOD_GROUP));
    graph.pass(name).binds(&binds).record(move |ctx| {
        ctx.bind_all(&pipeline, &binds);
        ctx.push(&pipeline, bytemuck::bytes_of(&params));
        ctx.dispatch_groups(groups);
    });
    Ok(())
}

/// The point budget: declares `{prefix}.budget.bins`, which sorts the samples every
/// refinement of a visible patch adds into bins of the projected error demanding it, and
/// `{prefix}.budget.threshold`, which admits refinements by decreasing error until `budget`
/// samples are reached and writes the threshold the path then chooses levels with (the CPU
/// reference is `ObjectTexture::budget_threshold`). Nothing with `budget` 0. A budget below
/// the patch count is refused: every patch in view draws at least its representative. Nothing
/// either when the budget holds every patch's finest level.
pub fn add_budget(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    inputs: (BufferId, BufferId, BufferId),
    lod: &GpuLod,
    epsilon: f32,
    budget: u32,
) -> Result<()> {
    // A budget the finest levels of every patch fit cannot bind: no passes.
    if budget == 0 || budget >= lod.max_selected {
        return Ok(());
    }
    if budget < lod.patch_count {
        bail!(
            "a point budget of {budget} samples is below the object texture's {} patches \
             (each in view draws at least its representative): raise it to at least {0}, or \
             0 for no budget",
            lod.patch_count
        );
    }
    let (frame, patches, counters) = inputs;
    let params = LodParams {
        epsilon,
        patch_count: lod.patch_count,
        budget,
        ..Default::default()
    };
    add_patch_pass(
        ctx,
        graph,
        &format!("{prefix}.budget.bins"),
        ("lod/budget_bins.comp", params),
        lod,
        (frame, patches, counters),
        None,
    )?;
    let binds = [Bind::updates(BINDING_LOD_COUNTERS, counters)];
    let threshold = Pipeline::compute(
        ctx,
        "lod/budget_threshold.comp",
        &bind::compute_layout(&binds),
    )?;
    graph
        .pass(&format!("{prefix}.budget.threshold"))
        .binds(&binds)
        .record(move |ctx| {
            ctx.bind_all(&threshold, &binds);
            ctx.push(&threshold, bytemuck::bytes_of(&params));
            ctx.dispatch(1, 1, 1);
        });
    Ok(())
}

/// `new_selection` with threshold `epsilon`, then the point budget's passes (`add_budget`).
fn budgeted_selection(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    list_entries: Option<u32>,
    lod: &GpuLod,
    (frame, patches): (BufferId, BufferId),
    (epsilon, budget): (f32, u32),
) -> Result<Selection> {
    let selection = new_selection(graph, prefix, list_entries, epsilon);
    let inputs = (frame, patches, selection.counters);
    add_budget(ctx, graph, prefix, inputs, lod, epsilon, budget)?;
    Ok(selection)
}

/// Declares the reset of the counters, the point budget's passes (`add_budget`) and the
/// selection pass over `patches` (the graph's id of `lod.patches`) for the camera in `frame`,
/// the threshold `epsilon` in pixels and `budget` samples (0: none).
#[allow(clippy::too_many_arguments)]
pub fn add_select(
    ctx: &Arc<Context>,
    graph: &mut GraphBuilder,
    prefix: &str,
    frame: BufferId,
    patches: BufferId,
    lod: &GpuLod,
    epsilon: f32,
    budget: u32,
) -> Result<Selection> {
    let selection = budgeted_selection(
        ctx,
        graph,
        prefix,
        Some(lod.max_selected),
        lod,
        (frame, patches),
        (epsilon, budget),
    )?;
    let Selection { list, counters } = selection;
    let params = LodParams {
        epsilon,
        patch_count: lod.patch_count,
        ..Default::default()
    };
    add_patch_pass(
        ctx,
        graph,
        &format!("{prefix}.select"),
        ("lod/select.comp", params),
        lod,
        (frame, patches, counters),
        Some(list),
    )?;
    Ok(selection)
}

/// A points pipeline drawing into the standard targets with reversed-Z depth, rasterized and
/// shaded by `splat/flat.frag` (squares or discs).
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
                (LOD_SPEC_GEOMETRY_CHUNK, options.geometry_chunk),
                (
                    SPLAT_SPEC_RASTER,
                    if options.discs {
                        SPLAT_RASTER_PERSPECTIVE
                    } else {
                        SPLAT_RASTER_SQUARES
                    },
                ),
                (SPLAT_SPEC_SHADING, SPLAT_SHADING_FLAT),
            ],
            geometry_output: shaders
                .iter()
                .any(|s| s.ends_with(".geom"))
                .then(|| GeometryOutput {
                    vertices: options.geometry_chunk,
                    invocations: LOD_PATCH_VERTICES / options.geometry_chunk,
                }),
        },
    )?))
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
    let selection = add_select(
        ctx,
        graph,
        prefix,
        frame,
        patches,
        lod,
        options.epsilon,
        options.budget,
    )?;
    let Selection { list, counters } = selection;
    let vertex_read = Access::StorageRead(Stages::Vertex);
    let binds = [
        Bind::buffer(BINDING_FRAME, frame, Access::UniformRead(Stages::Graphics)),
        Bind::buffer(BINDING_LOD_VERTICES, vertices, vertex_read),
        Bind::buffer(BINDING_LOD_LIST, list, vertex_read),
    ];
    let pipeline = draw_pipeline(
        ctx,
        &["lod/points.vert", "splat/flat.frag"],
        &bind::layout(
            &binds,
            vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
        ),
        &options,
    )?;
    let params = draw_params(lod, &options);
    let pass = graph
        .pass(&format!("{prefix}.draw"))
        .binds(&binds)
        .buffer_range(counters, BufferRange::new(0, 16), Access::IndirectRead);
    targets.cleared(pass).record(move |ctx| {
        ctx.bind_all(&pipeline, &binds);
        ctx.push(&pipeline, bytemuck::bytes_of(&params));
        ctx.draw_indirect(counters, 0, 1, 16);
    });
    Ok(selection)
}

/// How an expansion draw launches its patches.
#[derive(Clone, Copy)]
enum Launch {
    /// Task workgroups, folded into rows past `bind::MAX_GROUPS`.
    MeshTasks(u64),
    /// One vertex per patch.
    Vertices(u32),
}

/// The bindings of the mesh and geometry paths' draw: the frame, the patches and the vertices
/// read in `stages`, the counters updated and, under `record`, the list written.
fn expansion_binds(
    inputs: LodInputs,
    selection: Selection,
    stages: Stages,
    record: bool,
) -> [Bind; 5] {
    [
        Bind::buffer(
            BINDING_FRAME,
            inputs.frame,
            Access::UniformRead(Stages::Graphics),
        ),
        Bind::buffer(
            BINDING_LOD_PATCHES,
            inputs.patches,
            Access::StorageRead(stages),
        ),
        Bind::buffer(
            BINDING_LOD_VERTICES,
            inputs.vertices,
            Access::StorageRead(stages),
        ),
        if record {
            Bind::buffer(
                BINDING_LOD_LIST,
                selection.list,
                Access::StorageWrite(stages),
            )
        } else {
            Bind::unused_in(BINDING_LOD_LIST, stages)
        },
        Bind::buffer(
            BINDING_LOD_COUNTERS,
            selection.counters,
            Access::StorageReadWrite(stages),
        ),
    ]
}

/// Declares `{prefix}.draw` for the mesh and geometry paths: `pipeline` bound to `binds`
/// (`expansion_binds`), drawing into the cleared `targets`.
fn add_expansion_draw(
    graph: &mut GraphBuilder,
    prefix: &str,
    (pipeline, params): (Arc<Pipeline>, LodParams),
    launch: Launch,
    binds: [Bind; 5],
    t: DrawTargets,
) {
    let pass = graph.pass(&format!("{prefix}.draw")).binds(&binds);
    t.cleared(pass).record(move |ctx| {
        ctx.bind_all(&pipeline, &binds);
        ctx.push(&pipeline, bytemuck::bytes_of(&params));
        match launch {
            Launch::MeshTasks(groups) => {
                let (x, y) = bind::fold_groups(groups);
                ctx.draw_mesh_tasks(x, y, 1)
            }
            Launch::Vertices(n) => ctx.draw(n, 1),
        }
    });
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
    let selection = budgeted_selection(
        ctx,
        graph,
        prefix,
        options.record.then_some(lod.max_selected),
        lod,
        (inputs.frame, inputs.patches),
        (options.epsilon, options.budget),
    )?;
    let binds = expansion_binds(inputs, selection, Stages::Mesh, options.record);
    let stages = vk::ShaderStageFlags::TASK_EXT
        | vk::ShaderStageFlags::MESH_EXT
        | vk::ShaderStageFlags::FRAGMENT;
    let pipeline = draw_pipeline(
        ctx,
        &["lod/select.task", "lod/points.mesh", "splat/flat.frag"],
        &bind::layout(&binds, stages),
        &options,
    )?;
    let params = draw_params(lod, &options);
    let launch = Launch::MeshTasks(u64::from(lod.patch_count.div_ceil(LOD_TASK_GROUP)));
    add_expansion_draw(graph, prefix, (pipeline, params), launch, binds, targets);
    Ok(selection)
}

/// The geometry path: one vertex per patch; the geometry shader chooses the level and emits
/// its vertices (at most `LOD_PATCH_VERTICES`, `options.geometry_chunk` per invocation),
/// drawing into `targets`. The counters and the
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
    let chunk = options.geometry_chunk;
    if !chunk.is_power_of_two() || chunk > LOD_PATCH_VERTICES {
        bail!(
            "the geometry path's vertices per invocation must be a power of two up to \
             {LOD_PATCH_VERTICES}, not {chunk}"
        );
    }
    let components = chunk * GEOMETRY_VERTEX_COMPONENTS;
    if chunk > ctx.caps.max_geometry_output_vertices
        || components > ctx.caps.max_geometry_total_output_components
    {
        bail!(
            "{chunk} vertices per geometry invocation declare {components} output components; \
             the device allows {} vertices and {} components",
            ctx.caps.max_geometry_output_vertices,
            ctx.caps.max_geometry_total_output_components
        );
    }
    let invocations = LOD_PATCH_VERTICES / chunk;
    if invocations > ctx.caps.max_geometry_shader_invocations {
        bail!(
            "{chunk} vertices per invocation need {invocations} geometry invocations per \
             patch; the device allows {}",
            ctx.caps.max_geometry_shader_invocations
        );
    }
    let selection = budgeted_selection(
        ctx,
        graph,
        prefix,
        options.record.then_some(lod.max_selected),
        lod,
        (inputs.frame, inputs.patches),
        (options.epsilon, options.budget),
    )?;
    let binds = expansion_binds(inputs, selection, Stages::Graphics, options.record);
    let pipeline = draw_pipeline(
        ctx,
        &["lod/patch.vert", "lod/expand.geom", "splat/flat.frag"],
        &bind::layout(
            &binds,
            vk::ShaderStageFlags::GEOMETRY | vk::ShaderStageFlags::FRAGMENT,
        ),
        &options,
    )?;
    let params = draw_params(lod, &options);
    let launch = Launch::Vertices(lod.patch_count);
    add_expansion_draw(graph, prefix, (pipeline, params), launch, binds, targets);
    Ok(selection)
}
