#![no_main]

use std::path::Path;

// Scene files as TOML and as JSON.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for name in ["scene.toml", "scene.json"] {
        let _ = surfel::scene::scene_file::SceneFile::parse(text, Path::new(name));
    }
});
