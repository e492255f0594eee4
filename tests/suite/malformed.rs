//! Malformed inputs fail with an error that names the file, the place and what was expected;
//! none of them panics or allocates according to an absurd header count.

use crate::common;

use std::path::PathBuf;
use std::time::Instant;

use surfel::scene::{self, Cloud, LoadError};

/// Writes `bytes` to a fresh temporary file called `name`.
fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-malformed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn load(name: &str, bytes: &[u8]) -> Result<Cloud, LoadError> {
    scene::load(&file(name, bytes))
}

/// Loads and returns the error message, asserting it starts with the file path.
fn error(name: &str, bytes: &[u8]) -> String {
    let path = file(name, bytes);
    let message = match scene::load(&path) {
        Ok(c) => panic!("{name} loaded {} points; expected an error", c.len()),
        Err(e) => e.to_string(),
    };
    assert!(
        message.starts_with(&format!("{}: ", path.display())),
        "{message}"
    );
    message
}

fn assert_contains(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(message.contains(part), "{message:?} lacks {part:?}");
    }
}

const PLY_XYZ: &str = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n";

#[test]
fn truncated_binary_ply() {
    let mut bytes = PLY_XYZ.as_bytes().to_vec();
    bytes.extend_from_slice(&[0u8; 30]);
    let m = error("trunc.ply", &bytes);
    assert_contains(
        &m,
        &[
            "byte offset",
            "3 vertex records",
            "need at least 36 bytes",
            "only 30 bytes",
        ],
    );
}

#[test]
fn more_vertices_declared_than_present() {
    let ascii = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n3 3 3\n";
    let m = error("short.ply", ascii.as_bytes());
    assert_contains(&m, &["line 12", "unexpected end of file", "vertex 4 of 5"]);
}

#[test]
fn huge_vertex_count_fails_fast() {
    for format in ["ascii", "binary_little_endian"] {
        let header = format!(
            "ply\nformat {format} 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n"
        );
        let start = Instant::now();
        let m = error("huge.ply", header.as_bytes());
        assert!(
            start.elapsed().as_millis() < 500,
            "took {:?}",
            start.elapsed()
        );
        assert_contains(
            &m,
            &["4000000000 vertex records", "bytes follow the header"],
        );
    }
    let pcd = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 4000000000\nDATA binary\n\0\0\0\0";
    assert_contains(
        &error("huge.pcd", pcd.as_bytes()),
        &["4000000000 points", "DATA size mismatch"],
    );
}

#[test]
fn bad_number_names_line_and_expectation() {
    let ascii = "ply\nformat ascii 1.0\ncomment bad\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n1.0 abc\n";
    let m = error("bunny.ply", ascii.as_bytes());
    assert!(
        m.ends_with("bunny.ply: line 11: expected 2 numbers for vertex 2, found \"1.0 abc\""),
        "{m}"
    );
    let xyz = "# points\n0 0 0\n1 2 3\n4 5 x6\n";
    assert_contains(
        &error("pts.xyz", xyz.as_bytes()),
        &["line 4", "expected a number in column 3", "\"x6\""],
    );
    let obj = "v 0 0 0\nv 1 1 1\nv 2 zz 2\n";
    assert_contains(
        &error("m.obj", obj.as_bytes()),
        &["line 3", "expected numbers"],
    );
    let pcd = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n0 0 0\n1 1\n";
    assert_contains(
        &error("a.pcd", pcd.as_bytes()),
        &["line 7", "expected 3 numbers for point 1", "\"1 1\""],
    );
}

