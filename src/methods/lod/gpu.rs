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

use anyhow::{bail, Result};
use ash::vk;

use crate::gpu::{Context, GeometryOutput, GraphicsDesc};
use crate::gpu_scene::GpuLod;
use crate::graph::{
    bind, Access, Bind, Binds, BufferId, BufferRange, DrawPass, GraphBuilder, ImageId, Load, Stages,
};
use crate::layout::{
    LodParams, BINDING_FRAME, BINDING_LOD_COUNTERS, BINDING_LOD_LIST, BINDING_LOD_PATCHES,
    BINDING_LOD_VERTICES, LOD_BUDGET_BINS, LOD_GROUP, LOD_MAX_LEVELS, LOD_PATCH_VERTICES,
    LOD_SPEC_COLOR_LEVELS, LOD_SPEC_GEOMETRY_CHUNK, LOD_SPEC_RECORD, LOD_TASK_GROUP,
    SPLAT_RASTER_PERSPECTIVE, SPLAT_RASTER_SQUARES, SPLAT_SHADING_FLAT, SPLAT_SPEC_RASTER,
    SPLAT_SPEC_SHADING,
};
use crate::methods::{points_desc, SampleCounters};

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

/// How the selected points reach the screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Path {
    /// A selection pass writes the list; one indirect draw of it.
    Compute,
    /// Task and mesh shaders choose levels and emit the points.
    Mesh,
    /// A geometry shader chooses the level and emits the points.
    Geometry,
}

