//! The line model's file format ([`save`], [`load`]): an ASCII PLY file that other PLY readers
//! load as a mesh (they skip the `polyline` element):
//!
//! ```text
//! ply
//! format ascii 1.0
//! comment surfel line model
//! element vertex N           x y z dx dy dz radius (float), red green blue alpha (uchar)
//! element polyline P         kind (uchar: 0 ribbon, 1 tube), count (uint)
//! element face F             vertex_indices (list uchar uint), always 3 indices
//! end_header
//! ```
//!
//! Polylines take the first vertices in order (polyline `i` starts where `i - 1` ends), each
//! at least 2, all of one colour; `d` is the ribbon normal or the tube tangent. The vertices
//! after the polylines are the kept triangles' (`d` their normal, radius 0), and faces index
//! only those. The reader accepts exactly this header (counts aside), checks the counts
//! against the file's size before allocating, and names the line and what it expected.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use super::{LineKind, LineModel, LineStats, LineVertex, Polyline};
use crate::scene::cloud::{Cloud, LoadStats};
use crate::scene::error::{show, LoadError};

/// The header line that marks a line model among PLY files.
pub const MAGIC_COMMENT: &str = "comment surfel line model";

impl LineKind {
    /// The code in the file's `kind` property.
    fn code(self) -> u8 {
        match self {
            LineKind::Ribbon => 0,
            LineKind::Tube => 1,
        }
    }
}

/// Writes a line model (see the module documentation for the format).
pub fn save(path: &Path, model: &LineModel) -> std::io::Result<()> {
    std::fs::write(path, to_text(model))
}

/// A line model as the text of its file.
pub fn to_text(model: &LineModel) -> String {
    let tri = &model.triangles;
    let line_vertices: usize = model.polylines.iter().map(|p| p.vertices.len()).sum();
    let faces = tri.faces.as_deref().unwrap_or(&[]);
    let mut s = String::new();
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment surfel line model\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float dx\nproperty float dy\nproperty float dz\nproperty float radius\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
         element polyline {}\nproperty uchar kind\nproperty uint count\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        line_vertices + tri.len(),
        model.polylines.len(),
        faces.len()
    );
    let mut vertex = |p: Vec3, d: Vec3, r: f32, c: [u8; 4]| {
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} {} {} {} {} {}",
            p.x, p.y, p.z, d.x, d.y, d.z, r, c[0], c[1], c[2], c[3]
        );
    };
    for p in &model.polylines {
        for v in &p.vertices {
            vertex(v.position, v.dir, v.radius, p.color);
        }
    }
    for i in 0..tri.len() {
        let n = tri.normals.as_ref().map_or(Vec3::Z, |n| n[i]);
        let c = tri.colors.as_ref().map_or([255; 4], |c| c[i]);
        vertex(tri.positions[i], n, 0.0, c);
    }
    for p in &model.polylines {
        let _ = writeln!(s, "{} {}", p.kind.code(), p.vertices.len());
    }
    for f in faces {
        let [a, b, c] = f.map(|i| i as usize + line_vertices);
        let _ = writeln!(s, "3 {a} {b} {c}");
    }
    s
}

/// The header this module writes, line by line, with `{}` where a count goes.
const HEADER: [&str; 21] = [
    "ply",
    "format ascii 1.0",
    MAGIC_COMMENT,
    "element vertex {}",
    "property float x",
    "property float y",
    "property float z",
    "property float dx",
    "property float dy",
    "property float dz",
    "property float radius",
    "property uchar red",
    "property uchar green",
    "property uchar blue",
    "property uchar alpha",
    "element polyline {}",
    "property uchar kind",
    "property uint count",
    "element face {}",
    "property list uchar uint vertex_indices",
    "end_header",
];

/// The fewest bytes a data line of each element takes: 11 numbers, 2 numbers, 4 numbers, each
/// at least one character and a separator.
const MIN_LINE_BYTES: [usize; 3] = [22, 4, 8];

/// Whether `path` starts like a line model (its third header line is [`MAGIC_COMMENT`]).
pub fn is_line_model(path: &Path) -> bool {
    let mut head = [0u8; 64];
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    let n = std::io::Read::read(&mut file, &mut head).unwrap_or(0);
    String::from_utf8_lossy(&head[..n])
        .lines()
        .nth(2)
        .is_some_and(|l| l.trim_end() == MAGIC_COMMENT)
}

/// Reads a line model written by [`save`].
pub fn load(path: &Path) -> Result<LineModel, LoadError> {
    let data = crate::scene::read_file(path)?;
    parse(&path.display().to_string(), &data)
}

