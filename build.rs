//! Compiles every shader under `glsl/` to SPIR-V with shaderc and embeds it, and generates the
//! shared GLSL header from `src/gpu/layout_spec.rs` (the one source of bindings and layouts).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod spec {
    include!("src/gpu/layout_spec.rs");
}

const STAGES: &[(&str, shaderc::ShaderKind)] = &[
    ("vert", shaderc::ShaderKind::Vertex),
    ("frag", shaderc::ShaderKind::Fragment),
    ("geom", shaderc::ShaderKind::Geometry),
    ("comp", shaderc::ShaderKind::Compute),
    ("task", shaderc::ShaderKind::Task),
    ("mesh", shaderc::ShaderKind::Mesh),
];

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let root = Path::new("glsl");
    println!("cargo:rerun-if-changed=src/gpu/layout_spec.rs");
    println!("cargo:rerun-if-changed=glsl");

    let header = shared_header();
    std::fs::write(out.join("shared.glsl"), &header).expect("write shared.glsl");
    std::fs::write(out.join("constants.rs"), rust_constants()).expect("write constants.rs");

    let mut files = Vec::new();
    collect(root, &mut files);
    files.sort();

    let compiler = shaderc::Compiler::new().expect("shaderc compiler");
    let mut index =
        String::from("/// Every shader under `glsl/`, by path relative to it, as SPIR-V bytes.\n");
    index.push_str("pub static SHADERS: &[(&str, &[u8])] = &[\n");
    let mut errors = Vec::new();
    for path in &files {
        println!("cargo:rerun-if-changed={}", path.display());
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let Some(&(_, kind)) = STAGES.iter().find(|(e, _)| *e == ext) else {
            continue;
        };
        let rel = path.strip_prefix(root).expect("under glsl/");
        let rel_name = rel.to_string_lossy().replace('\\', "/");
        let source = std::fs::read_to_string(path).expect("read shader");
        let mut options = shaderc::CompileOptions::new().expect("shaderc options");
        options.set_target_env(
            shaderc::TargetEnv::Vulkan,
            shaderc::EnvVersion::Vulkan1_2 as u32,
        );
        options.set_target_spirv(shaderc::SpirvVersion::V1_5);
        options.set_optimization_level(shaderc::OptimizationLevel::Performance);
        options.set_generate_debug_info();
        let header = header.clone();
        options.set_include_callback(move |name, _ty, includer, _depth| {
            resolve_include(&header, name, includer)
        });
        match compiler.compile_into_spirv(
            &source,
            kind,
            &path.to_string_lossy(),
            "main",
            Some(&options),
        ) {
            Ok(artifact) => {
                let spv = out.join(format!("{rel_name}.spv"));
                std::fs::create_dir_all(spv.parent().expect("has parent")).expect("mkdir");
                std::fs::write(&spv, artifact.as_binary_u8()).expect("write spv");
                writeln!(
                    index,
                    "    ({rel_name:?}, include_bytes!(concat!(env!(\"OUT_DIR\"), \"/{rel_name}.spv\"))),"
                )
                .expect("write index");
            }
            Err(e) => errors.push(e.to_string()),
        }
    }
    index.push_str("];\n");
    if !errors.is_empty() {
        // shaderc reports `file:line: error: message`; print each so cargo shows them all.
        for e in &errors {
            for line in e.lines() {
                println!("cargo:warning={line}");
            }
            eprintln!("{e}");
        }
        std::process::exit(1);
    }
    std::fs::write(out.join("shaders.rs"), index).expect("write shaders.rs");
}

fn collect(dir: &Path, files: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir).expect("read glsl dir");
    for entry in entries {
        let path = entry.expect("dir entry").path();
        if path.is_dir() {
            collect(&path, files);
        } else {
            // Headers too: every source and include triggers a rebuild.
            println!("cargo:rerun-if-changed={}", path.display());
            files.push(path);
        }
    }
}

/// Resolves `#include "x"` relative to the including file, then to `glsl/common/`; the
/// generated `shared.glsl` is served from memory.
fn resolve_include(
    header: &str,
    name: &str,
    includer: &str,
) -> Result<shaderc::ResolvedInclude, String> {
    if name == "shared.glsl" {
        return Ok(shaderc::ResolvedInclude {
            resolved_name: "shared.glsl".into(),
            content: header.to_string(),
        });
    }
    let beside = Path::new(includer)
        .parent()
        .unwrap_or(Path::new(""))
        .join(name);
    let common = Path::new("glsl/common").join(name);
    for candidate in [beside, common] {
        if let Ok(content) = std::fs::read_to_string(&candidate) {
            return Ok(shaderc::ResolvedInclude {
                resolved_name: candidate.to_string_lossy().into_owned(),
                content,
            });
        }
    }
    Err(format!("{includer}: cannot find include \"{name}\""))
}

fn shared_header() -> String {
    let mut s =
        String::from("// Generated by build.rs from src/gpu/layout_spec.rs. Do not edit.\n");
    s.push_str("#ifndef SURFEL_SHARED_GLSL\n#define SURFEL_SHARED_GLSL\n");
    for (name, value) in spec::CONSTANTS {
        writeln!(s, "#define {name} {value}").expect("fmt");
    }
    for st in spec::STRUCTS {
        writeln!(s, "struct {} {{", st.name).expect("fmt");
        for field in st.fields {
            writeln!(s, "    {} {};", field.ty, field.name).expect("fmt");
        }
        s.push_str("};\n");
    }
    s.push_str("#endif\n");
    s
}

fn rust_constants() -> String {
    let mut s = String::from("// Generated by build.rs from src/gpu/layout_spec.rs.\n");
    for (name, value) in spec::CONSTANTS {
        writeln!(s, "pub const {name}: u32 = {value};").expect("fmt");
    }
    s
}
