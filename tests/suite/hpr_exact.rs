//! Exact HPR (`hpr::exact`) against independent references: the visible indices a second
//! implementation (Open3D 0.20's `hidden_point_removal`) computed once for a committed
//! 8,000-point cloud from three viewpoints (outside near and far with a small and a huge R,
//! inside), every point of a plane (whose spherical flip is strictly convex, so all of it is
//! on the hull), and the hull of every flipped point (`exact_reference`), whose result the
//! prefilter must not change, on scans, shells seen from inside and outside, and both radius
//! rules; and the complete approximate visible set (`hpr::complete`), which must hold every
//! point exact HPR finds.

use crate::common;

use std::path::PathBuf;

use glam::Vec3;
use surfel::hpr::{self, Radius};
use surfel::scene;

fn here(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| here("../shared/data"));
    root.join(rel)
}

/// One case of `tests/data/dragon-8k.open3d.txt`.
struct Case {
    name: String,
    eye: Vec3,
    radius: f64,
    visible: Vec<u32>,
}

fn open3d_cases() -> Vec<Case> {
    let text = std::fs::read_to_string(here("tests/data/dragon-8k.open3d.txt")).expect("fixture");
    let mut cases = Vec::new();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    while let Some(head) = lines.next() {
        let mut field = |key: &str| -> Vec<f64> {
            let line = lines.next().expect("a field");
            let rest = line.strip_prefix(key).expect(key);
            rest.split_whitespace()
                .map(|w| w.parse().expect("number"))
                .collect()
        };
        let eye = field("eye ");
        let radius = field("radius ")[0];
        let visible = field("visible ").into_iter().map(|v| v as u32).collect();
        cases.push(Case {
            name: head.strip_prefix("case ").expect("case").to_owned(),
            // The fixture's eyes are exact in f32.
            eye: Vec3::new(eye[0] as f32, eye[1] as f32, eye[2] as f32),
            radius,
            visible,
        });
    }
    cases
}

#[test]
fn exact_hpr_returns_open3d_s_visible_set() {
    let cloud = scene::load(&here("tests/data/dragon-8k.ply")).expect("cloud");
    assert_eq!(cloud.origin, glam::DVec3::ZERO, "positions as in the file");
    let cases = open3d_cases();
    assert_eq!(cases.len(), 3);
    for case in cases {
        let v = hpr::exact(&cloud.positions, case.eye, Radius::Absolute(case.radius))
            .unwrap_or_else(|e| panic!("{}: {e}", case.name));
        assert_eq!(v.visible.len(), case.visible.len(), "{}", case.name);
        assert_eq!(v.visible, case.visible, "{}", case.name);
    }
}

#[test]
fn every_point_of_a_plane_is_visible() {
    let points: Vec<Vec3> = (0..150)
        .flat_map(|j| (0..150).map(move |i| Vec3::new(i as f32 * 0.01, j as f32 * 0.013, 0.0)))
        .collect();
    for (eye, factor) in [
        (Vec3::new(0.7, 0.9, 1.5), 10.0),
        (Vec3::new(-0.4, 3.0, 0.3), 100.0),
        (Vec3::new(0.5, 0.5, 0.05), 1000.0),
    ] {
        let v = hpr::exact(&points, eye, Radius::Factor(factor)).expect("hpr");
        assert_eq!(
            v.visible.len(),
            points.len(),
            "eye {eye}, R factor {factor}"
        );
    }
}

