//! Orientation of estimated normals (`scene::orient`) on two synthetic surveys whose true
//! normals are known: an airborne tile (terrain, flat and gabled buildings, walls) and a
//! terrestrial scan of a street (ground, two facades, parked cars) seen from a known scanner
//! position. Each is estimated on the CPU and on the GPU (lavapipe, validation on); at least
//! 99 % of the estimated normals must agree in sign with the truth. Back-face culling must
//! then keep what the unculled pyramid shows from above.

use crate::common;

use glam::Vec3;
use surfel::rng::SplitMix64;
use surfel::scene::orient::Rule;
use surfel::scene::preprocess::{self, PreprocessOptions};
use surfel::scene::{Camera, Cloud, Sensor, Up};

fn options() -> PreprocessOptions {
    PreprocessOptions {
        progress: false,
        ..Default::default()
    }
}

/// An axis-aligned box: its minimum and maximum corners.
#[derive(Clone, Copy)]
struct Block {
    lo: Vec3,
    hi: Vec3,
}

impl Block {
    /// Where the segment `a → b` enters the box, as a fraction of its length.
    fn hit(&self, a: Vec3, b: Vec3) -> Option<f32> {
        let d = b - a;
        let (mut enter, mut leave) = (0f32, 1f32);
        for k in 0..3 {
            if d[k].abs() < 1e-12 {
                if a[k] < self.lo[k] || a[k] > self.hi[k] {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((self.lo[k] - a[k]) / d[k], (self.hi[k] - a[k]) / d[k]);
            enter = enter.max(t0.min(t1));
            leave = leave.min(t0.max(t1));
        }
        (enter <= leave).then_some(enter)
    }

    /// Points on the box's top and four sides, `spacing` apart with jitter, and their outward
    /// normals.
    fn surface(&self, spacing: f32, rng: &mut SplitMix64, out: &mut Vec<(Vec3, Vec3)>) {
        let size = self.hi - self.lo;
        let mut face = |origin: Vec3, u: Vec3, v: Vec3, normal: Vec3| {
            let (nu, nv) = (
                (u.length() / spacing).ceil() as usize,
                (v.length() / spacing).ceil() as usize,
            );
            for i in 0..nu {
                for j in 0..nv {
                    let s = (i as f32 + rng.next_f64() as f32) / nu as f32;
                    let t = (j as f32 + rng.next_f64() as f32) / nv as f32;
                    out.push((origin + u * s + v * t, normal));
                }
            }
        };
        let (x, y, z) = (Vec3::X * size.x, Vec3::Y * size.y, Vec3::Z * size.z);
        face(self.lo + z, x, y, Vec3::Z);
        face(self.lo, x, z, Vec3::NEG_Y);
        face(self.lo + y, x, z, Vec3::Y);
        face(self.lo, y, z, Vec3::NEG_X);
        face(self.lo + x, y, z, Vec3::X);
    }
}

/// The ground of the airborne tile.
fn ground(x: f32, y: f32) -> f32 {
    2.0 * (x / 13.0).sin() + 1.5 * (y / 9.0).cos()
}

/// An airborne tile, 100 m square: rolling ground, eight flat-roofed and eight gabled
/// buildings (walls sampled at half the density, as an oblique scan sees them), 0.5 m apart,
/// 2 cm of noise. Positions and true normals.
fn airborne() -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = SplitMix64::new(11);
    let spacing = 0.5;
    let footprints: Vec<(f32, f32, f32, f32, bool)> = (0..16)
        .map(|i| {
            let (cx, cy) = (12.0 + 25.0 * (i % 4) as f32, 12.0 + 25.0 * (i / 4) as f32);
            (
                cx,
                cy,
                6.0 + (i % 3) as f32,
                4.0 + (i % 5) as f32,
                i % 2 == 1,
            )
        })
        .collect();
    let roof = |x: f32, y: f32| {
        footprints
            .iter()
            .find_map(|&(cx, cy, half, height, gabled)| {
                let inside = (x - cx).abs() < half && (y - cy).abs() < half;
                let base = ground(cx, cy) + height;
                inside.then(|| {
                    if gabled {
                        // Ridge along y, roof pitch 0.5.
                        let z = base + 0.5 * (half - (x - cx).abs());
                        let n = Vec3::new(0.5 * (x - cx).signum(), 0.0, 1.0).normalize();
                        (z, n)
                    } else {
                        (base, Vec3::Z)
                    }
                })
            })
    };
    let mut points = Vec::new();
    let cells = (100.0 / spacing) as usize;
    for i in 0..cells {
        for j in 0..cells {
            let x = (i as f32 + rng.next_f64() as f32) * spacing;
            let y = (j as f32 + rng.next_f64() as f32) * spacing;
            let (z, n) = roof(x, y).unwrap_or_else(|| {
                let h = 1e-3;
                let dx = (ground(x + h, y) - ground(x - h, y)) / (2.0 * h);
                let dy = (ground(x, y + h) - ground(x, y - h)) / (2.0 * h);
                (ground(x, y), Vec3::new(-dx, -dy, 1.0).normalize())
            });
            points.push((Vec3::new(x, y, z), n));
        }
    }
    for &(cx, cy, half, height, _) in &footprints {
        let base = ground(cx, cy) + height;
        let lo = Vec3::new(cx - half, cy - half, ground(cx, cy) - 2.0);
        let block = Block {
            lo,
            hi: Vec3::new(cx + half, cy + half, base),
        };
        let mut walls = Vec::new();
        block.surface(spacing * 2.0, &mut rng, &mut walls);
        // Walls only, above the ground beside them.
        points.extend(
            walls
                .into_iter()
                .filter(|(p, n)| n.z == 0.0 && p.z > ground(p.x, p.y) + 0.1 && p.z < base - 0.1),
        );
    }
    let noise = |rng: &mut SplitMix64| (rng.next_f64() as f32 - 0.5) * 0.04;
    points
        .into_iter()
        .map(|(p, n)| {
            (
                p + Vec3::new(noise(&mut rng), noise(&mut rng), noise(&mut rng)),
                n,
            )
        })
        .unzip()
}

/// A terrestrial scan of a street from a scanner 1.8 m above it: the ground (60 × 20 m), a
/// facade on each side (12 m high) and three parked cars, sampled 0.25 m apart where the
/// scanner sees them (the surface faces it and no car is in the way). Positions, true normals
/// and the scanner.
fn terrestrial() -> (Vec<Vec3>, Vec<Vec3>, Vec3) {
    let mut rng = SplitMix64::new(5);
    let scanner = Vec3::new(0.0, 2.0, 1.8);
    let spacing = 0.25;
    let cars = [
        Block {
            lo: Vec3::new(-12.0, -7.5, 0.0),
            hi: Vec3::new(-7.5, -5.7, 1.5),
        },
        Block {
            lo: Vec3::new(5.0, -7.5, 0.0),
            hi: Vec3::new(9.5, -5.7, 1.5),
        },
        Block {
            lo: Vec3::new(10.0, 5.5, 0.0),
            hi: Vec3::new(14.5, 7.3, 1.6),
        },
    ];
    let mut surface = Vec::new();
    let mut plane = |origin: Vec3, u: Vec3, v: Vec3, normal: Vec3, rng: &mut SplitMix64| {
        let (nu, nv) = (
            (u.length() / spacing) as usize,
            (v.length() / spacing) as usize,
        );
        for i in 0..nu {
            for j in 0..nv {
                let s = (i as f32 + rng.next_f64() as f32) / nu as f32;
                let t = (j as f32 + rng.next_f64() as f32) / nv as f32;
                surface.push((origin + u * s + v * t, normal));
            }
        }
    };
    let (length, half_width, height) = (60.0, 10.0, 12.0);
    let start = Vec3::new(-length / 2.0, -half_width, 0.0);
    plane(
        start,
        Vec3::X * length,
        Vec3::Y * 2.0 * half_width,
        Vec3::Z,
        &mut rng,
    );
    plane(start, Vec3::X * length, Vec3::Z * height, Vec3::Y, &mut rng);
    plane(
        Vec3::new(-length / 2.0, half_width, 0.0),
        Vec3::X * length,
        Vec3::Z * height,
        Vec3::NEG_Y,
        &mut rng,
    );
    for car in &cars {
        car.surface(spacing, &mut rng, &mut surface);
    }
    let visible = |(p, n): &(Vec3, Vec3)| {
        let towards = scanner - *p;
        n.dot(towards) > 0.0
            && towards.length() < 40.0
            && !cars
                .iter()
                .any(|c| c.hit(scanner, *p - towards.normalize() * 1e-3).is_some())
    };
    let (positions, normals) = surface.into_iter().filter(visible).unzip();
    (positions, normals, scanner)
}

/// The fraction of `estimated` normals on the same side as `truth`.
fn agreement(estimated: &[Vec3], truth: &[Vec3]) -> f64 {
    let agree = estimated
        .iter()
        .zip(truth)
        .filter(|(e, t)| e.dot(**t) > 0.0)
        .count();
    agree as f64 / truth.len() as f64
}

/// The fraction of `truth` that faces away from the centroid: what the orientation by the
/// centroid alone would get right.
fn centroid_rule(positions: &[Vec3], truth: &[Vec3]) -> f64 {
    let centre = preprocess::centroid(positions);
    let agree = positions
        .iter()
        .zip(truth)
        .filter(|(p, t)| t.dot(**p - centre) > 0.0)
        .count();
    agree as f64 / truth.len() as f64
}

fn survey(positions: Vec<Vec3>) -> Cloud {
    Cloud {
        positions,
        up: Up::Z,
        survey: true,
        ..Cloud::default()
    }
}

/// Estimates on the CPU and the GPU; the agreement of each with `truth`.
fn oriented(name: &str, cloud: &Cloud, truth: &[Vec3], rule: Rule) -> [f64; 2] {
    assert_eq!(Rule::for_cloud(cloud), rule, "{name}");
    let mut cpu = cloud.clone();
    preprocess::preprocess(&mut cpu, &options());
    let ctx = common::context();
    let mut gpu = cloud.clone();
    surfel::knn_gpu::estimate(&ctx, &mut gpu, &options())
        .expect("GPU estimate")
        .expect("something to estimate");
    common::assert_clean(&ctx);
    let (on_cpu, on_gpu) = (
        agreement(cpu.normals.as_ref().unwrap(), truth),
        agreement(gpu.normals.as_ref().unwrap(), truth),
    );
    eprintln!(
        "{name}: {} points, {:?}: sign agreement CPU {:.4}, GPU {:.4} (centroid rule {:.4})",
        truth.len(),
        rule,
        on_cpu,
        on_gpu,
        centroid_rule(&cloud.positions, truth)
    );
    [on_cpu, on_gpu]
}

/// Asserts that at least 99 % of the normals of both estimates agree with `truth`.
fn assert_oriented(name: &str, cloud: &Cloud, truth: &[Vec3], rule: Rule) {
    for (on, agreement) in ["CPU", "GPU"]
        .iter()
        .zip(oriented(name, cloud, truth, rule))
    {
        assert!(agreement >= 0.99, "{name}: {on} agreement {agreement}");
    }
}

#[test]
fn airborne_normals_face_up_and_walls_outwards() {
    let (positions, truth) = airborne();
    assert_oriented("airborne", &survey(positions), &truth, Rule::Up(Up::Z));
}

#[test]
fn terrestrial_normals_face_the_scanner_or_up() {
    let (positions, truth, scanner) = terrestrial();
    let with_scanner = Cloud {
        sensors: vec![Sensor {
            first: 0,
            position: scanner,
        }],
        ..survey(positions.clone())
    };
    assert_oriented(
        "terrestrial, scanner known",
        &with_scanner,
        &truth,
        Rule::Sensor,
    );
    assert_oriented(
        "terrestrial, as LiDAR without a scanner",
        &survey(positions.clone()),
        &truth,
        Rule::Up(Up::Z),
    );
    // Bare points: the propagation makes the whole street consistent; its one sign is the
    // centroid's guess, wrong for a scene seen from inside.
    let bare = Cloud {
        positions,
        up: Up::Z,
        ..Cloud::default()
    };
    for (on, agreement) in ["CPU", "GPU"].iter().zip(oriented(
        "terrestrial, bare points",
        &bare,
        &truth,
        Rule::Propagate,
    )) {
        let consistent = agreement.max(1.0 - agreement);
        assert!(
            consistent >= 0.99,
            "bare points: {on} agreement {agreement}"
        );
    }
}

#[test]
fn culling_keeps_the_ground_of_both_surveys() {
    let (street, _, _) = terrestrial();
    for (name, positions) in [("airborne", airborne().0), ("street", street)] {
        let mut cloud = survey(positions);
        preprocess::preprocess(&mut cloud, &options());
        let above = |centre: Vec3, radius: f32| {
            Camera::look_at_up(Up::Z, centre + Vec3::Z * radius * 2.2, centre, radius)
        };
        let count = |method: &str| {
            let frame = common::render_view(&cloud, method, 192, Default::default(), above);
            common::covered(&frame).iter().filter(|&&c| c).count()
        };
        let (culled, all) = (count("pyramid"), count("pyramid:cull=0"));
        eprintln!("{name}, pyramid from above: {culled} pixels culled, {all} unculled");
        assert!(all > 192 * 192 / 8, "{name} fills the view: {all}");
        assert!(
            culled as f64 >= 0.99 * all as f64,
            "{name}: {culled} of {all}"
        );
    }
}

#[test]
fn info_names_the_rule_each_file_gets() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    for (file, rule) in [
        (
            "lidar/autzen_trim.laz",
            "up (z), propagated over the k-NN graph where |n·up| < 0.5 (walls, slopes)",
        ),
        (
            "e57/tiny_spherical.e57",
            "towards the scanner (the file's scan positions), propagated where |n·d| < 0.1",
        ),
        (
            "stanford/bun000.ply",
            "propagated over the k-NN graph (Hoppe 1992 spanning tree), each part facing away from the centroid",
        ),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_surfel"))
            .args(["info", data.join(file).to_str().expect("utf8"), "--no-device"])
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .expect("surfel runs");
        assert!(out.status.success(), "{file}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let line = format!("normal signs      {rule}\n");
        assert!(stdout.contains(&line), "{file}: {stdout}");
    }
}