/// Parses the text of a line model file; `file` names it in error messages.
pub fn parse(file: &str, data: &[u8]) -> Result<LineModel, LoadError> {
    let text = std::str::from_utf8(data).map_err(|e| {
        LoadError::at_byte(
            file,
            e.valid_up_to(),
            "expected ASCII text, found invalid UTF-8",
        )
    })?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end()));
    let mut counts = [0usize; 3];
    let mut which = 0;
    let mut header_bytes = 0;
    for expected in HEADER {
        let Some((n, line)) = lines.next() else {
            return Err(LoadError::whole(
                file,
                format!("the header ends early: expected \"{expected}\""),
            ));
        };
        header_bytes += line.len() + 1;
        let ok = match expected.strip_suffix("{}") {
            Some(prefix) => line
                .strip_prefix(prefix)
                .and_then(|c| c.parse().ok())
                .map(|c| {
                    counts[which] = c;
                    which += 1;
                }),
            None => (line == expected).then_some(()),
        };
        if ok.is_none() {
            return Err(LoadError::at_line(
                file,
                n,
                format!(
                    "expected \"{}\" (a surfel line model), found \"{}\"",
                    expected.replace("{}", "COUNT"),
                    show(line)
                ),
            ));
        }
    }
    let body = data.len().saturating_sub(header_bytes);
    let needed: usize = counts
        .iter()
        .zip(MIN_LINE_BYTES)
        .map(|(&c, b)| c.saturating_mul(b))
        .fold(0, usize::saturating_add);
    if needed > body {
        return Err(LoadError::whole(
            file,
            format!(
                "the header declares {} vertices, {} polylines and {} faces, which need at least {needed} bytes, but only {body} follow the header",
                counts[0], counts[1], counts[2]
            ),
        ));
    }
    let [vertex_count, polyline_count, face_count] = counts;
    let mut row = |expected: &str, len: usize| -> Result<(usize, Vec<&str>), LoadError> {
        let (n, line) = lines.next().ok_or_else(|| {
            LoadError::whole(file, format!("the file ends early: expected {expected}"))
        })?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        if words.len() != len {
            return Err(LoadError::at_line(
                file,
                n,
                format!(
                    "expected {expected} ({len} numbers), found \"{}\"",
                    show(line)
                ),
            ));
        }
        Ok((n, words))
    };
    fn number<T: std::str::FromStr>(
        file: &str,
        n: usize,
        word: &str,
        what: &str,
    ) -> Result<T, LoadError> {
        word.parse().map_err(|_| {
            LoadError::at_line(
                file,
                n,
                format!("expected {what}, found \"{}\"", show(word)),
            )
        })
    }
    let mut vertices = Vec::with_capacity(vertex_count);
    for _ in 0..vertex_count {
        let (n, w) = row("a vertex: x y z dx dy dz radius red green blue alpha", 11)?;
        let mut f = [0f32; 7];
        for (k, value) in f.iter_mut().enumerate() {
            *value = number(file, n, w[k], "a number")?;
            if !value.is_finite() {
                return Err(LoadError::at_line(
                    file,
                    n,
                    format!("expected a finite number, found \"{}\"", show(w[k])),
                ));
            }
        }
        let mut c = [0u8; 4];
        for (k, value) in c.iter_mut().enumerate() {
            *value = number(file, n, w[7 + k], "a colour component 0..255")?;
        }
        vertices.push((
            n,
            LineVertex {
                position: Vec3::new(f[0], f[1], f[2]),
                dir: Vec3::new(f[3], f[4], f[5]),
                radius: f[6],
            },
            c,
        ));
    }
    let mut polylines = Vec::with_capacity(polyline_count);
    let mut first = 0usize;
    for _ in 0..polyline_count {
        let (n, w) = row("a polyline: kind count", 2)?;
        let kind = match number::<u8>(file, n, w[0], "a kind (0 ribbon, 1 tube)")? {
            0 => LineKind::Ribbon,
            1 => LineKind::Tube,
            k => {
                return Err(LoadError::at_line(
                    file,
                    n,
                    format!("expected a kind (0 ribbon, 1 tube), found {k}"),
                ))
            }
        };
        let count: usize = number(file, n, w[1], "a vertex count")?;
        if count < 2 || count > vertex_count - first {
            return Err(LoadError::at_line(
                file,
                n,
                format!(
                    "expected a vertex count from 2 to the {} vertices left, found {count}",
                    vertex_count - first
                ),
            ));
        }
        let color = vertices[first].2;
        if let Some((m, _, _)) = vertices[first..first + count].iter().find(|v| v.2 != color) {
            return Err(LoadError::at_line(
                file,
                *m,
                "expected the colour of the polyline's first vertex",
            ));
        }
        polylines.push(Polyline {
            kind,
            vertices: vertices[first..first + count].iter().map(|v| v.1).collect(),
            color,
        });
        first += count;
    }
    let mut faces = Vec::with_capacity(face_count);
    for _ in 0..face_count {
        let (n, w) = row("a triangle: 3 a b c", 4)?;
        if w[0] != "3" {
            return Err(LoadError::at_line(
                file,
                n,
                format!("expected a triangle (3 indices), found {}", show(w[0])),
            ));
        }
        let mut f = [0u32; 3];
        for (k, value) in f.iter_mut().enumerate() {
            let i: usize = number(file, n, w[1 + k], "a vertex index")?;
            if i < first || i >= vertex_count {
                return Err(LoadError::at_line(
                    file,
                    n,
                    format!(
                        "expected a triangle vertex index from {first} to {}, found {i}",
                        vertex_count.saturating_sub(1)
                    ),
                ));
            }
            *value = (i - first) as u32;
        }
        faces.push(f);
    }
    if let Some((n, line)) = lines.find(|(_, l)| !l.trim().is_empty()) {
        return Err(LoadError::at_line(
            file,
            n,
            format!("expected the end of the file, found \"{}\"", show(line)),
        ));
    }
    let kept = &vertices[first..];
    let triangles = Cloud {
        positions: kept.iter().map(|v| v.1.position).collect(),
        normals: Some(kept.iter().map(|v| v.1.dir).collect()),
        colors: Some(kept.iter().map(|v| v.2).collect()),
        faces: Some(faces),
        stats: LoadStats {
            records: kept.len(),
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    let stats = LineStats::count(&polylines, &triangles);
    Ok(LineModel {
        polylines,
        triangles,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::lines::convert::tests::sample_model;

    #[test]
    fn a_line_model_survives_its_file() {
        let model = sample_model();
        assert_eq!(model.stats.components, 3);
        assert_eq!(
            (model.stats.ribbons.polylines, model.stats.tubes.polylines),
            (1, 1)
        );
        assert!(model.stats.triangles > 0);
        let text = to_text(&model);
        let back = parse("m.ply", text.as_bytes()).expect("parse");
        assert_eq!(back.polylines, model.polylines);
        assert_eq!(back.triangles.positions, model.triangles.positions);
        assert_eq!(back.triangles.normals, model.triangles.normals);
        assert_eq!(back.triangles.colors, model.triangles.colors);
        assert_eq!(back.triangles.faces, model.triangles.faces);
        let sizes = |s: &LineStats| (s.ribbons, s.tubes, s.triangles, s.triangle_vertices);
        assert_eq!(sizes(&back.stats), sizes(&model.stats));
        assert_eq!(to_text(&back), text);
    }

    #[test]
    fn malformed_files_name_the_line_and_what_was_expected() {
        let model = sample_model();
        let text = to_text(&model);
        let header_end = text.find("end_header\n").expect("header") + "end_header\n".len();
        let header_lines = text[..header_end].lines().count();
        let cases: Vec<(String, String)> = vec![
            (
                text.replacen("ply\n", "plx\n", 1),
                "m.ply: line 1: expected \"ply\"".into(),
            ),
            (
                text.replacen("element polyline 2", "element polyline many", 1),
                "m.ply: line 16: expected \"element polyline COUNT\"".into(),
            ),
            (
                text.replacen(
                    &format!("element face {}\n", model.stats.triangles),
                    "element face 9999999999\n",
                    1,
                ),
                "the header declares".into(),
            ),
            (
                text[..header_end + 10].to_string(),
                "the header declares".into(),
            ),
            (
                {
                    let mut lines: Vec<&str> = text.lines().collect();
                    lines[header_lines] = "0 0 0 0 0 1 x 1 2 3 255";
                    lines.join("\n")
                },
                format!(
                    "m.ply: line {}: expected a number, found \"x\"",
                    header_lines + 1
                ),
            ),
            (
                {
                    let mut lines: Vec<&str> = text.lines().collect();
                    let last = lines.len() - 1;
                    lines[last] = "3 0 1 2";
                    lines.join("\n")
                },
                "expected a triangle vertex index from".into(),
            ),
            (
                format!("{text}garbage\n"),
                "expected the end of the file, found \"garbage\"".into(),
            ),
        ];
        for (bad, expected) in cases {
            let err = parse("m.ply", bad.as_bytes())
                .expect_err(&expected)
                .to_string();
            assert!(err.contains(&expected), "{err} lacks {expected}");
        }
    }
}
