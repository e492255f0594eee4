//! Compiles every shader under `glsl/` to SPIR-V with shaderc and embeds it, and generates
//! from `src/layout/spec/` (the one source of bindings and layouts) the shared GLSL header
//! and the Rust constants and `#[repr(C)]` structs of `crate::layout`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[path = "src/layout/spec/mod.rs"]
mod spec;

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
    println!("cargo:rerun-if-changed=src/layout/spec");
    println!("cargo:rustc-env=SURFEL_COMMIT={}", commit());
    let constants: Vec<_> = spec::constants().collect();
    if let Some((a, b)) = spec::overlapping(&constants) {
        panic!("src/layout/spec: bindings {a} and {b} share a number");
    }
    println!("cargo:rerun-if-changed=glsl");

    let header = shared_header();
    std::fs::write(out.join("shared.glsl"), &header).expect("write shared.glsl");
    std::fs::write(out.join("layout.rs"), rust_layout()).expect("write layout.rs");

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

/// The commit the build comes from, for timing studies' metadata (`unknown` outside a git
/// checkout). The build reruns when HEAD or the branch it names moves; uncommitted changes
/// are not tracked (that would rebuild on every edit of the index).
fn commit() -> String {
    let head = std::fs::read_to_string(".git/HEAD").unwrap_or_default();
    let mut watched = vec![".git/HEAD".to_string(), ".git/packed-refs".to_string()];
    if let Some(branch) = head.trim().strip_prefix("ref: ") {
        watched.push(format!(".git/{branch}"));
    }
    for path in watched.iter().filter(|p| Path::new(p).exists()) {
        println!("cargo:rerun-if-changed={path}");
    }
    std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into())
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
    let mut s = String::from("// Generated by build.rs from src/layout/spec. Do not edit.\n");
    s.push_str("#ifndef SURFEL_SHARED_GLSL\n#define SURFEL_SHARED_GLSL\n");
    for family in spec::FAMILIES {
        writeln!(s, "// {} (src/layout/spec/{0}.rs)", family.name).expect("fmt");
        for (name, value) in family.constants {
            writeln!(s, "#define {name} {value}").expect("fmt");
        }
    }
    for st in spec::structs() {
        writeln!(s, "struct {} {{", st.name).expect("fmt");
        for field in st.fields {
            writeln!(s, "    {} {};", field.ty, field.name).expect("fmt");
        }
        s.push_str("};\n");
    }
    s.push_str("#endif\n");
    s
}

/// The Rust type of a GLSL type the spec allows.
fn rust_type(ty: &str) -> &'static str {
    match ty {
        "float" => "f32",
        "uint" => "u32",
        "int" => "i32",
        "vec2" => "[f32; 2]",
        "uvec2" => "[u32; 2]",
        "vec4" => "Vec4",
        "uvec4" => "[u32; 4]",
        "mat4" => "Mat4",
        other => panic!("src/layout/spec: type {other} is not std430-safe"),
    }
}

/// The constants, the `#[repr(C)]` structs (std430 and `#[repr(C)]` agree on the types the
/// spec allows) and, for the layout test, every struct's field offsets.
fn rust_layout() -> String {
    let mut s = String::from("// Generated by build.rs from src/layout/spec. Do not edit.\n");
    for (name, value) in spec::constants() {
        writeln!(s, "pub const {name}: u32 = {value};").expect("fmt");
    }
    for st in spec::structs() {
        let integral = st
            .fields
            .iter()
            .all(|f| matches!(f.ty, "uint" | "int" | "uvec2" | "uvec4"));
        let eq = if integral { ", Eq" } else { "" };
        writeln!(s, "#[doc = {:?}]", st.doc).expect("fmt");
        s.push_str("#[repr(C)]\n");
        writeln!(
            s,
            "#[derive(Clone, Copy, Debug, Default, PartialEq{eq}, Pod, Zeroable)]"
        )
        .expect("fmt");
        writeln!(s, "pub struct {} {{", st.name).expect("fmt");
        for f in st.fields {
            writeln!(s, "    pub {}: {},", f.name, rust_type(f.ty)).expect("fmt");
        }
        s.push_str("}\n");
    }
    s.push_str("/// Every generated struct's fields with their offsets, and its size.\n");
    s.push_str("#[cfg(test)]\npub fn mirrors() -> Vec<Mirror> {\n    vec![\n");
    for st in spec::structs() {
        let fields: Vec<String> = st
            .fields
            .iter()
            .map(|f| {
                format!(
                    "({:?}, std::mem::offset_of!({}, {}))",
                    f.name, st.name, f.name
                )
            })
            .collect();
        writeln!(
            s,
            "        ({:?}, vec![{}], std::mem::size_of::<{}>()),",
            st.name,
            fields.join(", "),
            st.name
        )
        .expect("fmt");
    }
    s.push_str("    ]\n}\n");
    s
}
