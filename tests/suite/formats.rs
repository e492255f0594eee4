//! E57 and COPC files from the shared test data, checked against the values their crates decode
//! (raw E57 records, the plain LAZ reading of a COPC file), the COPC point budget, and PCD
//! re-centring of projected coordinates.

use std::path::{Path, PathBuf};

use e57::{E57Reader, RecordName, RecordValue};
use glam::{DQuat, DVec3, Vec3};
use surfel::scene::{self, Cloud, Levels};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

fn load(rel: &str) -> Cloud {
    scene::load(&data(rel)).unwrap_or_else(|e| panic!("{e}"))
}

fn temp(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-formats-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The first scan of an E57 file as raw records, with its prototype's names, pose and limits.
struct RawScan {
    names: Vec<RecordName>,
    types: Vec<e57::RecordDataType>,
    records: Vec<Vec<RecordValue>>,
    pose: Option<e57::Transform>,
    colors: Option<e57::ColorLimits>,
}

impl RawScan {
    fn read(path: &Path) -> RawScan {
        let mut reader = E57Reader::from_file(path).unwrap();
        let pcs = reader.pointclouds();
        assert_eq!(pcs.len(), 1, "{}", path.display());
        let pc = &pcs[0];
        let records = reader
            .pointcloud_raw(pc)
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        RawScan {
            names: pc.prototype.iter().map(|r| r.name.clone()).collect(),
            types: pc.prototype.iter().map(|r| r.data_type.clone()).collect(),
            records,
            pose: pc.transform.clone(),
            colors: pc.color_limits.clone(),
        }
    }

    /// The value of field `name` in record `i`, as f64.
    fn value(&self, i: usize, name: RecordName) -> Option<f64> {
        let k = self.names.iter().position(|n| *n == name)?;
        Some(self.records[i][k].to_f64(&self.types[k]).unwrap())
    }

    /// Records whose `state` field is 0 (valid); all when the field is absent.
    fn valid(&self, state: RecordName) -> Vec<usize> {
        (0..self.records.len())
            .filter(|&i| self.value(i, state.clone()).unwrap_or(0.0) == 0.0)
            .collect()
    }

    /// `p` moved by the scan's pose (rotation quaternion, then translation).
    fn posed(&self, p: DVec3) -> DVec3 {
        match &self.pose {
            None => p,
            Some(t) => {
                let q = DQuat::from_xyzw(t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w);
                q * p + DVec3::new(t.translation.x, t.translation.y, t.translation.z)
            }
        }
    }
}

fn world(c: &Cloud, i: usize) -> DVec3 {
    c.positions[i].as_dvec3() + c.origin
}

#[test]
fn e57_bunny_cartesian_float() {
    let path = data("e57/bunnyFloat.e57");
    let raw = RawScan::read(&path);
    assert_eq!(raw.records.len(), 30_571);
    let valid = raw.valid(RecordName::CartesianInvalidState);
    // The file has a cartesianInvalidState field; every bunny point is marked valid.
    assert!(raw.names.contains(&RecordName::CartesianInvalidState));
    assert_eq!(valid.len(), 30_571);
    let c = load("e57/bunnyFloat.e57");
    assert_eq!(c.len(), 30_571);
    assert_eq!(c.stats.records, 30_571);
    assert_eq!(c.stats.dropped_invalid, 0);
    assert_eq!(c.up, scene::Up::Z);
    assert!(c.colors.is_none());
    for (k, &i) in valid.iter().enumerate().step_by(997) {
        let x = raw.value(i, RecordName::CartesianX).unwrap();
        let y = raw.value(i, RecordName::CartesianY).unwrap();
        let z = raw.value(i, RecordName::CartesianZ).unwrap();
        let expected = raw.posed(DVec3::new(x, y, z));
        assert!(
            (world(&c, k) - expected).abs().max_element() < 1e-7,
            "point {k}: {} vs {expected}",
            world(&c, k)
        );
    }
}

#[test]
fn e57_colors_are_normalized_to_srgb_bytes() {
    let raw = RawScan::read(&data("e57/tinyCartesianFloatRgb.e57"));
    let c = load("e57/tinyCartesianFloatRgb.e57");
    assert_eq!(c.len(), 2_090);
    assert_eq!(c.stats.dropped_invalid, 0);
    let limits = raw.colors.as_ref().expect("color limits");
    let limit = |v: &Option<RecordValue>| match v {
        Some(RecordValue::Integer(i)) => *i as f64,
        Some(RecordValue::Single(f)) => f64::from(*f),
        Some(RecordValue::Double(d)) => *d,
        other => panic!("unexpected color limit {other:?}"),
    };
    let ranges = [
        (&limits.red_min, &limits.red_max, RecordName::ColorRed),
        (&limits.green_min, &limits.green_max, RecordName::ColorGreen),
        (&limits.blue_min, &limits.blue_max, RecordName::ColorBlue),
    ];
    let colors = c.colors.as_ref().expect("colors");
    let mut distinct = std::collections::HashSet::new();
    for (i, color) in colors.iter().enumerate() {
        let expected = ranges.clone().map(|(lo, hi, name)| {
            let (lo, hi) = (limit(lo), limit(hi));
            (((raw.value(i, name).unwrap() - lo) / (hi - lo)) * 255.0).round() as u8
        });
        assert_eq!(color[..3], expected, "point {i}");
        assert_eq!(color[3], 255);
        distinct.insert(*color);
    }
    assert!(distinct.len() > 10, "{} distinct colors", distinct.len());
}

#[test]
fn e57_spherical_points_are_converted_and_invalid_ones_skipped() {
    let raw = RawScan::read(&data("e57/tiny_spherical.e57"));
    assert_eq!(raw.records.len(), 360);
    let valid = raw.valid(RecordName::SphericalInvalidState);
    let c = load("e57/tiny_spherical.e57");
    assert_eq!(valid.len(), 180);
    assert_eq!(c.len(), 180);
    assert_eq!(c.stats.records, 360);
    assert_eq!(c.stats.dropped_invalid, 180);
    for (k, &i) in valid.iter().enumerate() {
        let r = raw.value(i, RecordName::SphericalRange).unwrap();
        let az = raw.value(i, RecordName::SphericalAzimuth).unwrap();
        let el = raw.value(i, RecordName::SphericalElevation).unwrap();
        let expected = raw.posed(DVec3::new(
            r * el.cos() * az.cos(),
            r * el.cos() * az.sin(),
            r * el.sin(),
        ));
        assert!(
            (world(&c, k) - expected).abs().max_element() < 1e-6,
            "point {k}: {} vs {expected}",
            world(&c, k)
        );
    }
}

#[test]
fn e57_corrupt_checksum_names_the_file_and_page() {
    let path = data("e57/corrupt_crc.e57");
    let message = scene::load(&path).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!("{}: ", path.display())),
        "{message}"
    );
    assert!(
        message.contains(": corrupt page: Detected invalid checksum")
            && message.contains("page 33")
            && !message.contains("truncated"),
        "{message}"
    );
}

