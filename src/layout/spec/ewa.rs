//! EWA splatting (000 ch. 3, src/methods/ewa).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // EWA splatting (src/methods/ewa): splat.comp and resolve.comp.
    ("EWA_SPEC_MODE", 0),
    ("EWA_SPEC_LARGE", 1),
    ("EWA_SPEC_SHADE_FRAGMENTS", 2),
    ("EWA_SPEC_COVERAGE", 0),
    ("EWA_SPEC_SHADED", 1),
    // EWA splatting (000 ch. 3): a resampling ellipse whose bounding box reaches further than
    // EWA_MAX_RADIUS pixels from its centre is rasterized by a whole workgroup (the large
    // splats' list at BINDING_EWA_LARGE) instead of one thread.
    ("EWA_MAX_RADIUS", 16),
    // Fixed-point scale of EWA's accumulated weights: a fragment of unit weight adds this much
    // (a pixel's sums overflow past 2^32 / EWA_WEIGHT_SCALE = 262,144 unit-weight fragments).
    ("EWA_WEIGHT_SCALE", 16384),
    ("BINDING_EWA_LARGE", 14),
];

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the EWA splatting passes (000 ch. 3, src/methods/ewa).
    StructSpec {
        name: "EwaParams",
        doc: "Push constants of the EWA splatting passes (`EwaParams` in GLSL).",
        fields: &[
            // Scale of the per-point radius: the reconstruction kernel's standard deviation
            // in object space is radius * stream_radius (V_r = r^2 I, eq. 3.30).
            f("float", "radius"),
            // The Gaussian is truncated at this many standard deviations (Mahalanobis
            // distance of the resampling filter).
            f("float", "cutoff"),
            // Standard deviation of the screen-space prefilter in pixels (V_h, eq. 3.31).
            f("float", "prefilter"),
            // Half-width of a fragment's depth interval in units of the splat's standard
            // deviation (the adaptive interval of 3.2.3).
            f("float", "interval"),
        ],
    },
];
