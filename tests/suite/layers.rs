//! Imports point down: a module of `src/` uses only modules of its own layer or of lower ones
//! (the list opening `docs/architecture.md`). Every top-level module has a layer here, so a new
//! one fails until it is placed.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Lowest first: the GPU and the graph, the CPU data, what runs on the GPU, the front ends.
const LAYERS: &[&[&str]] = &[
    &["gpu", "graph", "frame", "rng", "suggest"],
    &["scene", "streams", "stream", "lines", "lod", "hpr", "color"],
    &["upload", "methods", "estimate", "post", "overlay", "render"],
    &["cli", "app", "eval"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read src") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of `text` without comments and string literals (an import is never inside them).
fn code(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '/' if chars.peek() == Some(&'/') => {
                for c in chars.by_ref() {
                    if c == '\n' {
                        out.push('\n');
                        break;
                    }
                }
            }
            '"' => {
                let mut escaped = false;
                for c in chars.by_ref() {
                    if escaped {
                        escaped = false;
                    } else if c == '\\' {
                        escaped = true;
                    } else if c == '"' {
                        break;
                    }
                }
                out.push_str("\"\"");
            }
            _ => out.push(c),
        }
    }
    out
}

/// The top-level modules `text` names through `crate::` (paths and `use crate::{a, b}` groups).
fn imports(text: &str) -> BTreeSet<String> {
    let text = code(text);
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut found = BTreeSet::new();
    for (at, _) in text.match_indices("crate::") {
        let rest = text[at + "crate::".len()..].trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            // Only the group's top level: `crate::{a::{x, y}, b}` names a and b.
            let mut depth = 0;
            let mut start = true;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && !c.is_whitespace() => {
                        found.insert(ident(&group[i..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            found.insert(ident(rest));
        }
    }
    found.remove("");
    found
}

#[test]
fn imports_point_down() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let mut problems = Vec::new();
    for path in &all {
        let rel = path.strip_prefix(&src).expect("under src");
        let top = rel
            .components()
            .next()
            .and_then(|c| c.as_os_str().to_str())
            .expect("name")
            .trim_end_matches(".rs")
            .to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let Some(own) = layer(&top) else {
            problems.push(format!(
                "src/{}: module '{top}' has no layer",
                rel.display()
            ));
            continue;
        };
        let text = std::fs::read_to_string(path).expect("read");
        for target in imports(&text) {
            if target == "self" || target == "super" {
                continue;
            }
            match layer(&target) {
                Some(l) if l <= own => {}
                Some(l) => problems.push(format!(
                    "src/{} (layer {own}, {top}) imports crate::{target} (layer {l})",
                    rel.display()
                )),
                None => problems.push(format!(
                    "src/{} imports crate::{target}, which has no layer",
                    rel.display()
                )),
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_import_scan_sees_paths_groups_and_skips_comments() {
    let text = "use crate::{gpu::{Buffer, Context}, scene};\n\
                // crate::eval in a comment\n\
                let s = \"crate::app\";\n\
                let x = crate::methods::find(\"a\");\n";
    let found: Vec<_> = imports(text).into_iter().collect();
    assert_eq!(found, ["gpu", "methods", "scene"]);
}