/// Points as comparable rows: f64 world position bits, color, intensity and classification.
fn rows(c: &Cloud) -> Vec<([u64; 3], [u8; 4], u32, u32)> {
    let colors = c.colors.as_ref().expect("colors");
    let mut rows: Vec<_> = (0..c.len())
        .map(|i| {
            (
                world(c, i).to_array().map(f64::to_bits),
                colors[i],
                c.scalars[0].values[i].to_bits(),
                c.scalars[1].values[i].to_bits(),
            )
        })
        .collect();
    rows.sort_unstable();
    rows
}

#[test]
fn copc_reads_every_level_like_the_plain_laz_reader() {
    let copc = load("copc/1.2-with-color.copc.laz");
    assert_eq!(copc.len(), 1_065);
    assert_eq!(copc.up, scene::Up::Z);
    assert_eq!(
        copc.stats.levels,
        Some(Levels {
            points: vec![24, 66, 197, 778],
            read: 4
        })
    );
    let names: Vec<&str> = copc.scalars.iter().map(|s| s.name.as_str()).collect();
    let standard = [
        "intensity",
        "classification",
        "return_number",
        "number_of_returns",
        "point_source_id",
        "gps_time",
    ];
    assert_eq!(names, standard);
    let colors = copc.colors.as_ref().unwrap();
    assert!(colors.iter().any(|c| c[0] != c[2]), "colors are not grey");
    // The same file under a plain .laz name goes through the LAS/LAZ loader: the same points.
    let bytes = std::fs::read(data("copc/1.2-with-color.copc.laz")).unwrap();
    let laz = scene::load(&temp("plain.laz", &bytes)).unwrap();
    assert_eq!(laz.len(), 1_065);
    assert_eq!(laz.origin, copc.origin);
    assert_eq!(rows(&copc), rows(&laz));
    let laz_names: Vec<&str> = laz.scalars.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(laz_names, standard);
    // Every field per point as the LAS reader reads it; GPS times count from each reader's
    // first point (the COPC reader's is the root node's), so they differ by one constant.
    let by_position = |c: &Cloud| {
        let mut rows: Vec<([u64; 3], Vec<f32>)> = (0..c.len())
            .map(|i| {
                let key = world(c, i).to_array().map(f64::to_bits);
                (key, c.scalars.iter().map(|s| s.values[i]).collect())
            })
            .collect();
        rows.sort_by_key(|r| r.0);
        rows
    };
    let (a, b) = (by_position(&copc), by_position(&laz));
    let shift = b[0].1[5] - a[0].1[5];
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0);
        assert_eq!(x.1[..5], y.1[..5]);
        assert!(
            (y.1[5] - x.1[5] - shift).abs() < 1e-3,
            "{} vs {}",
            x.1[5],
            y.1[5]
        );
    }

    let tiny = load("copc/autzen.copc.laz");
    assert_eq!(tiny.len(), 107);
    assert_eq!(
        tiny.stats.levels,
        Some(Levels {
            points: vec![107],
            read: 1
        })
    );
    assert!(tiny.colors.is_some());
}

