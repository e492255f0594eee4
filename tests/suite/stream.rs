//! Conversion to COPC and streaming from it: what is written reads back (through this
//! project's COPC reader and, independently, the `las` crate reading it as plain LAZ 1.4).

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use surfel::scene::copc::{CopcFile, Entry, Info, Key, Node};
use surfel::scene::{self, Cloud, Scalar};
use surfel::stream::convert;
use surfel::stream::select::{select, select_brute_force, Budget, Hierarchy, SelectView};
use surfel::stream::source::FileSource;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-stream-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A UTM-sized cloud of `n` points on a wavy sheet with every attribute a conversion keeps.
fn survey(n: usize) -> Cloud {
    let side = (n as f64).sqrt().ceil() as usize;
    let positions: Vec<Vec3> = (0..n)
        .map(|i| {
            let (u, v) = ((i % side) as f32 * 0.25, (i / side) as f32 * 0.25);
            Vec3::new(u, v, (u * 0.3).sin() + (v * 0.2).cos())
        })
        .collect();
    let scalar = |name: &str, f: &dyn Fn(usize) -> f32| Scalar {
        name: name.into(),
        values: (0..n).map(f).collect(),
    };
    Cloud {
        normals: Some(
            positions
                .iter()
                .map(|p| Vec3::new(p.x.sin(), 1.0, p.y.cos()).normalize())
                .collect(),
        ),
        radii: Some((0..n).map(|i| 0.1 + (i % 7) as f32 * 0.01).collect()),
        colors: Some(
            (0..n)
                .map(|i| [(i % 256) as u8, (i / 7 % 256) as u8, 200, 255])
                .collect(),
        ),
        scalars: vec![
            scalar("intensity", &|i| (i * 37 % 65536) as f32),
            scalar("classification", &|i| (i % 12) as f32),
            scalar("return_number", &|i| (i % 3 + 1) as f32),
            scalar("number_of_returns", &|_| 3.0),
            scalar("gps_time", &|i| i as f32 * 0.5),
            scalar("quality", &|i| i as f32 * 0.25),
        ],
        positions,
        origin: DVec3::new(500_000.0, 4_000_000.0, 100.0),
        ..Cloud::default()
    }
}

/// Points keyed by their real-world x and y (on the survey's 0.25 grid, so rounding to 0.01 is
/// exact), with their real-world z and index.
fn by_position(cloud: &Cloud) -> Vec<([i64; 2], f64, usize)> {
    let mut keyed: Vec<([i64; 2], f64, usize)> = cloud
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let w = cloud.origin + p.as_dvec3();
            ([w.x, w.y].map(|c| (c * 100.0).round() as i64), w.z, i)
        })
        .collect();
    keyed.sort_by_key(|k| k.0);
    keyed
}

fn scalar<'a>(cloud: &'a Cloud, name: &str) -> &'a [f32] {
    &cloud
        .scalars
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no scalar {name}"))
        .values
}

#[test]
fn conversion_keeps_every_point_and_attribute() {
    let cloud = survey(20_000);
    let out = scratch("survey.copc.laz");
    convert::write_with(&cloud, &out, 2_000).unwrap();
    let back = scene::load(&out).unwrap();
    assert_eq!(back.len(), cloud.len());
    let (a, b) = (by_position(&cloud), by_position(&back));
    for ((ka, za, ia), (kb, zb, ib)) in a.iter().zip(&b) {
        assert_eq!(ka, kb, "positions differ");
        // f32 offsets from two origins, quantized at 1e-5 in the file.
        assert!((za - zb).abs() < 2e-5, "z {za} vs {zb}");
        let (ia, ib) = (*ia, *ib);
        assert_eq!(
            cloud.colors.as_ref().unwrap()[ia],
            back.colors.as_ref().unwrap()[ib]
        );
        for name in [
            "intensity",
            "classification",
            "return_number",
            "number_of_returns",
            "quality",
        ] {
            assert_eq!(scalar(&cloud, name)[ia], scalar(&back, name)[ib], "{name}");
        }
        // GPS times come back relative to the earliest.
        assert_eq!(
            scalar(&cloud, "gps_time")[ia],
            scalar(&back, "gps_time")[ib]
        );
        let (na, nb) = (
            cloud.normals.as_ref().unwrap()[ia],
            back.normals.as_ref().unwrap()[ib],
        );
        assert!((na - nb).length() < 1e-6, "{na} vs {nb}");
        assert_eq!(
            cloud.radii.as_ref().unwrap()[ia],
            back.radii.as_ref().unwrap()[ib]
        );
    }
}

