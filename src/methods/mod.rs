//! Rendering methods. Each method registers itself in `METHODS` and builds its passes on the
//! render graph, writing the standard frame targets (color, linear depth, normal). Adding a
//! method to the viewer, the headless renderer and the benchmark sweeps needs only an entry here.

pub mod common;
pub mod compute;
mod ewa;
pub mod hpr;
pub mod kernel;
pub mod lod;
mod mesh;
pub mod pyramid;
mod splat;

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;

use crate::gpu::{Blend, Capabilities, Context, GraphicsDesc, ImageDesc};
use crate::gpu_scene::{GpuScene, UploadOptions};
use crate::graph::{Access, Bind, BufferId, GraphBuilder, ImageId, Stages};
use crate::layout::{BINDING_BATCHES, BINDING_FRAME, BINDING_OUTPUT0, BINDING_SEGMENTS};
use crate::suggest::did_you_mean;

/// Format of the color target (sRGB-encoded by the shaders, so it can be a storage image).
pub const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;
/// Linear view depth, 0 where empty.
pub const DEPTH_FORMAT: vk::Format = vk::Format::R32_SFLOAT;
/// View-space normal (w = 1 where covered).
pub const NORMAL_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// Hardware depth buffer (reversed-Z, cleared to 0).
pub const ZBUFFER_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// A tunable parameter of a method.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    pub name: &'static str,
    pub default: f32,
    pub min: f32,
    pub max: f32,
    pub doc: &'static str,
}

/// A registered method.
pub struct MethodInfo {
    pub name: &'static str,
    pub summary: &'static str,
    pub params: &'static [ParamSpec],
    /// Renders triangle faces (ground truth) rather than points.
    pub needs_faces: bool,
    /// Device features the method cannot run without.
    pub features: &'static [Feature],
    /// Projects only the points of batches inside the view frustum (`streams::batch_visible`);
    /// otherwise every point goes through projection each frame.
    pub culls_batches: bool,
    /// Draws the scene's object texture (`GpuScene::lod`, level of detail of 000 ch. 7).
    pub needs_lod: bool,
    /// Reads hidden point removal's flipping-radius data (`UploadOptions::hpr`).
    pub needs_hpr: bool,
    /// Reads the linear normal fields of Phong splatting (`Stream::NormalField`).
    pub needs_normal_field: bool,
    /// Reads per-point normals and splat radii: a cloud without them gets them estimated
    /// (k nearest neighbours, `scene::preprocess`) before the method's first frame. A method
    /// without this draws from the raw positions, unlit where the cloud has no normals.
    pub needs_surfels: bool,
    pub build: fn(&mut BuildContext<'_>) -> Result<()>,
}

/// A device feature a method may need.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// 64-bit integers and 64-bit atomics on storage buffers (`shaderInt64`,
    /// `shaderBufferInt64Atomics`).
    Int64Atomics,
    /// Mesh and task shaders (`VK_EXT_mesh_shader`).
    MeshShader,
    /// Geometry shaders.
    GeometryShader,
    /// Geometry shaders that emit sized points and write storage buffers
    /// (`shaderTessellationAndGeometryPointSize`, `vertexPipelineStoresAndAtomics`).
    GeometryPoints,
}

impl Feature {
    /// Whether a device with `caps` has the feature.
    pub fn supported(self, caps: &Capabilities) -> bool {
        match self {
            Feature::Int64Atomics => caps.buffer_int64_atomics,
            Feature::MeshShader => caps.mesh_shader && caps.task_shader,
            Feature::GeometryShader => caps.geometry_shader,
            Feature::GeometryPoints => caps.geometry_points,
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Feature::Int64Atomics => {
                "64-bit buffer atomics (shaderInt64, shaderBufferInt64Atomics)"
            }
            Feature::MeshShader => "mesh and task shaders (VK_EXT_mesh_shader)",
            Feature::GeometryShader => "geometry shaders",
            Feature::GeometryPoints => {
                "geometry shaders writing point sizes and storage buffers \
                 (shaderTessellationAndGeometryPointSize, vertexPipelineStoresAndAtomics)"
            }
        }
    }
}

