//! Octahedral normal encoding: a unit vector as two coordinates in −1..1 (the octahedron
//! |x| + |y| + |z| = 1 unfolded onto a square), stored as two unsigned 16-bit values. The
//! largest angular error at 16 bits is below 0.05°. `surfel convert` stores normals this way
//! as LAS extra bytes ([`NORMAL_OCT`]); loaders turn them back into normals.

use glam::{Vec2, Vec3};

/// Extra-bytes names of a normal's two octahedral coordinates (unsigned 16-bit each).
pub const NORMAL_OCT: [&str; 2] = ["normal_oct_u", "normal_oct_v"];

/// The octahedral coordinates of the unit vector `n`, in −1..1 each.
pub fn octahedral(n: Vec3) -> Vec2 {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs()).max(f32::MIN_POSITIVE);
    if n.z >= 0.0 {
        Vec2::new(n.x, n.y)
    } else {
        let sign = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        Vec2::new((1.0 - n.y.abs()) * sign(n.x), (1.0 - n.x.abs()) * sign(n.y))
    }
}

/// The unit vector of octahedral coordinates `e`.
pub fn from_octahedral(e: Vec2) -> Vec3 {
    let mut n = Vec3::new(e.x, e.y, 1.0 - e.x.abs() - e.y.abs());
    let t = (-n.z).max(0.0);
    n.x -= t.copysign(n.x);
    n.y -= t.copysign(n.y);
    n.normalize_or_zero()
}

/// `v` in −1..1 as an unsigned 16-bit value.
pub fn unorm16(v: f32) -> u16 {
    ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * 65535.0).round() as u16
}

/// The unsigned 16-bit value `q` back in −1..1.
pub fn from_unorm16(q: f32) -> f32 {
    q / 65535.0 * 2.0 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_normals_round_trip_within_a_twentieth_of_a_degree() {
        let mut worst = 0f32;
        for i in 0..2000 {
            let t = i as f32 * 0.7;
            let n =
                Vec3::new(t.sin() * (t * 0.3).cos(), t.cos(), (t * 1.7).sin() - 0.2).normalize();
            let e = octahedral(n);
            let q = Vec2::new(
                from_unorm16(f32::from(unorm16(e.x))),
                from_unorm16(f32::from(unorm16(e.y))),
            );
            let back = from_octahedral(q);
            worst = worst.max(back.dot(n).clamp(-1.0, 1.0).acos().to_degrees());
        }
        assert!(worst < 0.05, "{worst}°");
        assert!((from_octahedral(octahedral(-Vec3::Z)) + Vec3::Z).length() < 1e-6);
    }
}
