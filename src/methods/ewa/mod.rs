//! EWA surface splatting (Marroquim 2008, ch. 3; Zwicker et al. 2001), the quality reference
//! of the splatting methods, rasterized in compute like `compute-hq` (`glsl/ewa/`).
//!
//! Per splat: a tangent frame from its normal (a view-facing disc without normals), the
//! reconstruction Gaussian V_r = σ² I with σ = `radius` · r (eq. 3.30; by default σ = r / 2,
//! truncated at `cutoff` = 2 σ: the disc of radius r, with the Gaussian at e⁻² on its rim), the
//! Jacobian of the local affine approximation of the projection at its centre (eq. 3.25), the
//! screen-space resampling filter V_ρ = J V_r Jᵀ + V_h with a prefilter of `prefilter` pixels
//! (eqs. 3.23, 3.31), truncated at `cutoff` standard deviations; the bounding box of that
//! ellipse is rasterized with Gaussian weights, by the splat's thread when it reaches at most
//! `EWA_MAX_RADIUS` pixels from the centre, else by a whole workgroup (the large splats' list).
//!
//! * `ewa.clear`, `ewa.clear-accum`, `ewa.clear-large`: the 64-bit visibility keys to all
//!   ones, the accumulators to zero, the large splats' list to empty.
//! * `ewa.visibility` (one workgroup per batch; large splats are listed) and
//!   `ewa.visibility-large` (one workgroup per listed splat, dispatched indirectly): every
//!   fragment's depth interval (the splat plane's depth at the pixel ± `interval` standard
//!   deviations) through `atomicMin` of halo ‖ front ‖ back: the front-most interval per pixel
//!   among the core fragments (pixel centre inside the unfiltered footprint J V_r Jᵀ), else
//!   among the halo the prefilter adds.
//! * `ewa.accumulate` and `ewa.accumulate-large`: the ternary depth test against that
//!   interval: fragments inside it (or in front of it) blend (w·color, w·normal, w added with
//!   fixed-point atomics), fragments behind it are discarded, and the front-most one is the
//!   fragment every "in front → replace" of the sequential test would have ended with
//!   (`glsl/ewa/splat.comp` states the mapping). With `shading` = 1 (default) each fragment
//!   is lit at its point of the splat's plane with the splat's linear normal field (Phong
//!   splatting, Botsch et al. 2004: `crate::scene::normal_field`, fitted on upload) and the lit
//!   colors are filtered, as the ground truth filters shaded samples; with 0 albedo and
//!   normals are filtered and lit per pixel (deferred).
//! * `ewa.resolve`: normalization (eq. 3.36), coverage (a core fragment, or halo weights of at
//!   least half an interior pixel's: the ground truth's half-coverage rule, so the prefilter
//!   smooths silhouettes without dilating them) and, when deferred, per-pixel lighting into
//!   the standard targets.
//!
//! The splat set-up is recomputed in both rasterization passes rather than stored (no buffer
//! of per-splat ellipses). Every point is set up each frame (no batch culling: a batch's box
//! does not bound its splats' footprints).

use anyhow::Result;
use ash::vk;

use super::compute::{resolve_binds, Projection};
use super::{BuildContext, Feature, MethodInfo, ParamSpec};
use crate::graph::{Bind, Binds, BufferRange};
use crate::layout::{
    EwaParams, BINDING_ACCUM, BINDING_BATCHES, BINDING_EWA_LARGE, BINDING_FRAME, BINDING_SEGMENTS,
    BINDING_VISIBILITY, EWA_SPEC_COVERAGE, EWA_SPEC_LARGE, EWA_SPEC_MODE, EWA_SPEC_SHADED,
    EWA_SPEC_SHADE_FRAGMENTS, EWA_WEIGHT_SCALE, RESOLVE_GROUP,
};

pub const INFO: MethodInfo = MethodInfo {
    params: &[
        ParamSpec {
            name: "radius",
            default: 0.5,
            min: 0.01,
            max: 16.0,
            doc: "the reconstruction kernel's standard deviation in units of the per-point radius \
                  (default 0.5: with `cutoff` 2 the disc of radius r, where the Gaussian has \
                  fallen to e^-2)",
        },
        ParamSpec {
            name: "cutoff",
            default: 2.0,
            min: 0.5,
            max: 4.0,
            doc: "the Gaussian is truncated at this many standard deviations",
        },
        ParamSpec {
            name: "prefilter",
            default: 0.29,
            min: 0.0,
            max: 4.0,
            doc: "standard deviation of the screen-space prefilter in pixels (default 0.29: the \
                  variance of the one-pixel box the ground truth resolves with, 1/12; Zwicker \
                  et al. use 1)",
        },
        ParamSpec {
            name: "shading",
            default: 1.0,
            min: 0.0,
            max: 1.0,
            doc: "1: every fragment lit with its splat's linear normal field and the lit colors \
                  filtered (the shaded surface, as the ground truth filters it); 0: albedo and \
                  normals filtered and lit once per pixel (deferred)",
        },
        ParamSpec {
            name: "interval",
            // 2 σ = the splat's radius: the widest depth range [zmin, zmax] a disc of radius r
            // spans (seen edge-on), the bound of Räsänen's per-splat interval.
            default: 2.0,
            min: 0.0,
            max: 16.0,
            doc: "half-width of a fragment's depth interval in standard deviations of its splat",
        },
    ],
    features: &[Feature::Int64Atomics],
    needs_normal_field: true,
    needs_surfels: true,
    ..MethodInfo::new(
        "ewa",
        "EWA surface splatting: Gaussian resampling filters, ternary depth test, \
         normalization and deferred lighting (000 ch. 3)",
        build,
    )
};