impl MethodInfo {
    /// A method with no parameters, needs or features: a registration states only what
    /// differs, `MethodInfo { needs_surfels: true, ..MethodInfo::new(name, summary, build) }`.
    pub const fn new(
        name: &'static str,
        summary: &'static str,
        build: fn(&mut BuildContext<'_>) -> Result<()>,
    ) -> MethodInfo {
        MethodInfo {
            name,
            summary,
            params: &[],
            needs_faces: false,
            features: &[],
            culls_batches: false,
            needs_lod: false,
            needs_hpr: false,
            needs_normal_field: false,
            needs_surfels: false,
            build,
        }
    }

    /// Why the method cannot run on a device with `caps`, or `None` when it can.
    pub fn unsupported(&self, caps: &Capabilities) -> Option<String> {
        let missing: Vec<_> = self
            .features
            .iter()
            .filter(|f| !f.supported(caps))
            .map(|f| f.describe())
            .collect();
        (!missing.is_empty()).then(|| {
            format!(
                "method '{}' needs {}, which the device '{}' lacks",
                self.name,
                missing.join(" and "),
                caps.device_name
            )
        })
    }

    /// `options` with the per-scene data this method reads switched on (the object texture,
    /// the normal fields); what other methods need stays as `options` had it.
    pub fn upload_options(&self, options: UploadOptions) -> UploadOptions {
        UploadOptions {
            lod: options.lod || self.needs_lod,
            normal_field: options.normal_field || self.needs_normal_field,
            hpr: options.hpr || self.needs_hpr,
            ..options
        }
    }
}

/// Every method, in the order the viewer cycles through them.
pub static METHODS: &[MethodInfo] = &[
    splat::points::INFO,
    compute::COMPUTE,
    compute::COMPUTE_HQ,
    mesh::INFO,
    splat::POINTS_FLAT_INFO,
    splat::SQUARES_FLAT_INFO,
    splat::AFFINE_FLAT_INFO,
    splat::PERSPECTIVE_FLAT_INFO,
    splat::POINTS_DEFERRED_INFO,
    splat::SQUARES_DEFERRED_INFO,
    splat::AFFINE_DEFERRED_INFO,
    splat::PERSPECTIVE_DEFERRED_INFO,
    splat::POINTS_GOURAUD_INFO,
    splat::SQUARES_GOURAUD_INFO,
    splat::AFFINE_GOURAUD_INFO,
    splat::PERSPECTIVE_GOURAUD_INFO,
    splat::POINTS_PHONG_INFO,
    splat::SQUARES_PHONG_INFO,
    splat::AFFINE_PHONG_INFO,
    splat::PERSPECTIVE_PHONG_INFO,
    ewa::INFO,
    pyramid::INFO,
    pyramid::HYBRID_INFO,
    pyramid::LOD_INFO,
    kernel::KERNEL3,
    kernel::KERNEL5,
    kernel::KERNEL7,
    hpr::INFO,
    hpr::MESH_INFO,
    lod::COMPUTE_INFO,
    lod::MESH_INFO,
    lod::GEOMETRY_INFO,
    splat::paraboloids::INFO,
];

/// Looks a method up by name.
pub fn find(name: &str) -> Result<&'static MethodInfo> {
    METHODS.iter().find(|m| m.name == name).ok_or_else(|| {
        let names: Vec<_> = METHODS.iter().map(|m| m.name).collect();
        anyhow::anyhow!(
            "unknown method '{name}'{} (available: {})",
            did_you_mean(name, names.iter().copied()),
            names.join(", ")
        )
    })
}

/// A method and its parameter values, e.g. `points:size=3`.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodConfig {
    pub method: &'static MethodInfo,
    pub params: BTreeMap<String, f32>,
}

impl std::fmt::Debug for MethodInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

