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
    // Normals are accumulated facing the eye, so two-sided surfaces do not cancel out.
    vec3 n = dot(v_normal, hit.q) > 0.0 ? -v_normal : v_normal;
    vec3 c = v_color;
    if (SHADING == SPLAT_SHADING_PHONG) {
        // Eq. 5.7: the splat's linear normal field, n_i = ((q + n) - p) / |(q + n) - p|, lit per
        // fragment at q. As in the paper, q - p is in view units while n is a unit vector, so
        // the field tilts by atan(|q - p|) (up to atan(r) at the rim): strongly for splats of
        // radius near 1, hardly for small ones. Botsch et al. fit the field's slopes to the
        // neighbours' normals instead; the paper's construction is kept.
        n = normalize(hit.q + n - v_centre);
        c = shade(v_color, n, hit.q);
    }
    o_color = vec4(w * c, w);
    o_normal = vec4(w * n, w);
}
