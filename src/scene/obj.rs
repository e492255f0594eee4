//! Wavefront OBJ reader, built on the `obj` crate.
//!
//! Positions (`v`) and faces (`f`, any polygon size, fan-triangulated) are read; when faces
//! reference normals (`v//vn`, `v/vt/vn`), each position gets the normalized average of the
//! normals it is used with. Positions that faces use without a normal get the area-weighted
//! average of their faces' normals; positions no face uses get +Z. Material libraries
//! (`mtllib`) are not opened, so a missing `.mtl` is not an error. Unknown commands are ignored.
//! A file without vertices (empty, or only comments) is a mesh of 0 points, as PDAL and trimesh
//! read it.
//!
//! **Truncation.** A face with fewer than 3 corners (what a file cut inside its last face
//! leaves) is an error naming its line. A file whose last line is a record (`v`, `vn`, `vt`,
//! `f`) without a line end loads with a warning (`stats.warnings`) that it may be cut short:
//! a number cut after one of its digits still reads as a number.
//!
//! [`load_polygons`] keeps the polygons as they are (not triangulated), each with the diffuse
//! colour (`Kd`) of its material, for the line conversion (`lines`); a file without vertices
//! is an error there.

use std::path::Path;

use glam::Vec3;

use super::cloud::{Cloud, LoadStats};
use super::error::{show, LoadError};
use super::guard;
use super::pack::srgb_byte;

/// OBJ text with its continued lines (a line ending in `\\` goes on in the next, as the format
/// allows) joined, which the `obj` crate does not do, and the file's line number of each
/// joined line.
struct Joined<'a> {
    text: std::borrow::Cow<'a, [u8]>,
    /// The 1-based file line each joined line starts on; empty when nothing was joined.
    lines: Vec<usize>,
    /// Whether the file's last line has no line end.
    unterminated: bool,
}

impl<'a> Joined<'a> {
    fn new(data: &'a [u8]) -> Self {
        let unterminated = !data.is_empty() && !data.ends_with(b"\n");
        let continued = |line: &[u8]| line.strip_suffix(b"\r").unwrap_or(line).ends_with(b"\\");
        if !data.split(|&b| b == b'\n').any(continued) {
            return Joined {
                text: data.into(),
                lines: Vec::new(),
                unterminated,
            };
        }
        let mut text = Vec::with_capacity(data.len());
        let mut lines = vec![1];
        for (n, line) in data.split(|&b| b == b'\n').enumerate() {
            let body = line.strip_suffix(b"\r").unwrap_or(line);
            match body.strip_suffix(b"\\") {
                Some(head) => {
                    text.extend_from_slice(head);
                    text.push(b' ');
                }
                None => {
                    text.extend_from_slice(line);
                    text.push(b'\n');
                    lines.push(n + 2);
                }
            }
        }
        Joined {
            text: text.into(),
            lines,
            unterminated,
        }
    }

    /// The file's 1-based line number of 0-based joined line `index`.
    fn line(&self, index: usize) -> usize {
        self.lines.get(index).copied().unwrap_or(index + 1)
    }

    /// The text parsed by the `obj` crate, with the faces' corner counts checked (see the
    /// module docs on truncation).
    fn parse(&self, file: &str) -> Result<obj::ObjData, LoadError> {
        let parsed = guard::third_party(|| {
            obj::ObjData::load_buf_with_config(&self.text[..], obj::LoadConfig { strict: false })
        })
        .map_err(|e| LoadError::whole(file, e))?
        .map_err(|e| map_error(file, self, e))?;
        for (index, line) in self.text.split(|&b| b == b'\n').enumerate() {
            let mut words = line
                .split(u8::is_ascii_whitespace)
                .filter(|w| !w.is_empty());
            if words.next() == Some(b"f") {
                let corners = words.count();
                if corners < 3 {
                    return Err(LoadError::at_line(
                        file,
                        self.line(index),
                        format!(
                            "a face with {corners} corners; expected at least 3 (is the file cut short?)"
                        ),
                    ));
                }
            }
        }
        Ok(parsed)
    }

    /// The warning for text whose last line is a record without a line end, if it is one.
    fn cut_short(&self, file: &str) -> Option<String> {
        if !self.unterminated {
            return None;
        }
        let text = self.text.strip_suffix(b"\n").unwrap_or(&self.text);
        let index = text.iter().filter(|&&b| b == b'\n').count();
        let last = text.split(|&b| b == b'\n').next_back()?;
        let command = last
            .split(u8::is_ascii_whitespace)
            .find(|w| !w.is_empty())?;
        [&b"v"[..], b"vn", b"vt", b"f"].contains(&command).then(|| {
            format!(
                "{file}: line {}: the file ends inside a \"{}\" record, without a line end; it may be cut short",
                self.line(index),
                show(command)
            )
        })
    }
}