impl PartialEq for MethodInfo {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl MethodConfig {
    /// Parses `name` or `name:key=value,key=value`; unknown keys and out-of-range values are
    /// errors naming the key.
    pub fn parse(s: &str) -> Result<Self> {
        let (name, rest) = s.split_once(':').unwrap_or((s, ""));
        let method = find(name.trim())?;
        let mut params = BTreeMap::new();
        for kv in rest.split(',').filter(|t| !t.trim().is_empty()) {
            let Some((k, v)) = kv.split_once('=') else {
                bail!("method parameter '{kv}' must be key=value");
            };
            let (k, v) = (k.trim(), v.trim());
            let Some(spec) = method.params.iter().find(|p| p.name == k) else {
                let known: Vec<_> = method.params.iter().map(|p| p.name).collect();
                bail!(
                    "method '{}' has no parameter '{k}'{} (parameters: {})",
                    method.name,
                    did_you_mean(k, known.iter().copied()),
                    known.join(", ")
                );
            };
            let value: f32 = v
                .parse()
                .ok()
                .filter(|x: &f32| x.is_finite())
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "{}: {k}={v} is not a number (expected {}..={})",
                        method.name,
                        spec.min,
                        spec.max
                    )
                })?;
            if value < spec.min || value > spec.max {
                bail!(
                    "{}: {k}={v} is out of range ({}..={})",
                    method.name,
                    spec.min,
                    spec.max
                );
            }
            params.insert(k.to_string(), value);
        }
        Ok(Self { method, params })
    }

    /// Value of parameter `name` (its default when not set).
    pub fn get(&self, name: &str) -> f32 {
        self.params.get(name).copied().unwrap_or_else(|| {
            self.method
                .params
                .iter()
                .find(|p| p.name == name)
                .map_or(0.0, |p| p.default)
        })
    }

    /// Canonical `name:key=value,...` with every parameter (defaults included).
    pub fn label(&self) -> String {
        let params: Vec<_> = self
            .method
            .params
            .iter()
            .map(|p| format!("{}={}", p.name, self.get(p.name)))
            .collect();
        if params.is_empty() {
            self.method.name.to_string()
        } else {
            format!("{}:{}", self.method.name, params.join(","))
        }
    }
}

/// The standard outputs every method writes.
#[derive(Clone, Copy, Debug)]
pub struct Targets {
    pub color: ImageId,
    pub depth: ImageId,
    pub normal: ImageId,
}

impl Targets {
    /// The three targets as storage images a compute pass writes, at `BINDING_OUTPUT0` and the
    /// two bindings after it (color, depth, normal).
    pub fn compute_writes(&self) -> [Bind; 3] {
        let write = Access::StorageWrite(Stages::Compute);
        [self.color, self.depth, self.normal]
            .iter()
            .zip(BINDING_OUTPUT0..)
            .map(|(&image, binding)| Bind::image(binding, image, 0, write))
            .collect::<Vec<_>>()
            .try_into()
            .unwrap_or_else(|_| unreachable!("three targets"))
    }
}

/// A method's per-level sample counts on the GPU: `levels` u32 words at byte `offset` of
/// `buffer`, written every frame (the level-of-detail methods' vertices emitted per level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleCounters {
    pub buffer: BufferId,
    pub offset: u64,
    pub levels: u32,
}

/// What a method's `build` gets.
pub struct BuildContext<'a> {
    pub ctx: &'a Arc<Context>,
    pub graph: &'a mut GraphBuilder,
    pub config: &'a MethodConfig,
    pub scene: &'a GpuScene,
    pub frame: BufferId,
    /// The segment table (`GpuSegment`, device addresses of every stream).
    pub segments: BufferId,
    /// The batch table (`GpuBatch`).
    pub batches: BufferId,
    pub indices: Option<BufferId>,
    pub targets: Targets,
    pub width: u32,
    pub height: u32,
    /// Set by methods that count their samples per level on the GPU; the renderer reads the
    /// counts back every frame (`Renderer::samples_per_level`).
    pub samples: Option<SampleCounters>,
}

