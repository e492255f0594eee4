//! The line conversion (thesis 000 §5.1) on the low-poly plants of the shared data: every face
//! is converted or kept, leaves become ribbons and branches tubes, and the lines stay inside
//! the mesh.

use std::path::{Path, PathBuf};

use glam::Vec3;
use surfel::scene::lines::{self, LineKind, LineModel};
use surfel::scene::obj::{self, PolygonMesh};

fn plant(name: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join("plants").join(name)
}

fn convert(name: &str) -> (PolygonMesh, LineModel) {
    let mesh = obj::load_polygons(&plant(name)).unwrap_or_else(|e| panic!("{e}"));
    let model = lines::convert(&mesh);
    (mesh, model)
}

/// The checks every plant passes; returns the model for plant-specific ones.
fn sane(name: &str) -> LineModel {
    let (mesh, model) = convert(name);
    let s = &model.stats;
    assert_eq!(
        s.faces_converted + s.faces_kept,
        mesh.polygons.len(),
        "{name}"
    );
    assert_eq!(
        mesh.uncolored, 0,
        "{name}: every face has its material's colour"
    );
    let kept = model.triangles.faces.as_ref().expect("faces");
    assert_eq!(kept.len(), s.triangles);
    assert!(kept
        .iter()
        .flatten()
        .all(|&i| (i as usize) < model.triangles.len()));
    assert!(s.output_vertices() < s.input_vertices, "{name}: {s:?}");
    let (lo, hi) = mesh.positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let slack = 1e-5 * (hi - lo).length();
    let inside = |p: Vec3| p.cmpge(lo - slack).all() && p.cmple(hi + slack).all();
    for p in &model.polylines {
        assert!(p.vertices.len() >= 2);
        assert!(mesh.colors.contains(&p.color), "{name}: {:?}", p.color);
        for (i, v) in p.vertices.iter().enumerate() {
            assert!(inside(v.position), "{name}: {v:?} outside {lo} .. {hi}");
            assert!((v.dir.length() - 1.0).abs() < 1e-4, "{name}: {v:?}");
            assert!(v.radius.is_finite() && v.radius >= 0.0, "{name}: {v:?}");
            let end = i == 0 || i == p.vertices.len() - 1;
            assert!(
                end || v.radius > 0.0,
                "{name}: zero radius inside a line: {v:?}"
            );
        }
    }
    assert!(model.triangles.positions.iter().all(|&p| inside(p)));
    // The file keeps the model.
    let back = lines::parse(name, lines::to_text(&model).as_bytes()).expect("reparse");
    assert_eq!(back.polylines, model.polylines);
    assert_eq!(back.triangles.faces, model.triangles.faces);
    model
}

fn kinds(model: &LineModel, kind: LineKind) -> usize {
    model.polylines.iter().filter(|p| p.kind == kind).count()
}

#[test]
fn palm_fronds_become_ribbons_and_the_trunk_a_tube() {
    let model = sane("PalmTree_1.obj");
    let s = model.stats;
    assert_eq!(s.components, 16);
    assert_eq!(kinds(&model, LineKind::Ribbon), s.ribbons.polylines);
    // 15 fronds, one trunk: the trunk is long enough (radius 0.09, 3.8 long) to be a tube.
    assert_eq!((s.ribbons.polylines, s.tubes.polylines), (15, 1), "{s:?}");
    assert_eq!(s.faces_kept, 0, "{s:?}");
    // The fronds taper: narrow at both ends, pointed at the far one.
    for p in model
        .polylines
        .iter()
        .filter(|p| p.kind == LineKind::Ribbon)
    {
        let widest = p.vertices.iter().map(|v| v.radius).fold(0.0, f32::max);
        let (first, last) = (
            p.vertices[0].radius,
            p.vertices[p.vertices.len() - 1].radius,
        );
        assert!(first < 0.35 * widest && last < 0.05 * widest, "{p:?}");
    }
}

#[test]
fn dead_tree_branches_become_tubes_and_junctions_stay_triangles() {
    let model = sane("CommonTree_Dead_1.obj");
    let s = model.stats;
    assert_eq!(s.components, 1);
    assert!(s.tubes.polylines >= 10, "{s:?}");
    assert_eq!(s.ribbons.polylines, 0, "{s:?}");
    assert!(s.faces_converted > s.faces_kept, "{s:?}");
    assert!(s.triangles > 0, "junctions and the trunk are kept: {s:?}");
}

#[test]
fn plant_leaves_become_ribbons() {
    let model = sane("Plant_3.obj");
    let s = model.stats;
    assert_eq!(s.components, 14);
    assert!(s.ribbons.polylines >= 14, "{s:?}");
    assert_eq!(s.tubes.polylines, 0, "{s:?}");
    // Two components are pairs of leaves joined at the base: their joints become short
    // ribbons or caps, so nothing is left as triangles.
    assert_eq!(s.faces_kept, 0, "{s:?}");
}

#[test]
fn the_conversion_is_deterministic() {
    let (_, a) = convert("CommonTree_Dead_1.obj");
    let (_, b) = convert("CommonTree_Dead_1.obj");
    assert_eq!(a, b);
}

#[test]
fn committed_line_models_match_a_fresh_conversion() {
    // benches/data holds the plants' line models for the plants sweep; they must be what
    // `surfel convert-lines` writes today.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/data");
    for name in ["PalmTree_1", "CommonTree_Dead_1", "Plant_3"] {
        let (_, model) = convert(&format!("{name}.obj"));
        let committed = std::fs::read_to_string(data.join(format!("{name}.lines.ply")))
            .expect("committed line model");
        assert!(
            lines::to_text(&model) == committed,
            "benches/data/{name}.lines.ply is stale: regenerate it with `surfel convert-lines \
             ../shared/data/plants/{name}.obj --out benches/data/{name}.lines.ply`"
        );
    }
}

#[test]
fn a_line_model_loads_as_a_cloud_of_segments_and_kept_triangles() {
    for name in ["PalmTree_1", "CommonTree_Dead_1"] {
        let (_, model) = convert(&format!("{name}.obj"));
        let path =
            std::env::temp_dir().join(format!("surfel-{}-{name}.lines.ply", std::process::id()));
        lines::save(&path, &model).expect("save");
        assert!(lines::is_line_model(&path));
        let cloud = surfel::scene::load(&path).expect("load");
        std::fs::remove_file(&path).unwrap();
        let s = &model.stats;
        let polyline_vertices = s.ribbons.vertices + s.tubes.vertices;
        assert_eq!(
            cloud.len(),
            polyline_vertices + s.triangle_vertices,
            "{name}"
        );
        assert_eq!(cloud.radii.as_ref().map(Vec::len), Some(cloud.len()));
        let l = cloud.lines.as_ref().expect("lines");
        assert_eq!(
            (l.ribbons.len(), l.tubes.len()),
            (s.ribbons.segments, s.tubes.segments)
        );
        // Segments join consecutive vertices of one polyline; faces index the kept part only.
        assert!(l.ribbons.iter().chain(&l.tubes).all(|[a, b]| b - a == 1));
        let faces = cloud.faces.as_deref().unwrap_or_default();
        assert_eq!(faces.len(), s.triangles, "{name}");
        assert!(faces
            .iter()
            .flatten()
            .all(|&i| (i as usize) >= polyline_vertices && (i as usize) < cloud.len()));
        // The kept triangles are not expanded by the pyramid: radius 0.
        assert!(cloud.radii.as_ref().unwrap()[polyline_vertices..]
            .iter()
            .all(|&r| r == 0.0));
    }
    assert!(!lines::is_line_model(&plant("PalmTree_1.obj")));
}
