//! Rust mirrors of the structs and constants shared with GLSL. Both sides come from
//! `layout_spec.rs`; the test below fails when a mirror drifts from the std430 layout.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};

/// The shared layout specification (also read by build.rs).
pub mod spec {
    include!("layout_spec.rs");
}

include!(concat!(env!("OUT_DIR"), "/constants.rs"));

/// Bounds and point range of one batch (`GpuBatch` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBatch {
    pub min_x: f32,
    pub min_y: f32,
    pub min_z: f32,
    pub first: u32,
    pub max_x: f32,
    pub max_y: f32,
    pub max_z: f32,
    pub count: u32,
}

/// Device addresses of one segment's streams (`GpuSegment` in GLSL), as (lo, hi) pairs.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuSegment {
    pub position_coarse: [u32; 4],
    pub medium_fine: [u32; 4],
    pub normal_radius: [u32; 4],
    pub color_first: [u32; 4],
    pub scalar: [u32; 4],
    pub normal_field: [u32; 4],
    pub classes: [u32; 4],
}

/// One light, resolved to view space on the CPU.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub position: Vec4,
    pub color_kind: Vec4,
}

/// Per-frame uniforms.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct FrameUniforms {
    pub view: Mat4,
    pub proj: Mat4,
    pub view_proj: Mat4,
    pub viewport: Vec4,
    pub params: Vec4,
    pub base_color: Vec4,
    pub flags: u32,
    pub light_count: u32,
    pub point_count: u32,
    pub segment_points: u32,
    pub batch_count: u32,
    pub color_mode: u32,
    pub specular: f32,
    pub pad0: u32,
    pub color_axis: Vec4,
    pub color_range: Vec4,
    pub clip: Mat4,
    pub class_hidden_lo: [u32; 4],
    pub class_hidden_hi: [u32; 4],
}

/// One overlay quad (`GpuGlyph` in GLSL): a glyph from the atlas or a solid panel.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuGlyph {
    pub rect: Vec4,
    pub atlas_x: u32,
    pub atlas_y: u32,
    pub color: u32,
    pub flags: u32,
}

/// Push constants of the post-processing pass (`PostParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PostParams {
    pub offsets01: Vec4,
    pub offsets23: Vec4,
    pub offsets45: Vec4,
    pub offsets67: Vec4,
    pub background: Vec4,
    pub strength: f32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// Push constants of the splatting family (`SplatParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SplatParams {
    pub radius_scale: f32,
    pub epsilon: f32,
    pub max_point_size: f32,
    pub pad0: u32,
}

/// Push constants of the EWA splatting passes (`EwaParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct EwaParams {
    pub radius: f32,
    pub cutoff: f32,
    pub prefilter: f32,
    pub interval: f32,
}

/// Push constants of the pyramid passes (`PyramidParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PyramidParams {
    pub level: u32,
    pub level_count: u32,
    pub radius_scale: f32,
    pub falloff: f32,
}

/// Push constants of the GPU k-NN passes (`KnnParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct KnnParams {
    pub origin_cell: Vec4,
    pub dims_count: [u32; 4],
    pub sensor: Vec4,
    pub mean: Vec4,
    pub hash_bits: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// Push constants of the HPR passes (`HprParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct HprParams {
    pub sqrt_k_max: u32,
    pub sqrt_k: u32,
    pub point_count: u32,
    pub max_rounds: u32,
    pub radius: f32,
    pub density: f32,
    pub complete_side: u32,
    pub max_edge: f32,
}

/// One patch of the object texture (`GpuLodPatch` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLodPatch {
    pub sphere: Vec4,
    pub normal: Vec4,
    pub errors: Vec4,
    pub counts: [u32; 4],
    pub offset: u32,
    pub levels: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// One vertex of the object texture (`GpuLodVertex` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLodVertex {
    pub sphere: Vec4,
    pub normal_color: [u32; 4],
}

/// Push constants of the LOD selection (`LodParams` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LodParams {
    pub epsilon: f32,
    pub patch_count: u32,
    pub max_point_size: f32,
    pub budget: u32,
}

/// The per-frame HPR state (`HprFrame` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct HprFrame {
    pub axis_x: Vec4,
    pub axis_y: Vec4,
    pub axis_z: Vec4,
    pub eye_radius: Vec4,
    pub grid: Vec4,
    pub sqrt_k: u32,
    pub full: u32,
    pub coarse: u32,
    pub coarse_side: u32,
    pub groups_x: u32,
    pub groups_y: u32,
    pub groups_z: u32,
    pub changed: u32,
    pub rounds: u32,
    pub visible: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub index_count: u32,
    pub instance_count: u32,
    pub first_index: u32,
    pub vertex_offset: u32,
    pub first_instance: u32,
    pub pad2: u32,
    pub pad3: u32,
    pub pad4: u32,
}

/// The frame storage buffer: uniforms followed by the light array (`FrameBlock` in GLSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameBlock {
    pub u: FrameUniforms,
    pub lights: [GpuLight; MAX_LIGHTS as usize],
}