/// The pipeline state of point sprites drawn by `shaders` into the three standard targets,
/// reversed-Z, the nearest depth winning.
pub fn points_desc(shaders: &[&'static str]) -> GraphicsDesc {
    GraphicsDesc {
        shaders: shaders.to_vec(),
        color_formats: vec![COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT],
        blends: vec![Blend::Replace; 3],
        depth_format: Some(ZBUFFER_FORMAT),
        depth_test: true,
        depth_write: true,
        depth_compare: vk::CompareOp::GREATER,
        topology: vk::PrimitiveTopology::POINT_LIST,
        ..Default::default()
    }
}

impl BuildContext<'_> {
    /// A frame-sized reversed-Z depth buffer, `name`.
    pub fn zbuffer(&mut self, name: &str) -> ImageId {
        self.graph.image(
            name,
            ImageDesc {
                format: ZBUFFER_FORMAT,
                width: self.width,
                height: self.height,
                mip_levels: 1,
                usage: vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            },
        )
    }

    /// Workgroups of `group` x `group` pixels covering the frame.
    pub fn pixel_groups(&self, group: u32) -> (u32, u32) {
        (self.width.div_ceil(group), self.height.div_ceil(group))
    }

    /// The bindings of a draw whose vertex shader reads the point streams: the frame block
    /// (every graphics stage) and the segment table.
    pub fn draw_binds(&self) -> [Bind; 3] {
        [
            Bind::buffer(
                BINDING_FRAME,
                self.frame,
                Access::UniformRead(Stages::Graphics),
            ),
            Bind::buffer(
                BINDING_SEGMENTS,
                self.segments,
                Access::StorageRead(Stages::Vertex),
            ),
            // Which indices hold points (`glsl/common/live.glsl`).
            Bind::buffer(
                BINDING_BATCHES,
                self.batches,
                Access::StorageRead(Stages::Vertex),
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_error(spec: &str) -> String {
        format!("{:#}", MethodConfig::parse(spec).expect_err(spec))
    }

    #[test]
    fn a_value_outside_its_range_names_the_method_the_parameter_and_the_range() {
        assert_eq!(
            parse_error("points:size=100"),
            "points: size=100 is out of range (1..=64)"
        );
        assert_eq!(
            parse_error("pyramid:radius=0.01"),
            "pyramid: radius=0.01 is out of range (0.05..=20)"
        );
        assert_eq!(
            parse_error("points:size=big"),
            "points: size=big is not a number (expected 1..=64)"
        );
        assert_eq!(
            parse_error("points:size=inf"),
            "points: size=inf is not a number (expected 1..=64)"
        );
        let at_limit = MethodConfig::parse("points:size=64").expect("the upper limit");
        assert_eq!(at_limit.get("size"), 64.0);
    }

    #[test]
    fn a_mistyped_method_or_parameter_gets_the_closest_name() {
        let names: Vec<_> = METHODS.iter().map(|m| m.name).collect();
        let names = names.join(", ");
        assert_eq!(
            parse_error("pyrmid"),
            format!("unknown method 'pyrmid'; did you mean 'pyramid'? (available: {names})")
        );
        assert_eq!(
            parse_error("pyramid-hybird:cull=0"),
            format!("unknown method 'pyramid-hybird'; did you mean 'pyramid-hybrid'? (available: {names})")
        );
        assert_eq!(
            parse_error("splat"),
            format!("unknown method 'splat' (available: {names})")
        );
        let pyramid: Vec<_> = pyramid::INFO.params.iter().map(|p| p.name).collect();
        assert_eq!(
            parse_error("pyramid:cul=0"),
            format!(
                "method 'pyramid' has no parameter 'cul'; did you mean 'cull'? (parameters: {})",
                pyramid.join(", ")
            )
        );
        assert_eq!(
            parse_error("points:szie=2"),
            "method 'points' has no parameter 'szie'; did you mean 'size'? (parameters: size)"
        );
        assert_eq!(
            parse_error("points:width=2"),
            "method 'points' has no parameter 'width' (parameters: size)"
        );
    }
}