fn map_error(file: &str, joined: &Joined, err: obj::ObjError) -> LoadError {
    use obj::ObjError as E;
    // The crate counts lines from 0.
    match err {
        E::Io(e) => LoadError::whole(file, format!("cannot read the OBJ text: {e}")),
        E::MalformedFaceGroup { line_number, group } => LoadError::at_line(
            file,
            joined.line(line_number),
            format!(
                "expected a face vertex like 3, 3/1, 3//2 or 3/1/2, found \"{}\"",
                show(group)
            ),
        ),
        E::ArgumentListFailure { line_number, list } => LoadError::at_line(
            file,
            joined.line(line_number),
            format!("expected numbers, found {}", show(list)),
        ),
        E::UnexpectedCommand {
            line_number,
            command,
        } => LoadError::at_line(
            file,
            joined.line(line_number),
            format!("expected an OBJ command, found \"{}\"", show(command)),
        ),
        E::MissingMTLName { line_number } => LoadError::at_line(
            file,
            joined.line(line_number),
            "expected a file name after mtllib",
        ),
        E::ZeroVertexNumber { line_number } => LoadError::at_line(
            file,
            joined.line(line_number),
            "expected a 1-based or negative vertex index, found 0",
        ),
    }
}

/// The kind of index in a face corner (`v/vt/vn`) that was out of range.
#[derive(Clone, Copy)]
enum FaceIndex {
    Vertex,
    Normal,
}

impl FaceIndex {
    /// The corner field holding the index, and the command that defines what it indexes.
    fn field_and_command(self) -> (usize, &'static [u8]) {
        match self {
            FaceIndex::Vertex => (0, b"v"),
            FaceIndex::Normal => (2, b"vn"),
        }
    }

    fn noun(self) -> &'static str {
        match self {
            FaceIndex::Vertex => "vertices",
            FaceIndex::Normal => "normals",
        }
    }
}

/// The error for the first `kind` index in `data` that is out of range for a file with `count`
/// of them. The `obj` crate resolves indices without keeping lines or values, so the text is
/// scanned again for the line (indices are 1-based, negative ones count back from the last
/// definition so far); `face_index` is named when the scan finds nothing.
fn out_of_range(
    file: &str,
    joined: &Joined,
    kind: FaceIndex,
    count: usize,
    face_index: usize,
) -> LoadError {
    let (field, command) = kind.field_and_command();
    let mut defined = 0i64;
    for (line, text) in joined.text.split(|&b| b == b'\n').enumerate() {
        let mut words = text
            .split(u8::is_ascii_whitespace)
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(c) if c == command => defined += 1,
            Some(b"f") => {
                for corner in words {
                    let Some(index) = corner
                        .split(|&b| b == b'/')
                        .nth(field)
                        .and_then(|v| std::str::from_utf8(v).ok()?.parse::<i64>().ok())
                    else {
                        continue;
                    };
                    let resolved = if index < 0 {
                        defined + index
                    } else {
                        index - 1
                    };
                    if resolved < 0 || resolved >= count as i64 {
                        let what = match kind {
                            FaceIndex::Vertex => "face index",
                            FaceIndex::Normal => "face normal index",
                        };
                        return LoadError::at_line(
                            file,
                            joined.line(line),
                            format!(
                                "{what} {index} is out of range (the file has {count} {})",
                                kind.noun()
                            ),
                        );
                    }
                }
            }
            _ => {}
        }
    }
    LoadError::whole(
        file,
        format!(
            "face {face_index}: an index is out of range (the file has {count} {})",
            kind.noun()
        ),
    )
}

