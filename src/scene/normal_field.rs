//! Linear normal fields for Phong splatting (Botsch, Spernat, Kobbelt 2004): each splat's
//! normal varies linearly over its tangent plane, `n(q) = normalize(n + S (q - p))`, with `S` the
//! symmetric 2×2 shape operator in the splat's tangent frame ([`tangent_frame`]), fitted by
//! least squares to the neighbours' normals. A neighbour's normal `m`, scaled to a unit normal
//! component, has tangential part `(m · t_u, m · t_v) / (m · n)`: exactly what the unnormalized
//! field `n + S d` has at the neighbour's tangent offset `d`.
//!
//! The field is stored dimensionless, as `S` times the splat radius: a shape operator has units
//! of 1/length, so a fixed tolerance or f16 storage of `S` itself would depend on the model's
//! units; `S r` is the normal's tilt per splat radius and does not. On a sphere of radius `R`,
//! `S = I / R`.
//!
//! Deviation: Botsch et al. fit elliptical splats aligned with the principal curvature
//! directions and store the two principal slopes; the splats here are circular, so the full
//! symmetric operator (three numbers) is stored in a fixed tangent frame instead. The two agree
//! where the operator is diagonalized.

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use super::pack::{oct_decode, oct_encode};
use super::preprocess::Neighbours;

/// Neighbours a field is fitted to.
pub const FIELD_K: usize = 10;

/// Entries of `S r` are clamped to this: the normal turns at most 45° over the splat's radius
/// (a sphere whose radius equals the splat's). Sharper turns are creases the linear field
/// cannot follow; extrapolated to the rim they would light spots.
pub const MAX_SLOPE: f32 = 1.0;

/// Tikhonov weight of the fit, relative to the normal matrix's mean diagonal.
const RIDGE: f64 = 0.01;

/// Neighbours whose normal turns more than 60° from the splat's belong to another sheet (a
/// crease, a thin part's other side) and are left out of the fit.
const MIN_NORMAL_COSINE: f64 = 0.5;

/// The splat's tangent frame `(t_u, t_v)` for unit normal `n`: `t_u = normalize(n × h)` with the
/// helper axis `h` = +x unless |n.x| ≥ 0.9, then +y; `t_v = n × t_u`. Mirrors `tangent_frame` in
/// glsl/common/common.glsl; the field is fitted in the frame of the normal as the stream stores
/// it (octahedral), so the GPU picks the same helper.
pub fn tangent_frame(n: Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let tu = n.cross(helper).normalize();
    (tu, n.cross(tu))
}

/// `S r` as `[a, b, c]` (the operator `[[a, b], [b, c]]` in [`tangent_frame`] coordinates) for
/// every point: fitted to the normals of `neighbours` (zero where fewer than two neighbours with
/// comparable normals span the plane).
pub fn fit(
    positions: &[Vec3],
    normals: &[Vec3],
    radii: &[f32],
    neighbours: &Neighbours,
) -> Vec<[f32; 3]> {
    (0..positions.len())
        .into_par_iter()
        .map(|i| {
            let (idx, _) = neighbours.of(i);
            fit_one(positions, normals, i, idx).map_or([0.0; 3], |s| {
                let r = f64::from(radii[i]);
                s.map(|v| ((v * r) as f32).clamp(-MAX_SLOPE, MAX_SLOPE))
            })
        })
        .collect()
}

