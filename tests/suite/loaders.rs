//! Every file in the shared test data loads with the counts documented in its README.
//!
//! The data lives in `../shared/data` beside the crate (as in CI); `SURFEL_DATA` overrides it.

use std::path::PathBuf;

use glam::{DVec3, Vec3};
use surfel::scene::{self, ply, sample, Cloud};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

fn load(rel: &str) -> Cloud {
    let path = data(rel);
    scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn faces(c: &Cloud) -> usize {
    c.faces.as_ref().map_or(0, Vec::len)
}

fn assert_bounds(c: &Cloud, lo: [f64; 3], hi: [f64; 3], tol: f64) {
    let (a, b) = c.bounds().expect("non-empty");
    let (a, b) = (a.as_dvec3() + c.origin, b.as_dvec3() + c.origin);
    assert!(
        (a - DVec3::from(lo)).abs().max_element() < tol,
        "min {a} vs {lo:?}"
    );
    assert!(
        (b - DVec3::from(hi)).abs().max_element() < tol,
        "max {b} vs {hi:?}"
    );
}

#[test]
fn stanford_ply() {
    let bunny = load("stanford/bun_zipper.ply");
    assert_eq!(bunny.len(), 35_947);
    assert_eq!(faces(&bunny), 69_451);
    let names: Vec<&str> = bunny.scalars.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["confidence", "intensity"]);
    assert!(bunny.scalars.iter().all(|s| s.values.len() == 35_947));
    assert!(bunny.normals.is_none() && bunny.colors.is_none());
    assert_bounds(
        &bunny,
        [-0.0946899, 0.0329874, -0.0618736],
        [0.0610091, 0.187321, 0.0587997],
        1e-6,
    );

    let scan = load("stanford/bun000.ply");
    assert_eq!(scan.len(), 40_256);
    assert_eq!(faces(&scan), 0);
    assert_bounds(
        &scan,
        [-0.09475, 0.0357363, -0.0586982],
        [0.061, 0.18794, 0.0587228],
        1e-6,
    );

    let dragon = load("stanford/dragon_vrip.ply");
    assert_eq!((dragon.len(), faces(&dragon)), (437_645, 871_414));
    assert_bounds(
        &dragon,
        [-0.108324, 0.0527295, -0.0504143],
        [0.0965662, 0.197173, 0.0412075],
        1e-6,
    );
    let res2 = load("stanford/dragon_vrip_res2.ply");
    assert_eq!((res2.len(), faces(&res2)), (100_250, 202_520));
}

#[test]
fn stanford_obj() {
    let bunny = load("stanford/stanford-bunny.obj");
    assert_eq!((bunny.len(), faces(&bunny)), (35_947, 69_451));
    let armadillo = load("stanford/armadillo_50k.obj");
    assert_eq!((armadillo.len(), faces(&armadillo)), (49_990, 99_976));
    assert_bounds(
        &armadillo,
        [-63.4973, -54.22, -57.7145],
        [63.5174, 97.087, 57.6965],
        1e-3,
    );
    let buddha = load("stanford/happy_buddha_50k.obj");
    assert_eq!((buddha.len(), faces(&buddha)), (49_950, 100_000));
}

#[test]
fn bunny_ply_and_obj_agree() {
    let ply = load("stanford/bun_zipper.ply");
    let obj = load("stanford/stanford-bunny.obj");
    assert_eq!(ply.len(), obj.len());
    // The OBJ is a MeshLab re-export rounded to ~6 significant digits (max difference 5e-7).
    for (a, b) in ply.positions.iter().zip(&obj.positions) {
        assert!((*a - *b).abs().max_element() <= 1e-6, "{a} vs {b}");
    }
    assert_eq!(ply.faces, obj.faces);
}

#[test]
fn plant_obj_polygons_and_normals() {
    // Triangles + quads (2 triangles) + hexagons (4 triangles).
    let palm = load("plants/PalmTree_1.obj");
    assert_eq!(palm.len(), 918);
    assert_eq!(faces(&palm), 60 + 852 * 2 + 2 * 4);
    let dead = load("plants/CommonTree_Dead_1.obj");
    assert_eq!((dead.len(), faces(&dead)), (1_182, 1_180 * 2));
    let plant = load("plants/Plant_3.obj");
    assert_eq!((plant.len(), faces(&plant)), (328, 32 + 284 * 2));
    for c in [&palm, &dead, &plant] {
        let normals = c.normals.as_ref().expect("vn normals");
        assert_eq!(normals.len(), c.len());
        assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    }
}

