//! Imports point down: a module of `src/` uses only modules of its own layer or of lower ones
//! (the list opening `docs/architecture.md`), and the modules of one layer import each other
//! without a cycle. Every top-level module has a layer here, so a new one fails until it is
//! placed.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Lowest first: the GPU and the graph, the CPU data, what runs on the GPU, the front ends.
const LAYERS: &[&[&str]] = &[
    &[
        "gpu", "graph", "layout", "frame", "rng", "suggest", "source",
    ],
    &["scene", "point_streams", "copc", "lod", "hpr", "color"],
    &[
        "gpu_scene",
        "methods",
        "knn_gpu",
        "post",
        "overlay",
        "render",
    ],
    &["cli", "viewer", "eval"],
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

/// Per top-level module of `src/`, the top-level modules it imports and the files that do.
fn module_imports() -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let mut out: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
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
        let text = std::fs::read_to_string(path).expect("read");
        let entry = out.entry(top.clone()).or_default();
        for target in imports(&text) {
            if target != "self" && target != "super" && target != top {
                entry
                    .entry(target)
                    .or_default()
                    .insert(format!("src/{}", rel.display()));
            }
        }
    }
    out
}

#[test]
fn imports_point_down() {
    let mut problems = Vec::new();
    for (top, targets) in module_imports() {
        let Some(own) = layer(&top) else {
            problems.push(format!("module '{top}' has no layer"));
            continue;
        };
        for (target, files) in targets {
            let files: Vec<_> = files.into_iter().collect();
            match layer(&target) {
                Some(l) if l <= own => {}
                Some(l) => problems.push(format!(
                    "{} (layer {own}, {top}) import crate::{target} (layer {l})",
                    files.join(", ")
                )),
                None => problems.push(format!(
                    "{} import crate::{target}, which has no layer",
                    files.join(", ")
                )),
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// A cycle among `edges` (module → modules it imports), as the modules along it.
fn cycle(edges: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        at: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|m| m == at) {
            let mut found = path[k..].to_vec();
            found.push(at.to_string());
            return Some(found);
        }
        if done.contains(at) {
            return None;
        }
        path.push(at.to_string());
        for next in edges.get(at).into_iter().flatten() {
            if let Some(found) = visit(next, edges, path, done) {
                return Some(found);
            }
        }
        path.pop();
        done.insert(at.to_string());
        None
    }
    let mut done = BTreeSet::new();
    edges
        .keys()
        .find_map(|m| visit(m, edges, &mut Vec::new(), &mut done))
}

#[test]
fn no_layer_imports_itself_in_a_cycle() {
    let imports = module_imports();
    let mut problems = Vec::new();
    for (l, members) in LAYERS.iter().enumerate() {
        let edges: BTreeMap<String, BTreeSet<String>> = members
            .iter()
            .map(|m| {
                let targets = imports
                    .get(*m)
                    .into_iter()
                    .flat_map(|t| t.keys())
                    .filter(|t| members.contains(&t.as_str()))
                    .cloned()
                    .collect();
                (m.to_string(), targets)
            })
            .collect();
        if let Some(found) = cycle(&edges) {
            let steps: Vec<String> = found
                .windows(2)
                .map(|w| {
                    let files: Vec<_> = imports[&w[0]][&w[1]].iter().cloned().collect();
                    format!("{} -> {} ({})", w[0], w[1], files.join(", "))
                })
                .collect();
            problems.push(format!("layer {l}: {}", steps.join("; ")));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_cycle_search_finds_a_cycle_and_only_a_cycle() {
    let edges = |pairs: &[(&str, &str)]| {
        let mut e: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in pairs {
            e.entry(a.to_string()).or_default().insert(b.to_string());
            e.entry(b.to_string()).or_default();
        }
        e
    };
    assert_eq!(cycle(&edges(&[("a", "b"), ("b", "c"), ("a", "c")])), None);
    assert_eq!(
        cycle(&edges(&[("a", "b"), ("b", "c"), ("c", "a")])),
        Some(vec!["a".into(), "b".into(), "c".into(), "a".into()])
    );
}

#[test]
fn the_import_scan_sees_paths_groups_and_skips_comments() {
    let text = "use crate::{gpu::{Buffer, Context}, scene};\n\
                // crate::eval in a comment\n\
                let s = \"crate::viewer\";\n\
                let x = crate::methods::find(\"a\");\n";
    let found: Vec<_> = imports(text).into_iter().collect();
    assert_eq!(found, ["gpu", "methods", "scene"]);
}