/// Parses OBJ text held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: &[u8]) -> Result<Cloud, LoadError> {
    let data = &Joined::new(data);
    let parsed = data.parse(file)?;
    let n = parsed.position.len();
    if n > u32::MAX as usize {
        return Err(LoadError::whole(
            file,
            format!("{n} vertices exceed the 2^32 limit"),
        ));
    }
    let positions: Vec<Vec3> = parsed.position.iter().map(|p| Vec3::from(*p)).collect();
    let mut faces = Vec::new();
    let mut normal_sum = vec![Vec3::ZERO; n];
    let mut has_vn = vec![false; n];
    let mut any_vn = false;
    let mut face_index = 0usize;
    for group in parsed.objects.iter().flat_map(|o| &o.groups) {
        for poly in &group.polys {
            let mut corners = Vec::with_capacity(poly.0.len());
            for tuple in &poly.0 {
                let p = tuple.0;
                if p >= n {
                    return Err(out_of_range(file, data, FaceIndex::Vertex, n, face_index));
                }
                if let Some(vn) = tuple.2 {
                    let normal = parsed.normal.get(vn).ok_or_else(|| {
                        out_of_range(
                            file,
                            data,
                            FaceIndex::Normal,
                            parsed.normal.len(),
                            face_index,
                        )
                    })?;
                    let normal = Vec3::from(*normal).normalize_or_zero();
                    normal_sum[p] += normal;
                    has_vn[p] = true;
                    any_vn = true;
                }
                corners.push(p as u32);
            }
            for k in 2..corners.len() {
                faces.push([corners[0], corners[k - 1], corners[k]]);
            }
            face_index += 1;
        }
    }
    let normals = any_vn.then(|| {
        let mut face_sum = vec![Vec3::ZERO; n];
        for f in &faces {
            let [a, b, c] = f.map(|i| positions[i as usize]);
            let area_normal = (b - a).cross(c - a);
            for &i in f {
                face_sum[i as usize] += area_normal;
            }
        }
        (0..n)
            .map(|i| {
                let from_vn = if has_vn[i] {
                    normal_sum[i].normalize_or_zero()
                } else {
                    Vec3::ZERO
                };
                if from_vn != Vec3::ZERO {
                    from_vn
                } else {
                    let from_faces = face_sum[i].normalize_or_zero();
                    if from_faces == Vec3::ZERO {
                        Vec3::Z
                    } else {
                        from_faces
                    }
                }
            })
            .collect()
    });
    let mut cloud = Cloud {
        positions,
        normals,
        faces: Some(faces),
        stats: LoadStats {
            records: n,
            warnings: data.cut_short(file).into_iter().collect(),
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    cloud.retain_finite();
    Ok(cloud)
}

/// Loads an OBJ file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), &data)
}

/// An OBJ mesh with its polygons as the file has them (not triangulated).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolygonMesh {
    pub positions: Vec<Vec3>,
    /// Indices into `positions`, in the file's corner order.
    pub polygons: Vec<Vec<u32>>,
    /// One RGBA8 (sRGB) colour per polygon: its material's `Kd`, or [`NO_MATERIAL_COLOR`] when
    /// the polygon has no material or its `.mtl` has none by that name (or no `Kd`).
    pub colors: Vec<[u8; 4]>,
    /// Polygons that got [`NO_MATERIAL_COLOR`].
    pub uncolored: usize,
}

/// The colour of a polygon without a known material: light grey.
pub const NO_MATERIAL_COLOR: [u8; 4] = [200, 200, 200, 255];

/// Parses OBJ text held in memory into polygons; `material` gives the linear `Kd` of a material
/// name (`usemtl`), if known. `file` names the text in error messages. A polygon with fewer
/// than 3 corners, an index out of range or a corner at a non-finite position is an error.
pub fn parse_polygons(
    file: &str,
    data: &[u8],
    material: &dyn Fn(&str) -> Option<[f32; 3]>,
) -> Result<PolygonMesh, LoadError> {
    let data = &Joined::new(data);
    let parsed = data.parse(file)?;
    polygons_of(file, data, &parsed, material)
}

fn polygons_of(
    file: &str,
    data: &Joined,
    parsed: &obj::ObjData,
    material: &dyn Fn(&str) -> Option<[f32; 3]>,
) -> Result<PolygonMesh, LoadError> {
    let n = parsed.position.len();
    if n == 0 {
        return Err(LoadError::whole(
            file,
            "no vertices; expected \"v x y z\" lines",
        ));
    }
    if n > u32::MAX as usize {
        return Err(LoadError::whole(
            file,
            format!("{n} vertices exceed the 2^32 limit"),
        ));
    }
    let positions: Vec<Vec3> = parsed.position.iter().map(|p| Vec3::from(*p)).collect();
    let mut mesh = PolygonMesh {
        positions,
        ..PolygonMesh::default()
    };
    for group in parsed.objects.iter().flat_map(|o| &o.groups) {
        let kd = group.material.as_ref().and_then(|m| match m {
            obj::ObjMaterial::Ref(name) => material(name),
            obj::ObjMaterial::Mtl(m) => m.kd.or_else(|| material(&m.name)),
        });
        let color = kd.map_or(NO_MATERIAL_COLOR, |[r, g, b]| {
            [srgb_byte(r), srgb_byte(g), srgb_byte(b), 255]
        });
        for poly in &group.polys {
            let face_index = mesh.polygons.len();
            let mut corners = Vec::with_capacity(poly.0.len());
            for tuple in &poly.0 {
                let p = tuple.0;
                if p >= n {
                    return Err(out_of_range(file, data, FaceIndex::Vertex, n, face_index));
                }
                if !mesh.positions[p].is_finite() {
                    return Err(LoadError::whole(
                        file,
                        format!(
                            "face {face_index} uses vertex {} whose position is not finite",
                            p + 1
                        ),
                    ));
                }
                corners.push(p as u32);
            }
            mesh.polygons.push(corners);
            mesh.colors.push(color);
            if kd.is_none() {
                mesh.uncolored += 1;
            }
        }
    }
    Ok(mesh)
}

