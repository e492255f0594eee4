//! Uniform random sampling of a triangle mesh into a point cloud (`surfel sample`).
//!
//! Triangles are chosen with probability proportional to their area (Walker's alias method: one
//! uniform number and one table lookup per point), points are uniform inside a triangle (folded barycentric coordinates), the
//! normal is the face normal (right-handed with the winding: `(b - a) x (c - a)`), and colors
//! are interpolated when the mesh has them. Every point gets the radius
//! `sqrt(total_area / (pi N)) * SPLAT_RADIUS_FACTOR`: discs of radius `sqrt(A / (pi N))` have
//! the surface's total area, and with random (Poisson) positions they cover a fraction
//! `1 - exp(-f^2)` of it for a factor `f`, so `f = 2` covers about 98%.
//! Points are drawn in parallel blocks of fixed size, each with its own generator, so the output
//! is deterministic for a given seed whatever the number of threads.

use glam::Vec3;
use rayon::prelude::*;

use super::cloud::{Cloud, LoadStats};
use crate::rng::SplitMix64;

/// Points per block: each block of the output draws from its own generator, seeded from the
/// seed and the block index, so the result does not depend on the number of threads.
const BLOCK: usize = 1 << 16;

/// The generator of block `block`: the block index is hashed before it is mixed into the seed,
/// so the blocks' streams start far apart in the generator's sequence.
fn block_rng(seed: u64, block: usize) -> SplitMix64 {
    SplitMix64::new(seed ^ SplitMix64::new(block as u64).next_u64())
}

/// Walker's alias table: picks index `i` with probability `weights[i] / total` from one uniform
/// number, in constant time. Each slot keeps its own index with probability `keep` and
/// otherwise gives its `alias`; indices with zero weight are never picked.
struct AliasTable {
    slots: Vec<(f64, u32)>,
}

impl AliasTable {
    /// Vose's construction over non-negative `weights` with positive sum `total`.
    fn new(weights: &[f64], total: f64) -> Self {
        let n = weights.len();
        let mut scaled: Vec<f64> = weights.iter().map(|w| w * n as f64 / total).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        let mut slots = vec![(1.0, 0); n];
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            slots[s] = (scaled[s], l as u32);
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Rounding leaves slots that should be full; those without weight point to one that
        // has weight.
        let heaviest = (0..n).max_by(|&a, &b| weights[a].total_cmp(&weights[b]));
        for i in large.into_iter().chain(small) {
            slots[i] = if weights[i] > 0.0 {
                (1.0, i as u32)
            } else {
                (0.0, heaviest.unwrap_or(0) as u32)
            };
        }
        AliasTable { slots }
    }

    /// The index for a uniform `u` in [0, 1).
    fn pick(&self, u: f64) -> usize {
        let x = u * self.slots.len() as f64;
        let i = (x as usize).min(self.slots.len() - 1);
        let (keep, alias) = self.slots[i];
        if x - (i as f64) < keep {
            i
        } else {
            alias as usize
        }
    }
}

/// Radius factor over the equal-area disc radius (see the module documentation).
pub const SPLAT_RADIUS_FACTOR: f32 = 2.0;

/// Host memory a point of [`sample_mesh`]'s cloud takes: position and normal (12 bytes each),
/// radius and color (4 each; the color counted whether or not the mesh has colors).
pub const SAMPLED_POINT_BYTES: u64 = 32;

/// The host memory available now: `MemAvailable` of `/proc/meminfo` in bytes, `None` where it
/// cannot be read.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find_map(|l| l.strip_prefix("MemAvailable:"))?;
    let kib: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    kib.checked_mul(1024)
}

/// `bytes` for a message: MiB below a GiB, GiB below a TiB, else TiB, one decimal.
pub fn show_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    let (mib, gib) = (1024.0 * 1024.0, 1024.0 * 1024.0 * 1024.0);
    if b < gib {
        format!("{:.1} MiB", b / mib)
    } else if b < 1024.0 * gib {
        format!("{:.1} GiB", b / gib)
    } else {
        format!("{:.1} TiB", b / (1024.0 * gib))
    }
}