/// The written file is a COPC file by the specification's rules, and plain LAZ 1.4 to a
/// reader that knows nothing of COPC.
#[test]
fn converted_file_is_valid_copc_and_laz() {
    let cloud = survey(30_000);
    let out = scratch("valid.copc.laz");
    convert::write_with(&cloud, &out, 1_000).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    // The COPC info VLR is the first VLR, right after the 375-byte header.
    assert_eq!(&bytes[375 + 2..375 + 6], b"copc");
    assert_eq!(u16::from_le_bytes([bytes[375 + 18], bytes[375 + 19]]), 1);
    let source = FileSource::open(&out).unwrap();
    let copc = CopcFile::open(&source).unwrap();
    let mut pages = vec![copc.info.root];
    let mut total = 0;
    let mut keys = std::collections::HashSet::new();
    let mut nodes = Vec::new();
    while let Some((at, len)) = pages.pop() {
        for entry in scene::copc::read_page(&copc.file, &source, at, len, copc.size).unwrap() {
            match entry {
                Entry::Node(n) => {
                    total += n.points;
                    assert!(keys.insert(n.key), "{} twice", n.key);
                    nodes.push(n);
                }
                Entry::Page { offset, bytes, .. } => pages.push((offset, bytes)),
            }
        }
    }
    assert_eq!(total, cloud.len() as u64);
    assert!(nodes.len() > 8, "{} nodes", nodes.len());
    // Every node but the root has its parent, and its points lie in its cube.
    let slack = 1e-3;
    for n in &nodes {
        if n.key != Key::ROOT {
            assert!(keys.contains(&n.key.parent()), "{} without a parent", n.key);
        }
        let (lo, hi) = copc.info.cube(n.key);
        for p in copc.read_node(&source, n).unwrap().world {
            assert!(
                p.cmpge(lo - slack).all() && p.cmple(hi + slack).all(),
                "{p} outside {} ({lo} .. {hi})",
                n.key
            );
        }
    }
    // The `las` crate reads it as LAZ: the same number of points, in the same bounds.
    let mut reader = las::Reader::from_path(&out).unwrap();
    let points = reader.read_all().unwrap();
    assert_eq!(points.len(), cloud.len());
    let (lo, hi) = cloud.bounds().unwrap();
    for p in points.points() {
        let p = p.unwrap();
        let local = (DVec3::new(p.x, p.y, p.z) - cloud.origin).as_vec3();
        assert!(local.cmpge(lo - 1e-3).all() && local.cmple(hi + 1e-3).all());
    }
}

