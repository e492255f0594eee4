//! Octahedral normal encoding (the normal stream's format), sRGB byte conversions and mesh
//! vertex normals for inputs with faces.

use glam::{Vec2, Vec3};

/// A linear color component as an sRGB byte (clamped to [0, 1]).
pub fn srgb_byte(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// An sRGB byte as a linear color component.
pub fn linear_component(srgb: u8) -> f32 {
    let c = f32::from(srgb) / 255.0;
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Octahedral encoding of a unit normal into two snorm16 values.
pub fn oct_encode(n: Vec3) -> u32 {
    let n = n.normalize_or(Vec3::Z);
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    let mut p = Vec2::new(n.x, n.y) / l1;
    if n.z < 0.0 {
        let sign = Vec2::new(p.x.signum(), p.y.signum());
        p = (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * sign;
    }
    // Round half away from zero by truncation: `f32::round` is a libm call on baseline x86-64,
    // and this runs once per point on upload.
    let q = |v: f32| {
        let x = v.clamp(-1.0, 1.0) * 32767.0;
        ((x + 0.5f32.copysign(x)) as i16) as u16 as u32
    };
    q(p.x) | (q(p.y) << 16)
}

/// Inverse of `oct_encode` (mirrors `oct_decode` in common.glsl).
pub fn oct_decode(packed: u32) -> Vec3 {
    let s = |v: u32| ((v & 0xffff) as u16 as i16) as f32 / 32767.0;
    let e = Vec2::new(s(packed).max(-1.0), s(packed >> 16).max(-1.0));
    let mut n = Vec3::new(e.x, e.y, 1.0 - e.x.abs() - e.y.abs());
    if n.z < 0.0 {
        let sign = Vec2::new(
            if n.x >= 0.0 { 1.0 } else { -1.0 },
            if n.y >= 0.0 { 1.0 } else { -1.0 },
        );
        let xy = (Vec2::ONE - Vec2::new(n.y.abs(), n.x.abs())) * sign;
        n.x = xy.x;
        n.y = xy.y;
    }
    n.normalize_or(Vec3::Z)
}

/// Area-weighted vertex normals of a triangle mesh (vertices used by no face get +z).
pub fn vertex_normals(positions: &[Vec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for f in faces {
        let [a, b, c] = f.map(|i| i as usize);
        if a >= positions.len() || b >= positions.len() || c >= positions.len() {
            continue;
        }
        // The cross product's length is twice the area: area weighting for free.
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        acc[a] += n;
        acc[b] += n;
        acc[c] += n;
    }
    acc.into_iter().map(|n| n.normalize_or(Vec3::Z)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_round_trip_is_accurate_in_every_octant() {
        for &n in &[
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Z,
            Vec3::new(1.0, -2.0, -3.0).normalize(),
            Vec3::new(-0.3, 0.4, -0.866).normalize(),
            Vec3::new(0.577, 0.577, 0.577),
        ] {
            let d = oct_decode(oct_encode(n));
            assert!(d.dot(n.normalize()) > 0.99999, "{n} -> {d}");
        }
        assert_eq!(oct_decode(oct_encode(Vec3::ZERO)), Vec3::Z);
    }

    #[test]
    fn vertex_normals_of_a_ccw_square_face_up() {
        let pos = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::splat(9.0),
        ];
        let n = vertex_normals(&pos, &[[0, 1, 2], [0, 2, 3]]);
        assert!(n[..4].iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
        assert_eq!(n[4], Vec3::Z);
    }
}
