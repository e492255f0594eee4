//! Shader modules (embedded SPIR-V), push-descriptor layouts, graphics pipelines with dynamic
//! rendering, compute pipelines and mesh-shader pipelines, with specialization constants and
//! the context's pipeline cache.

use std::sync::Arc;

use anyhow::{anyhow, Context as _, Result};
use ash::vk;

use super::Context;

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// SPIR-V of the shader at `path` (relative to `glsl/`, e.g. `splat/points.vert`).
pub fn spirv(path: &str) -> Result<Vec<u32>> {
    let bytes = embedded::SHADERS
        .iter()
        .find(|(p, _)| *p == path)
        .map(|(_, b)| *b)
        .ok_or_else(|| anyhow!("no embedded shader named {path}"))?;
    ash::util::read_spv(&mut std::io::Cursor::new(bytes))
        .with_context(|| format!("bad SPIR-V in {path}"))
}

/// SPIR-V's `OpExecutionMode` and the execution modes `geometry_output` rewrites.
const OP_EXECUTION_MODE: u32 = 16;
const MODE_INVOCATIONS: u32 = 0;
const MODE_OUTPUT_VERTICES: u32 = 26;

/// Sets the literal of execution mode `mode` (one operand, e.g. `OutputVertices`) in `code`,
/// a SPIR-V module: no specialization constant can set a geometry shader's declared output
/// limit or invocation count, both literals of `OpExecutionMode`. Errors when the module does
/// not declare the mode.
pub fn set_execution_mode(code: &mut [u32], mode: u32, value: u32) -> Result<()> {
    // Header: magic, version, generator, bound, schema; then instructions, each led by
    // (word count << 16) | opcode.
    let mut at = 5;
    while at < code.len() {
        let (count, opcode) = ((code[at] >> 16) as usize, code[at] & 0xffff);
        if count == 0 || at + count > code.len() {
            return Err(anyhow!("malformed SPIR-V instruction at word {at}"));
        }
        if opcode == OP_EXECUTION_MODE && count == 4 && code[at + 2] == mode {
            code[at + 3] = value;
            return Ok(());
        }
        at += count;
    }
    Err(anyhow!("the module declares no execution mode {mode}"))
}

/// A geometry shader's declared limits, rewritten in its SPIR-V (`set_execution_mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GeometryOutput {
    /// `max_vertices`: the most vertices one invocation emits.
    pub vertices: u32,
    /// `invocations`: geometry shader instances per input primitive.
    pub invocations: u32,
}

/// One binding of the push-descriptor set 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Binding {
    pub binding: u32,
    pub ty: vk::DescriptorType,
    pub stages: vk::ShaderStageFlags,
}

impl Binding {
    pub fn new(binding: u32, ty: vk::DescriptorType, stages: vk::ShaderStageFlags) -> Self {
        Self {
            binding,
            ty,
            stages,
        }
    }

    /// A storage buffer of a compute shader.
    pub fn storage(binding: u32) -> Self {
        Self::new(
            binding,
            vk::DescriptorType::STORAGE_BUFFER,
            vk::ShaderStageFlags::COMPUTE,
        )
    }

    /// A storage image of a compute shader.
    pub fn storage_image(binding: u32) -> Self {
        Self::new(
            binding,
            vk::DescriptorType::STORAGE_IMAGE,
            vk::ShaderStageFlags::COMPUTE,
        )
    }
}

/// Size of the push-constant block every pipeline may use (all stages).
pub const PUSH_CONSTANT_BYTES: u32 = 128;