#[test]
fn open3d_fragment() {
    let frag = load("ply/frag_115.ply");
    assert_eq!((frag.len(), faces(&frag)), (64_365, 127_229));
    let normals = frag.normals.as_ref().unwrap();
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-3));
    let colors = frag.colors.as_ref().unwrap();
    assert_eq!(colors.len(), 64_365);
    assert!(colors.iter().any(|c| c[0] > 100) && colors.iter().all(|c| c[3] == 255));
    assert_bounds(
        &frag,
        [0.839844, 0.917969, 0.566406],
        [2.57239, 2.81355, 1.60887],
        1e-5,
    );
}

#[test]
fn pcd_compressed_with_nans() {
    for (file, nan, lo, hi) in [
        (
            "pcd/table_scene_mug_stereo_textured.pcd",
            97_920,
            [-0.45643, -0.51074, 0.69001],
            [0.71518, 0.17923, 2.5927],
        ),
        (
            "pcd/milk_cartoon_all_small_clorox.pcd",
            65_793,
            [-1.0608, -0.869233, 0.501],
            [1.15249, 0.219669, 2.063],
        ),
    ] {
        let c = load(file);
        assert_eq!(c.stats.records, 307_200);
        assert_eq!(c.stats.dropped_non_finite, nan);
        assert_eq!(c.len(), 307_200 - nan);
        assert!(c.positions.iter().all(|p| p.is_finite()));
        let colors = c.colors.as_ref().unwrap();
        assert!(colors.iter().all(|c| c[3] == 255));
        assert!(colors.iter().any(|c| c[0] > 100));
        assert_eq!(
            c.sensors,
            [surfel::scene::Sensor {
                first: 0,
                position: Vec3::ZERO
            }]
        );
        assert_eq!(c.up, scene::Up::NegY);
        assert_bounds(&c, lo, hi, 1e-4);
    }
}

#[test]
fn autzen_las_and_laz() {
    let las = load("lidar/autzen_trim.las");
    let laz = load("lidar/autzen_trim.laz");
    assert_eq!(las.len(), 110_000);
    assert_eq!(las.positions, laz.positions);
    assert_eq!(las.origin, laz.origin);
    assert_eq!(las.colors, laz.colors);
    assert_eq!(las.scalars, laz.scalars);
    // Known records (x, y, z in feet; intensity; RGB stored as 8-bit values in 16-bit fields).
    for (i, xyz, intensity, rgb) in [
        (0, [637177.98, 849393.95, 411.19], 4.0, [84, 102, 93]),
        (1, [637177.30, 849396.95, 411.25], 24.0, [82, 98, 90]),
        (
            50_000,
            [636601.86, 849018.59, 425.10],
            124.0,
            [134, 134, 104],
        ),
        (109_999, [636037.88, 849336.94, 423.20], 100.0, [64, 74, 70]),
    ] {
        let world = las.positions[i].as_dvec3() + las.origin;
        assert!(
            (world - DVec3::from(xyz)).abs().max_element() < 1e-3,
            "{i}: {world}"
        );
        assert_eq!(las.scalars[0].values[i], intensity);
        let c = las.colors.as_ref().unwrap()[i];
        assert_eq!([c[0], c[1], c[2]], rgb);
    }
    let colors = las.colors.as_ref().unwrap();
    let mean = colors.iter().map(|c| f64::from(c[0])).sum::<f64>() / colors.len() as f64;
    assert!(mean > 40.0, "RGB is near-black: mean red {mean}");
    let class = &las.scalars[1];
    assert_eq!(class.name, "classification");
    assert_eq!(class.values.iter().filter(|&&v| v == 2.0).count(), 26_107);
    assert_bounds(
        &las,
        [636001.76, 848935.20, 406.26],
        [637179.22, 849497.90, 520.51],
        1e-3,
    );
}

#[test]
fn vegetation_negative_offsets() {
    let c = load("lidar/vegetation_1_3.las");
    assert_eq!(c.len(), 10_683);
    assert!(c.colors.is_none());
    assert!(c.scalars[1].values.iter().all(|&v| v == 11.0));
    assert_bounds(
        &c,
        [-98451.2, -55975.4, -81460.1],
        [-98447.4, -55969.4, -81455.2],
        0.06,
    );
}

/// Size in bytes of a PLY scalar type.
fn type_size(name: &str) -> usize {
    match name {
        "char" | "int8" | "uchar" | "uint8" => 1,
        "short" | "int16" | "ushort" | "uint16" => 2,
        "int" | "int32" | "uint" | "uint32" | "float" | "float32" => 4,
        "double" | "float64" => 8,
        other => panic!("unknown PLY type {other}"),
    }
}

/// One property of a PLY element, for [`transcode`].
enum Prop {
    Scalar(usize),
    List {
        count: usize,
        item: usize,
    },
    /// An empty list written into the output only.
    Pad,
}