/// The operator of point `i` in 1/length, or `None` when the neighbours do not determine it.
fn fit_one(positions: &[Vec3], normals: &[Vec3], i: usize, neighbours: &[u32]) -> Option<[f64; 3]> {
    let n = oct_decode(oct_encode(normals[i]));
    let (tu, tv) = tangent_frame(n);
    let (n, tu, tv) = (n.as_dvec3(), tu.as_dvec3(), tv.as_dvec3());
    let p = positions[i].as_dvec3();
    // Normal equations of the rows [du, dv, 0] x = su and [0, du, dv] x = sv, x = (a, b, c).
    let mut ata = DMat3::ZERO;
    let mut atb = DVec3::ZERO;
    let mut spread = 0.0;
    let mut used = 0;
    for &j in neighbours {
        let m = normals[j as usize].as_dvec3();
        let d = positions[j as usize].as_dvec3() - p;
        // Normals of one surface may be oriented either way: compare the lines.
        let m = if m.dot(n) < 0.0 { -m } else { m };
        let cos = m.dot(n);
        if cos.is_nan() || cos <= MIN_NORMAL_COSINE || !d.is_finite() {
            continue;
        }
        let (du, dv) = (d.dot(tu), d.dot(tv));
        let (su, sv) = (m.dot(tu) / cos, m.dot(tv) / cos);
        let r0 = DVec3::new(du, dv, 0.0);
        let r1 = DVec3::new(0.0, du, dv);
        ata += outer(r0, r0) + outer(r1, r1);
        atb += r0 * su + r1 * sv;
        spread += du * du + dv * dv;
        used += 1;
    }
    if used < 2 || spread.is_nan() || spread <= 0.0 {
        return None;
    }
    // The determinant scales with the cube of the squared offsets: compare it with the spread
    // so collinear neighbours (one tangent direction only) count as degenerate at any scale.
    let det = ata.determinant();
    let scale = spread * spread * spread;
    if det.is_nan() || det <= 1e-6 * scale {
        return None;
    }
    // A ridge of RIDGE times the mean diagonal: directions the neighbours barely span get a
    // slope near zero instead of one fitted to noise.
    let ridge = RIDGE * (ata.x_axis.x + ata.y_axis.y + ata.z_axis.z) / 3.0;
    let x = (ata + DMat3::from_diagonal(DVec3::splat(ridge))).inverse() * atb;
    x.is_finite().then_some(x.to_array())
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Packs `[a, b, c]` as the stream stores it: f16 a, b in the first word, c and a zero in the
/// second (read by `stream_normal_field` in glsl/common/streams.glsl).
pub fn pack(s: [f32; 3]) -> [u32; 2] {
    let h = |v: f32| u32::from(half::f16::from_f32(v).to_bits());
    [h(s[0]) | (h(s[1]) << 16), h(s[2])]
}

/// The packed linear normal field of every point of `cloud` (its normals and radii; zeros
/// without them), fitted over each point's [`FIELD_K`] nearest neighbours.
pub fn fit_cloud(cloud: &super::Cloud) -> Vec<[u32; 2]> {
    let (Some(normals), Some(radii)) = (&cloud.normals, &cloud.radii) else {
        return vec![[0; 2]; cloud.len()];
    };
    let neighbours = Neighbours::compute(&cloud.positions, FIELD_K, false);
    let field = fit(&cloud.positions, normals, radii, &neighbours);
    field.into_iter().map(pack).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// `n` points on a sphere of radius `radius` around `centre`, with outward normals.
    fn sphere(n: usize, radius: f32, centre: Vec3) -> (Vec<Vec3>, Vec<Vec3>) {
        let normals = crate::scene::sample::fibonacci_sphere(n);
        let positions = normals.iter().map(|&d| centre + d * radius).collect();
        (positions, normals)
    }

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..200 {
            let mut f = || rng.next_f64() as f32 * 2.0 - 1.0;
            let n = Vec3::new(f(), f(), f()).normalize();
            let (tu, tv) = tangent_frame(n);
            assert!(tu.dot(n).abs() < 1e-6 && tv.dot(n).abs() < 1e-6 && tu.dot(tv).abs() < 1e-6);
            assert!((tu.length() - 1.0).abs() < 1e-5 && (tv.length() - 1.0).abs() < 1e-5);
            assert!(tu.cross(tv).dot(n) > 0.999);
        }
    }

    #[test]
    fn a_sphere_gets_the_identity_over_its_radius_at_every_scale() {
        for (scale, centre) in [
            (1.0, Vec3::ZERO),
            (1e-3, Vec3::splat(0.01)),
            (1e3, Vec3::splat(-500.0)),
        ] {
            let big = 2.0 * scale;
            let (positions, normals) = sphere(4000, big, centre);
            let splat = 0.05 * scale;
            let radii = vec![splat; positions.len()];
            let neighbours = Neighbours::compute(&positions, FIELD_K, false);
            let field = fit(&positions, &normals, &radii, &neighbours);
            // S r = (r / R) I = 0.025 I in every frame.
            for s in &field {
                assert!((s[0] - 0.025).abs() < 1e-3, "scale {scale}: {s:?}");
                assert!(s[1].abs() < 1e-3, "scale {scale}: {s:?}");
                assert!((s[2] - 0.025).abs() < 1e-3, "scale {scale}: {s:?}");
            }
            // Flipping a normal flips its operator: in the flipped frame (t_u turns, t_v
            // stays) a and c change sign and b does not.
            let flipped: Vec<Vec3> = normals
                .iter()
                .enumerate()
                .map(|(i, &n)| if i % 2 == 0 { -n } else { n })
                .collect();
            let again = fit(&positions, &flipped, &radii, &neighbours);
            for (i, (a, b)) in field.iter().zip(&again).enumerate() {
                let sign = if i % 2 == 0 { -1.0 } else { 1.0 };
                let expected = [a[0] * sign, a[1], a[2] * sign];
                for k in 0..3 {
                    assert!((expected[k] - b[k]).abs() < 1e-5, "{i}: {a:?} {b:?}");
                }
            }
        }
    }

    #[test]
    fn a_cylinder_bends_along_one_tangent_only_and_a_plane_not_at_all() {
        // A cylinder of radius 1 about z: S = (1/R) a a^T with a the circumferential direction.
        let (mut positions, mut normals) = (Vec::new(), Vec::new());
        for k in 0..40 {
            for j in 0..120 {
                let phi = j as f32 / 120.0 * std::f32::consts::TAU;
                let d = Vec3::new(phi.cos(), phi.sin(), 0.0);
                positions.push(d + Vec3::Z * (k as f32 * 0.05));
                normals.push(d);
            }
        }
        let radii = vec![0.05; positions.len()];
        let neighbours = Neighbours::compute(&positions, FIELD_K, false);
        let field = fit(&positions, &normals, &radii, &neighbours);
        for (i, s) in field
            .iter()
            .enumerate()
            .filter(|(i, _)| (i / 120) % 39 != 0)
        {
            let n = oct_decode(oct_encode(normals[i]));
            let (tu, tv) = tangent_frame(n);
            let a = Vec3::new(-normals[i].y, normals[i].x, 0.0);
            let (au, av) = (a.dot(tu), a.dot(tv));
            let expected = [au * au, au * av, av * av].map(|v| 0.05 * v);
            for k in 0..3 {
                assert!(
                    (s[k] - expected[k]).abs() < 2e-3,
                    "{i}: {s:?} vs {expected:?}"
                );
            }
        }
        let plane: Vec<Vec3> = (0..400)
            .map(|i| Vec3::new((i % 20) as f32, (i / 20) as f32, 0.0))
            .collect();
        let up = vec![Vec3::Z; 400];
        let flat = fit(
            &plane,
            &up,
            &[1.0; 400],
            &Neighbours::compute(&plane, FIELD_K, false),
        );
        assert!(flat.iter().all(|s| s == &[0.0; 3]));
        // A line of points determines no operator.
        let line: Vec<Vec3> = (0..50).map(|i| Vec3::X * i as f32).collect();
        let line_field = fit(
            &line,
            &[Vec3::Z; 50],
            &[1.0; 50],
            &Neighbours::compute(&line, 4, false),
        );
        assert!(line_field.iter().all(|s| s == &[0.0; 3]));
    }

    #[test]
    fn packing_keeps_three_halves() {
        let [w0, w1] = pack([0.5, -0.25, 2.0]);
        let h = |b: u32| half::f16::from_bits(b as u16).to_f32();
        assert_eq!((h(w0), h(w0 >> 16), h(w1), w1 >> 16), (0.5, -0.25, 2.0, 0));
    }
}