/// How a path draws.
#[derive(Clone, Copy, Debug)]
pub struct DrawOptions {
    pub path: Path,
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
    /// The compute path, threshold `epsilon`, the base color, squares, no budget, points up to 16 pixels,
    /// `DEFAULT_GEOMETRY_CHUNK` vertices per geometry invocation.
    pub fn new(epsilon: f32) -> DrawOptions {
        DrawOptions {
            path: Path::Compute,
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
    fn cleared(self, pass: DrawPass<'_>) -> DrawPass<'_> {
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
    graph: &mut GraphBuilder,
    name: &str,
    (shader, params): (&str, LodParams),
    lod: &GpuLod,
    (frame, patches, counters): (BufferId, BufferId, BufferId),
    list: Option<BufferId>,
) {
    let mut binds = Binds::from([
        Bind::constants(BINDING_FRAME, frame),
        Bind::reads(BINDING_LOD_PATCHES, patches),
        Bind::updates(BINDING_LOD_COUNTERS, counters),
    ]);
    if let Some(list) = list {
        binds.push(Bind::writes(BINDING_LOD_LIST, list));
    }
    graph
        .compute(name, shader, &binds)
        .push(&params)
        .dispatch(u64::from(lod.patch_count.div_ceil(LOD_GROUP)));
}

/// The point budget: declares `{prefix}.budget.bins`, which sorts the samples every
/// refinement of a visible patch adds into bins of the projected error demanding it, and
/// `{prefix}.budget.threshold`, which admits refinements by decreasing error until `budget`
/// samples are reached and writes the threshold the path then chooses levels with (the CPU
/// reference is `ObjectTexture::budget_threshold`). Nothing with `budget` 0. A budget below
/// the patch count is refused: every patch in view draws at least its representative. Nothing
/// either when the budget holds every patch's finest level.
pub fn add_budget(
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
        graph,
        &format!("{prefix}.budget.bins"),
        ("lod/budget_bins.comp", params),
        lod,
        (frame, patches, counters),
        None,
    );
    graph
        .compute(
            &format!("{prefix}.budget.threshold"),
            "lod/budget_threshold.comp",
            &[Bind::updates(BINDING_LOD_COUNTERS, counters)],
        )
        .push(&params)
        .dispatch(1);
    Ok(())
}

/// The counters and list of `new_selection`, then the point budget's passes (`add_budget`).
fn budgeted_selection(
    graph: &mut GraphBuilder,
    prefix: &str,
    list_entries: Option<u32>,
    lod: &GpuLod,
    (frame, patches): (BufferId, BufferId),
    (epsilon, budget): (f32, u32),
) -> Result<Selection> {
    let selection = new_selection(graph, prefix, list_entries, epsilon);
    let inputs = (frame, patches, selection.counters);
    add_budget(graph, prefix, inputs, lod, epsilon, budget)?;
    Ok(selection)
}

/// Declares the reset of the counters, the point budget's passes (`add_budget`) and the
/// selection pass over `patches` (the graph's id of `lod.patches`) for the camera in `frame`,
/// the threshold `epsilon` in pixels and `budget` samples (0: none).
pub fn add_select(
    graph: &mut GraphBuilder,
    prefix: &str,
    (frame, patches): (BufferId, BufferId),
    lod: &GpuLod,
    (epsilon, budget): (f32, u32),
) -> Result<Selection> {
    let entries = Some(lod.max_selected);
    let selection = budgeted_selection(
        graph,
        prefix,
        entries,
        lod,
        (frame, patches),
        (epsilon, budget),
    )?;
    let params = LodParams {
        epsilon,
        patch_count: lod.patch_count,
        ..Default::default()
    };
    add_patch_pass(
        graph,
        &format!("{prefix}.select"),
        ("lod/select.comp", params),
        lod,
        (frame, patches, selection.counters),
        Some(selection.list),
    );
    Ok(selection)
}

/// The points pipeline state of every path: the standard targets with reversed-Z depth,
/// rasterized and shaded by `splat/flat.frag` (squares or discs).
fn draw_desc(shaders: &[&'static str], options: &DrawOptions) -> GraphicsDesc {
    GraphicsDesc {
        specialization: vec![
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
        ..points_desc(shaders)
    }
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

/// Fails where the device cannot run the geometry path with `chunk` vertices per invocation.
fn check_geometry(ctx: &Context, chunk: u32) -> Result<()> {
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
    Ok(())
}

/// Declares `options.path`'s passes drawing `lod` into the cleared `targets`: the
/// counters' reset, the point budget's passes, then
/// * `Path::Compute`: the selection pass and one indirect draw of the list;
/// * `Path::Mesh`: task workgroups of `LOD_TASK_GROUP` patches choose levels and launch one
///   mesh workgroup per patch;
/// * `Path::Geometry`: one vertex per patch; the geometry shader chooses the level and emits
///   its vertices (at most `LOD_PATCH_VERTICES`, `options.geometry_chunk` per invocation).
///
/// The mesh and geometry paths count the vertices emitted per level; with `options.record`
/// their list holds every emitted index and the first counter their number (otherwise the
/// list is the counters buffer again, never written).
pub fn add_draw(
    ctx: &Context,
    graph: &mut GraphBuilder,
    prefix: &str,
    lod: &GpuLod,
    inputs: LodInputs,
    options: DrawOptions,
    targets: DrawTargets,
) -> Result<Selection> {
    if options.path == Path::Geometry {
        check_geometry(ctx, options.geometry_chunk)?;
    }
    let sources = (inputs.frame, inputs.patches);
    let threshold = (options.epsilon, options.budget);
    let selection = if options.path == Path::Compute {
        add_select(graph, prefix, sources, lod, threshold)?
    } else {
        let entries = options.record.then_some(lod.max_selected);
        budgeted_selection(graph, prefix, entries, lod, sources, threshold)?
    };
    let Selection { list, counters } = selection;
    let params = draw_params(lod, &options);
    let name = format!("{prefix}.draw");
    match options.path {
        Path::Compute => {
            let vertex_read = Access::StorageRead(Stages::Vertex);
            let binds = [
                Bind::buffer(
                    BINDING_FRAME,
                    inputs.frame,
                    Access::UniformRead(Stages::Graphics),
                ),
                Bind::buffer(BINDING_LOD_VERTICES, inputs.vertices, vertex_read),
                Bind::buffer(BINDING_LOD_LIST, list, vertex_read),
            ];
            let desc = draw_desc(&["lod/points.vert", "splat/flat.frag"], &options);
            targets
                .cleared(graph.draw(&name, desc, &binds))
                .push(&params)
                .declare(|p| {
                    p.buffer_range(counters, BufferRange::new(0, 16), Access::IndirectRead)
                })
                .draw(move |ctx| ctx.draw_indirect(counters, 0, 1, 16));
        }
        Path::Mesh => {
            let binds = expansion_binds(inputs, selection, Stages::Mesh, options.record);
            let shaders = ["lod/select.task", "lod/points.mesh", "splat/flat.frag"];
            let groups = u64::from(lod.patch_count.div_ceil(LOD_TASK_GROUP));
            targets
                .cleared(graph.draw(&name, draw_desc(&shaders, &options), &binds))
                .push(&params)
                .draw(move |ctx| {
                    let (x, y) = bind::fold_groups(groups);
                    ctx.draw_mesh_tasks(x, y, 1)
                });
        }
        Path::Geometry => {
            let binds = expansion_binds(inputs, selection, Stages::Graphics, options.record);
            let shaders = ["lod/patch.vert", "lod/expand.geom", "splat/flat.frag"];
            let patches = lod.patch_count;
            targets
                .cleared(graph.draw(&name, draw_desc(&shaders, &options), &binds))
                .push(&params)
                .draw(move |ctx| ctx.draw(patches, 1));
        }
    }
    Ok(selection)
}
