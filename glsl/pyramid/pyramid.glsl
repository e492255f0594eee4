// The pyramid point renderer (000 ch. 4): a level's texels and their ellipses.
//
// A texel lives in three storage images (000 Fig. 4.14): A = (normal.xyz, projected radius),
// B = (linear depth, depth-interval half range, displacement vector.xy), C = (linear albedo,
// primitive id). Radii and displacements are in level-0 pixels at every level, so a texel's
// ellipse is one object whatever level holds it; its centre is the texel's pixel centre
// (scaled to level 0) plus the displacement (000 Fig. 4.7). A depth of 0 marks an empty texel.
#ifndef SURFEL_PYRAMID_GLSL
#define SURFEL_PYRAMID_GLSL
#include "common.glsl"

// Whether the albedo group C is interpolated (`color` parameter); otherwise shading uses the
// frame's base color and the C bindings are never touched.
layout(constant_id = PYRAMID_SPEC_COLOR) const bool COLOR = true;

layout(push_constant) uniform Push { PyramidParams pyr; };

struct Texel {
    vec3 n;           // view-space unit normal, facing the camera
    float radius;     // projected radius in level-0 pixels; negative: a texel the synthesis
                      // filled across an enclosed gap (its grown ellipse, synthesis.comp)
    float depth;      // linear view depth; 0: empty
    float half_range; // half range of the depth interval, in view units (the splat's radius);
                      // negative: a texel the synthesis filled where the level was empty
    vec2 disp;        // ellipse centre minus the texel's pixel centre, in level-0 pixels
    vec4 color;       // linear albedo, primitive id
};

Texel empty_texel() {
    return Texel(vec3(0.0), 0.0, 0.0, 0.0, vec2(0.0), vec4(0.0));
}

// Centre of pixel `q` of `level`, in level-0 pixels.
vec2 pixel_centre(ivec2 q, uint level) {
    return (vec2(q) + 0.5) * float(1u << level);
}

// Whether the depth intervals of two texels overlap (the occlusion test of 4.2.2).
bool overlaps(Texel a, Texel b) {
    return abs(a.depth - b.depth) <= abs(a.half_range) + abs(b.half_range);
}

// Weighted sums of texels and of their ellipse centres: the average analysis takes (weight 1)
// and synthesis takes (Gaussian weights).
struct Blend {
    Texel sum;
    vec2 centres;
    float weight;
};

Blend blend_empty() {
    return Blend(empty_texel(), vec2(0.0), 0.0);
}

void blend_add(inout Blend b, Texel t, vec2 centre, float w) {
    b.sum.n += w * t.n;
    b.sum.radius += w * abs(t.radius);
    b.sum.depth += w * t.depth;
    b.sum.half_range += w * abs(t.half_range);
    b.sum.color += w * t.color;
    b.centres += w * centre;
    b.weight += w;
}

// The blended texel at pixel centre `x` (level-0 pixels): its displacement points to the mean
// centre; the primitive id is not averaged but the front-most texel's, whose normal also
// stands in for normals that cancel out.
Texel blend_finish(Blend b, Texel front, vec2 x) {
    float len = length(b.sum.n);
    Texel t;
    t.n = len > 0.0 ? b.sum.n / len : front.n;
    t.radius = b.sum.radius / b.weight;
    t.depth = b.sum.depth / b.weight;
    t.half_range = b.sum.half_range / b.weight;
    t.disp = b.centres / b.weight - x;
    t.color = vec4(b.sum.color.rgb / b.weight, front.color.a);
    return t;
}

// Squared elliptical distance of `x` (level-0 pixels) from the ellipse of texel `t` centred at
// `c` (000 Fig. 4.6): the major axis, of half-length `radius`, is perpendicular to the projected
// normal; the minor axis, along it, has half-length radius * |n_z|. 1 on the rim. A tube's
// texel (its A holds the tangent) is a view-facing disc (000 5.1.2).
// How far, in texels of the level being synthesized, the synthesis grows the parents' ellipses
// to fill an enclosed gap (synthesis.comp; the CPU model's reference::FILL_REACH).
const float PYRAMID_FILL_REACH = 1.5;
// How far, in texels, a gap's enclosing texels are looked for on each side (the CPU model's
// reference::FILL_SPAN).
const int PYRAMID_FILL_SPAN = 4;
// The gap fill runs on levels below this one only: gaps up to 4 x 4 pixels at any alignment
// (at level 2 a texel spans 4 pixels); wider openings are the background between parts of
// the model, which coarser levels would close (the CPU model's reference::FILL_LEVELS).
const uint PYRAMID_FILL_LEVELS = 3u;

// `grow` > 0 widens both axes to sqrt(axis^2 + grow^2), the ellipse convolved with a disc of
// that radius (the synthesis' reach into enclosed gaps, synthesis.comp).
float ellipse_distance2_grown(Texel t, vec2 c, vec2 x, float grow) {
    vec2 d = x - c;
    float a = max(abs(t.radius), 1e-6);
    if (COLOR && uint(t.color.a) == PRIMITIVE_TUBE) {
        if (grow > 0.0) {
            a = sqrt(a * a + grow * grow);
        }
        return dot(d, d) / (a * a);
    }
    float b = max(a * abs(t.n.z), 1e-3 * a);
    if (grow > 0.0) {
        a = sqrt(a * a + grow * grow);
        b = sqrt(b * b + grow * grow);
    }
    // The projected normal in pixel space: view x and y scale by proj[0][0] w / 2 and
    // proj[1][1] h / 2 (the sign of proj[1][1] carries the image's y direction).
    vec2 m = vec2(t.n.x * frame.u.proj[0][0] * frame.u.viewport.x,
                  t.n.y * frame.u.proj[1][1] * frame.u.viewport.y);
    float len = length(m);
    if (len < 1e-6) {
        return dot(d, d) / (a * a);
    }
    m /= len;
    float u = dot(d, m);
    float v = d.x * m.y - d.y * m.x;
    return (u * u) / (b * b) + (v * v) / (a * a);
}

float ellipse_distance2(Texel t, vec2 c, vec2 x) {
    return ellipse_distance2_grown(t, c, x, 0.0);
}
#endif