/// Loads an OBJ file as polygons with material colours. The `mtllib` files are read from the
/// OBJ's folder; a missing or unreadable `.mtl` is not an error (its polygons count as
/// `uncolored`).
pub fn load_polygons(path: &Path) -> Result<PolygonMesh, LoadError> {
    let data = super::read_file(path)?;
    let file = path.display().to_string();
    let joined = Joined::new(&data);
    let parsed = joined.parse(&file)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut kd = std::collections::HashMap::new();
    for lib in &parsed.material_libs {
        let mut lib = obj::Mtl::new(lib.filename.clone());
        let Ok(text) = std::fs::read(dir.join(&lib.filename)) else {
            continue;
        };
        if lib.reload(&text[..]).is_err() {
            continue;
        }
        for m in &lib.materials {
            if let Some(c) = m.kd {
                kd.entry(m.name.clone()).or_insert(c);
            }
        }
    }
    polygons_of(&file, &joined, &parsed, &|name| kd.get(name).copied())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_and_shared_normals() {
        let text = b"mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nvn 0 1 0\nusemtl leaf\nf 1//1 2//1 3//1 4//1\nf 1//2 2//2 3//2\n";
        let c = parse("m.obj", text).unwrap();
        assert_eq!(c.faces.as_ref().unwrap().len(), 3);
        let normals = c.normals.unwrap();
        let expected = Vec3::new(0.0, 1.0, 1.0).normalize();
        assert!((normals[0] - expected).length() < 1e-6);
        assert!((normals[3] - Vec3::Z).length() < 1e-6);
        assert_eq!(normals[4], Vec3::Z);
    }

    #[test]
    fn bad_number_names_line() {
        let err = parse("bad.obj", b"v 0 0 0\nv 1 x 0\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("bad.obj: line 2: expected numbers"),
            "{err}"
        );
    }

    #[test]
    fn polygons_keep_their_corners_and_material_colors() {
        let text =
            b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl leaf\nf 1 2 3 4\nusemtl none\nf 1 2 3\n";
        let kd = |name: &str| (name == "leaf").then_some([1.0, 0.0, 0.2]);
        let m = parse_polygons("m.obj", text, &kd).unwrap();
        assert_eq!(m.polygons, vec![vec![0, 1, 2, 3], vec![0, 1, 2]]);
        assert_eq!(m.colors[0], [255, 0, 124, 255]);
        assert_eq!(m.colors[1], NO_MATERIAL_COLOR);
        assert_eq!(m.uncolored, 1);
        let err = parse_polygons("m.obj", b"v 0 0 0\nf 1 2 3\n", &kd)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("m.obj: line 2: face index 2 is out of range"),
            "{err}"
        );
    }

    #[test]
    fn files_without_vertices_are_empty_meshes() {
        for text in [&b""[..], b"# exported\n", b"mtllib a.mtl\no empty\n"] {
            let c = parse("e.obj", text).unwrap();
            assert_eq!((c.len(), c.stats.records), (0, 0));
            assert_eq!(c.faces.as_deref(), Some(&[][..]));
        }
        let err = parse_polygons("e.obj", b"", &|_| None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "e.obj: no vertices; expected \"v x y z\" lines"
        );
    }

    #[test]
    fn truncated_files_are_errors_or_warnings() {
        let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
        for (cut, corners) in [("f 1 2", 2), ("f 4", 1), ("f", 0)] {
            let text = format!("{quad}f 1 2 3\n{cut}");
            let err = parse("t.obj", text.as_bytes()).unwrap_err().to_string();
            assert_eq!(
                err,
                format!("t.obj: line 6: a face with {corners} corners; expected at least 3 (is the file cut short?)")
            );
        }
        let c = parse("t.obj", format!("{quad}f 1 2 3\nf 1 3 4").as_bytes()).unwrap();
        assert_eq!(c.faces.as_ref().map(Vec::len), Some(2));
        assert_eq!(
            c.stats.warnings,
            ["t.obj: line 6: the file ends inside a \"f\" record, without a line end; it may be cut short"]
        );
        let c = parse("t.obj", b"v 0 0 0\nv 1 0 0\\\n\nv 0 1 0.2").unwrap();
        assert_eq!(
            c.stats.warnings,
            ["t.obj: line 4: the file ends inside a \"v\" record, without a line end; it may be cut short"]
        );
        for whole in [format!("{quad}f 1 2 3 4\n"), format!("{quad}# end")] {
            let c = parse("w.obj", whole.as_bytes()).unwrap();
            assert!(c.stats.warnings.is_empty(), "{whole}");
        }
    }
}