/// Refuses to sample `count` points when their cloud ([`SAMPLED_POINT_BYTES`] a point) needs
/// more than `available` bytes: the message says how much it needs.
pub fn check_memory(count: u64, available: u64) -> Result<(), String> {
    let needed = count.saturating_mul(SAMPLED_POINT_BYTES);
    if needed > available {
        return Err(format!(
            "{count} sampled points need {} of memory ({SAMPLED_POINT_BYTES} bytes each), {} is \
             available",
            show_bytes(needed),
            show_bytes(available)
        ));
    }
    Ok(())
}

/// Why a mesh cannot be sampled.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SampleError {
    /// The cloud has no triangles.
    #[error("cannot sample: the input has no faces (it is a point cloud, not a mesh)")]
    NoFaces,
    /// All triangles are degenerate.
    #[error("cannot sample: the faces have zero total area")]
    ZeroArea,
    /// A face uses a vertex that does not exist.
    #[error(
        "cannot sample: face {face} uses vertex {index}, but the mesh has {vertices} vertices"
    )]
    BadIndex {
        /// Face number.
        face: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
}

/// `n` unit directions spread evenly over the sphere along a Fibonacci spiral (y from top to
/// bottom, golden-angle steps about it): a synthetic sphere's points and outward normals.
pub fn fibonacci_sphere(n: usize) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let s = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            Vec3::new(s * a.cos(), y, s * a.sin())
        })
        .collect()
}

