//! Level of detail from object textures (000 ch. 7, `crate::lod`): the expansion paths.
//!
//! * `lod-compute`: a compute pre-pass chooses each patch's level and writes the list of the
//!   chosen vertices and an indirect draw's arguments; one indirect draw pulls them through
//!   the list (`crate::methods::lod::gpu::add_draw`, `Path::Compute`).
//! * `lod-mesh`: a task shader chooses the levels, one mesh workgroup per patch emits the
//!   chosen level's vertices (`Path::Mesh`).
//! * `lod-geometry`: the thesis' path (§7.2): one vertex per patch, the geometry shader chooses
//!   the level and emits its vertices (`Path::Geometry`).
//!
//! All three draw each sample as a perspective-correct disc (or, with `shape=0`, a square of
//! its projected diameter), honour the point budget (`budget`) and publish their selection's
//! per-level vertex counts (`BuildContext::samples`), which the renderer reads back every
//! frame.

use anyhow::{bail, Result};

use crate::layout::LOD_PATCH_VERTICES;
use crate::methods::{BuildContext, Feature, MethodInfo, ParamSpec};
pub mod gpu;

use gpu::{DrawOptions, DrawTargets, LodInputs, Path, DEFAULT_GEOMETRY_CHUNK};

/// The default ε: the largest measured value that costs the full dragon, drawn as discs,
/// less than 0.5 dB of PSNR against ε = 0 at every distance from 0.5 to 8 times the default
/// framing, or keeps it above 40 dB (visually lossless) where it costs more
/// (`benches/sweeps/lod.toml` on lavapipe, `crate::eval::lod`): at 0.02 the far views lose
/// 1.8-2.1 dB from 43.5-46 dB, while 0.03 drops the view at twice the framing distance from
/// 40.8 to 37.8 dB. The strict 0.5 dB rule allows only 0.005 up to 4 times the distance and
/// nothing at 8, where the samples are sub-pixel and any coarser level changes which disc a
/// pixel shows.
const DEFAULT_EPSILON: f32 = 0.02;

/// The default point budget: 4 M samples, about 9 ms of the hardware point pipeline on an
/// H100 (0.44 G points/s measured, `shared/gpu/README.md`). Clouds whose finest levels hold
/// fewer samples skip the budget's passes.
const DEFAULT_BUDGET: f32 = 4_000_000.0;

pub(super) const EPSILON: ParamSpec = ParamSpec {
    name: "epsilon",
    default: DEFAULT_EPSILON,
    min: 0.0,
    max: 64.0,
    doc: "threshold ε of the projected perpendicular error, in pixels (0: no error allowed)",
};

const LEVELS: ParamSpec = ParamSpec {
    name: "levels",
    default: 0.0,
    min: 0.0,
    max: 1.0,
    doc: "1: color splats by level (thesis Fig. 7.4: grey, yellow, blue, red for 0-3)",
};

/// Discs by default: drawn as squares of their projected diameter, the dragon at ε = 0 scores
/// 26.0 dB against the mesh with 0.93 px of silhouette error; as perspective-correct discs
/// 36.0 dB and 0.25 px (lavapipe, 512², default framing). The perpendicular error bounds how
/// far a parent's disc strays from its children's, not a square's corners.
const SHAPE: ParamSpec = ParamSpec {
    name: "shape",
    default: 1.0,
    min: 0.0,
    max: 1.0,
    doc: "0: image-aligned squares of the projected diameter (002 eq. 5.1); 1: \
          perspective-correct discs (002 eqs. 5.4-5.5)",
};

const MAX_SIZE: ParamSpec = ParamSpec {
    name: "max_size",
    default: 16.0,
    min: 1.0,
    max: 64.0,
    doc: "largest point size in pixels",
};

const BUDGET: ParamSpec = ParamSpec {
    name: "budget",
    default: DEFAULT_BUDGET,
    min: 0.0,
    max: 2_000_000_000.0,
    doc: "most samples a frame projects, filled by error priority (0: no budget)",
};

const CHUNK: ParamSpec = ParamSpec {
    name: "chunk",
    default: DEFAULT_GEOMETRY_CHUNK as f32,
    min: 1.0,
    max: LOD_PATCH_VERTICES as f32,
    doc: "vertices per geometry invocation, its declared output limit (a power of two; the \
          patch is split over 64 / chunk invocations; 64 exceeds the 1024 output components \
          most devices allow)",
};

const PARAMS: &[ParamSpec] = &[EPSILON, LEVELS, SHAPE, MAX_SIZE, BUDGET];

const GEOMETRY_PARAMS: &[ParamSpec] = &[EPSILON, LEVELS, SHAPE, MAX_SIZE, BUDGET, CHUNK];

pub const COMPUTE_INFO: MethodInfo = MethodInfo {
    params: PARAMS,
    needs_lod: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "lod-compute",
        "level of detail from object textures (000 ch. 7): compute selection, indirect draw",
        build_compute,
    )
};

pub const MESH_INFO: MethodInfo = MethodInfo {
    params: PARAMS,
    features: &[Feature::MeshShader],
    needs_lod: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "lod-mesh",
        "level of detail from object textures (000 ch. 7): task-shader selection, mesh draw",
        build_mesh,
    )
};

pub const GEOMETRY_INFO: MethodInfo = MethodInfo {
    params: GEOMETRY_PARAMS,
    features: &[Feature::GeometryShader, Feature::GeometryPoints],
    needs_lod: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "lod-geometry",
        "level of detail from object textures (000 ch. 7): geometry-shader expansion",
        build_geometry,
    )
};

fn build(b: &mut BuildContext<'_>, path: Path) -> Result<()> {
    let name = b.config.method.name;
    let Some(lod) = b.scene.lod.clone() else {
        bail!("method '{name}' needs the scene's object texture (UploadOptions::lod)");
    };
    let inputs = LodInputs::import(b.graph, b.frame, &lod);
    let options = DrawOptions {
        path,
        epsilon: b.config.get("epsilon"),
        color_levels: b.config.get("levels") >= 0.5,
        discs: b.config.get("shape") >= 0.5,
        max_point_size: b.config.get("max_size").min(b.ctx.caps.point_size_range[1]),
        record: false,
        budget: b.config.get("budget").round() as u32,
        geometry_chunk: match path {
            Path::Geometry => b.config.get("chunk").round() as u32,
            _ => LOD_PATCH_VERTICES,
        },
    };
    let zbuffer = b.zbuffer(&format!("{name}.zbuffer"));
    let t = b.targets;
    let targets = DrawTargets {
        color: t.color,
        depth: t.depth,
        normal: t.normal,
        zbuffer,
    };
    let selection = gpu::add_draw(b.ctx, b.graph, name, &lod, inputs, options, targets)?;
    b.samples = Some(selection.samples(&lod));
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