/// A pipeline with its layout; destroyed on drop.
pub struct Pipeline {
    ctx: Arc<Context>,
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pub bind_point: vk::PipelineBindPoint,
    pub stages: vk::ShaderStageFlags,
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        // SAFETY: pipelines are dropped after the frames using them completed.
        unsafe {
            self.ctx.device.destroy_pipeline(self.raw, None);
            self.ctx.device.destroy_pipeline_layout(self.layout, None);
            self.ctx
                .device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

fn layouts(
    ctx: &Context,
    bindings: &[Binding],
    stages: vk::ShaderStageFlags,
) -> Result<(vk::DescriptorSetLayout, vk::PipelineLayout)> {
    let vk_bindings: Vec<_> = bindings
        .iter()
        .map(|b| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b.binding)
                .descriptor_type(b.ty)
                .descriptor_count(1)
                .stage_flags(b.stages)
        })
        .collect();
    // SAFETY: valid create infos; objects are owned by the returned Pipeline.
    unsafe {
        let set_layout = ctx.device.create_descriptor_set_layout(
            &vk::DescriptorSetLayoutCreateInfo::default()
                .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
                .bindings(&vk_bindings),
            None,
        )?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(stages)
            .size(PUSH_CONSTANT_BYTES)];
        let set_layouts = [set_layout];
        let layout = ctx.device.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default()
                .set_layouts(&set_layouts)
                .push_constant_ranges(&ranges),
            None,
        )?;
        Ok((set_layout, layout))
    }
}

struct Modules<'a> {
    ctx: &'a Context,
    modules: Vec<vk::ShaderModule>,
}

impl<'a> Modules<'a> {
    fn load(
        ctx: &'a Context,
        paths: &[&str],
        geometry_output: Option<GeometryOutput>,
    ) -> Result<Self> {
        let mut modules = Modules {
            ctx,
            modules: Vec::new(),
        };
        for p in paths {
            let mut code = spirv(p)?;
            if let (Some(limits), vk::ShaderStageFlags::GEOMETRY) = (geometry_output, stage_of(p)?)
            {
                set_execution_mode(&mut code, MODE_OUTPUT_VERTICES, limits.vertices)
                    .with_context(|| format!("{p}: output vertices"))?;
                set_execution_mode(&mut code, MODE_INVOCATIONS, limits.invocations)
                    .with_context(|| format!("{p}: invocations"))?;
            }
            // SAFETY: code is valid SPIR-V produced by build.rs.
            let m = unsafe {
                ctx.device.create_shader_module(
                    &vk::ShaderModuleCreateInfo::default().code(&code),
                    None,
                )?
            };
            modules.modules.push(m);
        }
        Ok(modules)
    }
}

impl Drop for Modules<'_> {
    fn drop(&mut self) {
        for m in self.modules.drain(..) {
            // SAFETY: modules may be destroyed once the pipeline is created.
            unsafe { self.ctx.device.destroy_shader_module(m, None) };
        }
    }
}

/// Specialization constants `(constant_id, value)` as Vulkan map entries and their data.
struct Specialization {
    entries: Vec<vk::SpecializationMapEntry>,
    data: Vec<u8>,
}

impl Specialization {
    fn new(constants: &[(u32, u32)]) -> Self {
        Self {
            entries: constants
                .iter()
                .enumerate()
                .map(|(i, (id, _))| vk::SpecializationMapEntry {
                    constant_id: *id,
                    offset: (i * 4) as u32,
                    size: 4,
                })
                .collect(),
            data: constants
                .iter()
                .flat_map(|(_, v)| v.to_ne_bytes())
                .collect(),
        }
    }

    fn info(&self) -> vk::SpecializationInfo<'_> {
        vk::SpecializationInfo::default()
            .map_entries(&self.entries)
            .data(&self.data)
    }
}

fn stage_of(path: &str) -> Result<vk::ShaderStageFlags> {
    let ext = path.rsplit('.').next().unwrap_or("");
    Ok(match ext {
        "vert" => vk::ShaderStageFlags::VERTEX,
        "frag" => vk::ShaderStageFlags::FRAGMENT,
        "geom" => vk::ShaderStageFlags::GEOMETRY,
        "comp" => vk::ShaderStageFlags::COMPUTE,
        "task" => vk::ShaderStageFlags::TASK_EXT,
        "mesh" => vk::ShaderStageFlags::MESH_EXT,
        _ => return Err(anyhow!("unknown shader stage for {path}")),
    })
}

/// How a graphics pipeline blends into one color attachment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blend {
    /// Overwrite.
    Replace,
    /// dst += src (accumulation passes).
    Additive,
    /// dst = src * src.a + dst * (1 - src.a) (straight alpha; overlays).
    Alpha,
}