#[test]
fn the_prefilter_leaves_the_hull_unchanged() {
    let mut inputs: Vec<(String, Vec<Vec3>, Vec3)> = Vec::new();
    for (rel, eye) in [
        ("stanford/bun_zipper.ply", Vec3::new(0.2, 0.25, 0.3)),
        ("stanford/dragon_vrip.ply", Vec3::new(0.3, 0.35, 0.4)),
        ("lidar/autzen_trim.laz", Vec3::new(0.0, 0.0, 400.0)),
    ] {
        let cloud = scene::load(&data(rel)).unwrap_or_else(|e| panic!("{e}"));
        let (lo, hi) = cloud.bounds().expect("bounds");
        inputs.push((rel.into(), cloud.positions, (lo + hi) * 0.5 + eye));
    }
    let mut shells = common::shell(20_000, 1.0);
    shells.extend(common::shell(5_000, 0.5));
    inputs.push((
        "shells, eye outside".into(),
        shells.clone(),
        Vec3::new(3.0, 1.0, 0.5),
    ));
    inputs.push((
        "shells, eye inside".into(),
        shells,
        Vec3::new(0.1, 0.7, 0.2),
    ));
    for (name, points, eye) in &inputs {
        let spacing = (points.len() as f64).sqrt().recip();
        for radius in [
            Radius::Factor(100.0),
            Radius::Factor(1e4),
            Radius::Density { spacing },
        ] {
            let fast = hpr::exact(points, *eye, radius).expect("exact");
            let reference = hpr::exact_reference(points, *eye, radius).expect("reference");
            assert_eq!(fast.visible, reference.visible, "{name}, {radius:?}");
            assert_eq!(
                fast.triangles.len(),
                reference.triangles.len(),
                "{name}, {radius:?}: triangles"
            );
        }
    }
}

#[test]
fn the_prefilter_leaves_out_most_hidden_points() {
    let cloud = scene::load(&data("stanford/dragon_vrip.ply")).expect("dragon");
    let eye = Vec3::new(0.3, 0.35, 0.4).as_dvec3();
    let r = 100.0;
    let flipped: Vec<glam::DVec3> = cloud
        .positions
        .iter()
        .map(|p| {
            let p = p.as_dvec3() - eye;
            let d = p.length();
            p + 2.0 * (r - d) * p / d
        })
        .collect();
    let kept = hpr::prefilter::hull_candidates(&flipped);
    let visible = hpr::exact(&cloud.positions, eye.as_vec3(), Radius::Absolute(r))
        .expect("exact")
        .visible;
    // Every visible point is kept, and the hull sees at most three times as many points.
    let mut is_kept = vec![false; flipped.len()];
    for &k in &kept {
        is_kept[k] = true;
    }
    let lost: Vec<u32> = visible
        .iter()
        .copied()
        .filter(|&v| !is_kept[v as usize])
        .collect();
    assert!(lost.is_empty(), "visible points left out: {lost:?}");
    assert!(
        kept.len() < 3 * visible.len(),
        "{} kept for {} visible",
        kept.len(),
        visible.len()
    );
}

#[test]
fn the_complete_set_holds_every_exactly_visible_point() {
    // Open3D's sets: nothing it finds is missing.
    let dragon = scene::load(&here("tests/data/dragon-8k.ply")).expect("cloud");
    for case in open3d_cases() {
        let v = hpr::complete(
            &dragon.positions,
            case.eye,
            Radius::Absolute(case.radius),
            None,
        )
        .expect("complete");
        let (_, recall, _) = hpr::agreement(&v.visible, &case.visible);
        assert_eq!(recall, 1.0, "{}", case.name);
    }
    // Scans at the default R: recall 1 and F1 at least `f1` against exact HPR.
    for (rel, eye, f1) in [
        ("stanford/bun_zipper.ply", Vec3::new(0.25, 0.3, 0.35), 0.95),
        ("lidar/autzen_trim.laz", Vec3::new(0.0, 0.0, 600.0), 0.95),
        (
            "stanford/armadillo_50k.obj",
            Vec3::new(200.0, 150.0, 300.0),
            0.95,
        ),
    ] {
        let cloud = scene::load(&data(rel)).unwrap_or_else(|e| panic!("{e}"));
        let radius = Radius::Density {
            spacing: hpr::spacing(&cloud),
        };
        let exact = hpr::exact(&cloud.positions, eye, radius).expect("exact");
        let complete = hpr::complete(&cloud.positions, eye, radius, None).expect("complete");
        let (p, r, f) = hpr::agreement(&complete.visible, &exact.visible);
        assert_eq!(r, 1.0, "{rel}: recall");
        assert!(f >= f1, "{rel}: precision {p}, F1 {f}");
    }
    // A plane: all of it.
    let plane: Vec<Vec3> = (0..100)
        .flat_map(|j| (0..100).map(move |i| Vec3::new(i as f32 * 0.01, j as f32 * 0.01, 0.0)))
        .collect();
    let v = hpr::complete(
        &plane,
        Vec3::new(0.4, 0.6, 1.0),
        Radius::Factor(100.0),
        None,
    )
    .expect("complete");
    assert_eq!(v.visible.len(), plane.len());
}