#[test]
fn conversion_refuses_what_it_cannot_write() {
    let cloud = survey(100);
    let m = convert::write_with(&cloud, Path::new("/nonexistent-dir/x.copc.laz"), 1000)
        .unwrap_err()
        .to_string();
    assert!(m.contains("/nonexistent-dir/x.copc.laz"), "{m}");
    let m = convert::convert(
        Path::new("../shared/data/stanford/bun_zipper.ply"),
        &scratch("bunny.laz"),
        &convert::ConvertOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(m.contains("ends in .copc.laz"), "{m}");
}

/// A full octree of `depth` levels over [-8, 8]^3 whose nodes hold pseudo-random point
/// counts (some empty), with the deepest level's entries behind unread pages.
fn octree(depth: i32) -> (Hierarchy, Info) {
    let info = Info {
        center: DVec3::ZERO,
        halfsize: 8.0,
        spacing: 0.5,
        root: (0, 0),
        gps_time: (0.0, 0.0),
    };
    let mut h = Hierarchy::default();
    let mut entries = Vec::new();
    let mut state = 12345u64;
    for level in 0..depth {
        let n = 1 << level;
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let points = (state >> 33) % 30_000;
                    let key = Key { level, x, y, z };
                    if level > 0 && points < 3_000 {
                        continue;
                    }
                    entries.push(Entry::Node(Node {
                        key,
                        offset: 0,
                        bytes: 1,
                        points: points.max(1),
                        entry_at: 0,
                    }));
                }
            }
        }
    }
    for x in 0..(1 << depth) {
        entries.push(Entry::Page {
            key: Key {
                level: depth,
                x,
                y: 1 << (depth - 1),
                z: 1 << (depth - 1),
            },
            offset: 1 + x as u64,
            bytes: 32,
        });
    }
    assert!(h.add_page(0, entries));
    (h, info)
}

fn view(eye: Vec3, target: Vec3, error_px: f32) -> SelectView {
    let proj = glam::Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 1.5, 0.01);
    let look = glam::Mat4::look_at_rh(eye, target, Vec3::Z);
    SelectView {
        view_proj: proj * look,
        eye,
        pixels_per_radian: 540.0 / (30f32.to_radians().tan()),
        error_px,
    }
}

#[test]
fn node_selection_matches_a_brute_force_reference_within_budget() {
    let (h, info) = octree(5);
    let views = [
        view(Vec3::new(30.0, 0.0, 5.0), Vec3::ZERO, 1.0),
        view(Vec3::new(2.0, 1.0, 0.5), Vec3::new(-5.0, 0.0, 0.0), 1.0),
        view(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 8.0, 0.0), 2.0),
        view(Vec3::new(-7.0, -7.0, 7.0), Vec3::new(7.0, 7.0, -7.0), 0.5),
        view(Vec3::new(200.0, 0.0, 0.0), Vec3::ZERO, 1.0),
    ];
    let mut sizes = Vec::new();
    for v in &views {
        for (points, slots) in [
            (50_000, 1000),
            (400_000, 1000),
            (2_000_000, 60),
            (u64::MAX, u64::MAX),
        ] {
            let budget = Budget { points, slots };
            let fast = select(&h, &info, DVec3::ZERO, v, budget);
            let slow = select_brute_force(&h, &info, DVec3::ZERO, v, budget);
            assert_eq!(fast, slow, "budget {budget:?}");
            assert!(fast.points <= points && fast.slots <= slots);
            let sum: u64 = fast.nodes.iter().map(|k| h.nodes[k].points).sum();
            assert_eq!(sum, fast.points);
            let chosen: std::collections::HashSet<_> = fast.nodes.iter().collect();
            for k in &fast.nodes {
                assert!(
                    *k == Key::ROOT || chosen.contains(&k.parent()),
                    "{k} without its parent"
                );
            }
            sizes.push(fast.nodes.len());
        }
    }
    // The views and budgets select differently, and some reach the unread pages.
    let distinct: std::collections::HashSet<_> = sizes.iter().collect();
    assert!(distinct.len() > 6, "{sizes:?}");
    let unbounded = select(
        &h,
        &info,
        DVec3::ZERO,
        &views[1],
        Budget {
            points: u64::MAX,
            slots: u64::MAX,
        },
    );
    assert!(!unbounded.pages.is_empty());
    // A far view stops where the spacing projects below the error: the root's spacing of 0.5
    // at 200 units is 2.3 px, level 1's 1.2 px, level 2's 0.6 px.
    let far = select(
        &h,
        &info,
        DVec3::ZERO,
        &views[4],
        Budget {
            points: u64::MAX,
            slots: u64::MAX,
        },
    );
    assert_eq!(far.nodes.iter().map(|k| k.level).max(), Some(2));
}