/// The weight sum a pixel inside a uniformly sampled surface collects, in units of a kernel's
/// peak: per unit area the surface holds 1/h² splats (h the point spacing, the stream radius
/// from the density), each of integral 2π σ² (1 − e^(−c²/2)) truncated at c standard
/// deviations (σ = `radius` h, projection and prefilter preserve it, eq. 3.29), so
/// 2π radius² (1 − e^(−c²/2)).
fn full_weight(radius: f32, cutoff: f32) -> f32 {
    std::f32::consts::TAU * radius * radius * (1.0 - (-0.5 * cutoff * cutoff).exp())
}

/// Bytes of the large splats' list header: a `VkDispatchIndirectCommand` and the count listed.
const LARGE_HEADER: u64 = 16;

/// Bytes of the accumulators per pixel: w·r, w·g, w·b, w, w·nx, w·ny, w·nz and the weight of
/// the front-facing splats (the coverage of halo-only pixels).
const ACCUM_BYTES: u64 = 32;

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    let pixels = u64::from(b.width) * u64::from(b.height);
    let params = EwaParams {
        radius: b.config.get("radius"),
        cutoff: b.config.get("cutoff"),
        prefilter: b.config.get("prefilter"),
        interval: b.config.get("interval"),
    };
    let shade_fragments = u32::from(b.config.get("shading") == 1.0);
    // Usage flags follow from the declared accesses.
    let usage = vk::BufferUsageFlags::empty();
    let visibility = b.graph.buffer("ewa.visibility", pixels * 8, usage);
    let accum = b.graph.buffer("ewa.accum", pixels * ACCUM_BYTES, usage);
    // The large splats' list: a dispatch header (x, y, z, listed) and one index per point.
    let large = b.graph.buffer(
        "ewa.large",
        LARGE_HEADER + 4 * u64::from(b.scene.point_count.max(1)),
        usage,
    );
    let (frame, segments, batches) = (b.frame, b.segments, b.batches);
    // The visibility passes never touch the accumulators. Only `ewa.visibility` appends to the
    // large splats' list, but every variant of the shader declares it writable, so every
    // splat pass declares it read-write (synchronization validation tracks the shader's static
    // access).
    let visibility_binds = Binds::from([
        Bind::constants(BINDING_FRAME, frame),
        Bind::reads(BINDING_SEGMENTS, segments),
        Bind::reads(BINDING_BATCHES, batches),
        Bind::updates(BINDING_VISIBILITY, visibility),
        Bind::unused(BINDING_ACCUM),
        Bind::updates(BINDING_EWA_LARGE, large),
    ]);
    let accumulate_binds = visibility_binds
        .with(Bind::reads(BINDING_VISIBILITY, visibility))
        .with(Bind::updates(BINDING_ACCUM, accum));
    let coverage = 0.5 * full_weight(params.radius, params.cutoff) * EWA_WEIGHT_SCALE as f32;
    // Empty pixels hold the largest key; the accumulators start at zero.
    b.graph
        .fill_buffer("ewa.clear", visibility, BufferRange::WHOLE, u32::MAX);
    b.graph
        .fill_buffer("ewa.clear-accum", accum, BufferRange::WHOLE, 0);
    let empty: [u32; 4] = [0, 1, 1, 0];
    b.graph
        .update_buffer("ewa.clear-large", large, 0, bytemuck::bytes_of(&empty));
    // One workgroup per batch; the large splats' dispatch arguments come from the list.
    let batch_count = u64::from(b.scene.streams.batch_count);
    for (name, mode, listed) in [
        ("ewa.visibility", 0, false),
        ("ewa.visibility-large", 0, true),
        ("ewa.accumulate", 1, false),
        ("ewa.accumulate-large", 1, true),
    ] {
        let binds = if mode == 1 {
            &accumulate_binds
        } else {
            &visibility_binds
        };
        let pass = b
            .graph
            .compute(name, "ewa/splat.comp", binds)
            .spec(&[
                (EWA_SPEC_MODE, mode),
                (EWA_SPEC_LARGE, u32::from(listed)),
                (EWA_SPEC_SHADE_FRAGMENTS, shade_fragments),
            ])
            .push(&params);
        if listed {
            pass.dispatch_indirect(large, 0);
        } else {
            pass.dispatch(batch_count);
        }
    }
    let binds = resolve_binds(b, Projection { visibility, accum }, true);
    let groups = b.pixel_groups(RESOLVE_GROUP);
    b.graph
        .compute("ewa.resolve", "ewa/resolve.comp", &binds)
        .spec(&[
            (EWA_SPEC_COVERAGE, coverage.to_bits()),
            (EWA_SPEC_SHADED, shade_fragments),
        ])
        .dispatch_grid(groups);
    Ok(())
}