/// Samples `n_points` points uniformly by area from the mesh in `mesh` (its `faces` index its
/// `positions`). The result has positions, normals, radii, colors when the mesh has them, and
/// the mesh's origin.
pub fn sample_mesh(mesh: &Cloud, n_points: usize, seed: u64) -> Result<Cloud, SampleError> {
    let faces = mesh
        .faces
        .as_deref()
        .filter(|f| !f.is_empty())
        .ok_or(SampleError::NoFaces)?;
    let vertices = mesh.positions.len();
    let mut areas = Vec::with_capacity(faces.len());
    for (face, tri) in faces.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i as usize >= vertices) {
            return Err(SampleError::BadIndex {
                face,
                index,
                vertices,
            });
        }
        let [a, b, c] = tri.map(|i| mesh.positions[i as usize].as_dvec3());
        let area = 0.5 * (b - a).cross(c - a).length();
        areas.push(if area.is_finite() { area } else { 0.0 });
    }
    let total: f64 = areas.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Err(SampleError::ZeroArea);
    }
    let table = AliasTable::new(&areas, total);
    let colors = mesh.colors.as_ref().filter(|c| c.len() == vertices);
    let mut positions = vec![Vec3::ZERO; n_points];
    let mut normals = vec![Vec3::ZERO; n_points];
    let mut out_colors = colors.map(|_| vec![[0u8; 4]; n_points]);
    let color_blocks: Vec<Option<&mut [[u8; 4]]>> = match out_colors.as_deref_mut() {
        Some(c) => c.chunks_mut(BLOCK).map(Some).collect(),
        None => (0..n_points.div_ceil(BLOCK)).map(|_| None).collect(),
    };
    positions
        .par_chunks_mut(BLOCK)
        .zip(normals.par_chunks_mut(BLOCK))
        .zip(color_blocks)
        .enumerate()
        .for_each(|(block, ((positions, normals), mut out_colors))| {
            let mut rng = block_rng(seed, block);
            for (k, (position, normal)) in positions.iter_mut().zip(normals).enumerate() {
                let tri = faces[table.pick(rng.next_f64())];
                let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
                let (mut u, mut v) = (rng.next_f64() as f32, rng.next_f64() as f32);
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let w = 1.0 - u - v;
                *position = a * w + b * u + c * v;
                let n = (b - a).cross(c - a).normalize_or_zero();
                *normal = if n == Vec3::ZERO { Vec3::Z } else { n };
                if let (Some(out), Some(colors)) = (out_colors.as_deref_mut(), colors) {
                    let [ca, cb, cc] = tri.map(|i| colors[i as usize]);
                    out[k] = std::array::from_fn(|k| {
                        (f32::from(ca[k]) * w + f32::from(cb[k]) * u + f32::from(cc[k]) * v)
                            .round()
                            .clamp(0.0, 255.0) as u8
                    });
                }
            }
        });
    let radius = ((total / (std::f64::consts::PI * n_points.max(1) as f64)).sqrt() as f32)
        * SPLAT_RADIUS_FACTOR;
    Ok(Cloud {
        positions,
        normals: Some(normals),
        colors: out_colors,
        radii: Some(vec![radius; n_points]),
        origin: mesh.origin,
        sensors: Vec::new(),
        stats: LoadStats {
            records: n_points,
            ..LoadStats::default()
        },
        ..Cloud::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles in the z = 0 plane: area 1 (x in 0..1) and area 3 (x in 2..5).
    fn mesh() -> Cloud {
        Cloud {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(2.0, 2.0, 0.0),
                Vec3::new(9.0, 9.0, 9.0),
            ],
            colors: Some(vec![[255, 0, 0, 255]; 7]),
            faces: Some(vec![[0, 1, 2], [3, 4, 5], [6, 6, 6]]),
            ..Cloud::default()
        }
    }

    #[test]
    fn samples_lie_on_triangles_by_area() {
        let n = 20_000;
        let cloud = sample_mesh(&mesh(), n, 7).unwrap();
        assert_eq!(cloud.len(), n);
        let mut on_first = 0;
        for (p, normal) in cloud.positions.iter().zip(cloud.normals.as_ref().unwrap()) {
            assert_eq!(p.z, 0.0);
            assert_eq!(*normal, Vec3::Z);
            if p.x <= 1.0 {
                assert!(p.x >= 0.0 && p.y >= 0.0 && p.x + p.y / 2.0 <= 1.0 + 1e-6);
                on_first += 1;
            } else {
                assert!(p.x >= 2.0 && p.y >= 0.0 && (p.x - 2.0) / 3.0 + p.y / 2.0 <= 1.0 + 1e-6);
            }
        }
        let fraction = on_first as f64 / n as f64;
        assert!((fraction - 0.25).abs() < 0.02, "{fraction}");
        assert!(cloud.colors.unwrap().iter().all(|c| *c == [255, 0, 0, 255]));
        let r = cloud.radii.unwrap()[0];
        let expected = (4.0 / (std::f32::consts::PI * n as f32)).sqrt() * SPLAT_RADIUS_FACTOR;
        assert!((r - expected).abs() < 1e-6);
    }

    #[test]
    fn deterministic_per_seed() {
        let a = sample_mesh(&mesh(), 100, 1).unwrap();
        let b = sample_mesh(&mesh(), 100, 1).unwrap();
        let c = sample_mesh(&mesh(), 100, 2).unwrap();
        assert_eq!(a.positions, b.positions);
        assert_ne!(a.positions, c.positions);
    }

    #[test]
    fn rejects_non_meshes() {
        let mut m = mesh();
        m.faces = None;
        assert_eq!(sample_mesh(&m, 10, 0).unwrap_err(), SampleError::NoFaces);
        m.faces = Some(vec![[6, 6, 6]]);
        assert_eq!(sample_mesh(&m, 10, 0).unwrap_err(), SampleError::ZeroArea);
        m.faces = Some(vec![[0, 1, 70]]);
        assert!(sample_mesh(&m, 10, 0)
            .unwrap_err()
            .to_string()
            .contains("vertex 70"));
    }

    #[test]
    fn a_count_beyond_the_memory_is_refused_with_what_it_needs() {
        let gib = 1 << 30;
        assert_eq!(check_memory(1_000_000_000, 30 * gib), Ok(()));
        assert_eq!(
            check_memory(1_000_000_000, 16 * gib),
            Err(
                "1000000000 sampled points need 29.8 GiB of memory (32 bytes each), 16.0 GiB \
                 is available"
                    .to_owned()
            )
        );
        assert_eq!(
            check_memory(u64::MAX, 512 << 20),
            Err(format!(
                "{} sampled points need 16777216.0 TiB of memory (32 bytes each), 512.0 MiB is \
                 available",
                u64::MAX
            ))
        );
        assert!(available_memory().is_some_and(|m| m > 0));
    }
}