/// World positions in the COPC test file's units of 0.01 (its scale; its offsets are multiples).
fn grid(c: &Cloud) -> Vec<[i64; 3]> {
    (0..c.len())
        .map(|i| (world(c, i) * 100.0).round().to_array().map(|v| v as i64))
        .collect()
}

#[test]
fn copc_budget_reads_whole_levels_from_the_root() {
    let path = data("copc/1.2-with-color.copc.laz");
    let all = scene::load(&path).unwrap();
    for (budget, read) in [
        (1, 1),
        (89, 1),
        (90, 2),
        (286, 2),
        (287, 3),
        (1_064, 3),
        (1_065, 4),
    ] {
        let c = scene::load_with_budget(&path, Some(budget)).unwrap();
        let levels = c.stats.levels.clone().unwrap();
        assert_eq!(levels.read, read, "budget {budget}");
        let kept: u64 = [24, 66, 197, 778][..read].iter().sum();
        assert_eq!(c.len() as u64, kept, "budget {budget}");
        assert_eq!(levels.points_skipped(), 1_065 - kept, "budget {budget}");
        assert_eq!(c.stats.records, 1_065);
        // The first levels are a subset of the whole cloud (compared on the file's 0.01 grid:
        // each load has its own origin, so the f32 local coordinates differ in rounding).
        let whole: std::collections::HashSet<_> = grid(&all).into_iter().collect();
        assert!(
            grid(&c).iter().all(|r| whole.contains(r)),
            "budget {budget}"
        );
    }
    let m = scene::load_with_budget(&data("lidar/autzen_trim.laz"), Some(10))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("autzen_trim.laz: a point budget needs a COPC file"),
        "{m}"
    );
}