/// Everything that defines a graphics pipeline but its bindings (which come from the pass's
/// bind list).
#[derive(Clone, Debug, PartialEq)]
pub struct GraphicsDesc {
    /// Shader paths; vertex or mesh (+ optional task/geometry) and fragment.
    pub shaders: Vec<&'static str>,
    pub color_formats: Vec<vk::Format>,
    pub blends: Vec<Blend>,
    pub depth_format: Option<vk::Format>,
    pub depth_test: bool,
    pub depth_write: bool,
    /// Reversed-Z: nearer is greater.
    pub depth_compare: vk::CompareOp,
    pub topology: vk::PrimitiveTopology,
    pub cull: vk::CullModeFlags,
    /// Specialization constants `(constant_id, value)` for every stage (GLSL
    /// `layout(constant_id = N) const uint X = default;`); ids a stage lacks are ignored.
    pub specialization: Vec<(u32, u32)>,
    /// The geometry stage's declared output vertices and invocations, when not its own.
    pub geometry_output: Option<GeometryOutput>,
}

impl Default for GraphicsDesc {
    /// No shaders or attachments; no depth; triangles, no culling, no specialization.
    fn default() -> Self {
        Self {
            shaders: Vec::new(),
            color_formats: Vec::new(),
            blends: Vec::new(),
            depth_format: None,
            depth_test: false,
            depth_write: false,
            depth_compare: vk::CompareOp::ALWAYS,
            topology: vk::PrimitiveTopology::TRIANGLE_LIST,
            cull: vk::CullModeFlags::NONE,
            specialization: Vec::new(),
            geometry_output: None,
        }
    }
}

/// The stages of the shaders at `paths` (by extension; unknown ones are reported when the
/// pipeline is created).
pub fn stages_of(paths: &[&str]) -> vk::ShaderStageFlags {
    paths
        .iter()
        .filter_map(|p| stage_of(p).ok())
        .fold(vk::ShaderStageFlags::empty(), |a, s| a | s)
}

