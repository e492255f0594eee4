#version 460
// Blending pass (002 sections 5.3.2-5.3.4): additive accumulation of (sum w c, sum w) and
// (sum w n, sum w) into 16-bit float targets. The fragment is moved towards the eye by epsilon
// times its depth before the depth test against the visibility pass (no depth writes), so the
// overlapping splats of the visible surface blend and those behind it do not. Deviation: the
// paper's epsilon is a constant depth offset; here it is relative to the depth, so one value
// suits every scene scale and distance.
#include "fragment.glsl"

layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_normal;

void main() {
    SplatHit hit = splat_fragment();
    gl_FragDepth = zbuffer_depth(hit.q * (1.0 - splat.epsilon));
    float w = splat_weight(hit.rho);
    vec3 n = v_normal;
    vec3 c = v_color;
    if (SHADING == SPLAT_SHADING_PHONG) {
        // 002 section 5.3.3 with the normal field of Botsch et al. (2004): the splat's normal
        // varies linearly over its plane, n(q) = normalize(n + S (q - p)), with S fitted to the
        // neighbours' normals in preprocessing (src/scene/normal_field.rs), lit per fragment at
        // q. Deviation: eq. 5.7's field n + (q - p) adds an offset in scene units to a unit
        // vector, so its tilt depended on the model's units (none on a bunny in metres, up to
        // 45 degrees at the rim of a unit splat); the fitted field is the surface's own.
        n = normalize(n + v_field * (hit.q - v_centre));
        c = shade(v_color, n, hit.q);
    }
    // Normals are accumulated facing the eye, so two-sided surfaces do not cancel out (the
    // splat's own normal decides, so a field never flips within one splat).
    n = dot(v_normal, hit.q) > 0.0 ? -n : n;
    o_color = vec4(w * c, w);
    o_normal = vec4(w * n, w);
}