#[test]
fn face_index_out_of_range() {
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n";
    let m = error("faces.ply", ascii.as_bytes());
    assert_contains(
        &m,
        &[
            "line 14",
            "face 1",
            "vertex index 3 is out of range",
            "expected 0..3",
        ],
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# comment\nf 1 2 4\n";
    assert!(error("faces.obj", obj.as_bytes())
        .ends_with(": line 6: face index 4 is out of range (the file has 3 vertices)"),);
    let obj = "v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 0 1 0\n";
    assert!(error("neg.obj", obj.as_bytes())
        .ends_with(": line 3: face index -3 is out of range (the file has 3 vertices)"));
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n";
    assert!(error("normals.obj", obj.as_bytes())
        .ends_with(": line 5: face normal index 2 is out of range (the file has 1 normals)"));
}

/// The first `len` bytes of a file in the shared test data.
fn cut(rel: &str, len: impl Fn(usize) -> usize) -> Vec<u8> {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let mut bytes = std::fs::read(root.join(rel)).unwrap();
    bytes.truncate(len(bytes.len()));
    bytes
}

#[test]
fn truncated_laz_names_the_point_record_and_the_end() {
    let half = cut("lidar/autzen_trim.laz", |n| n / 2);
    let m = error("half.laz", &half);
    let (record, end) = m
        .strip_suffix(" ends past the end of the file at byte 301676 (truncated file?)")
        .and_then(|m| m.split_once(": point record "))
        .map(|(_, rest)| rest.split_once(" of ").unwrap())
        .unwrap_or_else(|| panic!("{m}"));
    assert_eq!(end, "110000", "{m}");
    // About half of the points decode before the data runs out.
    let record: u64 = record.parse().unwrap();
    assert!((45_000..60_000).contains(&record), "{m}");
    let header_only = cut("lidar/autzen_trim.laz", |_| 300);
    let m = error("header.laz", &header_only);
    assert!(
        m.ends_with(": byte offset 96: the point data starts at byte 2144, past the end of the file at byte 300 (truncated file?)"),
        "{m}"
    );
}

#[test]
fn truncated_las_names_the_point_record_and_the_end() {
    // 110,000 records of 34 bytes after a 2,038-byte header: (1,871,019 - 2,038) / 34 = 54,970
    // whole records.
    let half = cut("lidar/autzen_trim.las", |n| n / 2);
    assert!(error("half.las", &half).ends_with(
        ": point record 54970 of 110000 ends past the end of the file at byte 1871019 (truncated file?)"
    ));
}

#[test]
fn control_bytes_in_file_text_are_escaped() {
    let ply =
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty dbl n\x1b[31m\x07ame\nend_header\n0\n";
    let m = error("control.ply", ply);
    assert!(
        m.ends_with(": line 4: expected \"property <type> <name>\" or \"property list <count type> <item type> <name>\", found \"property dbl n\\u{1b}[31m\\u{7}ame\""),
        "{m}"
    );
    assert!(!m.chars().any(char::is_control), "{m:?}");
    let long = format!("{}\x01\n", "7".repeat(200));
    let m = error("long.xyz", long.as_bytes());
    assert!(
        m.ends_with(&format!(
            ": line 1: expected a number in column 1, found \"{}…\"",
            "7".repeat(80)
        )),
        "{m}"
    );
    let m = error("control.obj", b"v 0 0 0\nv 1 \x1bx 0\n");
    assert!(
        m.ends_with(r#": line 2: expected numbers, found "1" "\u{1b}x" "0""#),
        "{m}"
    );
}

#[test]
fn unknown_format() {
    let m = error("cloud.e58", b"whatever");
    assert_contains(
        &m,
        &["unsupported file type \"e58\"", ".ply", ".copc.laz", ".e57"],
    );
    let m = error("noext", b"whatever");
    assert_contains(&m, &["unsupported file type \"\""]);
}

fn compressed_pcd(block: &[u8], uncompressed: u32) -> Vec<u8> {
    let mut bytes =
        b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n"
            .to_vec();
    bytes.extend_from_slice(&(block.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&uncompressed.to_le_bytes());
    bytes.extend_from_slice(block);
    bytes
}

#[test]
fn pcd_compressed_corruption() {
    // A valid block: one literal run of 24 bytes (2 points x 3 floats).
    let mut block = vec![23u8];
    for v in [0f32, 1.0, 0.0, 1.0, 0.0, 1.0] {
        block.extend_from_slice(&v.to_le_bytes());
    }
    let ok = scene::load(&file("ok.pcd", &compressed_pcd(&block, 24))).unwrap();
    assert_eq!(ok.len(), 2);

    let mut truncated = compressed_pcd(&block, 24);
    truncated.truncate(truncated.len() - 5);
    assert_contains(
        &error("trunc.pcd", &truncated),
        &[
            "byte offset",
            "truncated compressed block",
            "expected 25 bytes, found 20",
        ],
    );

    let bad_ref = [0u8, 7, (1 << 5), 40, 0, 0];
    let m = error("backref.pcd", &compressed_pcd(&bad_ref, 24));
    assert_contains(
        &m,
        &[
            "corrupt LZF data",
            "back-reference at compressed offset 2 points 41 bytes back",
        ],
    );

    let m = error("size.pcd", &compressed_pcd(&block, 30));
    assert_contains(&m, &["DATA size mismatch", "need 24 bytes", "declares 30"]);
}

#[test]
fn pcd_binary_size_mismatch() {
    let mut bytes =
        b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4\nHEIGHT 1\nDATA binary\n".to_vec();
    bytes.extend_from_slice(&[0u8; 40]);
    let m = error("short.pcd", &bytes);
    assert_contains(
        &m,
        &[
            "DATA size mismatch",
            "4 points of 12 bytes (3 values) need 48 bytes",
            "only 40 bytes",
        ],
    );
    let header = "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n0 0 0\n";
    assert_contains(
        &error("fields.pcd", header.as_bytes()),
        &["one entry per field (3 fields)"],
    );
}

#[test]
fn empty_files() {
    for (name, expected) in [
        ("empty.ply", "empty file; expected a PLY header"),
        ("empty.pcd", "empty file; expected a PCD header"),
        ("empty.xyz", "no points; expected lines of x y z values"),
        ("empty.las", "invalid LAS header"),
        ("empty.laz", "invalid LAS header"),
    ] {
        assert_contains(&error(name, b""), &[expected]);
    }
    // An OBJ without vertices is a mesh of 0 points, as PDAL and trimesh read it.
    for (name, text) in [
        ("empty.obj", &b""[..]),
        ("comments.obj", b"# Blender export\n"),
        ("material.obj", b"mtllib m.mtl\no nothing\n"),
    ] {
        let c = load(name, text).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((c.len(), c.faces.as_ref().map(Vec::len)), (0, Some(0)));
    }
}

#[test]
fn truncated_obj_names_the_line_or_warns() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 3 2";
    let path = file("cut.obj", obj.as_bytes());
    assert_eq!(
        scene::load(&path).unwrap_err().to_string(),
        format!(
            "{}: line 5: a face with 2 corners; expected at least 3 (is the file cut short?)",
            path.display()
        )
    );
    let c = load("cut_vertex.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0.25").unwrap();
    assert_eq!(c.len(), 3);
    assert_eq!(c.stats.warnings.len(), 1);
    assert!(
        c.stats.warnings[0].ends_with(
            "cut_vertex.obj: line 3: the file ends inside a \"v\" record, without a line end; it may be cut short"
        ),
        "{:?}",
        c.stats.warnings
    );
}

#[test]
fn binary_garbage() {
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    assert_contains(
        &error("g.ply", &garbage),
        &["line 1", "expected the magic line \"ply\""],
    );
    assert_contains(
        &error("g.las", &garbage),
        &["byte offset 0: expected the LAS signature \"LASF\""],
    );
    assert_contains(
        &error("g.xyz", &garbage),
        &["line 1", "expected a number in column 1"],
    );
    assert_contains(
        &error("g.pcd", &garbage),
        &["line 1", "expected a PCD header keyword"],
    );
    // Garbage after a valid PLY header: the face list lengths cannot fit.
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nelement face 100\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    ply.extend_from_slice(&garbage[..24 + 100]);
    let m = error("g2.ply", &ply);
    assert_contains(&m, &["byte offset"]);
}

#[test]
fn xyz_with_two_columns() {
    let m = error("two.xyz", b"1 2\n3 4\n");
    assert!(
        m.ends_with("line 1: expected at least 3 numbers (x y z), found 2: \"1 2\""),
        "{m}"
    );
}

#[test]
fn nan_coordinates_dropped_and_counted() {
    let c = load("nan.xyz", b"0 0 0\nnan 1 1\n1 inf 1\n2 2 2\n").unwrap();
    assert_eq!(
        (c.len(), c.stats.records, c.stats.dropped_non_finite),
        (2, 4, 2)
    );
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\nnan 0 0\n0 1 0\n3 0 1 3\n3 0 1 2\n";
    let c = load("nan.ply", ply.as_bytes()).unwrap();
    assert_eq!(c.len(), 3);
    assert_eq!(c.stats.dropped_non_finite, 1);
    // The face through the dropped vertex is removed, the other re-indexed.
    assert_eq!(c.faces, Some(vec![[0, 1, 2]]));
}

/// `bytes` with the little-endian `value` written over `len` bytes at `at`.
fn patched(mut bytes: Vec<u8>, at: usize, value: u64, len: usize) -> Vec<u8> {
    bytes[at..at + len].copy_from_slice(&value.to_le_bytes()[..len]);
    bytes
}

#[test]
fn malformed_e57_names_the_offset() {
    // bunnyFloat.e57: 374,784 bytes, its XML section (2,176 bytes) at byte 372,332.
    let m = error("half.e57", &cut("e57/bunnyFloat.e57", |n| n / 2));
    assert!(
        m.ends_with(": byte offset 24: the XML section (2176 bytes at byte 372332) ends past the end of the file at byte 187392 (truncated file?)"),
        "{m}"
    );
    let m = error("head.e57", &cut("e57/bunnyFloat.e57", |_| 30));
    assert!(
        m.ends_with(": the file ends at byte 30, inside the 48-byte E57 header"),
        "{m}"
    );
    let whole = cut("e57/bunnyFloat.e57", |n| n);
    let m = error("xml.e57", &patched(whole.clone(), 32, 1 << 40, 8));
    assert_contains(
        &m,
        &["byte offset 24", "the XML section (1099511627776 bytes"],
    );
    let m = error("sig.e57", &patched(whole.clone(), 0, 0, 1));
    assert!(
        m.ends_with(": byte offset 0: expected the E57 signature \"ASTM-E57\""),
        "{m}"
    );
    // A flipped byte in the first data page: the page checksum fails while reading scan 0.
    let mut flipped = whole;
    flipped[1100] ^= 0x40;
    let m = error("crc.e57", &flipped);
    assert_contains(&m, &["scan 0, record 0: ", "invalid checksum", "page 1"]);
}

#[test]
fn malformed_copc_names_the_offset() {
    // 1.2-with-color.copc.laz: 33,684 bytes; the hierarchy EVLR at 31,544, its root page
    // (65 entries) at 31,604; the root node's entry (24 points, 665 bytes at byte 28,853) first.
    let rel = "copc/1.2-with-color.copc.laz";
    let m = error("half.copc.laz", &cut(rel, |n| n / 2));
    assert!(
        m.ends_with(": byte offset 31544: the first EVLR header (60 bytes) ends past the end of the file at byte 16842 (truncated file?)"),
        "{m}"
    );
    let m = error("cut.copc.laz", &cut(rel, |_| 31_700));
    assert!(
        m.ends_with(": byte offset 31564: the first EVLR (2080 bytes) ends past the end of the file at byte 31700 (truncated file?)"),
        "{m}"
    );
    let whole = cut(rel, |n| n);
    // The 64-bit point count (byte 247) with the legacy 32-bit one (byte 107) zero.
    let m = error(
        "huge.copc.laz",
        &patched(patched(whole.clone(), 107, 0, 4), 247, 1 << 40, 8),
    );
    assert!(
        m.ends_with(": byte offset 247: the header declares 1099511627776 points, more than a file of 33684 bytes can hold"),
        "{m}"
    );
    let m = error("more.copc.laz", &patched(whole.clone(), 107, 1_066, 4));
    assert!(
        m.ends_with(": the COPC hierarchy holds 1065 points, but the header declares 1066"),
        "{m}"
    );
    let m = error(
        "count.copc.laz",
        &patched(whole.clone(), 31_632, i32::MAX as u64, 4),
    );
    assert!(
        m.ends_with(": byte offset 31604: a chunk of 665 bytes cannot hold the 2147483647 points it declares"),
        "{m}"
    );
    let m = error("far.copc.laz", &patched(whole.clone(), 31_620, 1 << 40, 8));
    assert!(
        m.ends_with(": byte offset 31604: the chunk of 24 points (665 bytes at byte 1099511627776) is not inside the file of 33684 bytes (truncated file?)"),
        "{m}"
    );
    let one_more = patched(patched(whole.clone(), 31_632, 25, 4), 107, 1_066, 4);
    let m = error("chunk.copc.laz", &one_more);
    assert!(
        m.ends_with(": byte offset 28889: the chunk holds 24 points, but its hierarchy entry at byte 31604 declares 25"),
        "{m}"
    );
    let m = error("layers.copc.laz", &patched(whole, 28_893, 1 << 31, 4));
    assert_contains(
        &m,
        &[
            "byte offset 28893: the chunk's layers need",
            "bytes, but only",
        ],
    );
    let m = error("plain.copc.laz", &cut("lidar/autzen_trim.laz", |n| n));
    assert!(
        m.ends_with(": byte offset 24: expected LAS version 1.4 (COPC), found 1.2"),
        "{m}"
    );
}

#[test]
fn e57_scan_claiming_2_pow_40_records_fails_at_the_end_of_its_data() {
    // bunnyFloat.e57 with the scan's recordCount raised from 30,571 to 2^40.
    let bytes = common::bunny_e57_claiming(1 << 40);
    let m = error("records.e57", &bytes);
    assert_contains(&m, &["scan 0, record 30571: "]);
}