/// Size and alignment of a GLSL type under std430 (only the types the spec allows).
pub fn std430_size_align(ty: &str) -> Option<(usize, usize)> {
    Some(match ty {
        "float" | "uint" | "int" => (4, 4),
        "vec2" | "uvec2" => (8, 8),
        "vec4" | "uvec4" => (16, 16),
        "mat4" => (64, 16),
        _ => return None,
    })
}

/// std430 offsets of every field of `s`, and the struct size.
pub fn std430_layout(s: &spec::StructSpec) -> Option<(Vec<usize>, usize)> {
    let mut offset: usize = 0;
    let mut max_align = 4;
    let mut offsets = Vec::new();
    for f in s.fields {
        let (size, align) = std430_size_align(f.ty)?;
        offset = offset.div_ceil(align) * align;
        offsets.push(offset);
        offset += size;
        max_align = max_align.max(align);
    }
    Some((offsets, offset.div_ceil(max_align) * max_align))
}

/// Field names, offsets and size of a Rust mirror.
macro_rules! mirror {
    ($t:ty { $($field:ident),* $(,)? }) => {
        (
            stringify!($t),
            vec![$((stringify!($field), std::mem::offset_of!($t, $field))),*],
            std::mem::size_of::<$t>(),
        )
    };
}

/// A Rust mirror's name, `(field, offset)` pairs and size.
pub type Mirror = (&'static str, Vec<(&'static str, usize)>, usize);

/// Every Rust mirror.
pub fn mirrors() -> Vec<Mirror> {
    vec![
        mirror!(GpuBatch {
            min_x,
            min_y,
            min_z,
            first,
            max_x,
            max_y,
            max_z,
            count
        }),
        mirror!(GpuSegment {
            position_coarse,
            medium_fine,
            normal_radius,
            color_first,
            scalar,
            normal_field,
            classes
        }),
        mirror!(GpuLight {
            position,
            color_kind
        }),
        mirror!(FrameUniforms {
            view,
            proj,
            view_proj,
            viewport,
            params,
            base_color,
            flags,
            light_count,
            point_count,
            segment_points,
            batch_count,
            color_mode,
            specular,
            pad0,
            color_axis,
            color_range,
            clip,
            class_hidden_lo,
            class_hidden_hi
        }),
        mirror!(GpuGlyph {
            rect,
            atlas_x,
            atlas_y,
            color,
            flags
        }),
        mirror!(PostParams {
            offsets01,
            offsets23,
            offsets45,
            offsets67,
            background,
            strength,
            pad0,
            pad1,
            pad2
        }),
        mirror!(SplatParams {
            radius_scale,
            epsilon,
            max_point_size,
            pad0
        }),
        mirror!(EwaParams {
            radius,
            cutoff,
            prefilter,
            interval
        }),
        mirror!(PyramidParams {
            level,
            level_count,
            radius_scale,
            falloff
        }),
        mirror!(GpuLodPatch {
            sphere,
            normal,
            errors,
            counts,
            offset,
            levels,
            pad0,
            pad1
        }),
        mirror!(GpuLodVertex {
            sphere,
            normal_color
        }),
        mirror!(LodParams {
            epsilon,
            patch_count,
            max_point_size,
            budget
        }),
        mirror!(KnnParams {
            origin_cell,
            dims_count,
            sensor,
            mean,
            hash_bits,
            pad0,
            pad1,
            pad2
        }),
        mirror!(HprParams {
            sqrt_k_max,
            sqrt_k,
            point_count,
            max_rounds,
            radius,
            density,
            complete_side,
            max_edge
        }),
        mirror!(HprFrame {
            axis_x,
            axis_y,
            axis_z,
            eye_radius,
            grid,
            sqrt_k,
            full,
            coarse,
            coarse_side,
            groups_x,
            groups_y,
            groups_z,
            changed,
            rounds,
            visible,
            pad0,
            pad1,
            index_count,
            instance_count,
            first_index,
            vertex_offset,
            first_instance,
            pad2,
            pad3,
            pad4
        }),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rust_mirrors_match_the_std430_layout_of_the_spec() {
        let mirrors = mirrors();
        assert_eq!(
            mirrors.len(),
            spec::STRUCTS.len(),
            "a spec struct has no mirror"
        );
        for (name, fields, size) in mirrors {
            let s = spec::STRUCTS
                .iter()
                .find(|s| s.name == name)
                .unwrap_or_else(|| panic!("{name} is not in layout_spec.rs"));
            let (offsets, spec_size) = std430_layout(s).expect("spec uses std430-safe types");
            let spec_names: Vec<_> = s.fields.iter().map(|f| f.name).collect();
            let rust_names: Vec<_> = fields.iter().map(|(n, _)| *n).collect();
            assert_eq!(rust_names, spec_names, "{name}: field names/order drifted");
            let rust_offsets: Vec<_> = fields.iter().map(|(_, o)| *o).collect();
            assert_eq!(rust_offsets, offsets, "{name}: offsets drifted");
            assert_eq!(size, spec_size, "{name}: size drifted");
        }
    }

    #[test]
    fn frame_block_places_lights_after_the_uniforms() {
        assert_eq!(std::mem::offset_of!(FrameBlock, lights), 400);
        assert_eq!(std::mem::size_of::<GpuBatch>(), 32);
        assert_eq!(std::mem::size_of::<GpuSegment>(), 112);
        assert_eq!(TARGET_NORMAL, 2);
    }
}