/// A binary PCD with F4 x y z and the given points and viewpoint.
fn pcd(points: &[[f32; 3]], viewpoint: [f64; 3]) -> Vec<u8> {
    let mut bytes = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT {} {} {} 1 0 0 0\nPOINTS {n}\nDATA binary\n",
        viewpoint[0],
        viewpoint[1],
        viewpoint[2],
        n = points.len()
    )
    .into_bytes();
    for p in points {
        for v in p {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

#[test]
fn pcd_with_utm_coordinates_is_recentred() {
    // An airborne strip in UTM metres: f32 keeps 1/32 m at 512,000 and 1/2 m at 5.4 million.
    let points: Vec<[f32; 3]> = (0..1_000)
        .map(|i| {
            let f = i as f32;
            [
                512_000.0 + f * 0.125,
                5_412_000.0 + f * 0.5,
                230.0 + (f * 0.25) % 10.0,
            ]
        })
        .collect();
    let c = scene::load(&temp(
        "utm.pcd",
        &pcd(&points, [512_050.0, 5_412_200.0, 1_230.0]),
    ))
    .unwrap();
    let lo = DVec3::new(512_000.0, 5_412_000.0, 230.0);
    let hi = DVec3::new(512_124.875, 5_412_499.5, 239.75);
    assert_eq!(c.origin, (lo + hi) * 0.5);
    assert_eq!(c.len(), 1_000);
    for (p, q) in c.positions.iter().zip(&points) {
        // Exactly the file's f32 value minus the f64 origin: no precision lost.
        assert_eq!(*p, (DVec3::from(q.map(f64::from)) - c.origin).as_vec3());
    }
    assert_eq!(world(&c, 0), DVec3::from(points[0].map(f64::from)));
    assert_eq!(
        c.sensors.iter().map(|s| s.position).collect::<Vec<_>>(),
        [(DVec3::new(512_050.0, 5_412_200.0, 1_230.0) - c.origin).as_vec3()]
    );
    // Neighbouring points 0.125 m apart in x stay distinct and exact in local coordinates.
    assert_eq!(c.positions[1].x - c.positions[0].x, 0.125);

    // Small coordinates keep origin 0.
    let small = [[1.0, 2.0, 3.0], [99_999.0, -5.0, 0.5]];
    let c = scene::load(&temp("small.pcd", &pcd(&small, [0.0; 3]))).unwrap();
    assert_eq!(c.origin, DVec3::ZERO);
    assert_eq!(c.positions[1], Vec3::new(99_999.0, -5.0, 0.5));
}

/// Writes a two-scan E57 file: scan 0 Cartesian with colors, intensity, an invalid point and a
/// pose (90° about +z, then a UTM-sized translation); scan 1 spherical without colors or
/// intensity, translated only.
fn two_scans(path: &Path) {
    use e57::{E57Writer, Quaternion, Record, RecordValue as V, Transform, Translation};
    let mut writer = E57Writer::from_file(path, "two-scans").unwrap();
    let prototype = vec![
        Record::CARTESIAN_X_F64,
        Record::CARTESIAN_Y_F64,
        Record::CARTESIAN_Z_F64,
        Record::CARTESIAN_INVALID_STATE,
        Record::COLOR_RED_U8,
        Record::COLOR_GREEN_U8,
        Record::COLOR_BLUE_U8,
        Record::INTENSITY_U16,
    ];
    let mut scan = writer.add_pointcloud("scan-0", prototype).unwrap();
    let half = std::f64::consts::FRAC_1_SQRT_2;
    scan.set_transform(Some(Transform {
        rotation: Quaternion {
            w: half,
            x: 0.0,
            y: 0.0,
            z: half,
        },
        translation: Translation {
            x: 500_000.0,
            y: 5_400_000.0,
            z: 100.0,
        },
    }));
    for (xyz, state, rgb, intensity) in [
        ([1.0, 0.0, 0.0], 0, [255, 0, 0], 1_000),
        ([0.0, 2.0, 0.0], 2, [0, 255, 0], 2_000),
        ([0.5, 0.25, 3.0], 0, [0, 0, 128], 3_000),
    ] {
        let mut values: Vec<V> = xyz.into_iter().map(V::Double).collect();
        values.push(V::Integer(state));
        values.extend(rgb.map(V::Integer));
        values.push(V::Integer(intensity));
        scan.add_point(values).unwrap();
    }
    scan.finalize().unwrap();
    let prototype = vec![
        Record::SPHERICAL_RANGE_F64,
        Record::SPHERICAL_AZIMUTH_F64,
        Record::SPHERICAL_ELEVATION_F64,
    ];
    let mut scan = writer.add_pointcloud("scan-1", prototype).unwrap();
    scan.set_transform(Some(Transform {
        rotation: Quaternion {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        translation: Translation {
            x: 500_010.0,
            y: 5_400_010.0,
            z: 90.0,
        },
    }));
    let (azimuth, elevation) = (0.3_f64, -0.2_f64);
    scan.add_point(vec![
        V::Double(2.0),
        V::Double(azimuth),
        V::Double(elevation),
    ])
    .unwrap();
    scan.finalize().unwrap();
    writer.finalize().unwrap();
}

#[test]
fn e57_reads_every_scan_with_its_pose_and_recentres() {
    let path = std::env::temp_dir().join(format!("surfel-two-scans-{}.e57", std::process::id()));
    two_scans(&path);
    let c = scene::load(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(c.stats.records, 4);
    assert_eq!(c.stats.dropped_invalid, 1);
    assert_eq!(c.len(), 3);
    let t = DVec3::new(500_000.0, 5_400_000.0, 100.0);
    // 90° about +z maps (x, y, z) to (-y, x, z).
    let spherical = DVec3::new(500_010.0, 5_400_010.0, 90.0)
        + DVec3::new(
            2.0 * (-0.2f64).cos() * 0.3f64.cos(),
            2.0 * (-0.2f64).cos() * 0.3f64.sin(),
            2.0 * (-0.2f64).sin(),
        );
    let expected = [
        t + DVec3::new(0.0, 1.0, 0.0),
        t + DVec3::new(-0.25, 0.5, 3.0),
        spherical,
    ];
    for (k, e) in expected.iter().enumerate() {
        assert!(
            (world(&c, k) - *e).abs().max_element() < 1e-6,
            "point {k}: {} vs {e}",
            world(&c, k)
        );
    }
    // The origin is the f64 centre of the points' box.
    let lo = expected.iter().fold(DVec3::INFINITY, |a, b| a.min(*b));
    let hi = expected.iter().fold(DVec3::NEG_INFINITY, |a, b| a.max(*b));
    assert!((c.origin - (lo + hi) * 0.5).abs().max_element() < 1e-9);
    // Scan 1 has no colors or intensity: white and 0.
    assert_eq!(
        c.colors.as_deref(),
        Some(&[[255, 0, 0, 255], [0, 0, 128, 255], [255, 255, 255, 255]][..])
    );
    assert_eq!(c.scalars.len(), 1);
    assert_eq!(c.scalars[0].name, "intensity");
    assert_eq!(c.scalars[0].values, [1_000.0, 3_000.0, 0.0]);
}

/// A LAS 1.4 file of `n` points in point `format` (LAZ-compressed when `compressed`) with the
/// VLR `extra`, written by the `las` crate.
fn las_with_vlr(format: u8, n: usize, compressed: bool, extra: las::Vlr) -> Vec<u8> {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(format).unwrap();
    builder.point_format.is_compressed = compressed;
    builder.vlrs.push(extra);
    let header = builder.into_header().unwrap();
    let mut writer = las::Writer::new(std::io::Cursor::new(Vec::new()), header).unwrap();
    for i in 0..n {
        let format = *writer.header().point_format();
        writer
            .write_point(las::Point {
                x: i as f64,
                y: (i * 7 % 5) as f64,
                z: 1.0,
                gps_time: Some(1e9 + i as f64),
                color: format.has_color.then(|| las::Color::new(100, 200, 300)),
                nir: format.has_nir.then_some(4000 + i as u16),
                ..Default::default()
            })
            .unwrap();
    }
    writer.into_inner().unwrap().into_inner()
}

#[test]
fn a_pre_1_0_copc_draft_is_read_as_laz_with_a_note() {
    let entwine = las::Vlr {
        user_id: scene::copc::DRAFT_USER_ID.into(),
        record_id: 1,
        description: "COPC draft info".into(),
        data: vec![0; 160],
    };
    let dir = std::env::temp_dir().join(format!("surfel-draft-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("draft.copc.laz");
    std::fs::write(&path, las_with_vlr(6, 50, true, entwine)).unwrap();
    let c = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.len(), 50);
    let las = c.stats.las.as_ref().expect("LAS header");
    assert_eq!(las.note.as_deref(), Some(scene::copc::DRAFT_NOTE));
    assert_eq!((las.version.as_str(), las.point_format), ("1.4", 6));
    let e = scene::load_with_budget(&path, Some(10)).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{}: a pre-1.0 COPC draft (VLR user id \"entwine\") has no COPC 1.0 octree to read by levels; read it whole, without --level-budget", path.display())
    );
    // Without the draft's VLR the file is no COPC file at all.
    let other = las::Vlr {
        user_id: "someone".into(),
        ..Default::default()
    };
    std::fs::write(&path, las_with_vlr(6, 50, true, other)).unwrap();
    let e = scene::load(&path).unwrap_err().to_string();
    assert!(
        e.ends_with("not a COPC file: expected a COPC info VLR (user id \"copc\", record 1)"),
        "{e}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn converting_nir_warns_that_it_is_dropped() {
    let dir = std::env::temp_dir().join(format!("surfel-nir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = dir.join("nir.las");
    let note = las::Vlr {
        user_id: "surfel-test".into(),
        ..Default::default()
    };
    std::fs::write(&input, las_with_vlr(8, 40, false, note)).unwrap();
    let out = dir.join("nir.copc.laz");
    let options = surfel::copc::convert::ConvertOptions::default();
    let stats = surfel::copc::convert::convert(&input, &out, &options).unwrap();
    assert_eq!(
        stats.warnings,
        [format!("{}: point format 8 has NIR (near infrared), which a COPC file (point format 6 or 7) cannot hold; dropped", input.display())]
    );
    let back = scene::load(&out).unwrap();
    assert_eq!(back.len(), 40);
    assert!(back.scalars.iter().all(|s| s.name != "nir"));
    std::fs::remove_dir_all(dir).unwrap();
}