/// Re-encodes a binary PLY in the byte order `big`. With `pad`, every vertex record starts
/// with an empty list, so the vertices no longer have a fixed size and the loader decodes
/// them one record at a time.
fn transcode(data: &[u8], big: bool, pad: bool) -> Vec<u8> {
    let end = data.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&data[..end]).unwrap();
    let source_big = header.contains("binary_big_endian");
    let mut elements: Vec<(usize, Vec<Prop>)> = Vec::new();
    let mut out = String::new();
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", ..] => {
                let order = if big { "big" } else { "little" };
                out += &format!("format binary_{order}_endian 1.0\n");
                continue;
            }
            ["element", name, count] => {
                out += &format!("{line}\n");
                elements.push((count.parse().unwrap(), Vec::new()));
                if pad && *name == "vertex" {
                    out += "property list uchar int pad\n";
                    elements.last_mut().unwrap().1.push(Prop::Pad);
                }
                continue;
            }
            ["property", "list", count, item, _] => {
                elements.last_mut().unwrap().1.push(Prop::List {
                    count: type_size(count),
                    item: type_size(item),
                });
            }
            ["property", ty, _] => elements
                .last_mut()
                .unwrap()
                .1
                .push(Prop::Scalar(type_size(ty))),
            _ => {}
        }
        out += &format!("{line}\n");
    }
    let mut bytes = out.into_bytes();
    let mut at = end;
    // Copies one value of `size` bytes in the output's byte order and returns it as read.
    let mut copy = |bytes: &mut Vec<u8>, size: usize| {
        let value = &data[at..at + size];
        at += size;
        if source_big == big {
            bytes.extend_from_slice(value);
        } else {
            bytes.extend(value.iter().rev());
        }
        let digits: Vec<u8> = if source_big {
            value.to_vec()
        } else {
            value.iter().rev().copied().collect()
        };
        digits.iter().fold(0usize, |v, &b| v << 8 | usize::from(b))
    };
    for (count, props) in &elements {
        for _ in 0..*count {
            for prop in props {
                match *prop {
                    Prop::Scalar(size) => {
                        copy(&mut bytes, size);
                    }
                    Prop::List { count, item } => {
                        for _ in 0..copy(&mut bytes, count) {
                            copy(&mut bytes, item);
                        }
                    }
                    Prop::Pad => bytes.push(0),
                }
            }
        }
    }
    assert_eq!(at, data.len());
    bytes
}

/// Loads `bytes` through a file named `name` in the temp folder.
fn load_bytes(name: &str, bytes: &[u8]) -> Cloud {
    let path = std::env::temp_dir().join(format!("surfel-loaders-{}-{name}", std::process::id()));
    std::fs::write(&path, bytes).unwrap();
    let cloud = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    std::fs::remove_file(&path).unwrap();
    cloud
}

/// Little- and big-endian, streamed from a file and parsed from memory in parallel, and
/// decoded record by record (padded with a list property): all identical.
fn assert_binary_decodings_agree(name: &str, binary: &[u8]) {
    let reference = ply::parse(name, &transcode(binary, false, true)).unwrap();
    for big in [false, true] {
        let fixed = transcode(binary, big, false);
        let padded = transcode(binary, big, true);
        let label = format!("{name} big={big}");
        assert_eq!(load_bytes(name, &fixed), reference, "{label} streamed");
        assert_eq!(
            ply::parse(name, &fixed).unwrap(),
            reference,
            "{label} in memory"
        );
        assert_eq!(
            load_bytes(name, &padded),
            reference,
            "{label} record by record"
        );
    }
}

#[test]
fn binary_ply_parallel_matches_sequential() {
    let fragment = std::fs::read(data("ply/frag_115.ply")).unwrap();
    assert_binary_decodings_agree("frag_115.ply", &fragment);
    let mesh = load("ply/frag_115.ply");
    let mut sampled = sample::sample_mesh(&mesh, 200_000, 3).unwrap();
    let mut bytes = Vec::new();
    ply::write_binary(&sampled, &mut bytes).unwrap();
    assert_binary_decodings_agree("sampled.ply", &bytes);
    // Double coordinates far from zero: positions are decoded again relative to the origin.
    sampled.origin = DVec3::new(636_000.0, 849_000.0, 400.0);
    bytes.clear();
    ply::write_binary(&sampled, &mut bytes).unwrap();
    assert_binary_decodings_agree("wide.ply", &bytes);
}

#[test]
fn sample_is_identical_for_any_thread_count() {
    let mesh = load("ply/frag_115.ply");
    let write = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let cloud = sample::sample_mesh(&mesh, 300_000, 11).unwrap();
            let mut bytes = Vec::new();
            ply::write_binary(&cloud, &mut bytes).unwrap();
            bytes
        })
    };
    let one = write(1);
    assert_eq!(one, write(2));
    assert_eq!(one, write(3));
    let other_seed = sample::sample_mesh(&mesh, 300_000, 12).unwrap();
    let mut bytes = Vec::new();
    ply::write_binary(&other_seed, &mut bytes).unwrap();
    assert_ne!(one, bytes);
}
