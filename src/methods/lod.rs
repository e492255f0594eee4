//! Level of detail from object textures (000 ch. 7, `crate::lod`): the expansion paths.
//!
//! * `lod-compute`: a compute pre-pass chooses each patch's level and writes the list of the
//!   chosen vertices and an indirect draw's arguments; one indirect draw pulls them through
//!   the list (`crate::lod::gpu::add_compute`).
//! * `lod-mesh`: a task shader chooses the levels, one mesh workgroup per patch emits the
//!   chosen level's vertices (`crate::lod::gpu::add_mesh`).
//! * `lod-geometry`: the thesis' path (§7.2): one vertex per patch, the geometry shader chooses
//!   the level and emits its vertices (`crate::lod::gpu::add_geometry`).
//!
//! All three draw points covering each splat's projected diameter and publish their
//! selection's per-level vertex counts (`BuildContext::samples`), which the renderer reads
//! back every frame.

use anyhow::{bail, Result};
use ash::vk;

use super::{BuildContext, Feature, MethodInfo, ParamSpec, SampleCounters, ZBUFFER_FORMAT};
use crate::gpu::ImageDesc;
use crate::lod::gpu::{self, DrawOptions, DrawTargets, LodInputs, COUNTER_LEVELS_OFFSET};

/// The default ε: the largest measured value that costs the full dragon less than 0.5 dB of
/// PSNR against ε = 0 at every distance (`benches/sweeps/lod.toml` on lavapipe: 0.01 dB near,
/// 0.15 default framing, 0.28 far, where it draws a third faster; ε = 1 lost 8.5 dB). Denser
/// clouds seen from near need less (5 M points: 2.5 dB at 0.05).
const DEFAULT_EPSILON: f32 = 0.05;

const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "epsilon",
        default: DEFAULT_EPSILON,
        min: 0.0,
        max: 64.0,
        doc: "threshold ε of the projected perpendicular error, in pixels (0: no error allowed)",
    },
    ParamSpec {
        name: "levels",
        default: 0.0,
        min: 0.0,
        max: 1.0,
        doc: "1: color splats by level (thesis Fig. 7.4: grey, yellow, blue, red for 0-3)",
    },
    ParamSpec {
        name: "max_size",
        default: 16.0,
        min: 1.0,
        max: 64.0,
        doc: "largest point size in pixels",
    },
];

pub const COMPUTE_INFO: MethodInfo = MethodInfo {
    name: "lod-compute",
    summary: "level of detail from object textures (000 ch. 7): compute selection, indirect draw",
    params: PARAMS,
    needs_faces: false,
    features: &[],
    culls_batches: false,
    needs_lod: true,
    build: build_compute,
};

pub const MESH_INFO: MethodInfo = MethodInfo {
    name: "lod-mesh",
    summary: "level of detail from object textures (000 ch. 7): task-shader selection, mesh draw",
    params: PARAMS,
    needs_faces: false,
    features: &[Feature::MeshShader],
    culls_batches: false,
    needs_lod: true,
    build: build_mesh,
};

pub const GEOMETRY_INFO: MethodInfo = MethodInfo {
    name: "lod-geometry",
    summary: "level of detail from object textures (000 ch. 7): geometry-shader expansion",
    params: PARAMS,
    needs_faces: false,
    features: &[Feature::GeometryShader, Feature::GeometryPoints],
    culls_batches: false,
    needs_lod: true,
    build: build_geometry,
};

/// Which expansion path a method draws with.
#[derive(Clone, Copy)]
enum Path {
    Compute,
    Mesh,
    Geometry,
}

fn build(b: &mut BuildContext<'_>, path: Path) -> Result<()> {
    let name = b.config.method.name;
    let Some(lod) = b.scene.lod.clone() else {
        bail!("method '{name}' needs the scene's object texture (UploadOptions::lod)");
    };
    let inputs = LodInputs::import(b.graph, b.frame, &lod);
    let options = DrawOptions {
        epsilon: b.config.get("epsilon"),
        color_levels: b.config.get("levels") >= 0.5,
        max_point_size: b.config.get("max_size").min(b.ctx.caps.point_size_range[1]),
        record: false,
    };
    let zbuffer = b.graph.image(
        &format!("{name}.zbuffer"),
        ImageDesc {
            format: ZBUFFER_FORMAT,
            width: b.width,
            height: b.height,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        },
    );
    let t = b.targets;
    let targets = DrawTargets {
        color: t.color,
        depth: t.depth,
        normal: t.normal,
        zbuffer,
    };
    let add = match path {
        Path::Compute => gpu::add_compute,
        Path::Mesh => gpu::add_mesh,
        Path::Geometry => gpu::add_geometry,
    };
    let selection = add(b.ctx, b.graph, name, &lod, inputs, options, targets)?;
    b.samples = Some(SampleCounters {
        buffer: selection.counters,
        offset: COUNTER_LEVELS_OFFSET,
        levels: lod.levels,
    });
    Ok(())
}

fn build_compute(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, Path::Compute)
}

fn build_mesh(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, Path::Mesh)
}

fn build_geometry(b: &mut BuildContext<'_>) -> Result<()> {
    build(b, Path::Geometry)
}
