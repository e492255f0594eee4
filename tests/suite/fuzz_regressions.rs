//! Every input that once crashed a loader (found by the fuzz targets in `fuzz/` or by hand),
//! kept under `tests/data/fuzz/TARGET/`: each loads, or is refused with an error that names
//! the file; none panics, aborts or hangs. `fuzz/README.md` says how a finding gets here.

use std::path::{Path, PathBuf};

use surfel::scene::{self, scene_file::SceneFile};

/// The cases of one target, sorted, and the extension its files are loaded with.
fn cases(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fuzz")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("an entry").path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no cases in {}", dir.display());
    files
}

/// Loads every case of `target`: the number that loaded, and the errors.
fn load_all(target: &str) -> (usize, Vec<String>) {
    let mut loaded = 0;
    let mut errors = Vec::new();
    for path in cases(target) {
        match scene::load(&path) {
            Ok(_) => loaded += 1,
            Err(e) => {
                let message = e.to_string();
                assert!(
                    message.starts_with(&format!("{}: ", path.display())),
                    "{message}"
                );
                errors.push(message);
            }
        }
    }
    (loaded, errors)
}

#[test]
fn laz_and_copc_cases() {
    // Each refused with an error naming the file, or read (a mutant can still be a valid file).
    let (_, errors) = load_all("laz");
    assert!(errors.len() >= 15, "{errors:#?}");
    let (_, errors) = load_all("copc");
    assert_eq!(errors.len(), 1, "{errors:#?}");
    let point_wise = cases("laz")
        .into_iter()
        .find(|p| p.ends_with("point-wise.laz"))
        .expect("the point-wise case");
    assert_eq!(scene::load(&point_wise).expect("point-wise").len(), 48);
}

#[test]
fn pcd_and_text_cases_are_refused() {
    for target in ["pcd", "text"] {
        let (loaded, errors) = load_all(target);
        assert_eq!(loaded, 0, "{target}: {errors:#?}");
    }
}

#[test]
fn obj_cases_are_refused_or_empty() {
    // An OBJ without vertices is a mesh of 0 points, as PDAL and trimesh read it.
    for path in cases("obj") {
        match scene::load(&path) {
            Ok(c) => assert_eq!(c.len(), 0, "{}", path.display()),
            Err(e) => assert!(
                e.to_string().starts_with(&format!("{}: ", path.display())),
                "{e}"
            ),
        }
    }
}

#[test]
fn scene_cases_are_refused() {
    for path in cases("scene") {
        let text = std::fs::read_to_string(&path).expect("text");
        let e = SceneFile::parse(&text, &path).expect_err("refused");
        assert!(format!("{e:#}").contains("invalid scene file"), "{e:#}");
    }
}