impl Pipeline {
    /// A graphics pipeline for dynamic rendering with viewport/scissor dynamic.
    pub fn graphics(ctx: &Arc<Context>, desc: &GraphicsDesc, bindings: &[Binding]) -> Result<Self> {
        let mut stages = vk::ShaderStageFlags::empty();
        for p in &desc.shaders {
            stages |= stage_of(p)?;
        }
        let (set_layout, layout) = layouts(ctx, bindings, stages)?;
        let modules = Modules::load(ctx, &desc.shaders, desc.geometry_output)?;
        let specialization = Specialization::new(&desc.specialization);
        let spec_info = specialization.info();
        let stage_infos = desc
            .shaders
            .iter()
            .zip(&modules.modules)
            .map(|(p, m)| {
                Ok(vk::PipelineShaderStageCreateInfo::default()
                    .stage(stage_of(p)?)
                    .module(*m)
                    .name(c"main")
                    .specialization_info(&spec_info))
            })
            .collect::<Result<Vec<_>>>()?;
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(desc.topology);
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(desc.depth_test)
            .depth_write_enable(desc.depth_write)
            .depth_compare_op(desc.depth_compare);
        let attachments: Vec<_> = desc
            .color_formats
            .iter()
            .enumerate()
            .map(|(i, _)| {
                let base = vk::PipelineColorBlendAttachmentState::default()
                    .color_write_mask(vk::ColorComponentFlags::RGBA);
                match desc.blends.get(i).copied().unwrap_or(Blend::Replace) {
                    Blend::Replace => base,
                    Blend::Additive => base
                        .blend_enable(true)
                        .src_color_blend_factor(vk::BlendFactor::ONE)
                        .dst_color_blend_factor(vk::BlendFactor::ONE)
                        .color_blend_op(vk::BlendOp::ADD)
                        .src_alpha_blend_factor(vk::BlendFactor::ONE)
                        .dst_alpha_blend_factor(vk::BlendFactor::ONE)
                        .alpha_blend_op(vk::BlendOp::ADD),
                    Blend::Alpha => base
                        .blend_enable(true)
                        .src_color_blend_factor(vk::BlendFactor::SRC_ALPHA)
                        .dst_color_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                        .color_blend_op(vk::BlendOp::ADD)
                        .src_alpha_blend_factor(vk::BlendFactor::ONE)
                        .dst_alpha_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                        .alpha_blend_op(vk::BlendOp::ADD),
                }
            })
            .collect();
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let mut rendering = vk::PipelineRenderingCreateInfo::default()
            .color_attachment_formats(&desc.color_formats)
            .depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED));
        let is_mesh = stages.contains(vk::ShaderStageFlags::MESH_EXT);
        let mut info = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stage_infos)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(layout)
            .push_next(&mut rendering);
        if !is_mesh {
            info = info
                .vertex_input_state(&vertex_input)
                .input_assembly_state(&assembly);
        }
        // SAFETY: every referenced state lives until this call returns.
        let raw = unsafe {
            ctx.device
                .create_graphics_pipelines(ctx.pipeline_cache, &[info], None)
                .map_err(|(_, e)| anyhow!("creating pipeline {:?}: {e}", desc.shaders))?[0]
        };
        Ok(Self {
            ctx: ctx.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::GRAPHICS,
            stages,
        })
    }

    /// A compute pipeline from one `.comp` shader.
    pub fn compute(ctx: &Arc<Context>, shader: &str, bindings: &[Binding]) -> Result<Self> {
        Self::compute_specialized(ctx, shader, bindings, &[])
    }

    /// A compute pipeline with specialization constants `(constant_id, value)` (shader
    /// variants, e.g. workgroup sizes or modes, without copying the shader).
    pub fn compute_specialized(
        ctx: &Arc<Context>,
        shader: &str,
        bindings: &[Binding],
        specialization: &[(u32, u32)],
    ) -> Result<Self> {
        let stages = vk::ShaderStageFlags::COMPUTE;
        let (set_layout, layout) = layouts(ctx, bindings, stages)?;
        let modules = Modules::load(ctx, &[shader], None)?;
        let specialization = Specialization::new(specialization);
        let spec_info = specialization.info();
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(stages)
            .module(modules.modules[0])
            .name(c"main")
            .specialization_info(&spec_info);
        let info = vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout);
        // SAFETY: valid create info.
        let raw = unsafe {
            ctx.device
                .create_compute_pipelines(ctx.pipeline_cache, &[info], None)
                .map_err(|(_, e)| anyhow!("creating compute pipeline {shader}: {e}"))?[0]
        };
        Ok(Self {
            ctx: ctx.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::COMPUTE,
            stages,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The literal of `mode` in `code`, if declared.
    fn mode_value(code: &[u32], mode: u32) -> Option<u32> {
        let mut at = 5;
        while at < code.len() {
            let count = (code[at] >> 16) as usize;
            if code[at] & 0xffff == OP_EXECUTION_MODE && count == 4 && code[at + 2] == mode {
                return Some(code[at + 3]);
            }
            at += count;
        }
        None
    }

    #[test]
    fn geometry_limits_are_rewritten_in_the_spirv() {
        let mut code = spirv("lod/expand.geom").expect("embedded");
        assert_eq!(mode_value(&code, MODE_OUTPUT_VERTICES), Some(64));
        assert_eq!(mode_value(&code, MODE_INVOCATIONS), Some(1));
        set_execution_mode(&mut code, MODE_OUTPUT_VERTICES, 16).expect("output vertices");
        set_execution_mode(&mut code, MODE_INVOCATIONS, 4).expect("invocations");
        assert_eq!(mode_value(&code, MODE_OUTPUT_VERTICES), Some(16));
        assert_eq!(mode_value(&code, MODE_INVOCATIONS), Some(4));
        // A vertex shader declares neither; a truncated module is reported, not read past.
        let mut vert = spirv("lod/points.vert").expect("embedded");
        let err = set_execution_mode(&mut vert, MODE_OUTPUT_VERTICES, 16).unwrap_err();
        assert!(err.to_string().contains("no execution mode 26"), "{err}");
        let mut truncated = code[..code.len() / 2].to_vec();
        truncated[5] |= 0xffff << 16;
        let err = set_execution_mode(&mut truncated, MODE_OUTPUT_VERTICES, 16).unwrap_err();
        assert!(err.to_string().contains("malformed SPIR-V"), "{err}");
    }
}
