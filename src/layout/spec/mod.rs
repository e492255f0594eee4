//! The single source of the bindings, constants and struct layouts shared by GLSL and Rust,
//! one file per method family. build.rs reads it (`#[path]`) to generate `shared.glsl`, the
//! header every shader includes, and the Rust constants and `#[repr(C)]` structs of
//! `crate::layout`.
//!
//! Binding numbers are declared by the family that owns them, in blocks that never overlap
//! (the build fails when two bindings share a number): families are bound together in one
//! pipeline (EWA with the compute rasterizer's buffers, the pyramid with LOD lists, the GPU
//! k-NN with the radix sort's keys).

pub mod common;
pub mod compute;
pub mod ewa;
pub mod hpr;
pub mod kernel;
pub mod knn;
pub mod lod;
pub mod overlay;
pub mod post;
pub mod pyramid;
pub mod sort;
pub mod splat;

/// One member of a shared struct: GLSL type and name. Only 4-byte scalars, vec2/vec4/uvec4 and
/// mat4 are allowed, so std430 and `#[repr(C)]` agree without hidden padding.
pub struct FieldSpec {
    pub ty: &'static str,
    pub name: &'static str,
}

/// A struct shared by GLSL (std430) and Rust.
pub struct StructSpec {
    pub name: &'static str,
    /// The Rust struct's documentation.
    pub doc: &'static str,
    pub fields: &'static [FieldSpec],
}

const fn f(ty: &'static str, name: &'static str) -> FieldSpec {
    FieldSpec { ty, name }
}

/// One family's integer constants (`#define` in GLSL, `pub const` in Rust) and structs.
pub struct Family {
    pub name: &'static str,
    pub constants: &'static [(&'static str, u32)],
    pub structs: &'static [StructSpec],
}

macro_rules! families {
    ($($family:ident),* $(,)?) => {
        /// Every family, `common` first.
        pub const FAMILIES: &[Family] = &[$(Family {
            name: stringify!($family),
            constants: $family::CONSTANTS,
            structs: $family::STRUCTS,
        }),*];
    };
}

families!(common, post, overlay, compute, ewa, splat, pyramid, kernel, hpr, sort, lod, knn);

/// Every shared struct, in family order.
pub fn structs() -> impl Iterator<Item = &'static StructSpec> {
    FAMILIES.iter().flat_map(|f| f.structs)
}

/// Every constant, in family order.
pub fn constants() -> impl Iterator<Item = (&'static str, u32)> {
    FAMILIES.iter().flat_map(|f| f.constants.iter().copied())
}

/// Bindings that take three consecutive numbers (one per attribute group or target).
pub const TRIPLE_BINDINGS: &[&str] = &[
    "BINDING_OUTPUT0",
    "BINDING_PYRAMID_PARENT",
    "BINDING_PYRAMID_LEVEL",
    "BINDING_PYRAMID_OUT",
    "BINDING_KERNEL_ACCUM",
];

/// The first two of `constants`' bindings (`BINDING_*`, three numbers wide when in
/// `TRIPLE_BINDINGS`) that share a number, if any.
pub fn overlapping(constants: &[(&'static str, u32)]) -> Option<(&'static str, &'static str)> {
    let spans: Vec<_> = constants
        .iter()
        .filter(|(name, _)| name.starts_with("BINDING_"))
        .map(|&(name, first)| {
            let width = if TRIPLE_BINDINGS.contains(&name) {
                3
            } else {
                1
            };
            (name, first, first + width)
        })
        .collect();
    spans.iter().enumerate().find_map(|(i, &(a, start, end))| {
        spans[i + 1..]
            .iter()
            .find(|&&(_, s, e)| s < end && start < e)
            .map(|&(b, _, _)| (a, b))
    })
}
