//! Writes the seed corpus of every target into `corpus/TARGET/`, from the real files in
//! `../shared/data` (small ones whole, larger ones cut to a few dozen points and written again
//! in each encoding the loader reads). Run from `fuzz/`: `cargo run --release --example seed -- ../../shared/data`.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use las::{Builder, Reader, Writer};

/// Points kept from a large file.
const POINTS: usize = 48;

fn put(target: &str, name: &str, bytes: &[u8]) {
    let dir = PathBuf::from("corpus").join(target);
    std::fs::create_dir_all(&dir).expect("corpus folder");
    std::fs::write(dir.join(name), bytes).expect("seed file");
}

fn copy(data: &Path, target: &str, rel: &str) {
    let bytes = std::fs::read(data.join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"));
    put(target, &rel.replace('/', "_"), &bytes);
}

/// The first [`POINTS`] points of a LAS/LAZ file, written again as LAS 1.2/1.4, compressed or
/// not, with its own point format.
fn las_subset(data: &Path, rel: &str, version: (u8, u8), compressed: bool) -> Vec<u8> {
    let mut reader = Reader::from_path(data.join(rel)).expect("readable LAS");
    let mut builder = Builder::from(version);
    builder.point_format = *reader.header().point_format();
    builder.point_format.is_compressed = compressed;
    builder.transforms = *reader.header().transforms();
    if version.1 >= 4 {
        builder.evlrs.push(las::Vlr {
            user_id: "surfel".into(),
            record_id: 1,
            description: "seed EVLR".into(),
            data: vec![7; 40],
        });
    }
    let header = builder.into_header().expect("valid header");
    let mut writer = Writer::new(Cursor::new(Vec::new()), header).expect("writer");
    for point in reader.points().take(POINTS) {
        writer
            .write_point(point.expect("a point"))
            .expect("written");
    }
    writer.close().expect("closed");
    writer.into_inner().expect("bytes").into_inner()
}

/// LZF literal runs (at most 32 bytes each): valid `binary_compressed` data.
fn lzf_literals(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for run in bytes.chunks(32) {
        out.push((run.len() - 1) as u8);
        out.extend_from_slice(run);
    }
    out
}

fn pcd_seeds(data: &Path) {
    let cloud = surfel::scene::load(&data.join("pcd/table_scene_mug_stereo_textured.pcd"))
        .expect("readable PCD");
    let points: Vec<([f32; 3], [u8; 4])> = cloud
        .positions
        .iter()
        .zip(cloud.colors.as_deref().unwrap_or(&[]))
        .take(POINTS)
        .map(|(p, c)| (p.to_array(), *c))
        .collect();
    let header = |encoding: &str| {
        format!(
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {encoding}\n",
            n = points.len()
        )
        .into_bytes()
    };
    let rgb = |c: [u8; 4]| u32::from_le_bytes([c[2], c[1], c[0], c[3]]);
    let mut ascii = header("ascii");
    for (p, c) in &points {
        ascii.extend(format!("{} {} {} {}\n", p[0], p[1], p[2], rgb(*c)).bytes());
    }
    put("pcd", "ascii.pcd", &ascii);
    let mut binary = header("binary");
    for (p, c) in &points {
        for v in p {
            binary.extend(v.to_le_bytes());
        }
        binary.extend(rgb(*c).to_le_bytes());
    }
    put("pcd", "binary.pcd", &binary);
    let mut columns = Vec::new();
    for axis in 0..3 {
        for (p, _) in &points {
            columns.extend(p[axis].to_le_bytes());
        }
    }
    for (_, c) in &points {
        columns.extend(rgb(*c).to_le_bytes());
    }
    let block = lzf_literals(&columns);
    let mut compressed = header("binary_compressed");
    compressed.extend((block.len() as u32).to_le_bytes());
    compressed.extend((columns.len() as u32).to_le_bytes());
    compressed.extend(block);
    put("pcd", "binary_compressed.pcd", &compressed);
}

fn ply_seeds(data: &Path) {
    let mut cloud = surfel::scene::load(&data.join("ply/frag_115.ply")).expect("readable PLY");
    cloud.faces = None;
    let keep = POINTS.min(cloud.positions.len());
    cloud.positions.truncate(keep);
    if let Some(n) = cloud.normals.as_mut() {
        n.truncate(keep);
    }
    if let Some(c) = cloud.colors.as_mut() {
        c.truncate(keep);
    }
    cloud.scalars.clear();
    let mut binary = Vec::new();
    surfel::scene::ply::write_binary(&cloud, &mut binary).expect("written");
    put("ply", "binary.ply", &binary);
    let bunny = std::fs::read_to_string(data.join("stanford/bun_zipper.ply")).expect("bunny");
    let (head, body) = bunny.split_once("end_header\n").expect("a PLY header");
    let lines: Vec<&str> = body.lines().collect();
    let faces: Vec<&str> = lines[35_947..]
        .iter()
        .filter(|f| {
            f.split_whitespace()
                .skip(1)
                .all(|i| i.parse::<usize>().is_ok_and(|i| i < POINTS))
        })
        .copied()
        .collect();
    let head = head
        .replace("element vertex 35947", &format!("element vertex {POINTS}"))
        .replace(
            "element face 69451",
            &format!("element face {}", faces.len()),
        );
    let ascii = format!(
        "{head}end_header\n{}\n{}\n",
        lines[..POINTS].join("\n"),
        faces.join("\n")
    );
    put("ply", "ascii.ply", ascii.as_bytes());
}

fn text_seeds(data: &Path) {
    let cloud = surfel::scene::load(&data.join("lidar/autzen_trim.las")).expect("readable LAS");
    let mut named = String::from("X,Y,Z,Intensity,Red,Green,Blue\r\n");
    let mut bare = String::from("# x y z r g b\n");
    for (i, p) in cloud.positions.iter().take(POINTS).enumerate() {
        let w = cloud.origin + p.as_dvec3();
        let c = cloud.colors.as_ref().map_or([0; 4], |c| c[i]);
        named += &format!(
            "{:.2},{:.2},{:.2},{},{},{},{}\r\n",
            w.x, w.y, w.z, cloud.scalars[0].values[i], c[0], c[1], c[2]
        );
        bare += &format!(
            "{:.2} {:.2} {:.2} {} {} {}\n",
            w.x, w.y, w.z, c[0], c[1], c[2]
        );
    }
    // The text target reads its first byte as the extension: 0 .xyz, 1 .txt, 2 .pts, 3 .csv.
    put("text", "named.csv", &[b"\x03", named.as_bytes()].concat());
    put("text", "bare.xyz", &[b"\x00", bare.as_bytes()].concat());
    put(
        "text",
        "count.pts",
        b"\x022\n0 0 0 10 1 2 3\n1 1 1 20 4 5 6\n",
    );
}

fn scene_seeds() {
    put(
        "scene",
        "scene.toml",
        b"up = \"z\"\nedl = { strength = 1.0, radius = 1.4 }\nbackground = \"#202020\"\ncolor_by = \"intensity\"\n[camera]\norbit = [30.0, 15.0]\ndistance = 1.5\n[[lights]]\nkind = \"static\"\nposition = [1.0, 2.0, 3.0]\ncolor = [1.0, 0.9, 0.8]\n[[inputs]]\npath = \"b.obj\"\nas = \"points\"\ntranslate = [0.3, 0.0, 0.0]\nscale = 0.2\n",
    );
    put(
        "scene",
        "scene.json",
        br#"{"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]}, "lights": [{"kind": "orbit"}], "background": "transparent", "edl": {}}"#,
    );
}

fn main() {
    let data = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "../../shared/data".into()),
    );
    for rel in ["copc/autzen.copc.laz", "copc/1.2-with-color.copc.laz"] {
        copy(&data, "copc", rel);
    }
    for rel in [
        "e57/tiny_spherical.e57",
        "e57/tinyCartesianFloatRgb.e57",
        "e57/corrupt_crc.e57",
    ] {
        copy(&data, "e57", rel);
    }
    for rel in ["plants/Plant_3.obj", "plants/PalmTree_1.obj"] {
        copy(&data, "obj", rel);
    }
    for (target, compressed) in [("las", false), ("laz", true)] {
        for (rel, version) in [
            ("lidar/autzen_trim.las", (1, 2)),
            ("lidar/vegetation_1_3.las", (1, 3)),
            ("lidar/autzen_trim.las", (1, 4)),
        ] {
            let name = format!("{}_1{}.{target}", rel.replace('/', "_"), version.1);
            put(target, &name, &las_subset(&data, rel, version, compressed));
        }
    }
    pcd_seeds(&data);
    ply_seeds(&data);
    text_seeds(&data);
    scene_seeds();
    println!("seeds written under corpus/");
}
