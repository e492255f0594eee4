//! What every loader target does with an input: write it to a file named for its format and
//! load it through `surfel::scene::load`, the path the command line takes. Any result is
//! fine; a panic, an abort, an allocation past libFuzzer's `-malloc_limit_mb` or a run past
//! `-timeout` is a finding.

use std::path::PathBuf;

/// Loads `data` as a file named `input.{extension}` in a folder of this process.
pub fn load(extension: &str, data: &[u8]) {
    let dir = std::env::temp_dir().join(format!("surfel-fuzz-{}", std::process::id()));
    let path: PathBuf = dir.join(format!("input.{extension}"));
    if std::fs::write(&path, data).is_err() {
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        std::fs::write(&path, data).expect("a temporary file");
    }
    if let Err(e) = surfel::scene::load(&path) {
        let message = e.to_string();
        assert!(
            message.starts_with(&path.display().to_string()),
            "an error that does not name the file: {message}"
        );
    }
}
